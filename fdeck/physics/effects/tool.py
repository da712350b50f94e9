"""A rigid tool as a body of its own: its surface (analytic or triangulated) and its translation u(t).

Motion kinds (``cards.contact.Motion``): a prescribed displacement u(t) = value a(t) d, a prescribed velocity
(u integrated by the rectangle rule on the engine's steps, so u(t) is exact for a constant velocity), or a force
F(t) = value a(t) along d driving a tool of mass M against the contact reactions of the blank:
M dV/dt = F(t) - (sum of the contact forces of the tool on the blank) . d, integrated with the blank's central
differences (V at half steps, u at full steps), so a blank holder presses the blank with F once it has settled.
The tool moves along d only (a holder guided in its press).

Contact pairs (``effects.contact``) read ``u`` and add their force on the blank to ``load`` each cycle; the tool
reports its displacement (and, driven by a force, its velocity and kinetic energy) as history columns. Its kinetic
energy and the driving force's work are outside the blank's ledger: the contact pairs book the work of the tool
on the blank (``tool_work_<name>``), which is what the blank's balance needs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.engine.ledger import VALUE, Term
from fdeck.physics.tools import analytic, triangulated
from fdeck.registry import EffectKind, register_effect

ANALYTIC, MESH = 0, 1


class RigidTool(Effect):
    """One tool: ``kind`` ANALYTIC (``shape_kind``, ``params`` of ``tools.analytic``) or MESH (``mesh`` triangle
    arrays, the query grid built by the first contact pair, which knows the search radius); ``u`` (3,) [mm]."""

    forces = "internal"  # adds nothing to the blank: clears the contact pairs' load before they run
    moves = True
    subcycling_safe = True  # no force of its own on the blank

    def __init__(self, name, card, amplitude, surface, extent):
        self.name, self.tool = f"tool:{name}", name
        self.extent = extent  # (6,) lo, hi of the blank [mm]: where to facet an analytic tool for display
        mo = card.motion
        self.mode = "fixed" if mo is None else mo.kind
        d = np.asarray(mo.direction if mo is not None else (0.0, 0.0, -1.0), float)
        self.direction = d / np.linalg.norm(d)
        self.value = mo.value if mo is not None else 0.0
        self.amp = amplitude
        self.mass = mo.mass if mo is not None and mo.kind == "force" else None
        self.kind, self.shape_kind, self.params, self.mesh = surface
        self.grid = None  # triangulated.Surface once a contact pair has built it
        self.u, self.V = np.zeros(3), 0.0  # displacement [mm], speed along the direction [mm/s] (half step)
        if self.mode == "displacement":
            self.u = self.value * self.amp(0.0) * self.direction
        self.load = np.zeros(3)  # force of the tool on the blank, summed by the contact pairs [N]
        self.load_stiffness = 0.0  # sum of the pairs' largest nodal stiffnesses [N/mm] (force-driven step bound)
        self.terms = tuple(Term(f"tool_{name}_displacement_{c}", VALUE) for c in "xyz")
        if self.mass is not None:
            self.terms += (Term(f"tool_{name}_velocity", VALUE), Term(f"tool_{name}_kinetic_energy", VALUE))

    def speed_bound(self, t0: float, t1: float) -> float:
        """Largest speed of the tool over [t0, t1] [mm/s] (sampled finely for a prescribed motion; a force-driven
        tool's current speed is used by ``stable_dt`` instead)."""
        if self.mode in ("fixed", "force"):
            return 0.0
        t = np.linspace(t0, t1, 4001)
        a = np.array([self.amp(s) for s in t])
        if self.mode == "velocity":
            return float(np.abs(self.value * a).max())
        return float(np.abs(np.diff(self.value * a)).max() / (t[1] - t[0]))

    def velocity(self, t: float, dt: float) -> np.ndarray:
        """(3,) [mm/s] the tool's velocity over [t, t + dt] as ``advance`` will move it (a force-driven tool: its
        last half step's, its next one depending on the load being computed)."""
        if self.mode == "displacement":
            return self.value * (self.amp(t + dt) - self.amp(t)) / dt * self.direction
        if self.mode == "velocity":
            return self.value * self.amp(t + 0.5 * dt) * self.direction
        return self.V * self.direction if self.mode == "force" else np.zeros(3)

    def advance(self, t_next, dt, dt_avg):
        if self.mode == "displacement":
            self.u = self.value * self.amp(t_next) * self.direction
        elif self.mode == "velocity":
            self.u = self.u + dt * self.value * self.amp(t_next - 0.5 * dt) * self.direction
        elif self.mode == "force":
            # load is the force at t_n of the tool on the blank; the blank pushes back with -load
            f = self.value * self.amp(t_next - dt) - float(np.dot(self.load, self.direction))
            self.V += dt_avg * f / self.mass
            self.u = self.u + dt * self.V * self.direction

    def add_force(self, t, x, v, f):
        self.load[:] = 0.0  # the contact pairs, built after the tools, add theirs

    def stable_dt(self):
        if self.mass is None or self.load_stiffness <= 0.0:
            return math.inf
        return math.sqrt(self.mass / self.load_stiffness)

    def term_values(self):
        out = tuple(self.u.tolist())
        if self.mass is not None:
            out += (self.V, 0.5 * self.mass * self.V * self.V)
        return out

    def display(self) -> tuple[np.ndarray, np.ndarray]:
        """(points (n, 3), triangles (m, 3)) of the tool surface at rest, for the frame series; analytic shapes are
        faceted around the region the blank occupies."""
        if self.kind == MESH:
            return self.mesh
        return analytic.facets(self.shape_kind, self.params, self.extent)

    def surfaces(self):
        P, T = self.display()
        return [(self.tool, P + self.u, T)]


def build_tool(name: str, card, ctx) -> RigidTool:
    """The tool ``name`` of the deck (``card`` its ``cards.contact.Tool``), its file read relative to the deck."""
    s = card.surface
    if s.shape == "mesh":
        path = Path(s.file) if Path(s.file).is_absolute() else ctx.base / s.file
        if not path.exists():
            raise CompileError([(("tools", name, "surface", "file"), f"surface file '{path}' does not exist")])
        try:
            P, T = triangulated.read(path, s.part)
            P = P * s.scale + np.asarray(s.offset)
            if s.flip:
                T = T[:, ::-1].copy()
            triangulated.pseudonormals(P, T)  # refuses degenerate and non-manifold surfaces here, located
        except (ValueError, OSError) as exc:
            raise CompileError([(("tools", name, "surface"), f"{path.name}: {exc}")]) from None
        surface = (MESH, -1, np.zeros(8), (np.ascontiguousarray(P), np.ascontiguousarray(T, np.int64)))
    else:
        try:
            kind, params = analytic.pack(s)
        except ValueError as exc:  # a profile whose fillets do not fit
            raise CompileError([(("tools", name, "surface"), str(exc))]) from None
        surface = (ANALYTIC, kind, params, None)
    amp = ctx.amplitude(card.motion.amplitude_name) if card.motion is not None else (lambda t: 0.0)
    return RigidTool(name, card, amp, surface, np.concatenate([ctx.X.min(axis=0), ctx.X.max(axis=0)]))


register_effect(EffectKind("tool", build_tool))
