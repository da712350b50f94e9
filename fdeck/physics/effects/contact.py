"""Node-to-rigid-surface penalty contact with Coulomb friction (MODELS 7), against analytic tools.

Per blank node i: its tributary area A_i, for hexahedra the outward vector area a_i of the exterior faces around it
(a quarter of each face's area vector) projected on the contact normal, A_i = max(0, -a_i . n), so that a corner
node of a block resting on a plane carries only its share of the bottom face; for shells a quarter of each element's
area, on both faces, with half the thickness as offset o_i.
gap g = d(x - u) - o with d the tool's signed distance (``physics.tools.analytic``) and u the tool's translation;
overclosure h = -g. Normal force f_n = p(h) A n, from the linear law p = k h or the exponential law of MODELS 7
continued linearly beyond its stiffness cap. Its energy A int p dh is stored (``contact_energy``), so f_n = -dE/dx and
the normal contact is conservative on a plane (on a curved tool A_i varies with n, a term the force omits).

Friction: an elastic stick spring of stiffness k_t = stick_stiffness * (dp/dh)_max A per node carries the tangential
force; the trial force f_t - k_t du_t (du_t the increment of the node's displacement relative to the tool, in the
tangent plane) is returned to mu_d f_n when it exceeds mu_s f_n (mu_d while sliding), a backward-Euler return map
(Simo & Hughes, Computational Inelasticity, 1998, ch. 1, the 1-D elastoplastic analogue). The spring's energy
|f_t|^2 / (2 k_t) is stored; the energy the return map removes, |f_t| times the plastic slip, is dissipated
(``friction_dissipation``), as is the spring's energy when a node leaves contact.

The tool's work on the blank is integrated by the trapezoidal rule on its translation increments
(``tool_work_<tool>``); its force on the blank and its displacement are history columns. With the blank's own work of
the contact forces booked by the engine as internal forces, the balance reads kinetic + stored + dissipated -
tool work = const. Stable step: each contact node is a spring of stiffness k = max(1, stick_stiffness) (dp/dh)_max A
on its lumped mass m; the effect bounds the step by sqrt(m / k) = 1 / omega, half the node's own critical step, so
that the node stays stable with the element stiffness added (up to three times the penalty's) and the penalty's
ringing, which the ledger sees at the dt^2 omega^2 / 8 level of central differences, stays small.

Tools move by a prescribed translation only (no rotation, no force control yet); a tool that moves more than its
nodes' offsets in one cycle against a thin shell could pass through it: the step bound does not prevent that.
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.cards.contact import Contact
from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.engine.ledger import DISSIPATED, STORED, VALUE, WORK, Term
from fdeck.jit import njit, njit_parallel, prange
from fdeck.physics.tools import analytic
from fdeck.registry import EffectKind, register_effect

LINEAR, EXPONENTIAL = 0, 1
E1 = math.e - 1.0


def pack_law(law) -> np.ndarray:
    """(8,) [kind, ...]: linear [0, k]; exponential [1, p0, c0, k_max, h_cap, p_cap, e_cap] with the cap point where
    dp/dh reaches k_max (found by bisection; h_cap = +inf when the cap is never reached before 100 c0)."""
    out = np.zeros(8)
    if law.law == "linear":
        out[:2] = LINEAR, law.stiffness
        return out
    p0, c0, kmax = law.p0, law.c0, law.max_stiffness
    lo, hi = 0.0, 100.0  # z = h / c0 + 1
    if _exp_slope(p0, c0, hi) < kmax:
        h_cap = math.inf
    else:
        if _exp_slope(p0, c0, lo) >= kmax:
            hi = 0.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _exp_slope(p0, c0, mid) < kmax else (lo, mid)
        h_cap = (hi - 1.0) * c0
    out[:5] = EXPONENTIAL, p0, c0, kmax, h_cap
    if math.isfinite(h_cap):
        z = h_cap / c0 + 1.0
        out[5], out[6] = p0 / E1 * z * (math.exp(z) - 1.0), c0 * p0 / E1 * ((z - 1.0) * math.exp(z) + 1.0 - z * z / 2)
    return out


def _exp_slope(p0, c0, z):
    return p0 / (E1 * c0) * (math.exp(z) - 1.0 + z * math.exp(z))


@njit
def normal_law(law, h):
    """(p [MPa], dp/dh [MPa/mm], energy per area int p dh [mJ/mm^2]) at overclosure h [mm]."""
    if law[0] == LINEAR:
        if h <= 0.0:
            return 0.0, 0.0, 0.0
        return law[1] * h, law[1], 0.5 * law[1] * h * h
    p0, c0, kmax, h_cap = law[1], law[2], law[3], law[4]
    if h <= -c0:
        return 0.0, 0.0, 0.0
    if h > h_cap:
        dh = h - h_cap
        return law[5] + kmax * dh, kmax, law[6] + law[5] * dh + 0.5 * kmax * dh * dh
    z = h / c0 + 1.0
    ez = math.exp(z)
    return (p0 / E1 * z * (ez - 1.0), p0 / (E1 * c0) * (ez - 1.0 + z * ez),
            c0 * p0 / E1 * ((z - 1.0) * ez + 1.0 - 0.5 * z * z))


def max_slope(law) -> float:
    """Largest dp/dh of the law [MPa/mm] (the linear stiffness, or the exponential law's cap)."""
    return float(law[1] if law[0] == LINEAR else law[3])


@njit_parallel
def contact_forces(x, nodes, area, vec, offset, two_sided, kind, shape, u, law, kt, mu_s, mu_d, x_prev, u_prev,
                   ft, status, f, gap, pressure, energy, dissipated):
    """Contact forces of every contact node (one node per iteration: no race, same bits on any thread count).

    x (n_node, 3) positions; nodes (k,) node indices; area (k,) [mm^2] of shell nodes; vec (k, 3) outward vector
    area of solid nodes [mm^2]; offset (k,) [mm]; two_sided (k,) bool (shell nodes); kind, shape: the tool
    surface; u (3,) tool translation, u_prev (3,) at the last call; law (8,); kt (k,) stick stiffness [N/mm];
    x_prev (k, 3) node positions at the last call (updated); ft (k, 3) tangential force (updated); status (k,)
    0 open, 1 stick, 2 slip (updated). Outputs f (k, 3) force of the tool on each node [N], gap, pressure (k,)
    [mm, MPa], energy (k,) stored normal + stick energy [mJ], dissipated (k,) friction dissipation of this call [mJ].
    """
    for i in prange(nodes.shape[0]):
        a = nodes[i]
        d, n0, n1, n2 = analytic.distance(kind, shape, x[a, 0] - u[0], x[a, 1] - u[1], x[a, 2] - u[2])
        if two_sided[i] and d < 0.0:
            d, n0, n1, n2 = -d, -n0, -n1, -n2
        g = d - offset[i]
        A = area[i] if two_sided[i] else max(0.0, -(vec[i, 0] * n0 + vec[i, 1] * n1 + vec[i, 2] * n2))
        p, _, e_n = normal_law(law, -g)
        fn = p * A
        # relative tangential displacement increment since the last call
        du0 = (x[a, 0] - x_prev[i, 0]) - (u[0] - u_prev[0])
        du1 = (x[a, 1] - x_prev[i, 1]) - (u[1] - u_prev[1])
        du2 = (x[a, 2] - x_prev[i, 2]) - (u[2] - u_prev[2])
        x_prev[i, 0], x_prev[i, 1], x_prev[i, 2] = x[a, 0], x[a, 1], x[a, 2]
        e_old = (ft[i, 0] ** 2 + ft[i, 1] ** 2 + ft[i, 2] ** 2) / (2.0 * kt[i]) if kt[i] > 0.0 else 0.0
        lost = 0.0
        t0 = t1 = t2 = 0.0
        state = 0
        if fn > 0.0 and kt[i] > 0.0:
            t0, t1, t2 = ft[i, 0] - kt[i] * du0, ft[i, 1] - kt[i] * du1, ft[i, 2] - kt[i] * du2
            tn = t0 * n0 + t1 * n1 + t2 * n2  # keep the tangential part only
            t0, t1, t2 = t0 - tn * n0, t1 - tn * n1, t2 - tn * n2
            trial = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            limit = (mu_s if status[i] != 2 else mu_d) * fn
            state = 1
            if trial > limit:
                slide = mu_d * fn
                lost = slide * (trial - slide) / kt[i]  # |f_t| x plastic slip
                t0, t1, t2 = t0 * slide / trial, t1 * slide / trial, t2 * slide / trial
                state = 2
        elif e_old > 0.0:
            lost = e_old  # the stick spring lets go: its energy is not recovered
        elif fn > 0.0:
            state = 1
        ft[i, 0], ft[i, 1], ft[i, 2] = t0, t1, t2
        status[i] = state if fn > 0.0 else 0
        f[i, 0], f[i, 1], f[i, 2] = fn * n0 + t0, fn * n1 + t1, fn * n2 + t2
        gap[i], pressure[i] = g, p
        e_t = (t0 * t0 + t1 * t1 + t2 * t2) / (2.0 * kt[i]) if kt[i] > 0.0 else 0.0
        energy[i] = A * e_n + e_t
        dissipated[i] = lost


class RigidContact(Effect):
    """Blank nodes against one analytic tool moving by a prescribed translation; see the module docstring."""

    forces = "internal"
    moves = True

    def __init__(self, tool_name, nodes, area, vec, offset, two_sided, kind, shape, motion, law, friction, X):
        self.name, self.tool = f"contact:{tool_name}", tool_name
        self.nodes, self.offset, self.two_sided = nodes, offset, two_sided
        self.vec = np.ascontiguousarray(vec)
        self.area = np.where(two_sided, area, np.linalg.norm(vec, axis=1))  # bound of the projected area
        self.kind, self.shape, self.motion, self.law = kind, shape, motion, law
        k = len(nodes)
        stick = friction.stick_stiffness if friction is not None else 0.0
        self.kt = stick * max_slope(law) * area
        self.k_max = max(1.0, stick) * max_slope(law) * area  # (k,) largest nodal contact stiffness [N/mm]
        self.mu_s = friction.static if friction is not None else 0.0
        self.mu_d = (friction.dynamic if friction.dynamic is not None else friction.static) if friction else 0.0
        self.u, self.u_prev, self.u_force = self.motion(0.0), np.zeros(3), np.zeros(3)
        self.x_prev = np.ascontiguousarray(X[nodes])
        self.ft, self.status = np.zeros((k, 3)), np.zeros(k, np.int64)
        self.f, self.gap, self.pressure = np.zeros((k, 3)), np.zeros(k), np.zeros(k)
        self.energy, self.dissipated = np.zeros(k), np.zeros(k)
        self.force = np.zeros(3)  # total force of the tool on the blank at the last call [N]
        self.work = self.friction = 0.0
        self.dt = math.inf
        self.terms = (Term("contact_energy", STORED), Term("friction_dissipation", DISSIPATED),
                      Term(f"tool_work_{tool_name}", WORK),
                      *(Term(f"tool_{tool_name}_force_{c}", VALUE) for c in "xyz"),
                      *(Term(f"tool_{tool_name}_displacement_{c}", VALUE) for c in "xyz"))

    def begin_step(self, index, plan):
        m = plan.mass[self.nodes]
        touching = self.k_max > 0.0
        self.dt = float(np.min(np.sqrt(m[touching] / self.k_max[touching]))) if touching.any() else math.inf

    def advance(self, t_next, dt, dt_avg):
        self.u = self.motion(t_next)

    def add_force(self, t, x, v, f):
        u_call = np.array(self.u)
        contact_forces(x, self.nodes, self.area, self.vec, self.offset, self.two_sided, self.kind, self.shape, u_call,
                       self.law, self.kt, self.mu_s, self.mu_d, self.x_prev, self.u_force, self.ft, self.status, self.f,
                       self.gap, self.pressure, self.energy, self.dissipated)
        force = self.f.sum(axis=0)
        self.work += 0.5 * float(np.dot(self.force + force, u_call - self.u_force))
        self.force, self.u_force = force, u_call
        self.friction += float(self.dissipated.sum())
        np.subtract.at(f, self.nodes, self.f)  # internal forces carry the resisting sign

    def stable_dt(self):
        return self.dt

    def term_values(self):
        return (float(self.energy.sum()), self.friction, self.work, *self.force.tolist(), *self.u.tolist())

    def initial_penetrations(self) -> np.ndarray:
        """Indices of the contact nodes that start inside the tool (gap < 0 at rest, before any motion)."""
        out = []
        for i, a in enumerate(self.nodes):
            x = self.x_prev[i] - self.u
            d = analytic.distance(self.kind, self.shape, x[0], x[1], x[2])[0]
            d = abs(d) if self.two_sided[i] else d
            if d - self.offset[i] < -1e-9 * max(1.0, abs(self.offset[i])):
                out.append(a)
        return np.asarray(out, np.int64)


def tributary(ctx) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(area (n_node,) [mm^2], vector area (n_node, 3) [mm^2], offset (n_node,) [mm], two_sided (n_node,)) from the
    exterior faces (outward by their node order): a quarter of each face's area (a third of a triangle's) and of
    its area vector to each of its distinct nodes; shell nodes get half their section's thickness and both faces."""
    n = len(ctx.X)
    area, vec, offset, two_sided = np.zeros(n), np.zeros((n, 3)), np.zeros(n), np.zeros(n, bool)
    faces = ctx.surface["faces"]
    xf = ctx.X[faces]
    av = 0.5 * np.cross(xf[:, 2] - xf[:, 0], xf[:, 3] - xf[:, 1])
    a = np.linalg.norm(av, axis=1)
    tri = faces[:, 2] == faces[:, 3]
    share = np.where(tri, 1.0 / 3.0, 0.25)
    for c in range(4):
        use = ~tri if c == 3 else np.ones(len(faces), bool)
        np.add.at(area, faces[use, c], a[use] * share[use])
        np.add.at(vec, faces[use, c], av[use] * share[use, None])
    for g in ctx.groups:
        if not g.solid:
            offset[g.conn.ravel()] = np.maximum(offset[g.conn.ravel()], 0.5 * g.h)
            two_sided[g.conn.ravel()] = True
    return area, vec, offset, two_sided


def build(card: Contact, ctx) -> RigidContact:
    tools = ctx.deck.tools
    if card.tool not in tools:
        from fdeck.deck.errors import unknown_name

        raise CompileError([(ctx.path + ("tool",), unknown_name("tool", card.tool, tools))])
    tool = tools[card.tool]
    area, vec, offset, two_sided = tributary(ctx)
    nodes = ctx.node_set(card.nodes) if card.nodes is not None else np.nonzero(area > 0)[0]
    nodes = nodes[area[nodes] > 0]
    if len(nodes) == 0:
        raise CompileError([(ctx.path + ("nodes",), "no node of this set lies on the blank's exterior")])
    kind, shape = analytic.pack(tool.surface)
    if tool.motion is None:
        motion = lambda t: np.zeros(3)  # noqa: E731
    else:
        direction = np.asarray(tool.motion.direction, float)
        direction = direction / np.linalg.norm(direction)
        amp, value = ctx.amplitude(tool.motion.amplitude), tool.motion.value
        motion = lambda t: value * amp(t) * direction  # noqa: E731
    effect = RigidContact(card.tool, np.ascontiguousarray(nodes, np.int64), area[nodes], vec[nodes], offset[nodes],
                          two_sided[nodes], kind, shape, motion, pack_law(card.normal), card.friction, ctx.X)
    inside = effect.initial_penetrations()
    if len(inside):
        raise CompileError([(ctx.path, f"{len(inside)} blank nodes start inside tool '{card.tool}' (initial "
                             f"penetration), nodes (1-based, in mesh order) {(inside[:10] + 1).tolist()}")])
    return effect


register_effect(EffectKind("contact", build))
