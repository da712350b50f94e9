"""Spring grip: every node of a set tied to an anchor by linear springs, the anchors moved by a prescribed
translation (a clamp with compliance, or one that pre-tensions the blank).

Node i (reference position X_i, current x_i) and its anchor at X_i + a(t), a(t) = value * amplitude(t) * direction
restricted to the gripped dofs (mask P, a diagonal of ones and zeros): elongation d_i = P (x_i - X_i - a) [mm];
force of the grip on the node -k d_i [N], so the internal force (resisting sign) is +k d_i; stored energy
k |d_i|^2 / 2 [mJ] (``grip_energy``). Then dE/dt = k d . v - k d . da/dt: the first part is the blank's work of the
internal force (booked by the engine through the kinetic energy), the second is the work of the moving anchors on
the blank, integrated by the trapezoidal rule on the anchor increments between calls (``grip_work_<set>``), as the
tool work of ``physics.effects.contact``; kinetic + stored - work then stays constant.

Stable step: each gripped node is a spring k on its lumped mass m; the effect bounds the step by sqrt(m / k) =
1 / omega, half the node's own critical step 2 / omega, leaving room for the element stiffness the node also carries
(the bound of the contact effect, same reasoning).
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.cards.grip import AXIS
from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.engine.ledger import STORED, VALUE, WORK, Term
from fdeck.jit import njit
from fdeck.registry import EffectKind, register_effect


@njit
def grip_forces(x, nodes, X, a, mask, k, f, total):
    """Add the springs' internal forces k d (resisting sign) [N] of the nodes (k,) to f (n_node, 3), from positions
    x (n_node, 3), their reference X (k, 3), the anchor translation a (3,) [mm], the dof mask (3,) and the stiffness
    k [N/mm]; write the total force of the grip on the blank to total (3,) [N]; return the stored energy [mJ].
    Serial over nodes (a few hundred at most): the same sums in the same order on any thread count."""
    energy = 0.0
    total[:] = 0.0
    for i in range(nodes.shape[0]):
        n = nodes[i]
        for c in range(3):
            d = (x[n, c] - X[i, c] - a[c]) * mask[c]
            f[n, c] += k * d
            total[c] -= k * d
            energy += 0.5 * k * d * d
    return energy


class SpringGrip(Effect):
    """Linear springs from the nodes of a set to their moving anchors; see the module docstring.

    nodes (k,) node indices; mask (3,) 1 on gripped dofs, 0 elsewhere; stiffness k [N/mm]; motion(t) -> (3,)
    anchor translation [mm] (already masked); X (n_node, 3) reference positions [mm]; moving: the anchors travel."""

    forces = "internal"

    def __init__(self, set_name, nodes, mask, stiffness, motion, X, moving=True):
        self.name, self.set, self.moving = f"spring_grip:{set_name}", set_name, moving
        self.nodes, self.mask, self.k, self.motion = nodes, mask, stiffness, motion
        self.X = np.ascontiguousarray(X[nodes])
        self.a = np.zeros(3)  # anchor translation at the last call [mm]
        self.force = np.zeros(3)  # total force of the grip on the blank at the last call [N]
        self.energy = self.work = 0.0
        self.dt = math.inf
        self.terms = (Term("grip_energy", STORED), Term(f"grip_work_{set_name}", WORK),
                      *(Term(f"grip_{set_name}_force_{c}", VALUE) for c in "xyz"),
                      *(Term(f"grip_{set_name}_anchor_{c}", VALUE) for c in "xyz"))

    def begin_step(self, index, plan):
        self.dt = float(np.sqrt(plan.mass[self.nodes].min() / self.k))

    def add_force(self, t, x, v, f):
        a = self.motion(t)
        force = np.empty(3)
        self.energy = grip_forces(x, self.nodes, self.X, a, self.mask, self.k, f, force)
        self.work += 0.5 * float(np.dot(self.force + force, a - self.a))  # trapezoid on the anchor's increment
        self.force, self.a = force, a

    def stable_dt(self):
        return self.dt

    def term_values(self):
        return (self.energy, self.work, *self.force.tolist(), *self.a.tolist())

    def describe(self, plan) -> str:
        self.begin_step(0, plan)
        moving = "moving anchors" if self.moving else "fixed anchors"
        return (f"spring grip on '{self.set}': {len(self.nodes)} nodes, {self.k:g} N/mm per node, {moving}, step "
                f"bound sqrt(m/k) = {self.dt:.4g} s")


def build(card, ctx):
    nodes = np.ascontiguousarray(np.unique(ctx.node_set(card.nodes)), np.int64)
    mask = np.zeros(3)
    mask[[AXIS[d] for d in card.dofs]] = 1.0
    if card.value == 0.0:
        motion = lambda t: np.zeros(3)  # noqa: E731
    else:
        direction = np.asarray(card.direction, float)
        step = card.value * mask * direction / np.linalg.norm(direction)
        amp = ctx.amplitude(card.amplitude)
        motion = lambda t: amp(t) * step  # noqa: E731
    if len(nodes) == 0:
        raise CompileError([(ctx.path + ("nodes",), f"node set '{card.nodes}' is empty")])
    return SpringGrip(card.nodes, nodes, mask, card.stiffness, motion, ctx.X, card.value != 0.0)


register_effect(EffectKind("spring_grip", build))
