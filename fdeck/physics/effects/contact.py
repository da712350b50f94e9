"""Node-to-rigid-surface penalty contact with Coulomb friction (MODELS 7), against analytic or triangulated tools.

Three questions, three places: where the tool is and how it moves (``effects.tool``), how far a node is from it and
along which normal (``tools.analytic`` closed forms, or ``tools.triangulated``: a grid broad phase built once in the
tool's frame and a closest-point narrow phase), and what force follows (``contact_forces`` below).

Per blank node i: its tributary area A_i, for hexahedra the outward vector area a_i of the exterior faces around it
(a quarter of each face's area vector) projected on the contact normal, A_i = max(0, -a_i . n), so that a corner
node of a block resting on a plane carries only its share of the bottom face; for shells a quarter of each element's
area, on both faces, with half the thickness as offset o_i.
gap g = d(x - u) - o with d the tool's signed distance and u the tool's translation;
overclosure h = -g. Normal force f_n = p(h) A n, from the linear law p = k h or the exponential law of MODELS 7
continued linearly beyond its stiffness cap. Its energy A e(h), e = int p dh, is stored (``contact_energy``), so
f_n = -dE/dx while A stays put, as on a plane.

Area: A_i = max(0, -a_i . n) changes when n turns against the node's reference vector area a_i (a blank drawn over
a die's radius, a node sliding over a curved punch), and the force omits dA/dx, so A e is not a potential of it.
The difference is booked as a work of its own, ``contact_area_work``: per node and call (e_old + e_new) / 2 (A_new -
A_old), so that stored energy minus it changes by minus the trapezoidal work of the normal force (to third order in
the increment per call). Measured with
``python studies/ledger_closure.py --study decks/studies/tetrahedron_in_plane_tracking.yaml --variant
in_plane_tracked`` (10 mm two-layer half tetrahedron with in-plane fibre bending, 18 247 cycles): the die's contact
would close with -32.0 mJ without this term (the blank drawn over the die opening's radius), -2.0 mJ with it (the
punch's +1.5 / -0.1 mJ), and the run's balance error falls from -31.9 to -3.5 mJ (0.8 % to 0.09 % of the strain
energy). The force is not changed to the current area (a blank turned 45 degrees against its reference carries
0.71 of its area here, so under the linear law it sinks 1.4 times deeper than on a plane): that would move every
forming answer. Booked, this energy that the force law itself makes no longer shows in the balance error; the
column shows its size instead (compare it with the balance error).

Friction: an elastic stick spring of stiffness k_t = stick_stiffness * (dp/dh)_max A per node carries the tangential
force; the trial force f_t - k_t du_t (du_t the increment of the node's displacement relative to the tool, in the
tangent plane) is returned to mu_d f_n when it exceeds mu_s f_n (mu_d while sliding), a backward-Euler return map
(Simo & Hughes, Computational Inelasticity, 1998, ch. 1, the 1-D elastoplastic analogue). The spring's energy
|f_t|^2 / (2 k_t) is stored; the energy the return map removes, the mean of the old and new tangential force (along
the slip) times the plastic slip, is dissipated
(``friction_dissipation``), as is the spring's energy when a node leaves contact (with the work of its force falling
to zero): the booking follows the trapezoidal work the engine integrates, so the balance closes when f_n varies.

The tool's work on the blank is integrated by the trapezoidal rule on its translation increments
(``tool_work_<tool>``); its force on the blank and its displacement are history columns. With the blank's own work of
the contact forces booked by the engine as internal forces, the balance reads kinetic + stored + dissipated -
tool work = const. Stable step: each contact node is a spring of stiffness k = max(1, stick_stiffness) (dp/dh)_max A
on its lumped mass m; the effect bounds the step by sqrt(m / k) = 1 / omega, half the node's own critical step, so
that the node stays stable with the element stiffness added (up to three times the penalty's) and the penalty's
ringing, which the ledger sees at the dt^2 omega^2 / 8 level of central differences, stays small. With
``springs: implicit`` the engine takes each node's normal and stick springs into its own velocity update while it is
in contact (``engine.springs``: linearly implicit, dissipative, booked as ``contact_implicit_dissipation``), so they
bound the step no more, except that a sliding node's return to sticking is still decided on the stick spring
explicitly: the step stays below 2 sqrt(m / k_t) (``implicit_bound``).

Output: every frame carries the contact pressure, gap, status (open / stick / slip) and accumulated slip of each
blank node (``node_fields``; the pairs of several tools merged by ``run.Outputs``).

Broad phase against a triangulated tool: the tool's grid (``tools.triangulated``) answers a node's query with one
cell look-up; a node found out of reach at its last query (its distance to the nearest triangle minus its offset and
the law's clearance, its slack) is not queried again until its travel relative to the tool since then exceeds that
slack, so the nodes away from a tool cost a distance check per cycle, not a query.

Tunnelling: a shell node that crosses the tool surface in one cycle would be pushed out on the wrong face, and a
node that travels beyond a triangulated tool's search distance is no longer seen. The effect therefore also bounds
the step by half that distance over the tool's largest speed in the step (sub-stepping the whole model rather than
letting a node pass through unseen); ``fdeck info`` prints both bounds. Tools translate only (no rotation).
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.cards.contact import Contact
from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.engine.ledger import DISSIPATED, STORED, VALUE, WORK, Term
from fdeck.jit import njit, njit_parallel, prange
from fdeck.physics.effects.tool import MESH
from fdeck.physics.tools import analytic, triangulated
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
def query_analytic(x, nodes, kind, shape, u, d, nrm):
    """Signed distance d (k,) [mm] and outward normal nrm (k, 3) of every contact node to an analytic tool
    translated by u (3,)."""
    for i in prange(nodes.shape[0]):
        a = nodes[i]
        d[i], nrm[i, 0], nrm[i, 1], nrm[i, 2] = analytic.distance(kind, shape, x[a, 0] - u[0], x[a, 1] - u[1],
                                                                  x[a, 2] - u[2])


@njit_parallel
def query_mesh(x, nodes, P, T, face_n, edge_n, vert_n, rim_e, rim_v, lo, h, dims, start, items, r, u, d, nrm,
               reach, xq, uq, slack):
    """The same against a triangulated tool (``tools.triangulated``; d = r, normal 0 for a node farther than r),
    skipping the nodes that cannot have come within reach since their last query (a travel bound).

    reach (k,) [mm]: the distance from the tool within which a node can feel a force (its offset plus the law's
    clearance); xq (k, 3), uq (k, 3): node position and tool translation at each node's last query; slack (k,) [mm]:
    its distance to the nearest triangle then (negative inside the tool), less its reach. A node whose travel
    relative to the tool since then, |x - xq| + |u - uq|, is below its slack is still out of reach: it is reported
    far (d = r, normal 0, no force, exactly what a query gives beyond r) without a query. All updated in place; one
    node per iteration."""
    for i in prange(nodes.shape[0]):
        a = nodes[i]
        moved = math.sqrt((x[a, 0] - xq[i, 0]) ** 2 + (x[a, 1] - xq[i, 1]) ** 2 + (x[a, 2] - xq[i, 2]) ** 2)
        moved += math.sqrt((u[0] - uq[i, 0]) ** 2 + (u[1] - uq[i, 1]) ** 2 + (u[2] - uq[i, 2]) ** 2)
        if moved < slack[i]:
            d[i], nrm[i, 0], nrm[i, 1], nrm[i, 2] = r, 0.0, 0.0, 0.0
        else:
            dd, n0, n1, n2, near = triangulated.closest(P, T, face_n, edge_n, vert_n, rim_e, rim_v, lo, h, dims,
                                                        start, items, r, x[a, 0] - u[0], x[a, 1] - u[1],
                                                        x[a, 2] - u[2])
            d[i], nrm[i, 0], nrm[i, 1], nrm[i, 2] = dd, n0, n1, n2
            xq[i, 0], xq[i, 1], xq[i, 2] = x[a, 0], x[a, 1], x[a, 2]
            uq[i, 0], uq[i, 1], uq[i, 2] = u[0], u[1], u[2]
            slack[i] = min(dd, near) - reach[i]  # dd < 0 inside the tool: no slack


@njit_parallel
def contact_forces(x, nodes, dist, nrm, area, vec, offset, two_sided, u, law, kt, mu_s, mu_d, x_prev, u_prev,
                   ft, status, slip, last, f, gap, pressure, energy, dissipated, area_work, stiff, f_int):
    """Contact forces of every contact node (one node per iteration: no race, same bits on any thread count).

    x (n_node, 3) positions; nodes (k,) node indices; dist (k,), nrm (k, 3) signed distance and normal to the tool
    (``query_*``); area (k,) [mm^2] of shell nodes; vec (k, 3) outward vector area of solid nodes [mm^2]; offset (k,)
    [mm]; two_sided (k,) bool (shell nodes); u (3,) tool translation, u_prev (3,) at the last call; law (8,); kt (k,)
    stick stiffness [N/mm]; x_prev (k, 3) node positions at the last call (updated); ft (k, 3) tangential force
    (updated); status (k,) 0 open, 1 stick, 2 slip (updated); slip (k,) [mm] the node's tangential travel relative to
    the tool summed over the calls that find it in contact (updated); last (k, 2) the node's area A [mm^2] and
    normal energy per area [mJ/mm^2] at the last call (A < 0 before the first; updated). Outputs f (k, 3) force of
    the tool on each node [N], gap, pressure (k,) [mm, MPa], energy (k,) stored normal + stick energy [mJ],
    dissipated (k,) friction dissipation of this call [mJ], area_work (k,) the work of this call's change of A [mJ]
    (module docstring, *Area*), stiff (k, 2) [N/mm] the node's normal stiffness A dp/dh and its stick stiffness
    (0 when open; the stick stiffness 0 while slipping), read by implicit springs (``engine.springs``); f is also
    subtracted from the engine's internal forces f_int (n_node, 3) (resisting
    sign; the nodes of a pair are distinct, so the writes do not race).
    """
    for i in prange(nodes.shape[0]):
        a = nodes[i]
        d, n0, n1, n2 = dist[i], nrm[i, 0], nrm[i, 1], nrm[i, 2]
        if two_sided[i] and d < 0.0:
            d, n0, n1, n2 = -d, -n0, -n1, -n2
        g = d - offset[i]
        A = area[i] if two_sided[i] else max(0.0, -(vec[i, 0] * n0 + vec[i, 1] * n1 + vec[i, 2] * n2))
        p, dp, e_n = normal_law(law, -g)
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
                # the mean of the old and new tangential force times the plastic slip (trial - slide) / kt: the
                # engine books the node's work with the mean force, so this closes the balance when f_n varies
                along = (ft[i, 0] * t0 + ft[i, 1] * t1 + ft[i, 2] * t2) / trial  # old force along the trial
                lost = (trial - slide) * (slide + along) / (2.0 * kt[i])
                t0, t1, t2 = t0 * slide / trial, t1 * slide / trial, t2 * slide / trial
                state = 2
        elif e_old > 0.0:
            # the node leaves contact and its stick spring lets go: the spring's energy is not recovered, and the
            # force falling from f_t to 0 over du does the mean-force work -f_t . du / 2 as well
            lost = e_old - 0.5 * (ft[i, 0] * du0 + ft[i, 1] * du1 + ft[i, 2] * du2)
        elif fn > 0.0:
            state = 1
        ft[i, 0], ft[i, 1], ft[i, 2] = t0, t1, t2
        status[i] = state if fn > 0.0 else 0
        if fn > 0.0:
            dn = du0 * n0 + du1 * n1 + du2 * n2
            slip[i] += math.sqrt((du0 - dn * n0) ** 2 + (du1 - dn * n1) ** 2 + (du2 - dn * n2) ** 2)
        f[i, 0], f[i, 1], f[i, 2] = fn * n0 + t0, fn * n1 + t1, fn * n2 + t2
        f_int[a, 0] -= f[i, 0]
        f_int[a, 1] -= f[i, 1]
        f_int[a, 2] -= f[i, 2]
        gap[i], pressure[i] = g, p
        stiff[i, 0] = dp * A if fn > 0.0 else 0.0
        stiff[i, 1] = kt[i] if state == 1 and fn > 0.0 else 0.0
        # the area's change, not a work of f: booked with the mean energy per area, so that A e - (this) changes by
        # the mean A times the change of e, which equals minus the normal force's trapezoidal work to O(dx^3)
        area_work[i] = 0.5 * (last[i, 1] + e_n) * (A - last[i, 0]) if last[i, 0] >= 0.0 else 0.0
        last[i, 0], last[i, 1] = A, e_n
        e_t = (t0 * t0 + t1 * t1 + t2 * t2) / (2.0 * kt[i]) if kt[i] > 0.0 else 0.0
        energy[i] = A * e_n + e_t
        dissipated[i] = lost


class RigidContact(Effect):
    """Blank nodes against one rigid tool (``effects.tool.RigidTool``); see the module docstring."""

    forces = "internal"
    subcycling_safe = True  # its springs' steps cap the contact nodes' levels (node_dt)

    def __init__(self, tool, nodes, area, vec, offset, two_sided, law, friction, X, search, implicit=False):
        self.name, self.tool = f"contact:{tool.tool}", tool
        self.implicit = implicit  # springs integrated by ``engine.springs`` (refused by subcycling)
        self.nodes, self.offset, self.two_sided = nodes, offset, two_sided
        self.vec = np.ascontiguousarray(vec)
        self.area = np.where(two_sided, area, np.linalg.norm(vec, axis=1))  # bound of the projected area
        self.law = law
        k = len(nodes)
        stick = friction.stick_stiffness if friction is not None else 0.0
        self.kt = stick * max_slope(law) * area
        self.k_max = max(1.0, stick) * max_slope(law) * area  # (k,) largest nodal contact stiffness [N/mm]
        tool.load_stiffness += float(self.k_max.sum())
        self.mu_s = friction.static if friction is not None else 0.0
        self.mu_d = (friction.dynamic if friction.dynamic is not None else friction.static) if friction else 0.0
        self.search = search
        self.grid = None if tool.kind != MESH else triangulated.build(*tool.mesh, search)
        # travel bound of the triangulated query (``query_mesh``): zero slack queries every node at the first call
        self.reach = offset + (law[2] if law[0] == EXPONENTIAL else 0.0)
        self.xq, self.uq, self.slack = np.zeros((k, 3)), np.zeros((k, 3)), np.zeros(k)
        self.u_force = np.array(tool.u)  # tool translation at the last call
        self.x_prev = np.ascontiguousarray(X[nodes])
        self.ft, self.status, self.slip = np.zeros((k, 3)), np.zeros(k, np.int64), np.zeros(k)
        self.dist, self.nrm = np.zeros(k), np.zeros((k, 3))
        self.f, self.gap, self.pressure = np.zeros((k, 3)), np.zeros(k), np.zeros(k)
        self.energy, self.dissipated, self.area_work = np.zeros(k), np.zeros(k), np.zeros(k)
        self.stiff = np.zeros((k, 2))  # normal and stick stiffness of each node at the last call [N/mm]
        self.fc, self.fc_prev = np.zeros((k, 3)), np.zeros((k, 3))  # implicit springs' forces [N] (engine.springs)
        self.fc_total = np.zeros(3)  # their sum at the last cycle [N]
        self.u_before = np.array(tool.u)  # tool translation at the call before the last
        self.implicit_dissipation = 0.0
        self.last = np.full((k, 2), -1.0)  # (A, e_n) at the last call; A < 0: no call yet
        self.force = np.zeros(3)  # total force of the tool on the blank at the last call [N]
        self.work = self.friction = self.area_total = 0.0
        self.dt_spring = self.dt_travel = self.dt = math.inf
        name = tool.tool
        self.terms = (Term("contact_energy", STORED), Term("friction_dissipation", DISSIPATED),
                      Term(f"tool_work_{name}", WORK), Term("contact_area_work", WORK),
                      *(Term(f"tool_{name}_force_{c}", VALUE) for c in "xyz"))
        if implicit:
            self.terms += (Term("contact_implicit_dissipation", DISSIPATED),)

    @property
    def travel_limit(self) -> float:
        """Largest relative travel of a node and the tool in one cycle that cannot carry a node through the
        surface unseen [mm]: a shell node (two-sided) flips side once it crosses its offset, a node against a
        triangulated tool is lost beyond the search distance; half of it, for margin."""
        lim = math.inf
        if self.two_sided.any():
            lim = float(self.offset[self.two_sided].min())
        if self.grid is not None:
            lim = min(lim, self.search)
        return 0.5 * lim

    def explicit_bound(self, m: np.ndarray) -> float:
        """The springs' own bound sqrt(m / k) [s] over the contact nodes of masses m (k,) (inf without any)."""
        touching = self.k_max > 0.0
        return float(np.min(np.sqrt(m[touching] / self.k_max[touching]))) if touching.any() else math.inf

    def begin_step(self, index, plan):
        m = plan.mass[self.nodes]
        touching = self.k_max > 0.0
        self.dt_spring = self.implicit_bound(m) if self.implicit else self.explicit_bound(m)
        speed = self.tool.speed_bound(plan.start, plan.start + plan.duration)
        self.dt_travel = self.travel_limit / speed if speed > 0.0 else math.inf
        self.dt = min(self.dt_spring, self.dt_travel)
        self.dt_nodes = (self.nodes[touching], np.sqrt(m[touching] / self.k_max[touching]))

    def implicit_bound(self, m: np.ndarray) -> float:
        """With implicit springs, the step bound left [s]: a sliding node's return to sticking is decided on the
        stick spring explicitly (its trial force at the next call), and jitters between slip directions once
        dt^2 k_t / m passes the spring's own critical 4: the bound is 2 sqrt(m / k_t) (inf without friction).
        Measured on the 10 mm block on an incline below its friction angle (tests/test_contact_implicit.py): it
        sticks with dt^2 k_t / m up to 4.3 and creeps at 8.5."""
        stick = self.kt > 0.0
        return float(2.0 * np.min(np.sqrt(m[stick] / self.kt[stick]))) if stick.any() else math.inf

    def node_dt(self):
        """Each contact node's spring step sqrt(m / k) [s] with the step's masses (from ``begin_step``)."""
        return self.dt_nodes

    def check_plan(self, plans) -> list[str]:
        """A tool that a node can only catch up with after crossing its offset (a shell node) or the search distance
        (a triangulated tool) would pass through whatever the step: the penalty spring k on the node's mass m stops
        a relative speed v after a penetration v sqrt(m / k). Refused, with the stiffness that would do."""
        limit = np.where(self.two_sided, self.offset, self.search if self.grid is not None else np.inf)
        out = []
        for plan in plans:
            speed = self.tool.speed_bound(plan.start, plan.start + plan.duration)
            if speed == 0.0 or not np.isfinite(limit).any():
                continue
            depth = speed * np.sqrt(plan.mass[self.nodes] / self.k_max)
            ratio = depth / limit
            worst = int(np.argmax(ratio))
            if ratio[worst] > 1.0:
                out.append(f"tool '{self.tool.tool}' moves at up to {speed:.4g} mm/s in step '{plan.name}': the "
                           f"contact stiffness stops a node only after a penetration v sqrt(m/k) = "
                           f"{depth[worst]:.3g} mm, "
                           f"beyond the {limit[worst]:.3g} mm it may cross (node {self.nodes[worst] + 1}); it would "
                           f"pass through. Raise the normal stiffness to at least "
                           f"{max_slope(self.law) * ratio[worst] ** 2:.3g} MPa/mm or slow the tool")
        return out

    def query(self, x, u):
        """Fill ``dist`` and ``nrm`` for positions x and tool translation u."""
        if self.grid is None:
            query_analytic(x, self.nodes, self.tool.shape_kind, self.tool.params, u, self.dist, self.nrm)
        else:
            query_mesh(x, self.nodes, *self.grid.arrays(), u, self.dist, self.nrm, self.reach, self.xq, self.uq,
                       self.slack)

    def add_force(self, t, x, v, f):
        tool = self.tool
        if tool.mode == "force":  # a force-driven tool's speed is known only as it runs
            self.dt = min(self.dt_spring, self.travel_limit / abs(tool.V) if tool.V != 0.0 else math.inf)
        u_call = np.array(tool.u)
        self.query(x, u_call)
        contact_forces(x, self.nodes, self.dist, self.nrm, self.area, self.vec, self.offset, self.two_sided, u_call,
                       self.law, self.kt, self.mu_s, self.mu_d, self.x_prev, self.u_force, self.ft, self.status,
                       self.slip, self.last, self.f, self.gap, self.pressure, self.energy, self.dissipated,
                       self.area_work, self.stiff, f)
        force = self.f.sum(axis=0)
        self.work += 0.5 * float(np.dot(self.force + force, u_call - self.u_force))
        self.force, self.u_before, self.u_force = force, self.u_force, u_call
        tool.load += force
        self.friction += float(self.dissipated.sum())
        self.area_total += float(self.area_work.sum())

    def book_implicit(self, total: np.ndarray, blank_work: float) -> None:
        """The implicit springs' forces of this cycle (``engine.springs``): their sum total (3,) [N] and their
        trapezoidal work on the blank over the last increment [mJ]; the tool's share over its own increment is tool
        work, the rest dissipated; the tool's load takes the sum (a force-driven tool feels it)."""
        w_tool = 0.5 * float(np.dot(self.fc_total + total, self.u_force - self.u_before))
        self.work += w_tool
        self.implicit_dissipation += w_tool - blank_work
        self.fc_total = total
        self.tool.load += total

    def stable_dt(self):
        return self.dt

    def node_fields(self):
        """The contact's nodal fields at the last call, for every frame (the pairs of several tools merged by
        ``run.Outputs`` at the nodes they share): contact_pressure [MPa] (largest), contact_gap [mm] (smallest; NaN at
        nodes that are no contact node; against a triangulated tool a node out of its reach shows the search distance
        less its offset, since such nodes are not queried), contact_status (0 open, 1 in contact: sticking, or
        frictionless; 2 slipping; largest) and contact_slip [mm] (the node's tangential travel relative to the tool
        while in contact, accumulated over the run; largest)."""
        return {"contact_pressure": (self.nodes, self.pressure, "max", 0.0),
                "contact_gap": (self.nodes, self.gap, "min", np.nan),
                "contact_status": (self.nodes, self.status.astype(float), "max", 0.0),
                "contact_slip": (self.nodes, self.slip, "max", 0.0)}

    def describe(self, plan) -> str:
        self.begin_step(0, plan)
        law = ("linear, " if self.law[0] == LINEAR else "exponential, capped at ") + f"{max_slope(self.law):g} MPa/mm"
        friction = f"friction {self.mu_s:g}/{self.mu_d:g} (static/dynamic)" if self.mu_s > 0 else "frictionless"
        travel = (f", travel bound {self.travel_limit:.3g} mm per cycle -> {self.dt_travel:.4g} s"
                  if math.isfinite(self.dt_travel) else "")
        search = f", search distance {self.search:.3g} mm ({len(self.grid.T)} triangles)" if self.grid else ""
        if self.implicit:
            explicit = self.explicit_bound(plan.mass[self.nodes])
            bound = (f"springs implicit: step bound 2 sqrt(m/k_t) = {self.dt_spring:.4g} s from the stick springs "
                     f"(explicit springs: sqrt(m/k) = {explicit:.4g} s)")
        else:
            bound = f"step bound sqrt(m/k) = {self.dt_spring:.4g} s"
        return (f"contact with tool '{self.tool.tool}': {len(self.nodes)} blank nodes, {law}, {friction}, "
                f"{bound}{travel}{search}")

    def term_values(self):
        force = (self.force + self.fc_total).tolist()
        out = (float(self.energy.sum()), self.friction, self.work, self.area_total, *force)
        return out + (self.implicit_dissipation,) if self.implicit else out

    def initial_penetrations(self, X) -> np.ndarray:
        """Indices of the contact nodes that start inside the tool (gap < 0 at rest, before any motion)."""
        self.query(X, np.array(self.tool.u))
        d = np.where(self.two_sided, np.abs(self.dist), self.dist)
        inside = d - self.offset < -1e-9 * np.maximum(1.0, np.abs(self.offset))
        return self.nodes[inside]


def tributary(ctx) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(area (n_node,) [mm^2], vector area (n_node, 3) [mm^2], offset (n_node,) [mm], two_sided (n_node,)) from the
    exterior faces (outward by their node order): a quarter of each face's area (a third of a triangle's) and of
    its area vector to each of its distinct nodes; shell nodes get half their section's thickness and both faces."""
    n = len(ctx.X)
    area, vec, offset, two_sided = np.zeros(n), np.zeros((n, 3)), np.zeros(n), np.zeros(n, bool)
    faces = ctx.surface["faces"]
    # a collapsed face (a triangle: two consecutive corners on one node, as the halves of a diagonal lattice) is
    # turned so that the repeated node sits at corners 2 and 3 (a cyclic turn keeps its area vector)
    repeated = faces == np.roll(faces, -1, axis=1)
    turn = (np.argmax(repeated, axis=1) - 2) % 4 * repeated.any(axis=1)
    faces = np.take_along_axis(faces, (np.arange(4)[None, :] + turn[:, None]) % 4, axis=1)
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
    tool = ctx.tools[card.tool]
    area, vec, offset, two_sided = tributary(ctx)
    nodes = ctx.node_set(card.nodes) if card.nodes is not None else np.nonzero(area > 0)[0]
    nodes = nodes[area[nodes] > 0]
    if len(nodes) == 0:
        raise CompileError([(ctx.path + ("nodes",), "no node of this set lies on the blank's exterior")])
    law = pack_law(card.normal)
    search = card.search_distance
    if search is None:
        faces = ctx.surface["faces"]
        edge = max(float(np.linalg.norm(ctx.X[faces] - ctx.X[np.roll(faces, 1, axis=1)], axis=2).max()), 0.0)
        search = float(offset[nodes].max()) + (law[2] if law[0] == EXPONENTIAL else 0.0) + 0.25 * edge
    effect = RigidContact(tool, np.ascontiguousarray(nodes, np.int64), area[nodes], vec[nodes], offset[nodes],
                          two_sided[nodes], law, card.friction, ctx.X, search, card.springs == "implicit")
    inside = effect.initial_penetrations(ctx.X)
    if len(inside):
        raise CompileError([(ctx.path, f"{len(inside)} blank nodes start inside tool '{card.tool}' (initial "
                             f"penetration), nodes (1-based, in mesh order) {(inside[:10] + 1).tolist()}")])
    return effect


register_effect(EffectKind("contact", build))
