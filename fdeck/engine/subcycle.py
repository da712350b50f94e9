"""Subcycling: explicit central differences with node steps that are powers of two of the smallest (opt-in per step,
``steps[i].subcycling``; the deck card is ``cards.subcycling``, the ledger-facing effect ``effects.subcycling``).

Scheme: the nodal partition of Belytschko, Yen & Mullen ("Mixed methods for time integration", Comput. Methods
Appl. Mech. Engrg. 17/18, 1979) with integer step ratios 2^k, as analysed for explicit-explicit partitions by
Smolinski, Sleith & Belytschko ("Stability of an explicit multi-time step integration algorithm for linear structural
dynamics equations", Comput. Mech. 18, 1996):

* every element e gets a level b_e, the largest k <= L with 2^k dt_min <= dt_e (its own stable step, dt_min the
  smallest); a node takes the smallest level of its elements, n_a = min_e b_e, and is integrated with the step
  2^(n_a) h (h = dt_safety dt_min): its velocity is kicked only at its own times, with the central-difference
  average of its previous and next steps, and it drifts with that constant velocity in between;
* an element is updated at the rate of its fastest node, u_e = min_a n_a (so every node that is kicked sees fresh
  forces from all its elements); elements are built into one group per (section, u) with the formulation's own
  build hook on element subsets, so the element kernels are untouched;
* the slow nodes' positions at the minor times are the linear interpolation of BYM (constant velocity over their
  step), which is what drifting every node every minor step with its current velocity gives;
* an element never runs above its own step: the largest step among its nodes is 2^(m_e) h with m_e = max_a n_a
  <= b_e; at every synchronised time (the end of a major cycle, 2^L minor steps) the levels are re-derived from the
  current element steps ("regrouping": an element drops to a lower level as soon as its step falls below its bin's,
  and rises again when it recovers or when the smallest step elsewhere falls); the groups' membership is fixed at
  compile time, so a group containing an element that now needs a faster rate runs at that rate as a whole (no
  state is moved between groups). So that a local stiffening (a crushed region, a kink stiffened by fibre bending)
  slows only its neighbourhood, each section is split at compile time into spatially compact blocks of at most
  ``block_elements`` elements (recursive coordinate bisection of the centroids) as well as by level: a block runs at
  the rate of its fastest element. Every group update in between measures the ratio of the step its slowest node
  uses to its own current step (``step_ratio_max``, must stay below 1) and counts the updates where it exceeded
  dt_safety;
* the minor step h follows a fall of the smallest element step at once and grows by at most
  ``engine.solver.STEP_GROWTH`` from one major cycle to the next (as the uniform engine's step per cycle: a bound
  that flickers must not alternate the run between a short and a long step);
* rigid tools advance and contact pairs are evaluated at every minor step (a node is seen by the tool whatever its
  level), and each contact node's spring step sqrt(m/k) (``Effect.node_dt``) caps its level;
* section add-ons with a stiffness of their own (fibre bending: hinges joining neighbouring elements) act on the
  whole section, seen through a ``SectionView`` of its blocks; they are evaluated at every minor step (their forces
  are then fresh at every node that is kicked), and their element steps (``Effect.element_dt``) lower the levels of
  the elements they stiffen.

Why this scheme: it is explicit at every node (no interface solve), needs no change to the element kernels (BYM's
interpolation is the drift of the central-difference update itself), and its stability for nodal partitions is
proved (pseudo-energy argument of Smolinski et al. 1996) with the element-wise bound used here. Daniel ("The subcycled
Newmark algorithm", Comput. Mech. 20, 1997) showed that undamped BYM subcycling has narrow unstable bands of the step
that get narrower as the model grows and that placing interface elements with the faster partition narrows them
further; that is the partition used here (u_e = min_a n_a). Neal & Belytschko's non-integer ratios (Comput. Struct.
31, 1989) are not needed with powers of two. The energy is not conserved exactly at the interface, so the ledger
measures it: history rows (and frames) are taken only at synchronised times, where every node has just been kicked
(kinetic energy from the mean of the velocities before and after, as the uniform engine) and every group was updated
(stored energies); the work of external forces and reactions is the trapezoidal rule over each node's own step.

Not supported (refused at compile time by ``effects.subcycling``): shells and rotations, non-hexahedral groups,
selective mass scaling, damping and bulk viscosity, checkpoints/restart.
"""

from __future__ import annotations

import math
import time

import numpy as np

from fdeck.engine.step_mass import StepMassChange, changes_mass
from fdeck.jit import njit

# -- levels -------------------------------------------------------------------------------------------------------


def element_levels(dt_e: np.ndarray, dt_min: float, top: int) -> np.ndarray:
    """(n_el,) int64: the largest k <= top with 2^k dt_min <= dt_e (0 where dt_e < 2 dt_min; top where dt_e is
    infinite)."""
    out = np.empty(len(dt_e), np.int64)
    _levels(np.asarray(dt_e, float), float(dt_min), int(top), out)
    return out


@njit
def _levels(dt_e, dt_min, top, out):
    # doubling instead of log2: exact at powers of two, and a handful of comparisons per element (called for every
    # group at every synchronised time, so numpy's temporaries would cost more than the comparisons)
    for e in range(dt_e.shape[0]):
        k = 0
        step = 2.0 * dt_min
        while k < top and step <= dt_e[e]:
            k += 1
            step *= 2.0
        out[e] = k


@njit
def foresee(now, last, over, safety, out):
    """out (n_el,) = the element steps expected one major cycle ahead: now, times (now / last)^2 where the step fell
    since the last synchronised time (a stiffening element continues at its rate), so that an element whose step
    is collapsing (a blank pinched at closure) drops a level before it runs above its own step, not after; and
    times safety / over for an element that ran above ``safety`` of its own step during the last major cycle
    (``over`` (n_el,): its largest used / own step then, reset here), so that one that stiffened faster than
    foreseen drops further. Then last = now. Returns out. All (n_el,) [s]."""
    for e in range(now.shape[0]):
        d = now[e]
        out[e] = d * (d / last[e]) ** 2 if d < last[e] else d
        if over[e] > safety:
            out[e] *= safety / over[e]
        over[e] = 0.0
        last[e] = d
    return out


@njit
def step_ratio(dt_e, lowered, used, over):
    """Largest used / own step over a group's elements: dt_e (n_el,) their current steps, lowered (n_el,) the
    add-ons' steps from the synchronised time (inf where none), used (n_el,) the step of each one's slowest node;
    over (n_el,) keeps each element's largest ratio since the last synchronised time (for ``foresee``)."""
    worst = 0.0
    for e in range(dt_e.shape[0]):
        r = used[e] / min(dt_e[e], lowered[e])
        over[e] = max(over[e], r)
        worst = max(worst, r)
    return worst


def static_plan(groups: list, n_node: int, top: int):
    """Levels from the groups' rest steps: (own, node, update, highest) of ``node_levels`` with own b_e per group."""
    dt_e = [g.rest_dt(g.rho) for g in groups]
    dt_min = min(float(d.min()) for d in dt_e)
    own = [element_levels(d, dt_min, top) for d in dt_e]
    return (own,) + node_levels(groups, own, n_node, top)


def node_levels(groups: list, own: list[np.ndarray], n_node: int, top: int, caps: np.ndarray | None = None):
    """From the elements' own levels ``own`` (per group (n_el,)): (node, update, highest) with node (n_node,) the
    node levels n_a = min over the node's elements of b_e and of the node's own cap ``caps`` (n_node,) (a contact
    spring's step, ``node_caps``), graded so that the levels of an element's nodes differ by at most one (``top`` at
    nodes without elements); per group (n_el,) update levels u_e = min over the element's nodes of n_a and m_e =
    max over them."""
    node = np.full(n_node, top, np.int64) if caps is None else caps.copy()
    for g, b in zip(groups, own):
        np.minimum.at(node, g.conn.ravel(), np.repeat(b, g.conn.shape[1]))
    for _ in range(top):  # grade: across any element the node steps differ by at most a factor 2
        for g in groups:
            np.minimum.at(node, g.conn.ravel(), np.repeat(node[g.conn].min(axis=1) + 1, g.conn.shape[1]))
    update = [node[g.conn].min(axis=1) for g in groups]
    highest = [node[g.conn].max(axis=1) for g in groups]
    return node, update, highest


def subset_recipe(build, name, section, X, conn, ids, kind, params, orient, rho, ctype, idx, section_index):
    """A function (sel, level) -> element group of the elements ``sel`` (local indices) of one section, built by the
    formulation's own hook exactly as ``compile.problem.build_groups`` builds the whole section."""

    def make(sel: np.ndarray, label: str):
        # the orientation's own class (compile.orientation, which the engine does not import: one direction)
        o = type(orient)(orient.reference[sel], orient.warp_angle[sel], orient.normal)
        rows = params[sel]  # the section's one row, kept a broadcast view as compile.problem builds it (laws such
        # as fabric_hyper take their block path only for such a row)
        g = build(f"{name}/{label}", section, X, conn[sel], ids[sel], kind, np.broadcast_to(rows[:1], rows.shape), o,
                  rho[sel], ctype)
        g.element_index, g.section_index = idx[sel], section_index
        g.subset = sel  # (n_el,) its elements' indices in the section's elements of this cell type
        return g

    return make


def spatial_blocks(centroids: np.ndarray, sel: np.ndarray, size: int) -> list[np.ndarray]:
    """``sel`` (k,) split into spatially compact blocks of at most ``size`` indices by recursive coordinate
    bisection of ``centroids`` (n, 3): halve at the median of the longest extent until small enough. Deterministic
    (stable sorts); each block is sorted."""
    if len(sel) <= size:
        return [np.sort(sel)]
    c = centroids[sel]
    order = np.argsort(c[:, int(np.argmax(c.max(axis=0) - c.min(axis=0)))], kind="stable")
    half = len(sel) // 2
    return spatial_blocks(centroids, sel[order[:half]], size) + spatial_blocks(centroids, sel[order[half:]], size)


def split_groups(groups: list, recipes: list, X: np.ndarray, top: int, block: int) -> list:
    """Groups split by update level and into spatial blocks of at most ``block`` elements (``spatial_blocks``); a
    group with one level and no more elements than a block stays as it is, as do groups that are not hexahedra (the
    subcycling card refuses those)."""
    _, _, update, _ = static_plan(groups, len(X), top)
    out = []
    for g, make, u in zip(groups, recipes, update):
        levels = np.unique(u)
        if not g.solid or (len(levels) == 1 and len(g.conn) <= block):
            out.append(g)
            continue
        centroids = X[g.conn].mean(axis=1)
        for k in levels:
            parts = spatial_blocks(centroids, np.flatnonzero(u == k), block)
            out += [make(sel, f"level{k}" + (f"/block{b}" if len(parts) > 1 else "")) for b, sel in enumerate(parts)]
    return out


class SectionView:
    """The blocks one section (of one cell type) was split into for subcycling, seen as one element group by a
    section add-on whose stencil crosses blocks (fibre bending's hinges join neighbouring elements). Elements in
    part order; what an add-on reads of a group: conn, ids, frame, rho, dt_e after ``stable_dt``, ``mass(rho)``,
    ``rest_dt(rho)``; ``slice(part)`` locates a part's elements in the view's arrays."""

    solid = True
    rotational = False

    def __init__(self, parts: list):
        self.parts = parts
        self.name = parts[0].name.split("/level")[0]
        self.cell_type, self.section_index = parts[0].cell_type, parts[0].section_index
        self.conn = np.ascontiguousarray(np.concatenate([p.conn for p in parts]))
        self.ids = np.concatenate([p.ids for p in parts])
        self.frame = np.ascontiguousarray(np.concatenate([p.frame for p in parts]))
        self.bounds = np.cumsum([0] + [len(p.conn) for p in parts])
        self._slices = {id(p): slice(int(a), int(b)) for p, a, b in zip(parts, self.bounds[:-1], self.bounds[1:])}
        self.dt_e = np.zeros(len(self.conn))
        self._rho, self._rho_of = None, None

    def slice(self, part) -> slice:
        return self._slices[id(part)]  # the parts are held by the view, so their ids stay theirs

    def _split(self, a: np.ndarray) -> list[np.ndarray]:
        return [a[self.bounds[j]:self.bounds[j + 1]] for j in range(len(self.parts))]

    @property
    def rho(self) -> np.ndarray:
        """(n_el,) the parts' current densities; the same object while no part's density changed (add-ons cache
        their lumped mass by its identity)."""
        now = [p.rho for p in self.parts]
        if self._rho_of is None or any(a is not b for a, b in zip(now, self._rho_of)):
            self._rho, self._rho_of = np.concatenate(now), now
        return self._rho

    def with_part_rho(self, part, rho: np.ndarray) -> np.ndarray:
        """(n_el,) the current densities with ``part``'s replaced by rho."""
        full = self.rho.copy()
        full[self.slice(part)] = rho
        return full

    def stable_dt(self) -> float:
        for p, out in zip(self.parts, self._split(self.dt_e)):
            p.stable_dt()
            out[:] = p.dt_e
        return float(self.dt_e.min())

    def rest_dt(self, rho: np.ndarray) -> np.ndarray:
        return np.concatenate([p.rest_dt(r) for p, r in zip(self.parts, self._split(np.asarray(rho, float)))])

    def mass(self, rho: np.ndarray) -> np.ndarray:
        return np.concatenate([p.mass(r) for p, r in zip(self.parts, self._split(np.asarray(rho, float)))])


def section_units(groups: list, section_index: int) -> list:
    """What a section add-on of section ``section_index`` acts on: per cell type the section's group, or a
    ``SectionView`` of its blocks when subcycling split it."""
    out = []
    mine = [g for g in groups if g.section_index == section_index]
    for ctype in dict.fromkeys(g.cell_type for g in mine):
        parts = [g for g in mine if g.cell_type == ctype]
        split = len(parts) > 1 or getattr(parts[0], "subset", None) is not None
        out.append(SectionView(parts) if split else parts[0])
    return out


def element_steps(groups: list, effects: list) -> list[np.ndarray]:
    """Per group (n_el,) the current element steps [s] (after ``stable_dt`` of groups and effects): the group's
    own, lowered where a section add-on's ``element_dt`` (over its group or ``SectionView``) is smaller."""
    steps = [g.dt_e for g in groups]
    where = {id(g): j for j, g in enumerate(groups)}
    for e in effects:
        own = e.element_dt() if e.group is not None else None
        if own is None:
            continue
        for p in getattr(e.group, "parts", [e.group]):
            j = where[id(p)]
            steps[j] = np.minimum(steps[j], own[e.group.slice(p)] if p is not e.group else own)
    return steps


def node_caps(effects: list, n_node: int, dt_min: float, top: int) -> np.ndarray:
    """(n_node,) int: the highest level each node may take for the effects acting on it alone (``Effect.node_dt``:
    a contact spring on the node's mass), ``top`` where none does."""
    caps = np.full(n_node, top, np.int64)
    for e in effects:
        own = e.node_dt()
        if own is not None:
            np.minimum.at(caps, own[0], element_levels(own[1], dt_min, top))
    return caps


def regroup(sub, groups: list, steps: list[np.ndarray], caps: np.ndarray, dt_min: float) -> bool:
    """Re-derive the levels from the elements' current steps ``steps`` (per group (n_el,), ``element_steps``) and
    the nodes' caps (``node_caps``): sets ``sub.node``, ``sub.group_level`` (a group runs at the fastest rate any of
    its elements now needs; its membership is fixed) and ``sub.highest``. Returns whether anything changed (nothing
    is recomputed when no level changed)."""
    own = [element_levels(d, dt_min, sub.top) for d in steps]
    if all(np.array_equal(a, b) for a, b in zip(own, sub.own_now)) and np.array_equal(caps, sub.caps_now):
        return False
    sub.own_now, sub.caps_now = own, caps
    sub.node, update, sub.highest = node_levels(groups, own, len(sub.node), sub.top, caps)
    sub.group_level = [int(u.min()) for u in update]
    return True


def trailing_zeros(i: int) -> int:
    return (i & -i).bit_length() - 1


# -- node kernels -------------------------------------------------------------------------------------------------
# Serial: they make a few flops per node against the hundreds per element of the groups' kernels, their sums are
# then the same on any thread count, and they compile in 1.6 CPU-s instead of 4 (measured cold, parallel=True).


@njit
def kick_nodes(idx, level, h, v, v_old, inv_m, f_ext, f_int, h_prev, dt_avg):
    """Nodes idx start a step of 2^level h [s]: dt_avg = (h_prev + that) / 2, v_old = v, v += dt_avg (f_ext - f_int)
    / m. Shapes: idx (k,), level (n_node,) int, v, v_old, f_ext, f_int (n_node, 3), inv_m, h_prev, dt_avg (n_node,)."""
    for j in range(idx.shape[0]):
        a = idx[j]
        step = h * (1 << level[a])
        d = 0.5 * (h_prev[a] + step)
        dt_avg[a] = d
        h_prev[a] = step
        for i in range(3):
            v_old[a, i] = v[a, i]
            v[a, i] += d * inv_m[a] * (f_ext[a, i] - f_int[a, i])


@njit
def book_nodes(idx, m, v, v_old, f_ext, f_int, dt_avg, fe_prev, dx, reaction):
    """After the constraints, at the nodes idx just kicked: reaction = m (v - v_old) / dt_avg - (f_ext - f_int), the
    work of f_ext + reaction over each node's last step dx by the trapezoidal rule (returned, [mJ]); then
    fe_prev = f_ext + reaction and dx = 0 (``drift_nodes`` accumulates the next step's displacement)."""
    w = 0.0
    for j in range(idx.shape[0]):
        a = idx[j]
        for i in range(3):
            r = m[a] * (v[a, i] - v_old[a, i]) / dt_avg[a] - (f_ext[a, i] - f_int[a, i])
            reaction[a, i] = r
            fe = f_ext[a, i] + r
            w += 0.5 * (fe_prev[a, i] + fe) * dx[a, i]
            fe_prev[a, i] = fe
            dx[a, i] = 0.0
    return w


@njit
def drift_nodes(x, v, dx, h):
    """Every node moves h v (its constant velocity over its own step: BYM's linear interpolation), dx += h v."""
    for a in range(x.shape[0]):
        for i in range(3):
            d = h * v[a, i]
            dx[a, i] += d
            x[a, i] += d


@njit
def kinetic(m, v, v_old, first):
    """Kinetic energy [mJ] at a synchronised time (every node just kicked): v = (v_old + v) / 2 (v_old on the first
    cycle, the initial velocity)."""
    ke = 0.0
    for a in range(v.shape[0]):
        for i in range(3):
            vn = v_old[a, i] if first else 0.5 * (v_old[a, i] + v[a, i])
            ke += 0.5 * m[a] * vn * vn
    return ke


# -- the loop -----------------------------------------------------------------------------------------------------


def run(problem, sink, should_stop, resume, sub):
    """``engine.solver.run`` for a problem with subcycling (``sub``: the ``effects.subcycling`` effect)."""
    from fdeck.engine.solver import (STEP_GROWTH, Result, RunStopped, _Timer, guard_energy, history_columns, ledger,
                                     past, step_setter)

    res = Result(columns=history_columns(problem))
    groups, effects = problem.groups, problem.effects
    X = problem.X
    n = len(X)
    x, v = X.copy(), np.zeros((n, 3))
    res.final_positions, res.final_velocities, res.final_directors = x, v, None
    if resume is not None:
        res.status = "failed"
        res.message = "a run with subcycling cannot continue from a checkpoint (its per-level state is not saved)"
        return res
    step_mass = StepMassChange() if changes_mass(problem) else None
    book = ledger(problem, step_mass)
    forcing = [e for e in effects if e.forces is not None]
    movers = [e for e in effects if e.moves]
    constraints = [e for e in effects if e.constrains]
    f_int, f_ext = np.zeros((n, 3)), np.zeros((n, 3))
    v_old, fe_prev, dx, reaction = (np.zeros((n, 3)) for _ in range(4))
    h_prev, dt_avg = np.zeros(n), np.zeros(n)
    h_last = 0.0  # the last minor step, for the tools' central-difference update
    level = None  # node levels of the current major cycle's plan (with g_level, below, scale)
    unlowered = [np.full(len(g.conn), np.inf) for g in groups]  # no add-on's step on these elements
    last_steps = [np.full(len(g.conn), np.inf) for g in groups]  # element steps at the last synchronised time
    ahead_steps = [np.zeros(len(g.conn)) for g in groups]
    overshoot = [np.zeros(len(g.conn)) for g in groups]  # each element's largest used / own step in the cycle
    timer = _Timer()
    T = problem.duration
    frame_times = np.linspace(0.0, T, problem.deck.output.frames + 1)
    hist_times = np.linspace(0.0, T, problem.deck.output.history_points)
    next_frame, next_hist = 0, 0
    w_ext, energy0, H_prev = 0.0, None, 0.0
    balance = problem.deck.checks.energy_balance
    energy_stop = None if balance is None else balance.stop_above
    energy_scale = energy_prev = 0.0
    sizes = [len(g.conn) for g in groups]
    t = 0.0
    wall0 = last_progress = time.perf_counter()

    def update(g, t):
        g.update(x, v)
        g.add_forces(f_int)
        jmin, el = g.worst_jacobian()
        if not jmin > 0.0:
            raise RunStopped("element inverted (det F <= 0)" if jmin <= 0.0 else "non-finite deformation (NaN)", t,
                             el)

    try:
        t_step_end = 0.0
        for k, plan in enumerate(problem.steps):
            t_step_end += plan.duration
            m_old = m if k > 0 else None
            for g, rho in zip(groups, plan.rho):
                g.set_density(rho)
            m = plan.mass
            inv_m = 1.0 / m
            for e in effects:
                e.begin_step(k, plan)
            if step_mass is not None and k > 0:  # the kinetic energy of the step's new masses (engine.step_mass)
                step_mass.jump(v, m_old, m)
            if k == 0:
                for g in groups:
                    update(g, 0.0)
                for e in forcing:
                    e.add_force(0.0, x, v, f_int if e.forces == "internal" else f_ext)
            res.added_mass.append(plan.added_mass)
            step_cycles = 0
            collapse = getattr(problem.deck.steps[k], "min_dt_ratio", 0.0)
            dt_start = None
            h_grow = math.inf  # the last major cycle's stable minor step: growth is limited from it
            while t < t_step_end * (1 - 1e-12):
                stop = should_stop()
                if stop:
                    res.status = "interrupted"
                    res.message = stop if isinstance(stop, str) else f"stopped by signal at t = {t:.6g} s"
                    break
                if plan.max_cycles is not None and step_cycles >= plan.max_cycles:
                    res.stopped_steps.append(plan.name)
                    res.message = (f"step '{plan.name}' stopped at max_cycles = {plan.max_cycles}, "
                                   f"t = {t:.6g} s of {t_step_end:.6g} s")
                    t_step_end = t
                    break
                t0 = time.perf_counter()
                # synchronised time: every group is current; the step and the levels of the next major cycle
                dt_min = min([g.stable_dt() for g in groups] + [e.stable_dt() for e in effects])
                # a fall is followed at once, growth by at most STEP_GROWTH per major cycle (engine.solver; per
                # major cycle, not per minor step, so that 2^L minor steps cannot compound it into a jump)
                h = min(plan.dt_safety * dt_min, STEP_GROWTH * h_grow)
                dt_start = h if dt_start is None else dt_start
                if h < collapse * dt_start:
                    raise RunStopped(f"stable time step collapsed to {h:.3g} s, below {collapse:g} x the step's first "
                                     f"{dt_start:.3g} s (steps[{k}].min_dt_ratio), set by "
                                     f"{step_setter(groups, effects)}", t)
                steps_now = element_steps(groups, effects)
                ahead = [foresee(d, p, o, plan.dt_safety, a)
                         for d, p, o, a in zip(steps_now, last_steps, overshoot, ahead_steps)]
                changed = regroup(sub, groups, ahead, node_caps(effects, n, dt_min, sub.top), dt_min)
                sub.regroups += changed
                # an add-on's steps are taken here, at the synchronised time, for the checks at the minor updates
                lowered = [none if d is g.dt_e else d for d, g, none in zip(steps_now, groups, unlowered)]
                cap = min(sub.caps[k], int(sub.node.max()))  # a major cycle no longer than the slowest node's step
                remaining = t_step_end - t
                while cap > 0 and (1 << cap) * h > remaining:  # the step's end is a synchronised time
                    cap -= 1
                h_stable = h_grow = h  # the step range reported is the stable step's, not the cut to the step's end
                h = min(h, remaining / (1 << cap))
                if not h > 0.0 or not math.isfinite(h):
                    raise RunStopped(f"stable time step is {h:.3g} s", t)
                N = 1 << cap
                if changed or cap != sub.cap or level is None:  # the plan of the major cycle, kept while it holds
                    level = np.minimum(sub.node, cap)
                    g_level = [min(int(u), cap) for u in sub.group_level]
                    below = [np.flatnonzero(level <= j) for j in range(cap + 1)]  # nodes kicked when level j is due
                    scale = [np.exp2(np.minimum(mh, cap)) for mh in sub.highest]  # each element's slowest node
                used = [h * s for s in scale]  # [s]
                sub.cap = cap
                for i in range(N):
                    due = cap if i == 0 else trailing_zeros(i)
                    idx = below[due]
                    kick_nodes(idx, level, h, v, v_old, inv_m, f_ext, f_int, h_prev, dt_avg)
                    for c in constraints:
                        c.constrain(t + h, h, x, v)
                    w_ext += book_nodes(idx, m, v, v_old, f_ext, f_int, dt_avg, fe_prev, dx, reaction)
                    if i == 0:  # ledger at the synchronised time t
                        ke = kinetic(m, v, v_old, res.cycles == 0)
                        H = N * h
                        book.integrate(0.5 * (H_prev + H) if H_prev > 0 else 0.5 * H)
                        H_prev = H
                        if not math.isfinite(ke):
                            raise RunStopped("non-finite energy (NaN or overflow in forces)", t)
                        if energy0 is None:
                            energy0 = book.energy(ke)
                        if next_hist < len(hist_times) and t >= hist_times[next_hist] - 1e-12 * T:
                            row, error = book.row(t, h, ke, w_ext, 0.0, energy0, [])
                            if not all(math.isfinite(r) for r in row[:len(book.columns)]):
                                raise RunStopped("non-finite energy (NaN or overflow in forces)", t)
                            if energy_stop is not None:
                                energy_scale, energy_prev = guard_energy(energy_stop, energy_scale, energy_prev,
                                                                         row, error, t)
                            for nodes in problem.reactions.values():
                                row += reaction[nodes].sum(axis=0).tolist()
                            for meas in problem.measures:
                                row += meas.evaluate(x, v)
                            res.history.append(row)
                            sink.history(row)
                            next_hist = past(hist_times, next_hist, t, T)
                    for e in movers:  # the tools at t + h, before the forces there (every minor step)
                        e.advance(t + h, h, 0.5 * (h_last + h) if h_last > 0.0 else h)
                    h_last = h
                    drift_nodes(x, v, dx, h)
                    t += h
                    res.cycles += 1
                    step_cycles += 1
                    t0 = timer.add("integrator", t0)
                    due = cap if i + 1 == N else trailing_zeros(i + 1)
                    f_int.fill(0.0)
                    f_ext.fill(0.0)
                    for j, (g, gl) in enumerate(zip(groups, g_level)):
                        if gl <= due:
                            update(g, t)
                            sub.element_cycles += sizes[j]
                            g.stable_dt()  # current dt_e: no element may run above its own step
                            worst = step_ratio(g.dt_e, lowered[j], used[j], overshoot[j])
                            sub.step_ratio_max = max(sub.step_ratio_max, worst)
                            sub.over_safety += int(worst > plan.dt_safety * (1 + 1e-12))
                            t0 = timer.add(g.name, t0)
                    for e in forcing:  # every minor step: fresh at every node kicked next
                        e.add_force(t, x, v, f_int if e.forces == "internal" else f_ext)
                        t0 = timer.add(e.name, t0)
                sub.element_cycles_uniform += N * sum(sizes)
                for j in range(sub.top + 1):  # steps of the nodes of each plan level (capped this cycle)
                    sub.level_cycles[j] += N >> min(j, cap)
                res.dt_min, res.dt_max = min(res.dt_min, h_stable), max(res.dt_max, h_stable)
                if next_frame < len(frame_times) and t >= frame_times[next_frame] - 1e-12 * T:
                    sink.frame(t, x, v)
                    next_frame = past(frame_times, next_frame, t, T)
                now = time.perf_counter()
                if now - last_progress > 0.5:
                    sink.progress(t, res.cycles, h)
                    last_progress = now
            if res.status == "interrupted":
                break
        if res.status == "running":
            res.status = "completed"
    except RunStopped as exc:
        res.status, res.message = "failed", str(exc)
    res.t = t
    res.wall = time.perf_counter() - wall0
    res.timings = timer.acc
    return res
