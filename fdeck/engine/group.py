"""What the engine and the compiler need from an element group (one section: one formulation x one material).

Groups are built by the formulation's registry hook (``registry.FormulationKind.build``); ``compile.problem`` and
``engine.solver`` use only what this protocol names, so a new element kind is a new module, not an edit there.
Densities are the step plan's: mass and rest steps are pure functions of a given density, and the engine hands a
step's densities to the group once, with ``set_density``, at the start of that step.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from fdeck.engine.ledger import Term


@runtime_checkable
class ElementGroup(Protocol):
    name: str
    cell_type: str  # meshio cell type of the elements ("hexahedron", "quad", "triangle")
    conn: np.ndarray  # (n_el, nodes per element) node indices
    ids: np.ndarray  # (n_el,) user element ids
    element_index: np.ndarray  # (n_el,) indices into the mesh's cells of ``cell_type`` (set by the compiler)
    section_index: int  # index of the deck section (set by the compiler)
    rho: np.ndarray  # (n_el,) density in use [t/mm^3]
    solid: bool  # continuum hexahedra with centre gradients b (n_el, 8, 3), V0, L0, dt_e (bulk viscosity)
    rotational: bool  # nodes carry directors and rotations (see ``RotationalGroup``)
    terms: tuple[Term, ...]  # the group's ledger entries (see ``engine.ledger``)

    def update(self, x: np.ndarray, v: np.ndarray) -> None:
        """Kinematics, material and element forces at positions x and velocities v (n_node, 3)."""

    def add_forces(self, f_int: np.ndarray) -> None:
        """Add the internal nodal forces [N] into f_int (n_node, 3)."""

    def term_values(self) -> tuple[float, ...]:
        """Current values of ``terms`` (stored energies [mJ], dissipation rates [mW])."""

    def stable_dt(self) -> float:
        """Smallest element step [s] at the current state and densities."""

    def rest_dt(self, rho: np.ndarray) -> np.ndarray:
        """(n_el,) element steps [s] at rest with densities rho (n_el,)."""

    def mass(self, rho: np.ndarray) -> np.ndarray:
        """(n_el, nodes per element) lumped nodal masses [t] with densities rho (n_el,)."""

    def set_density(self, rho: np.ndarray) -> None:
        """Use densities rho (n_el,) [t/mm^3] from now on (the start of a step)."""

    def worst_jacobian(self) -> tuple[float, int]:
        """(smallest det F over the group's points, its element id)."""

    def cell_fields(self, idx=None, names=None) -> dict[str, np.ndarray]:
        """Per-element output fields for all elements or the local indices idx; with ``names`` (field names) a
        group may leave out the costly fields not named (the cheap ones may come along)."""


@runtime_checkable
class RotationalGroup(ElementGroup, Protocol):
    """A group whose nodes carry directors (shells): the compiler sets the directors, the engine binds rotations."""

    def add_normals(self, acc: np.ndarray, mag: np.ndarray) -> None:
        """Add area-weighted unit normals at the group's nodes into acc (n_node, 3) and their weights into mag."""

    def flipped_elements(self, d0: np.ndarray) -> np.ndarray:
        """User ids of elements whose normal opposes the nodal directors d0 (n_node, 3)."""

    def set_directors(self, d0: np.ndarray) -> None:
        """Derive the reference arrays from the nodal directors d0 (n_node, 3)."""

    def inertia(self, rho: np.ndarray) -> np.ndarray:
        """(n_el, nodes per element) lumped rotational inertia [t mm^2] with densities rho."""

    def bind(self, rotations) -> None:
        """Use the engine's nodal rotations (``engine.rotation.Rotations``)."""
