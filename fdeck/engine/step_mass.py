"""The kinetic energy a step's new masses give the model at its start, booked as work.

A step may scale its mass otherwise than the one before (``mass_scaling`` per step: another factor or target, none,
or a step that does not track after one that tracked selective mass; what tracking adds during a step it books
itself, ``mass_tracking_work``). The velocities carry over, so the kinetic energy
1/2 v^T M v jumps by about 1/2 v^T (M_new - M_old) v at the boundary: energy the model gains or loses by the deck's
choice, not by any force. Unbooked, it showed as a jump of the balance error (a block compressed with mass scaling
10 then 1: -0.48 -> -2.54 mJ at the boundary); booked here as the work column ``step_mass_work``, built only for
decks whose steps can change the mass (``changes_mass``).

Booked as the ledger counts kinetic energy: the engine's kinetic energy at t_n uses the average of the half-step
velocities v(n-1/2) and v(n+1/2), and the kick between them is made with the new step's masses. So in the new
step's first cycle, once its velocities are updated (``close``), the booking is that kinetic energy minus the one
the old masses would have given: on free dofs the old masses' kick dt f / m_old, on prescribed dofs the same
velocities, whose reactions m dv / dt - f then do other work over the last increment (subtracted). A first version
booked 1/2 (m_new - m_old) |v(n-1/2)|^2 at the boundary: on a vibrating block scaled 10 -> 1 it missed 10 % of the
jump (the kick's half step). An old selective mass (``engine.selective_mass``) kicks by its diagonal in this
estimate (its solve is not repeated), its kinetic energy 1/2 sum c_e |(I - P_e) v_e|^2 at the estimated
velocities; rotational inertia enters by 1/2 sum (I_new - I_old) |w|^2 at the averaged angular velocities (the
first version's estimate, without the kick's correction: not measured on shells). A boundary that changes no mass
(a tracking step followed by another of the same target: ``physics.effects.selective_mass`` carries the tracked
mass) books 0.
"""

from __future__ import annotations

import numpy as np

from fdeck.engine.ledger import WORK, Term

__all__ = ["StepMassChange", "changes_mass", "same_masses"]


def same_masses(a, b) -> bool:
    """Whether step plans a and b (``compile.problem.StepPlan``) give the same densities, lumped masses, inertias and
    selective factors."""
    def equal(p, q) -> bool:
        if p is None or q is None:
            return p is q
        if isinstance(p, list):
            return len(p) == len(q) and all(np.array_equal(x, y) for x, y in zip(p, q))
        return np.array_equal(p, q)

    return all(equal(getattr(a, k), getattr(b, k)) for k in ("mass", "inertia", "rho", "selective"))


def changes_mass(problem) -> bool:
    """Whether a step boundary of ``problem`` may change the mass: two consecutive steps whose masses differ
    (``same_masses``), or a step that tracks selective mass (it adds mass during the step) followed by another."""
    plans = problem.steps
    if not all(same_masses(a, b) for a, b in zip(plans, plans[1:])):
        return True
    tracking = [getattr(e, "targets", None) for e in problem.effects if getattr(e, "solves_mass", False)]
    return any(t is not None and any(x is not None for x in t[:-1]) for t in tracking)


class StepMassChange:
    """Ledger source of ``step_mass_work`` [mJ]: the kinetic energy added (negative: removed) at step boundaries."""

    name = "step_mass"
    terms = (Term("step_mass_work", WORK),)

    def __init__(self):
        self.work = 0.0  # [mJ] cumulative
        # from a boundary (``open``) to ``close``: the old masses, and the selective factors the step starts with
        self.m_old = self.c_old = self.diag_old = self.I_old = self.c_new = None

    def term_values(self) -> tuple[float]:
        return (self.work,)

    def open(self, m: np.ndarray, rot=None, sms=None) -> None:
        """At a step boundary, before the new step's set-up: keep the old lumped masses m (n_node,) [t] (the plan's
        array, which the engine does not change), the rotational inertias and the selective mass."""
        self.m_old = m
        active = sms is not None and sms.active
        self.c_old = sms.solver.c.copy() if active else None
        self.diag_old = sms.solver.diag.copy() if active else None
        self.I_old = None if rot is None else rot.I.copy()

    def set_up(self, sms=None) -> None:
        """After the new step's set-up, before its first stable step (which may track, booking what it adds as
        ``mass_tracking_work``): the selective factors the step starts with."""
        if self.m_old is not None:
            self.c_new = sms.solver.c.copy() if sms is not None and sms.active else None

    def close(self, v, v_old, r, m, free, dt_avg, dx, rot=None, sms=None) -> None:
        """In the new step's first cycle, velocities updated, before the engine's ledger (``drift``): book the kinetic
        energy the new masses m (n_node,) [t] gave against the old ones (module docstring). v, v_old (n_node, 3)
        [mm/s]: v(n+1/2), v(n-1/2); r (n_node, 3) [N]: the cycle's force f_ext - f_int + f_damp; free (n_node, 3):
        1.0 on free dofs; dx (n_node, 3) [mm]: the last increment."""
        if self.m_old is None:
            return
        c_new = self.c_new
        # (the carried tracked mass is re-added from its densities: equal to round-off, not bitwise)
        same = np.array_equal(m, self.m_old) and ((c_new is None and self.c_old is None) or (
            c_new is not None and self.c_old is not None and np.allclose(c_new, self.c_old, rtol=1e-12, atol=0.0)))
        if rot is not None:
            same = same and np.array_equal(rot.I, self.I_old)
        if not same:
            self.work += self._change(v, v_old, r, m, free, dt_avg, dx, rot, sms, c_new)
        self.m_old = self.c_old = self.diag_old = self.I_old = self.c_new = None

    def _change(self, v, v_old, r, m, free, dt_avg, dx, rot, sms, c_new) -> float:
        # the old masses' kick: lumped exactly, a selective old mass by its diagonal (the solve's preconditioner)
        mass_old = self.diag_old if self.diag_old is not None else self.m_old[:, None]
        v_hyp = np.where(free > 0.0, v_old + dt_avg * r / mass_old, v)
        vn, vn_hyp = 0.5 * (v_old + v), 0.5 * (v_old + v_hyp)
        work = 0.5 * float(np.einsum("i,ij,ij->", m, vn, vn) - np.einsum("i,ij,ij->", self.m_old, vn_hyp, vn_hyp))
        if c_new is not None:
            work += sms.solver.kinetic(vn, c_new)
        if self.c_old is not None:
            work -= sms.solver.kinetic(vn_hyp, self.c_old)
        # prescribed dofs: the same velocities, other reactions m dv / dt_avg - f over the last increment
        dv = v - v_old
        work -= 0.5 * float(np.einsum("ij,ij->", np.where(free > 0.0, 0.0, (m - self.m_old)[:, None] * dv / dt_avg),
                                      dx))
        if rot is not None:
            wn = 0.5 * (rot.w_old + rot.w)
            work += 0.5 * float(np.einsum("i,ij,ij->", rot.I - self.I_old, wn, wn))
        return work

    def jump(self, v: np.ndarray, m_old: np.ndarray, m: np.ndarray) -> None:
        """At a boundary of the subcycled loop (``engine.subcycle``: lumped translational mass only): book
        1/2 sum (m - m_old) |v|^2 at the last velocities v (n_node, 3), the first version's estimate (module
        docstring), as that loop's per-node kicks have no single step to rescale."""
        self.work += 0.5 * float(np.einsum("i,ij,ij->", m - m_old, v, v))
