"""End-of-run tables a forming engineer reads: the shear angle along user paths, the per-element fibre table.

* ``PathTable``: a polyline given in the reference configuration (``output.paths``) sampled evenly along its arc
  length; each sample is located once in its element (``locate``) and followed to the current configuration
  through that element's shape functions; its shear angle is the one of that element (the element holding the
  sample, or the nearest one; the ``distance`` column says which), or with ``through_thickness`` the mean over a
  stack of points across the blank's thickness (a layered blank's mid-plane is a layer interface, where "the
  element holding the sample" is a tie), and with ``window`` over a square around the sample (a filter, so two
  meshes compare the same quantity where the shear changes within an element).
* ``fibre_table``: per element in mesh order, the current centroid, the current unit warp and weft directions and
  the shear angle, for mapping the draped fibre architecture onto a structural model.

Columns are plain arrays; writing them is ``fdeck.io.tables``'s job.
"""

from __future__ import annotations

import numpy as np

from fdeck.compile.mesh import centroids as element_centroids
from fdeck.physics.measures.locate import locate


def polyline(points, samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Corners (k, 3) [mm] -> arc lengths s (samples,) [mm] from the first corner, the points (samples, 3) and the
    unit direction (samples, 3) of the segment each point lies on (at a corner, the later segment's)."""
    P = np.asarray(points, dtype=float)
    d = np.diff(P, axis=0)
    seg = np.linalg.norm(d, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.linspace(0.0, cum[-1], samples)
    i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    t = (s - cum[i]) / seg[i]
    return s, P[i] + t[:, None] * d[i], d[i] / seg[i, None]


class PathTable:
    """One ``output.paths`` entry over the element groups (located once, in the reference configuration).

    With ``through_thickness`` and/or ``window`` each of the n samples carries k averaging points (``stack``
    (n, k, 3): a stack along the thickness axis, times an 8 x 8 grid over the window); the shear angle of a sample
    is the mean over them, and min/max say how much they differ. Points beyond the blank take the nearest element
    (a window hanging over a free edge weights the edge elements more). The sample's own point (as the polyline
    gives it) is still located for the current position and the element column."""

    def __init__(self, card, groups: list, X: np.ndarray, cells: dict[str, np.ndarray]):
        self.name, self.groups = card.name, groups
        starts = np.cumsum([0] + [len(c) for c in cells.values()])
        self.offset = dict(zip(cells, starts.tolist()))  # first mesh-order index of each cell type
        self.s, self.P, direction = polyline(card.points, card.samples)
        self.where = locate(groups, X, self.P)
        self.stack = None
        tt, w = card.through_thickness, card.window
        if tt is not None or w is not None:
            self.stack = self.P[:, None, :] + _offsets(self.P, direction, tt, w)
            self.stack_where = locate(groups, X, self.stack.reshape(-1, 3))

    def _shear(self, where) -> tuple[np.ndarray, np.ndarray]:
        """Shear angle [deg] (NaN where the law has none) and element (1-based, mesh order) at located points."""
        n = len(where.group)
        gamma = np.full(n, np.nan)
        element = np.zeros(n, np.int64)
        for gi, g in enumerate(self.groups):
            sel = np.nonzero(where.group == gi)[0]
            if not len(sel):
                continue
            local, inverse = np.unique(where.element[sel], return_inverse=True)
            element[sel] = self.offset[g.cell_type] + g.element_index[local][inverse] + 1
            fields = g.cell_fields(local, ("shear_angle",))
            if "shear_angle" in fields:
                gamma[sel] = fields["shear_angle"][inverse]
        return gamma, element

    def columns(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Columns at positions x (n_node, 3): arc length [mm], reference point [mm], distance to the element [mm],
        current point [mm], element (1-based, mesh order as in fibres.csv and the frames), shear angle [deg] (NaN where the
        element's law has none; with ``through_thickness`` or ``window`` the mean over the averaging points, plus
        their min and max). Call after the groups were updated at x (their cell fields are read)."""
        gamma, element = self._shear(self.where)
        cur = self.where.current(self.groups, x)
        out = {"arc_length": self.s, "X": self.P[:, 0], "Y": self.P[:, 1], "Z": self.P[:, 2],
               "distance": self.where.distance, "x": cur[:, 0], "y": cur[:, 1], "z": cur[:, 2],
               "element": element, "shear_angle": gamma}
        if self.stack is not None:
            g, _ = self._shear(self.stack_where)
            g = g.reshape(self.stack.shape[:2])
            out["shear_angle"] = g.mean(axis=1)
            out["shear_angle_min"], out["shear_angle_max"] = g.min(axis=1), g.max(axis=1)
        return out


WINDOW_POINTS = 8  # per direction of a path's averaging window


def _offsets(P: np.ndarray, direction: np.ndarray, tt, window: float | None) -> np.ndarray:
    """(n, k, 3) offsets [mm] from each path sample P (n, 3) to its averaging points: through the thickness
    (``tt``: axis, span [faces' coordinates along it], samples) and over a square ``window`` aligned with the path's
    ``direction`` (n, 3) projected on the plane normal to the axis; midpoints of equal sub-intervals, so every point
    carries the same weight."""
    axis = np.asarray(tt.axis if tt is not None else (0.0, 0.0, 1.0), float)
    axis = axis / np.linalg.norm(axis)
    n = len(P)
    if tt is not None:
        lo, hi = tt.span
        c = lo + (np.arange(tt.samples) + 0.5) * (hi - lo) / tt.samples
        through = (c[None, :] - (P @ axis)[:, None])[..., None] * axis  # (n, kt, 3): onto each level
    else:
        through = np.zeros((n, 1, 3))
    if window is None:
        return through
    t = direction - (direction @ axis)[:, None] * axis
    t /= np.linalg.norm(t, axis=1, keepdims=True)  # nonzero: the deck refuses a windowed segment along the axis
    m = np.cross(axis, t)
    u = (np.arange(WINDOW_POINTS) + 0.5) / WINDOW_POINTS * window - window / 2
    a, b = (v.reshape(-1) for v in np.meshgrid(u, u, indexing="ij"))
    plane = a[None, :, None] * t[:, None, :] + b[None, :, None] * m[:, None, :]
    return (through[:, :, None, :] + plane[:, None, :, :]).reshape(n, -1, 3)


def fibre_table(cells: dict[str, np.ndarray], x: np.ndarray, fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per element in mesh order (cells {type: conn}, concatenated in dict order; ``fields`` the assembled cell
    fields, see ``fdeck.run.assemble_cells``): element (1-based), current centroid (mean of the element's distinct
    nodes) [mm], current warp and weft unit vectors (the laws' point-averaged directions renormalised), shear
    angle [deg]. Elements whose law has no fibres get NaN."""
    centroids = np.concatenate([element_centroids(x, conn) for conn in cells.values()])
    n = len(centroids)
    out = {"element": np.arange(1, n + 1), "cx": centroids[:, 0], "cy": centroids[:, 1], "cz": centroids[:, 2]}
    for fam in ("warp", "weft"):
        keys = [f"{fam}_{c}" for c in "xyz"]
        d = np.stack([fields[k] for k in keys], axis=1) if all(k in fields for k in keys) else np.full((n, 3), np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            d = d / np.linalg.norm(d, axis=1, keepdims=True)
        out.update({k: d[:, i] for i, k in enumerate(keys)})
    out["shear_angle"] = fields.get("shear_angle", np.full(n, np.nan))
    return out
