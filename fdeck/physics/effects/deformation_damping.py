"""Deformation damping: a viscous force on each element's nodal velocities relative to its rigid-body motion.

Mass-proportional damping (``steps[i].damping``) drags every velocity, including the rigid sliding of a flange
being drawn in: on the square tube it takes about 40 % of the work (README, *Forming*). This effect damps only
what deforms the element. Per element e with nodes a, weights w_a = m_a / k_a (the node's lumped mass of the step
shared among the k_a elements that hold it, so that the weights of all elements sum to the lumped mass), the
velocities are split into the element's weighted rigid motion (translation of the weighted centre plus a spin w
from the least-squares fit of the angular momentum, I w = L) and the rest:

    v_def,a = v_a - v_c - w x (x_a - x_c)         f_a = -c w_a v_def,a         power_e = -c sum_a w_a |v_def,a|^2

The split is a projection orthogonal in the weights, so the forces of each element have zero resultant and zero
moment (momentum and angular momentum are untouched), rigid motion at any speed and orientation feels nothing
(objective), and the power is never positive: the engine books it as damping dissipation. A wave of wavelength
lambda moves the nodes of an element of size h relative to each other by about pi h / lambda of its velocity, so it
decays as mass-proportional damping of rate alpha = c pi^2 (h / lambda)^2 would (a stretching wave; a transverse one
on cube-shaped elements half that, the spin taking the rest), while a node-to-node zig-zag (lambda = 2 h) is damped
at alpha = c (c / 2 transverse; the kinetic energy decays at 2 alpha): ``tests/test_deformation_damping.py``. So
element-scale oscillation (the fibre switch of ``fabric_membrane``, node-to-node flutter) is damped at about the
rate c, long waves and rigid motion hardly: in this it acts like stiffness-proportional Rayleigh damping (LS-DYNA
*DAMPING_PART_STIFFNESS, Abaqus beta), whose rate also grows as 1 / lambda^2 for non-dispersive waves, without a
second evaluation of the material law.

Step: the weights of all elements sum to the lumped mass and each split is a projection, so C <= c M; with the
element estimate dt_e of the fastest mode (K <= (2 / dt_e)^2 M), central differences stay stable while
M - (dt / 2) C - (dt^2 / 4) K is positive, which holds for dt = dt_e (sqrt(1 + xi^2) - xi), xi = c dt_e / 4 (the
damped limit of the fastest mode). The step's mass-proportional damping, if any, is not added to xi (its own bound
is not modelled either), and ``fdeck info``'s rest step does not include the factor (1 - xi at most; 0.25 % at
c = 2000 1/s and dt_e = 5e-6 s).

Shells with nodal rotations: the rigid motion is then fitted to the velocities and the nodes' angular velocities
together (weights I_a / k_a, the nodes' rotational inertia of the step; a rigid motion turns every director with
the element's spin), and each node's angular velocity relative to the element's spin is damped the same way,
m_a = -c (I_a / k_a) P_a (w_a - w_e), both without the drilling part (P_a = 1 - d_a d_a^T, d_a the director: the
drilling rotation has no stiffness and is not driven, so a plate turning in its plane has none at its nodes): a
director turning against its element (a kink, a flutter of the rotations) is damped, a shell turning as a whole,
in or out of its plane, is not. A step setting (``steps[i].deformation_damping``): built only when a step asks for
it.
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.engine.effect import Effect
from fdeck.engine.gather import gather_add
from fdeck.jit import njit_parallel, prange
from fdeck.registry import EffectKind, register_effect


@njit_parallel
def relative_forces(x, v, w_rot, d, conn, w_node, j_node, c, fe, me, power):
    """fe (n_el, n, 3) damping forces [N], me (n_el, n, 3) damping moments [N mm] and power (n_el,) [mW] (<= 0)
    of the elements conn (n_el, n).

    x, v (n_node, 3) [mm, mm/s]; w_rot (n_node, 3) nodal angular velocities [rad/s] and d (n_node, 3) the nodes'
    unit directors (zeros without rotations); w_node (n_node,) nodal weights m_a / k_a [t]; j_node (n_node,)
    rotational weights I_a / k_a [t mm^2] (zeros without rotations: the fit is then translation and spin from the
    positions alone, and me stays zero); c the damping rate [1/s]. Only the spin about axes normal to the director
    counts, P_a = 1 - d_a d_a^T: a shell's drilling rotation has no stiffness and is not driven, so a plate turning in
    its plane has no drilling spin at its nodes, and P_a w_e is what a rigid motion gives them. The rigid motion is
    the weighted least-squares fit of a translation and one spin w_e to the velocities and the nodes' projected
    angular velocities: (I_e + sum j_a P_a) w_e = L + sum j_a P_a w_a with I_e = sum w_a (|r|^2 1 - r r^T); the
    moments are m_a = -c j_a P_a (w_a - w_e). An element whose fit is singular (collinear nodes without rotations:
    det <= 1e-12 of its scale) keeps its translation only.
    """
    n = conn.shape[1]
    for e in prange(conn.shape[0]):
        W = 0.0
        xc0 = xc1 = xc2 = vc0 = vc1 = vc2 = 0.0
        for a in range(n):
            k = conn[e, a]
            wa = w_node[k]
            W += wa
            xc0 += wa * x[k, 0]
            xc1 += wa * x[k, 1]
            xc2 += wa * x[k, 2]
            vc0 += wa * v[k, 0]
            vc1 += wa * v[k, 1]
            vc2 += wa * v[k, 2]
        if W <= 0.0:
            for a in range(n):
                fe[e, a, 0] = fe[e, a, 1] = fe[e, a, 2] = 0.0
                me[e, a, 0] = me[e, a, 1] = me[e, a, 2] = 0.0
            power[e] = 0.0
            continue
        xc0 /= W
        xc1 /= W
        xc2 /= W
        vc0 /= W
        vc1 /= W
        vc2 /= W
        # L = sum w r x u + sum j P w_rot and the matrix I_e + sum j P (symmetric)
        L0 = L1 = L2 = 0.0
        i00 = i11 = i22 = i01 = i02 = i12 = 0.0
        for a in range(n):
            k = conn[e, a]
            wa = w_node[k]
            ja = j_node[k]
            r0, r1, r2 = x[k, 0] - xc0, x[k, 1] - xc1, x[k, 2] - xc2
            u0, u1, u2 = v[k, 0] - vc0, v[k, 1] - vc1, v[k, 2] - vc2
            n0, n1, n2 = d[k, 0], d[k, 1], d[k, 2]
            dw = n0 * w_rot[k, 0] + n1 * w_rot[k, 1] + n2 * w_rot[k, 2]
            L0 += wa * (r1 * u2 - r2 * u1) + ja * (w_rot[k, 0] - n0 * dw)
            L1 += wa * (r2 * u0 - r0 * u2) + ja * (w_rot[k, 1] - n1 * dw)
            L2 += wa * (r0 * u1 - r1 * u0) + ja * (w_rot[k, 2] - n2 * dw)
            i00 += wa * (r1 * r1 + r2 * r2) + ja * (1.0 - n0 * n0)
            i11 += wa * (r0 * r0 + r2 * r2) + ja * (1.0 - n1 * n1)
            i22 += wa * (r0 * r0 + r1 * r1) + ja * (1.0 - n2 * n2)
            i01 -= wa * r0 * r1 + ja * n0 * n1
            i02 -= wa * r0 * r2 + ja * n0 * n2
            i12 -= wa * r1 * r2 + ja * n1 * n2
        # w_e by cofactors
        c00, c11, c22 = i11 * i22 - i12 * i12, i00 * i22 - i02 * i02, i00 * i11 - i01 * i01
        c01, c02, c12 = i02 * i12 - i01 * i22, i01 * i12 - i02 * i11, i01 * i02 - i00 * i12
        det = i00 * c00 + i01 * c01 + i02 * c02
        scale = i00 + i11 + i22
        w0 = w1 = w2 = 0.0
        if det > 1e-12 * scale * scale * scale:
            w0 = (c00 * L0 + c01 * L1 + c02 * L2) / det
            w1 = (c01 * L0 + c11 * L1 + c12 * L2) / det
            w2 = (c02 * L0 + c12 * L1 + c22 * L2) / det
        p = 0.0
        for a in range(n):
            k = conn[e, a]
            wa = w_node[k]
            ja = j_node[k]
            r0, r1, r2 = x[k, 0] - xc0, x[k, 1] - xc1, x[k, 2] - xc2
            d0 = v[k, 0] - vc0 - (w1 * r2 - w2 * r1)
            d1 = v[k, 1] - vc1 - (w2 * r0 - w0 * r2)
            d2 = v[k, 2] - vc2 - (w0 * r1 - w1 * r0)
            n0, n1, n2 = d[k, 0], d[k, 1], d[k, 2]
            s0, s1, s2 = w_rot[k, 0] - w0, w_rot[k, 1] - w1, w_rot[k, 2] - w2
            ds = n0 * s0 + n1 * s1 + n2 * s2  # the drilling part, dropped: s = P (w_a - w_e)
            s0 -= n0 * ds
            s1 -= n1 * ds
            s2 -= n2 * ds
            fe[e, a, 0] = -c * wa * d0
            fe[e, a, 1] = -c * wa * d1
            fe[e, a, 2] = -c * wa * d2
            me[e, a, 0] = -c * ja * s0
            me[e, a, 1] = -c * ja * s1
            me[e, a, 2] = -c * ja * s2
            p -= c * (wa * (d0 * d0 + d1 * d1 + d2 * d2) + ja * (s0 * s0 + s1 * s1 + s2 * s2))
        power[e] = p


class DeformationDamping(Effect):
    """Deformation damping on every element group; rate c [1/s] per step, zero in steps that do not ask for it."""
    deck_settings = ("rates",)  # per step, from the deck: not saved (engine.snapshot)

    follows_element_steps = True  # its step is a share of the elements' own: mass tracking raises both (solver)

    name = "deformation damping"
    forces = "damping"

    def __init__(self, groups, rates, n_node, rotational=False):
        self.groups = groups
        self.rates = rates  # [1/s] per step
        self.rate = 0.0
        self.rotational = rotational  # shells with nodal rotations: their angular velocities are damped too
        self.rot = None
        count = np.zeros(n_node)
        for g in groups:
            count += np.bincount(g.conn.ravel(), minlength=n_node)  # a degenerate shell repeats a node: counted
        self.count = count  # elements (node entries) at each node, over all groups
        self.w_node = np.zeros(n_node)  # m_a / k_a of the current step [t]
        self.j_node = np.zeros(n_node)  # I_a / k_a of the current step [t mm^2] (zero without rotations)
        self.no_spin = None if rotational else np.zeros((n_node, 3))  # w and d of a model without rotations
        self.buffers = [(np.zeros(g.conn.shape + (3,)), np.zeros(g.conn.shape + (3,)), np.zeros(len(g.conn)))
                        for g in groups]

    def bind(self, rotations) -> None:
        self.rot = rotations

    def begin_step(self, index, plan):
        self.rate = self.rates[index]
        held = self.count > 0
        self.w_node[:] = 0.0
        self.w_node[held] = plan.mass[held] / self.count[held]
        self.j_node[:] = 0.0
        if self.rot is not None and plan.inertia is not None:
            self.j_node[held] = plan.inertia[held] / self.count[held]

    def add_force(self, t, x, v, f):
        if self.rate == 0.0:
            return
        spin, d = (self.rot.w, self.rot.d) if self.rot is not None else (self.no_spin, self.no_spin)
        for g, (fe, me, power) in zip(self.groups, self.buffers):
            relative_forces(x, v, spin, d, g.conn, self.w_node, self.j_node, self.rate, fe, me, power)
            gather_add(fe, g.ptr, g.slots, f)
            if self.rot is not None:
                gather_add(me, g.ptr, g.slots, self.rot.m_damp)

    def stable_dt(self):
        """Smallest damped element step [s]: dt_e (sqrt(1 + xi^2) - xi) with xi = c dt_e / 4 (see the module)."""
        if self.rate == 0.0:
            return math.inf
        out = math.inf
        for g in self.groups:
            # zero before the groups' first estimate, inf for an element without stiffness: no bound from those
            dt_e = g.dt_e[np.isfinite(g.dt_e) & (g.dt_e > 0.0)]
            if dt_e.size:
                xi = 0.25 * self.rate * dt_e
                out = min(out, float(np.min(dt_e / (np.sqrt(1.0 + xi * xi) + xi))))  # = dt_e (sqrt(1 + xi^2) - xi)
        return out


def build(cards: list, ctx) -> DeformationDamping | None:
    """The effect, or None when no step asks for it. cards: each step's card or None."""
    rates = [c.rate if c is not None else 0.0 for c in cards]
    if not any(r > 0 for r in rates):
        return None
    return DeformationDamping(list(ctx.groups), rates, len(ctx.X), rotational=ctx.rotations is not None)


register_effect(EffectKind("deformation_damping", build))
