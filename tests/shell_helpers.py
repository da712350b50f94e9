"""Shared helpers for shell tests: a shell group on a small mesh, driven without the engine, and strip decks."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numba
import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.compile.mesh import plate
from fdeck.compile.problem import setup_rotations
from fdeck.physics.elements.shell4 import ShellGroup
from fdeck.registry import CARDS, MATERIALS

from helpers import term

LINEAR = dict(type="fabric_membrane", density=1e-9,
              warp={"tension": [[0, 0], [0.01, 100.0]], "compression": [[0, 0], [-0.01, -20.0]]},
              weft={"tension": [[0, 0], [0.01, 50.0]], "compression": [[0, 0], [-0.01, -50.0]]},
              shear={"curve": [[0, 0], [30, 0.3]], "locking_angle": 40, "locking_modulus": 10.0})
"""A fabric with asymmetric linear curves (tension 1e4 / 5e3 MPa, compression 2e3 / 5e3 MPa) and soft shear."""

SECTIONS = {
    "sm": dict(thickness=0.2, bending_stiffness=0.5, twisting_stiffness=0.2),
    "ts": dict(thickness=0.2, points=3, transverse_shear_modulus=5.0),
    "ts_lobatto": dict(thickness=0.2, points=4, integration="lobatto", transverse_shear_modulus=5.0),
    "membrane": dict(thickness=0.2),
}


@pytest.fixture(autouse=False)
def one_thread():
    """Run kernels on one thread: these meshes are tiny, and on a shared machine a parallel region waits for a
    descheduled second thread (milliseconds per call instead of microseconds). The engine does the same below
    ``solver.SERIAL_BELOW`` elements."""
    n = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(n)


def linear_fabric(E1, E2=None, G=0.3, density=1e-9):
    """A fabric whose fibres are linear and symmetric in tension and compression: a linear orthotropic sheet
    (fibre moduli E1, E2 [MPa], no Poisson coupling) with a linear shear curve of slope G [MPa/rad]."""
    E2 = E1 if E2 is None else E2
    return dict(type="fabric_membrane", density=density,
                warp={"tension": [[0, 0], [0.01, 0.01 * E1]], "compression": [[0, 0], [-0.01, -0.01 * E1]]},
                weft={"tension": [[0, 0], [0.01, 0.01 * E2]], "compression": [[0, 0], [-0.01, -0.01 * E2]]},
                shear={"curve": [[0, 0], [60, G * math.pi / 3]], "locking_angle": 80, "locking_modulus": G})


def make(section: str, X, conn, cell_type="quad", mat=LINEAR, orientation=None, fields=None):
    """(group, state): a shell group of one section on (X, conn) with its reference directors, bound to a
    minimal rotational state (``state.d`` the directors the group reads, ``state.m_int`` its moments).
    ``section``: a key of SECTIONS, or a formulation name with its card ``fields``."""
    kind = MATERIALS["fabric_membrane"]
    card = CARDS["material"]["fabric_membrane"].card(**mat)
    p = kind.pack(card)
    n = len(conn)
    form = "ts" if section.startswith("ts") else section
    extra = {} if orientation is None else {"orientation": orientation}
    fields = SECTIONS[section] if fields is None else fields
    sc = CARDS["formulation"][form].card(formulation=form, material="m", **fields, **extra)
    g = ShellGroup("g", sc, X, conn, np.arange(1, n + 1), kind, np.broadcast_to(p, (n, len(p))),
                   np.full(n, card.density), cell_type)
    g.section_index = 0
    rot = setup_rotations(None, [g], len(X))
    d0 = rot.d0 if rot is not None else np.zeros((len(X), 3))
    state = SimpleNamespace(d=d0.copy(), m_int=np.zeros((len(X), 3)), d0=d0)
    g.bind(state)
    return g, state


def evaluate(g, state, x, d=None):
    """Update the group at (x, d); -> (nodal forces (n, 3), director forces (n, 3), moments (n, 3), energy)."""
    state.d = state.d0 if d is None else d
    state.m_int = np.zeros_like(x)
    g.update(x, np.zeros_like(x))
    f = np.zeros_like(x)
    g.add_forces(f)
    return f, g.director_forces(len(x)), state.m_int, term(g, "strain_energy")


def patch(triangles=False, seed=0, curved=0.0):
    """A distorted 3 x 3 patch on [0, 3] x [0, 2] (nodes moved in-plane by up to 12 % of an edge); optionally
    lifted onto z = curved sin(x) (a curved reference)."""
    m = plate((0, 0, 0), (3.0, 2.0), (3, 3), triangles=triangles)
    rng = np.random.default_rng(seed)
    X = m.X.copy()
    X[:, 0] += 0.12 * rng.uniform(-1, 1, len(X))
    X[:, 1] += 0.08 * rng.uniform(-1, 1, len(X))
    X[:, 2] += curved * np.sin(X[:, 0])
    ctype = "triangle" if triangles else "quad"
    return X, m.cells[ctype], ctype


def rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def strip_deck(form, section, span, width, n, P, material, periods=6.0, timoshenko_ratio=0.0,
               EI=None, rho_h=None):
    """Half of a simply supported strip (0 <= x <= span/2) under a central line load P (total) [N], brought to rest
    with mass-proportional damping: symmetry at x = 0 (x, ry, rz fixed; half the load), support at x = span/2
    (z fixed), y fixed everywhere (no Poisson in the fabric law). Run for ``periods`` first periods of the
    strip, the first 2 of them loading, damped at 2 omega_1 (omega_1 from EI, rho h and the Timoshenko ratio).
    Node sets: sym (x = 0), sup (x = span/2); measure w = mean z of sym."""
    w1 = math.pi**2 * math.sqrt(EI / (rho_h * width * span**4)) / math.sqrt(1.0 + timoshenko_ratio)
    T1 = 2 * math.pi / w1
    return {
        "mesh": {"plate": {"size": [span / 2, width], "divisions": [n, 1]},
                 "node_sets": {"sym": {"box": [[0, 0, 0], [0, width, 0]]},
                               "sup": {"box": [[span / 2, 0, 0], [span / 2, width, 0]]}}},
        "materials": {"m": material},
        "sections": [dict(material="m", formulation=form, **section)],
        "amplitudes": {"load": {"type": "smooth_step", "t1": 2 * T1}},
        "boundary": [{"type": "fixed", "nodes": "all", "dofs": ["y"]},
                     {"type": "fixed", "nodes": "sym", "dofs": ["x", "ry", "rz"]},
                     {"type": "fixed", "nodes": "sup", "dofs": ["z"]}],
        "loads": [{"type": "nodal_force", "nodes": "sym", "force": [0, 0, -P / 2], "distribution": "total",
                   "amplitude": "load"}],
        "steps": [{"duration": periods * T1, "damping": {"mass_proportional": 2 * w1}}],
        "output": {"history_points": 50, "measures": [
            {"type": "node_displacement", "name": "w", "nodes": "sym", "component": "z"}]},
    }
