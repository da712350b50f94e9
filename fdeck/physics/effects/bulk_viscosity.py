"""Bulk viscosity of solid elements: a viscous pressure on the volumetric strain rate, switched per step.

The usual explicit-dynamics device against ringing behind sharp wave fronts (Abaqus *BULK VISCOSITY, LS-DYNA
*CONTROL_BULK_VISCOSITY; von Neumann & Richtmyer 1950, Wilkins 1980): per element, with the centre deformation
gradient F = sum_a x_a (x) b_a, its rate Fdot = sum_a v_a (x) b_a and the volumetric strain rate
e = tr(Fdot F^-1) [1/s],

    q = rho c L (-b1 e) + rho L^2 b2^2 e^2 [e < 0]        (pressure, positive in compression) [MPa]

acts as the Cauchy stress -q I, i.e. nodal forces f_a = q V0 cof(F) b_a [N] (q J F^-T in the reference), whose
power sum_a f_a . v_a = q V e is never positive: the energy it takes is booked as damping dissipation in the ledger.
L = L0 (the element's smallest height) and c = L0 / dt_e, the wave speed that sets the element's stable step, so
the linear term damps a one-dimensional wave at the element's fastest frequency by the fraction b1 of critical.
The element's uniform-dilatation mode feels the pressure in all three directions: its damping ratio is
3 b1 sqrt(M / (3 lam + 2 mu)), up to 3 b1 (nu = 0). The stable step therefore shrinks to dt_e (sqrt(1 + xi^2) - xi)
with xi = 3 (b1 + b2^2 L |min(e, 0)| / c), the damped central-difference limit of that mode (with b1 alone,
as Abaqus states it, a 1 x 1 x 1 mm steel bar element with nu = 0 goes unstable at b1 = 0.2).

Applies to every solid group (``group.solid``: uniform gradients ``b``, ``V0``, ``L0`` and step estimates ``dt_e``).
A step setting (``steps[i].bulk_viscosity``): coefficients per step; a step without it runs none of this.
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.engine.effect import Effect
from fdeck.engine.gather import gather_add
from fdeck.jit import njit_parallel, prange
from fdeck.registry import EffectKind, register_effect


@njit_parallel
def viscous_forces(x, v, conn, b, V0, L0, rho, dt_e, b1, b2, fe, power, xi):
    """fe (n_el, 8, 3) bulk-viscous nodal forces [N]; power (n_el,) q V e [mW] (<= 0); xi (n_el,) damping ratio.

    x, v (n_node, 3) [mm, mm/s]; conn (n_el, 8); b (n_el, 8, 3) [1/mm]; V0, L0, rho, dt_e (n_el,) (dt_e = 0
    before the first step estimate, when the velocities are still zero: no linear term then).
    """
    for e in prange(conn.shape[0]):
        # centre F = sum_a x_a (x) b_a and its rate, as scalars (no allocation in the parallel loop)
        f00 = f01 = f02 = f10 = f11 = f12 = f20 = f21 = f22 = 0.0
        d00 = d01 = d02 = d10 = d11 = d12 = d20 = d21 = d22 = 0.0
        for a in range(8):
            n = conn[e, a]
            b0, b1_, b2_ = b[e, a, 0], b[e, a, 1], b[e, a, 2]
            f00 += x[n, 0] * b0
            f01 += x[n, 0] * b1_
            f02 += x[n, 0] * b2_
            f10 += x[n, 1] * b0
            f11 += x[n, 1] * b1_
            f12 += x[n, 1] * b2_
            f20 += x[n, 2] * b0
            f21 += x[n, 2] * b1_
            f22 += x[n, 2] * b2_
            d00 += v[n, 0] * b0
            d01 += v[n, 0] * b1_
            d02 += v[n, 0] * b2_
            d10 += v[n, 1] * b0
            d11 += v[n, 1] * b1_
            d12 += v[n, 1] * b2_
            d20 += v[n, 2] * b0
            d21 += v[n, 2] * b1_
            d22 += v[n, 2] * b2_
        # cofactor of F: cof = J F^-T, so tr(Fdot F^-1) = cof : Fdot / J
        c00, c01, c02 = f11 * f22 - f12 * f21, f12 * f20 - f10 * f22, f10 * f21 - f11 * f20
        c10, c11, c12 = f02 * f21 - f01 * f22, f00 * f22 - f02 * f20, f01 * f20 - f00 * f21
        c20, c21, c22 = f01 * f12 - f02 * f11, f02 * f10 - f00 * f12, f00 * f11 - f01 * f10
        J = f00 * c00 + f01 * c01 + f02 * c02
        rate = (c00 * d00 + c01 * d01 + c02 * d02 + c10 * d10 + c11 * d11 + c12 * d12
                + c20 * d20 + c21 * d21 + c22 * d22) / J
        c = L0[e] / dt_e[e] if dt_e[e] > 0.0 else 0.0  # wave speed that sets this element's step [mm/s]
        comp = min(rate, 0.0)
        q = -b1 * rho[e] * c * L0[e] * rate + rho[e] * (b2 * L0[e] * comp) ** 2
        # the element's uniform-dilatation mode feels the pressure in all three directions: up to 3x the ratio
        xi[e] = 3.0 * (b1 - (b2 * b2 * L0[e] * comp / c if c > 0.0 else 0.0))
        power[e] = q * V0[e] * J * rate
        s = q * V0[e]
        for a in range(8):
            b0, b1_, b2_ = b[e, a, 0], b[e, a, 1], b[e, a, 2]
            fe[e, a, 0] = s * (c00 * b0 + c01 * b1_ + c02 * b2_)
            fe[e, a, 1] = s * (c10 * b0 + c11 * b1_ + c12 * b2_)
            fe[e, a, 2] = s * (c20 * b0 + c21 * b1_ + c22 * b2_)


class BulkViscosity(Effect):
    """Bulk viscosity on the solid groups; coefficients (b1, b2) per step, zero in steps that do not ask for it."""
    deck_settings = ("coefficients",)  # per step, from the deck: not saved (engine.snapshot)

    follows_element_steps = True  # its step is a share of the elements' own: mass tracking raises both (solver)

    name = "bulk viscosity"
    forces = "damping"

    def __init__(self, groups, coefficients):
        self.groups = groups  # solid element groups
        self.coefficients = coefficients  # [(b1, b2)] per step
        self.buffers = [(np.zeros((len(g.conn), 8, 3)), np.zeros(len(g.conn)), np.zeros(len(g.conn)))
                        for g in groups]
        self.b1 = self.b2 = 0.0

    def begin_step(self, index, plan):
        self.b1, self.b2 = self.coefficients[index]

    def add_force(self, t, x, v, f):
        if self.b1 == 0.0 and self.b2 == 0.0:
            return
        for g, (fe, power, xi) in zip(self.groups, self.buffers):
            viscous_forces(x, v, g.conn, g.b, g.V0, g.L0, g.rho, g.dt_e, self.b1, self.b2, fe, power, xi)
            gather_add(fe, g.ptr, g.slots, f)

    def stable_dt(self):
        """Smallest damped element step [s]: dt_e (sqrt(1 + xi^2) - xi), with dt_e from the groups' last estimate."""
        if self.b1 == 0.0 and self.b2 == 0.0:
            return math.inf
        out = math.inf
        for g, (_, _, xi) in zip(self.groups, self.buffers):
            out = min(out, float(np.min(g.dt_e * (np.sqrt(1.0 + xi * xi) - xi))))
        return out


def build(cards: list, ctx) -> BulkViscosity | None:
    """The effect, or None when no step asks for it or no group is solid. cards: each step's card or None."""
    coeffs = [(c.linear, c.quadratic) if c is not None else (0.0, 0.0) for c in cards]
    solids = [g for g in ctx.groups if g.solid]
    if not solids or all(c == (0.0, 0.0) for c in coeffs):
        return None
    return BulkViscosity(solids, coeffs)


register_effect(EffectKind("bulk_viscosity", build))
