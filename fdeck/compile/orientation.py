"""Fibre orientation per element: the section's `orientation` card, optionally varied element by element by a
cell field of the mesh file (a draped blank, a blank cut at several angles).

Convention (as in Abaqus' *ORIENTATION and LS-DYNA's AOPT/BETA): the reference direction is projected on the plane
normal to the sheet normal and turned by the warp angle about that normal. For hexahedra the plane is the section's
`normal`; shells use each element's own tangent plane (``fdeck.physics.elements.shell4.local_bases``).

A field of one component adds a warp angle [deg] per element to the card's `warp_angle`; a field of three
components replaces `reference` element by element (a warp direction computed by a draping tool, for example).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ElementOrientation:
    """reference (n_el, 3) unit-free direction of warp at angle 0; warp_angle (n_el,) [deg]; normal (3,)."""

    reference: np.ndarray
    warp_angle: np.ndarray
    normal: np.ndarray

    def frames(self) -> np.ndarray:
        """(n_el, 3, 3) rows warp, weft, thickness (unit, right-handed). Raises ValueError on a reference parallel
        to the normal (the normal is checked non-zero by ``element_orientation``)."""
        n = self.normal / np.linalg.norm(self.normal)
        r = self.reference - (self.reference @ n)[:, None] * n
        norm = np.linalg.norm(r, axis=1)
        bad = norm <= 1e-9 * np.linalg.norm(self.reference, axis=1)  # also catches a zero reference
        if bad.any():
            raise ValueError(f"`reference` is parallel to `normal` (or zero) for {int(bad.sum())} elements")
        r /= norm[:, None]
        a = np.radians(self.warp_angle)[:, None]
        warp = np.cos(a) * r + np.sin(a) * np.cross(n, r)
        return np.ascontiguousarray(np.stack([warp, np.cross(n, warp), np.broadcast_to(n, warp.shape)], axis=1))


def element_orientation(card, n_el: int, field: np.ndarray | None = None) -> ElementOrientation:
    """From a deck Orientation card and, if the card names one, its cell field (n_el,) or (n_el, 1) angles [deg]
    or (n_el, 3) reference directions. Raises ValueError with a user-facing message."""
    normal = np.asarray(card.normal, float)
    if np.linalg.norm(normal) == 0:
        raise ValueError("`normal` must not be zero")
    reference = np.tile(np.asarray(card.reference, float), (n_el, 1))
    angle = np.full(n_el, float(card.warp_angle))
    if field is not None:
        values = np.asarray(field, float).reshape(n_el, -1)
        if not np.isfinite(values).all():
            raise ValueError(f"cell field '{card.field}' holds NaN or infinite values")
        if values.shape[1] == 1:
            angle = angle + values[:, 0]
        elif values.shape[1] == 3:
            reference = values.copy()
        else:
            raise ValueError(f"cell field '{card.field}' has {values.shape[1]} components; expected 1 (warp angle "
                             "[deg]) or 3 (reference direction)")
    return ElementOrientation(reference, angle, normal)

