"""Central-difference explicit integration with lumped mass, energy ledger and monitors.

Per cycle n (Belytschko, Liu & Moran, Nonlinear FE for Continua and Structures, 2000, box 6.1):
    v(n+1/2) = v(n-1/2) + dt_avg a(n)          then prescribed velocities are imposed (reactions R = m dv / dt_avg)
    x(n+1)   = x(n) + dt v(n+1/2)
    forces at x(n+1) -> a(n+1); stable step from the groups' current wave moduli.
Ledger at t(n) (``engine.ledger``): kinetic energy from v(n) = (v(n-1/2) + v(n+1/2)) / 2; internal energy is the
STORED energy the groups and effects report (strain energy, hourglass and other springs), not the integrated
internal work, so the balance error KE + stored + dissipated - work exposes forces inconsistent with energies or
instability; the engine integrates the work of external forces and reactions and the dissipation of damping forces
with the trapezoidal rule, the sources book their own work and dissipation as named terms.
Effects that move bodies of their own (rigid tools, ``Effect.moves``) advance them to t(n+1) after the positions.

Rotational degrees of freedom (``engine.rotation``) exist only when the problem has groups that need them
(``problem.rotations`` is not None, e.g. shells): then nodal directors and angular velocities are advanced beside
x and v, groups and effects that declare ``rotational = True`` are bound to them once, and the ledger adds the
rotational kinetic energy and the work of moments. A problem without them runs the same operations as before they
existed (no rotational arrays, no extra kernel calls).

Checkpoints: at the end of a cycle the sink may ask for one (``Sink.checkpoint_due``); the engine then hands it its
whole state: the loop's variables (step index, t, the step's end, dt_prev, dt_next, cycles of the step, next frame
and history sample, external work, damping dissipation, energy0), the nodal arrays (x, v, v_old, the three force
arrays, fe_prev, fd_prev, dx, reaction), every group's, effect's, measure's and the rotations' mutable arrays and
scalars (``engine.snapshot``), the ledger's integrals, the history rows. It also hands one when a run is stopped
(at the top of a cycle, before anything moved) and when it completes. ``run(..., resume=state)`` sets the step up
as usual and then puts the state back, so the continued run performs the uninterrupted run's operations on the
same bits.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numba
import numpy as np

from fdeck.engine import snapshot
from fdeck.engine.effect import free_dofs
from fdeck.engine.integrate import drift, kick
from fdeck.engine.ledger import CORE, Ledger
from fdeck.engine.rotation import Rotations, drift_rot, kick_rot
from fdeck.engine.springs import Springs
from fdeck.engine.step_mass import StepMassChange, changes_mass


class RunStopped(Exception):
    """Numerical failure: ``cause`` says what, ``element`` which element (user id) or None, ``node`` which node
    (1-based, mesh order) or None."""

    def __init__(self, cause: str, t: float, element: int | None = None, node: int | None = None):
        self.cause, self.t, self.element, self.node = cause, t, element, node
        where = f" in element {element}" if element is not None else ""
        where += f" at node {node} (1-based, mesh order)" if node is not None else ""
        super().__init__(f"{cause}{where} at t = {t:.6g} s")


_SCALE_COLUMNS = [CORE.index(c) for c in ("kinetic_energy", "internal_energy", "damping_energy", "external_work")]


def energy_magnitude(row) -> float:
    """Largest |kinetic|, |internal|, |damping|, |external work| of a history row: the scale the energy guard
    compares the balance error with (as ``checks.energy_balance`` does over the whole history)."""
    return max(abs(row[i]) for i in _SCALE_COLUMNS)


def guard_energy(stop: float, scale: float, previous: float, row, error: float, t: float) -> tuple[float, float]:
    """The opt-in energy guard (``checks.energy_balance.stop_above`` = ``stop``) at a history row: returns the
    running energy scale (largest ``energy_magnitude`` so far) and this row's balance error over it; raises
    ``RunStopped`` when two rows in a row are above ``stop``, the second higher (an instability grows faster than
    the energies, while round-off at the first tiny energies of a run shrinks relative to them)."""
    scale = max(scale, energy_magnitude(row))
    ratio = error / scale if scale > 0.0 else 0.0
    if stop < previous < ratio:
        raise RunStopped(f"energy created: balance error {error:.4g} mJ is {ratio:.3g} of the largest energy "
                         f"{scale:.4g} mJ, above checks.energy_balance.stop_above {stop:g}", t)
    return scale, ratio


def past(times: np.ndarray, i: int, t: float, T: float) -> int:
    """The first index from i on whose time lies after t (to 1e-12 of the run's duration T): the next frame or
    history sample still due once the ones at t are written."""
    while i < len(times) and times[i] <= t + 1e-12 * T:
        i += 1
    return i


def first_bad_node(*arrays: np.ndarray) -> int | None:
    """1-based index of the first node with a non-finite value in any of ``arrays`` (n_node, 3), or None."""
    bad = np.zeros(len(arrays[0]), dtype=bool)
    for a in arrays:
        bad |= ~np.isfinite(a).all(axis=1)
    idx = np.flatnonzero(bad)
    return int(idx[0]) + 1 if len(idx) else None


def step_setter(groups, effects) -> str:
    """Who sets the stable step now: 'element <id> (<group>)' for an element group (its smallest ``dt_e``), or the
    effect's name; an effect whose bound is a share of the elements' own steps (``follows_element_steps``: bulk
    viscosity, deformation damping) names the element too, as 'element <id> (<group>) under <effect>'. Call right
    after the groups' and effects' ``stable_dt()``."""
    best, who = math.inf, "unknown"
    for g in groups:
        dt_e = getattr(g, "dt_e", None)
        if dt_e is not None and len(dt_e) and float(dt_e.min()) < best:
            i = int(np.argmin(dt_e))
            best, who = float(dt_e[i]), f"element {int(g.ids[i])} ({g.name})"
    element = who
    for e in effects:
        if e.stable_dt() < best:
            best = e.stable_dt()
            who = f"{element} under {e.name}" if getattr(e, "follows_element_steps", False) else f"effect {e.name}"
    return who


@dataclass
class Result:
    status: str = "running"  # completed | failed | interrupted
    message: str = ""
    cycles: int = 0
    t: float = 0.0
    wall: float = 0.0
    dt_min: float = math.inf
    dt_max: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    history: list[list[float]] = field(default_factory=list)
    columns: list[str] = field(default_factory=list)
    added_mass: list[float] = field(default_factory=list)
    stopped_steps: list[str] = field(default_factory=list)  # steps ended by their max_cycles


class Sink:
    """Where the engine sends results (implemented by fdeck.run with fdeck.io)."""

    def frame(self, t: float, x: np.ndarray, v: np.ndarray, point_fields: dict | None = None) -> None:
        """A frame at t; ``point_fields`` holds extra nodal fields (the director of shell nodes) when there are."""

    def history(self, row: list[float]) -> None: ...

    def progress(self, t: float, cycles: int, dt: float) -> None: ...

    def checkpoint_due(self, cycles: int) -> bool:
        """Whether to save the state at the end of this cycle (``cycles`` done so far)."""
        return False

    def checkpoint(self, state, reason: str) -> None:
        """Save ``state()`` (a dict, see ``run``'s ``resume``; built only when called); ``reason`` is "every",
        "interrupted" or "completed"."""


def ledger(problem, step_mass: StepMassChange | None = None) -> Ledger:
    """The run's ledger: every group's and effect's terms, after the core columns and (with rotational dofs) the
    rotational share of the kinetic energy; with steps that change the mass, ``step_mass`` (a new one if None)."""
    extra = ("rotational_kinetic_energy",) if problem.rotations is not None else ()
    sources = list(problem.groups) + list(problem.effects)
    if changes_mass(problem):  # the kinetic energy of a step's new masses (``engine.step_mass``)
        sources.append(step_mass if step_mass is not None else StepMassChange())
    return Ledger(sources, extra)


def keyed(effects: list) -> dict:
    """The effects by name and occurrence ("contact#1"): a checkpoint restores each effect by this key, not by its
    place in the list, where an effect that an added step brings (damping) is placed among the others."""
    count: dict[str, int] = {}
    out = {}
    for e in effects:
        n = count.get(e.name, 0)
        count[e.name] = n + 1
        out[f"{e.name}#{n}"] = e
    return out


def history_columns(problem) -> list[str]:
    """History columns: the ledger's, then the reactions (forces, and moments with rotational dofs) of the sets
    named in ``output.reactions``, then the measures' columns."""
    cols = list(ledger(problem).columns)
    for name in problem.reactions:
        cols += [f"reaction_{name}_{c}" for c in "xyz"]
        if problem.rotations is not None:
            cols += [f"reaction_{name}_m{c}" for c in "xyz"]
    for m in problem.measures:
        cols += m.columns
    return cols


class _Timer:
    def __init__(self):
        self.acc: dict[str, float] = {}

    def add(self, name: str, t0: float) -> float:
        t1 = time.perf_counter()
        self.acc[name] = self.acc.get(name, 0.0) + t1 - t0
        return t1


# The stable step follows a fall at once but grows by at most 2 % per cycle. An element whose state toggles in and
# out of a stiff branch from cycle to cycle (a fibre about the end of its toe, where the step modulus rises 5-fold)
# would otherwise alternate the run between two steps, the longer one taken while the element is stiff again, and
# pump energy: measured on the `sm` square tube with deformation damping (variant sm_slow_deformation2000 of
# decks/studies/square_tube_slow.yaml, a history row per cycle up to 0.245 s), steps of 4.24e-6 and 2.42e-6 s
# alternating (75 switches between t = 0.2370 and 0.2385 s) created 0.57 mJ there, 0.66 mJ in all; with this limit
# 0.006 mJ in all, for the same number of cycles (57 707 against 57 706). A step that recovers over about 28 cycles
# stays short through such an episode; steady growth (elements unloading) is far slower than 2 % per cycle.
STEP_GROWTH = 1.02

# Below this many elements a cycle's work is shorter than waking a second thread (about 10 us per parallel
# kernel launch with OpenMP on this class of machine, 8 launches per cycle): run such problems on one thread.
SERIAL_BELOW = 2000


def run(problem, sink: Sink, should_stop=lambda: False, resume: dict | None = None) -> Result:
    """Run every step of ``problem``; never raises for numerical failure (status 'failed' with a message).

    ``should_stop()`` is polled every cycle: a truthy value interrupts the run (a string is taken as the message).
    ``resume``: an engine state from ``sink.checkpoint`` of an earlier run of the same problem (or of one whose
    steps were a prefix of this one's): the run continues from it and, with the same deck, ends bitwise identical
    to the uninterrupted run."""
    threads = numba.get_num_threads()
    if problem.n_element < SERIAL_BELOW:
        numba.set_num_threads(1)
    try:
        return _run(problem, sink, should_stop, resume)
    finally:
        numba.set_num_threads(threads)


def _run(problem, sink: Sink, should_stop, resume) -> Result:
    sub = next((e for e in problem.effects if getattr(e, "subcycles", False)), None)
    if sub is not None:  # steps with subcycling: a loop of its own (the uniform loop below is untouched)
        from fdeck.engine import subcycle

        return subcycle.run(problem, sink, should_stop, resume, sub)
    res = Result(columns=history_columns(problem))
    groups, effects = problem.groups, problem.effects
    step_mass = StepMassChange() if changes_mass(problem) else None
    book = ledger(problem, step_mass)
    forcing = [e for e in effects if e.forces is not None]
    constraints = [e for e in effects if e.constrains]
    movers = [e for e in effects if e.moves]
    sms = next((e for e in effects if getattr(e, "solves_mass", False)), None)  # selective mass scaling
    for e in effects if sms is not None else ():
        if hasattr(e, "bind_selective"):  # damping of the added mass (physics.effects.damping)
            e.bind_selective(sms)
    implicit = [e for e in effects if getattr(e, "implicit", False)]  # contact pairs with implicit springs
    # under mass tracking: effects whose step is a share of the elements' own (bulk viscosity) follow the added
    # mass, the hinges of fibre bending (``sms.stiff``) cap it, the others (contact) bound it
    follow = [e for e in effects if getattr(e, "follows_element_steps", False)]
    bounding = [e for e in effects if e not in follow and (sms is None or e not in sms.stiff)]
    X = problem.X
    n = len(X)
    x, v = X.copy(), np.zeros((n, 3))
    f_int, f_ext, f_damp = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    target = {"internal": f_int, "external": f_ext, "damping": f_damp}
    fe_prev = np.zeros((n, 3))  # external + reaction force at the previous cycle
    fd_prev = np.zeros((n, 3))  # damping force at the previous cycle
    dx = np.zeros((n, 3))  # last position increment
    v_old, reaction = np.zeros((n, 3)), np.zeros((n, 3))
    springs = Springs(implicit, n) if implicit else None
    arrays = dict(x=x, v=v, v_old=v_old, f_int=f_int, f_ext=f_ext, f_damp=f_damp, fe_prev=fe_prev, fd_prev=fd_prev,
                  dx=dx, reaction=reaction)
    rot = None
    if problem.rotations is not None:
        rot = Rotations(problem.rotations.d0, problem.rotations.nodes)
        for obj in list(groups) + list(effects):
            if obj.rotational:
                obj.bind(rot)
    objects = [list(groups), keyed(effects), list(problem.measures), rot, step_mass]
    ke_rot = 0.0
    timer = _Timer()
    T = problem.duration
    frame_times = np.linspace(0.0, T, problem.deck.output.frames + 1)
    hist_times = np.linspace(0.0, T, problem.deck.output.history_points)
    next_frame, next_hist = 0, 0
    w_ext = d_damp = 0.0
    energy0 = None
    balance = problem.deck.checks.energy_balance
    energy_stop = None if balance is None else balance.stop_above  # guard against created energy (opt-in)
    energy_scale = 0.0  # largest |kinetic|, |internal|, |damping|, |external work| over the history rows so far
    energy_prev = 0.0  # balance error / energy_scale at the previous history row
    t = 0.0
    wall0 = time.perf_counter()
    last_progress = wall0
    k0 = 0 if resume is None else resume["scalars"]["k"]

    def forces(t, x, v):
        """Fill f_int, f_ext, f_damp (and the moments) at (t, x, v)."""
        f_int.fill(0.0)
        f_ext.fill(0.0)
        f_damp.fill(0.0)
        if rot is not None:
            rot.clear()
        t0 = time.perf_counter()
        for g in groups:
            g.update(x, v)
            g.add_forces(f_int)
            t0 = timer.add(g.name, t0)
        for e in forcing:
            e.add_force(t, x, v, target[e.forces])
            t0 = timer.add(e.name, t0)

    def check(t):
        for g in groups:
            jmin, el = g.worst_jacobian()
            if not jmin > 0.0:  # also catches nan
                cause = "element inverted (det F <= 0)" if jmin <= 0.0 else "non-finite deformation (NaN)"
                raise RunStopped(cause, t, el)

    def stable_dt(safety):
        group_dt = [g.stable_dt() for g in groups]
        if sms is None or not sms.active or sms.track_dt is None:
            return safety * min(group_dt + [min([e.stable_dt() for e in effects], default=math.inf)])
        # selective mass that keeps the target step, never above what the other effects (contact) allow, nor above
        # what the hinges of fibre bending allow (they turn whole elements, which the added mass does not slow)
        effect_dt = min([e.stable_dt() for e in bounding], default=math.inf)
        stiff_dt = min([e.stable_dt() for e in sms.stiff], default=math.inf)  # hinges and continuum together
        wb2 = sms.rotation_omega2()  # per group (n_el,) [1/s^2] or None, the hinges' stiffness of that stable_dt
        hinge_dt = min([2.0 / math.sqrt(w.max()) for w in wb2 if w is not None and w.max() > 0.0], default=math.inf)
        keep = min(sms.track_dt, safety * effect_dt, safety * sms.reach * hinge_dt)
        if safety * min(group_dt + [stiff_dt]) < keep * (1.0 - 1e-9):
            group_dt = sms.track(group_dt, keep, safety, v, v_old, wb2, (f_ext, f_int, f_damp), dt_prev)
            stiff_dt = min([e.stable_dt() for e in sms.stiff], default=math.inf)  # with the new mass
        follow_dt = min([e.stable_dt() for e in follow], default=math.inf)  # from the elements' steps as they are now
        return safety * min(group_dt + [effect_dt, stiff_dt, follow_dt])

    def state(k) -> dict:
        """Everything the loop needs to continue from the end of the current cycle (a checkpoint's engine part)."""
        loop = dict(k=k, t=t, t_step_end=t_step_end, dt_prev=dt_prev, dt_next=dt_next, dt_start=dt_start,
                    step_cycles=step_cycles, next_frame=next_frame, next_hist=next_hist, w_ext=w_ext,
                    d_damp=d_damp, energy0=energy0, ke_rot=ke_rot, energy_prev=energy_prev)
        return {"scalars": loop, "arrays": {name: a.copy() for name, a in arrays.items()},
                "directors": None if rot is None else rot.d.copy(),  # also in "objects"; here for readers
                "objects": snapshot.capture(objects), "ledger": book.state(),
                "result": dict(cycles=res.cycles, dt_min=res.dt_min, dt_max=res.dt_max, message=res.message,
                               added_mass=list(res.added_mass), stopped_steps=list(res.stopped_steps),
                               columns=list(res.columns),
                               history=np.array(res.history, dtype=np.float64).reshape(len(res.history),
                                                                                       len(res.columns))),
                "times": dict(T=T, frames=len(frame_times), history=len(hist_times))}

    try:
        dt_prev = 0.0
        t_step_end = 0.0
        for k, plan in enumerate(problem.steps):
            if k < k0:
                t_step_end += plan.duration
                continue
            t_step_end += plan.duration
            if step_mass is not None and k > 0 and not (resume is not None and k == k0):
                step_mass.open(m, rot, sms)  # booked in the step's first cycle (``close``)
            for g, rho in zip(groups, plan.rho):
                g.set_density(rho)
            m = plan.mass
            inv_m = 1.0 / m
            if rot is not None:
                rot.set_inertia(plan.inertia)
            for e in effects:
                e.begin_step(k, plan)
            if sms is not None:
                sms.prepare(constraints, x)
            if springs is not None:
                springs.prepare(constraints, x)
            if step_mass is not None:
                step_mass.set_up(sms)
            collapse = getattr(problem.deck.steps[k], "min_dt_ratio", 0.0)
            if resume is not None and k == k0:
                # the step's set-up above, then the saved state over it (history variables, loop counters)
                for name, a in resume["arrays"].items():
                    arrays[name][...] = a
                snapshot.restore(objects, resume["objects"])
                book.load_state(resume["ledger"])
                sc, rr = resume["scalars"], resume["result"]
                t, t_step_end, dt_prev, dt_next = sc["t"], sc["t_step_end"], sc["dt_prev"], sc["dt_next"]
                dt_start = sc["dt_start"]
                step_cycles, w_ext, d_damp, energy0, ke_rot = (sc["step_cycles"], sc["w_ext"], sc["d_damp"],
                                                               sc["energy0"], sc["ke_rot"])
                res.cycles, res.dt_min, res.dt_max = rr["cycles"], rr["dt_min"], rr["dt_max"]
                res.message = rr["message"]
                res.added_mass, res.stopped_steps = list(rr["added_mass"]), list(rr["stopped_steps"])
                res.history = [list(map(float, row)) for row in rr["history"]]
                energy_scale = max(map(energy_magnitude, res.history), default=0.0)
                energy_prev = sc.get("energy_prev", 0.0)
                if resume["times"] == dict(T=T, frames=len(frame_times), history=len(hist_times)):
                    next_frame, next_hist = sc["next_frame"], sc["next_hist"]
                else:  # steps were added: the frame and history times are spread over the new duration
                    next_frame = int(np.searchsorted(frame_times, t + 1e-12 * T, side="right"))
                    next_hist = int(np.searchsorted(hist_times, t - 1e-12 * T, side="left"))
            else:
                if k == 0:
                    forces(0.0, x, v)
                    check(0.0)
                res.added_mass.append(plan.added_mass)
                dt_next = stable_dt(plan.dt_safety)
                dt_start = dt_next
                step_cycles = 0
            while t < t_step_end * (1 - 1e-12):
                stop = should_stop()
                if stop:
                    res.status = "interrupted"
                    res.message = stop if isinstance(stop, str) else f"stopped by signal at t = {t:.6g} s"
                    sink.checkpoint(lambda: state(k), "interrupted")
                    break
                if plan.max_cycles is not None and step_cycles >= plan.max_cycles:
                    res.stopped_steps.append(plan.name)
                    res.message = (f"step '{plan.name}' stopped at max_cycles = {plan.max_cycles}, "
                                   f"t = {t:.6g} s of {t_step_end:.6g} s")
                    t_step_end = t  # the next step starts here and keeps its own duration
                    break
                t0 = time.perf_counter()
                dt = min(dt_next, t_step_end - t)
                if not dt > 0.0 or not math.isfinite(dt):
                    raise RunStopped(f"stable time step is {dt:.3g} s", t)
                dt_avg = 0.5 * (dt_prev + dt) if dt_prev > 0 else 0.5 * dt
                kick(v, v_old, inv_m, f_ext, f_int, f_damp, dt_avg)
                if rot is not None:
                    kick_rot(rot.w, rot.w_old, rot.inv_I, rot.m_ext, rot.m_int, rot.m_damp, dt_avg)
                for c in constraints:
                    c.constrain(t + dt, dt, x, v)
                solved = sms is not None and sms.active  # non-diagonal mass: the free dofs' accelerations solved
                if springs is not None:  # the nodes in contact take their springs implicitly (engine.springs)
                    t0 = timer.add("integrator", t0)
                    springs.gather(t, dt)
                    if not solved:
                        springs.lumped(v, v_old, m, dt, dt_avg)
                    t0 = timer.add("contact springs (implicit)", t0)
                if solved:
                    t0 = timer.add("integrator", t0)
                    sms.solver.accelerate(v, v_old, f_ext, f_int, f_damp, dt_avg, springs, dt)
                    w_ext += sms.solver.work(dx)
                    t0 = timer.add(sms.name, t0)
                if springs is not None:
                    t0 = timer.add("integrator", t0)
                    springs.finish(v, dt, f_int, dx)
                    t0 = timer.add("contact springs (implicit)", t0)
                if step_mass is not None and step_mass.m_old is not None:  # a step's first cycle: its new masses
                    r = f_ext - f_int + f_damp
                    step_mass.close(v, v_old, r, m, free_dofs(constraints, x), dt_avg, dx, rot, sms)
                # ledger at t_n (kinetic energy needs v(n+1/2)), then positions move to t_(n+1)
                w, dd, ke = drift(x, v, v_old, m, f_ext, f_int, f_damp, fe_prev, fd_prev, dx, reaction, dt, dt_avg,
                                  res.cycles == 0)
                w_ext += w
                d_damp += dd
                row_due = next_hist < len(hist_times) and t >= hist_times[next_hist] - 1e-12 * T
                if sms is not None and sms.active:  # reactions and kinetic energy of the added mass (the latter
                    # read only by history rows and the first cycle's energy: not computed on other cycles)
                    sms.ke = sms.solver.book(v, v_old, reaction, fe_prev, res.cycles == 0, row_due or energy0 is None)
                    ke += sms.ke
                if rot is not None:
                    w, dd, ke_rot = drift_rot(rot.d, rot.w, rot.w_old, rot.I, rot.m_ext, rot.m_int, rot.m_damp,
                                              rot.me_prev, rot.md_prev, rot.dtheta, rot.reaction, dt, dt_avg,
                                              res.cycles == 0)
                    w_ext += w
                    d_damp += dd
                    ke += ke_rot
                book.integrate(dt_avg)
                if not math.isfinite(ke):
                    raise RunStopped("non-finite energy (NaN or overflow in forces)", t,
                                     node=first_bad_node(x, v, f_int, f_ext, f_damp))
                if energy0 is None:
                    energy0 = book.energy(ke)
                if row_due:
                    extra = [ke_rot] if rot is not None else []
                    row, error = book.row(t, dt, ke, w_ext, d_damp, energy0, extra)
                    if not all(math.isfinite(r) for r in row[:len(book.columns)]):
                        raise RunStopped("non-finite energy (NaN or overflow in forces)", t,
                                         node=first_bad_node(x, v, f_int, f_ext, f_damp))
                    if energy_stop is not None:
                        energy_scale, energy_prev = guard_energy(energy_stop, energy_scale, energy_prev, row, error,
                                                                 t)
                    for nodes in problem.reactions.values():
                        row += reaction[nodes].sum(axis=0).tolist()
                        if rot is not None:
                            row += rot.reaction[nodes].sum(axis=0).tolist()
                    t0 = timer.add("integrator", t0)
                    for meas in problem.measures:
                        row += meas.evaluate(x, v)
                    t0 = timer.add("measures", t0)
                    res.history.append(row)
                    sink.history(row)
                    next_hist = past(hist_times, next_hist, t, T)
                for e in movers:
                    e.advance(t + dt, dt, dt_avg)
                t += dt
                dt_prev = dt
                res.cycles += 1
                step_cycles += 1
                # the stable step, not the last one shortened to land on the step's end
                res.dt_min, res.dt_max = min(res.dt_min, dt_next), max(res.dt_max, dt_next)
                t0 = timer.add("integrator", t0)
                if sms is not None and sms.active:  # the added mass's rigid modes follow the elements
                    sms.follow(x, v)
                    t0 = timer.add(sms.name, t0)
                forces(t, x, v)
                t0 = time.perf_counter()
                check(t)
                dt_next = min(stable_dt(plan.dt_safety), STEP_GROWTH * dt_next)
                if dt_next < collapse * dt_start:
                    raise RunStopped(f"stable time step collapsed to {dt_next:.3g} s, below {collapse:g} x the "
                                     f"step's first {dt_start:.3g} s (steps[{k}].min_dt_ratio), set by "
                                     f"{step_setter(groups, effects)}", t)
                t0 = timer.add("stable step and monitors", t0)
                if next_frame < len(frame_times) and t >= frame_times[next_frame] - 1e-12 * T:
                    if rot is None:
                        sink.frame(t, x, v)
                    else:
                        sink.frame(t, x, v, {"director": rot.d})
                    next_frame = past(frame_times, next_frame, t, T)
                    t0 = timer.add("output", t0)
                if sink.checkpoint_due(res.cycles):
                    sink.checkpoint(lambda: state(k), "every")
                    t0 = timer.add("checkpoints", t0)
                now = time.perf_counter()
                if now - last_progress > 0.5:
                    sink.progress(t, res.cycles, dt)
                    last_progress = now
            if res.status == "interrupted":
                break
        if res.status == "running":
            res.status = "completed"
            sink.checkpoint(lambda: state(len(problem.steps) - 1), "completed")
    except RunStopped as exc:
        res.status, res.message = "failed", str(exc)
    res.t = t
    res.wall = time.perf_counter() - wall0
    res.timings = timer.acc
    res.final_positions = x  # the frame writer of an interrupted or failed run writes these
    res.final_velocities = v
    res.final_directors = None if rot is None else rot.d
    return res
