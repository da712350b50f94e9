"""Subcycling (``engine.subcycle``, ``steps[i].subcycling``): a bar of a stiff and a soft half struck by a force
pulse runs its soft half at 8x the step and transmits and reflects the pulse as the uniform step does and as the
impedance ratio predicts, with the energy balance closed, momentum equal to the impulse, no element above its own
stable step, and the cycles of each level counted; unsupported combinations are refused with located errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fdeck.compile.errors import CompileError
from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import solver

RHO, E1, RATIO = 7.8e-9, 210000.0, 70.0  # soft half: E1 / 70, so its wave speed is 8.37x lower (own level 3)
C1 = math.sqrt(E1 / RHO)  # [mm/s]
F0 = 100.0  # peak of the force pulse [N]
# lengths in mm (1 mm elements, 1 mm^2 section); times in units of 1 mm / C1. The pulse is 128 stiff elements long
# (15 soft elements); stiff probe at 96, interface at 192, soft probe 8 mm into the soft half, far end at 256:
# at T/2 = 224 the incident pulse has passed the stiff probe (96 + 128) and the reflection has not come back
# (2 * 192 - 96 = 288); at T = 448 the reflection has passed it (288 + 128 = 416 < 448) and its re-reflection from the
# free loaded end has not arrived (384 + 96 = 480), and the transmitted pulse has passed the soft probe
# (192 + 8.37 * 8 + 128 = 387) while the far end's reflection has not (192 + 8.37 * 120 > 448).
L1, L2, PULSE, T, STIFF_PROBE, SOFT_PROBE = 192, 64, 128.0, 448.0, 96.0, 200.0


def amplitude_points() -> list[list[float]]:
    """sin^2 pulse of duration PULSE / C1 as a 65-point table (the load is exactly its piecewise-linear form)."""
    tau = PULSE / C1
    ts = np.linspace(0.0, tau, 65)
    return [[float(t), float(np.sin(np.pi * t / tau) ** 2)] for t in ts] + [[2 * T / C1, 0.0]]


def bar(levels: int | None, **step) -> dict:
    """The two-material bar, uniaxial (Poisson 0, lateral faces free), loaded by F0 x pulse at x = 0 (free end)."""
    s = {"name": "pulse", "duration": T / C1, **step}
    if levels:
        s["subcycling"] = {"levels": levels}
    return {"title": "bar", "units": "mm-t-s-N-MPa",
            "mesh": {"block": {"size": [L1 + L2, 1, 1], "divisions": [L1 + L2, 1, 1]},
                     "element_sets": {"stiff": {"box": [[0, 0, 0], [L1, 1, 1]]},
                                      "soft": {"box": [[L1, 0, 0], [L1 + L2, 1, 1]]}}},
            "materials": {"a": {"type": "linear_elastic", "density": RHO, "youngs_modulus": E1, "poisson_ratio": 0.0},
                          "b": {"type": "linear_elastic", "density": RHO, "youngs_modulus": E1 / RATIO,
                                "poisson_ratio": 0.0}},
            "sections": [{"elements": "stiff", "material": "a", "formulation": "full"},
                         {"elements": "soft", "material": "b", "formulation": "full"}],
            "amplitudes": {"pulse": {"type": "tabular", "points": amplitude_points()}},
            "loads": [{"type": "nodal_force", "nodes": "xmin", "force": [F0, 0, 0], "distribution": "total",
                       "amplitude": "pulse"}],
            "steps": [s], "output": {"frames": 2, "history_points": 2000}}


class Frames(solver.Sink):
    def __init__(self):
        self.frames = []

    def frame(self, t, x, v, point_fields=None):
        self.frames.append((t, x.copy(), v.copy()))


def run(levels):
    """(problem, result, frames, group update calls) of the bar; update calls counted by wrapping each group."""
    problem = compile_deck(Deck.model_validate(bar(levels)))
    calls = [0] * len(problem.groups)
    for j, g in enumerate(problem.groups):
        def counted(x, v, _update=g.update, _j=j):
            calls[_j] += 1
            _update(x, v)
        g.update = counted
    sink = Frames()
    result = solver.run(problem, sink)
    assert result.status == "completed", result.message
    return problem, result, sink.frames, calls


@pytest.fixture(scope="module")
def runs():
    return {"uniform": run(None), "subcycled": run(4)}


def probe(problem, u: np.ndarray, x0: float) -> float:
    """Mean axial displacement [mm] of the 4 nodes at x = x0."""
    return float(u[np.isclose(problem.X[:, 0], x0), 0].mean())


def pulse_displacements(problem, result, frames):
    """(incident at the stiff probe, incident + reflected there, transmitted at the soft probe) [mm]: the time
    integrals of the velocity pulses, read as displacement plateaus."""
    t_half, x_half, _ = frames[-2]
    assert 224.0 <= t_half * C1 < 288.0  # the frame is inside the plateau between incident and reflection
    u_end = result.final_positions - problem.X
    return (probe(problem, x_half - problem.X, STIFF_PROBE), probe(problem, u_end, STIFF_PROBE),
            probe(problem, u_end, SOFT_PROBE))


def test_waves_match_uniform_step_and_impedance_ratio(runs):
    """Requirement: transmitted and reflected pulses of the subcycled run equal the uniform-step run's within 1 % and
    the closed-form impedance-ratio coefficients within 1 %.

    Reference: a pulse of impulse I = F0 int(a) dt on the free end of a bar of impedance Z1 = A sqrt(E1 rho) moves the
    material behind it by D = I / Z1; at the interface to Z2 = Z1 / sqrt(70) the velocity is reflected with
    R = (Z1 - Z2) / (Z1 + Z2) and transmitted with T = 2 Z1 / (Z1 + Z2) (one-dimensional waves). Tolerance 1 %: the
    pulse spans 128 stiff and 15 soft elements, so the mesh's dispersion changes the plateaus by well under that
    (measured: at most 0.016 % between the runs, at most 0.07 % against the closed form)."""
    problem, result, frames, _ = runs["uniform"]
    sub = runs["subcycled"]
    d_u = pulse_displacements(problem, result, frames)
    d_s = pulse_displacements(sub[0], sub[1], sub[2])
    impulse = F0 * np.trapezoid(*np.array(amplitude_points()).T[::-1])
    z1 = math.sqrt(E1 * RHO)
    z2 = z1 / math.sqrt(RATIO)
    D = impulse / z1
    R, Tc = (z1 - z2) / (z1 + z2), 2 * z1 / (z1 + z2)
    for name, (inc, both, trans) in (("uniform", d_u), ("subcycled", d_s)):
        assert inc == pytest.approx(D, rel=0.01), name
        assert both / inc - 1 == pytest.approx(R, rel=0.01), name
        assert trans / inc == pytest.approx(Tc, rel=0.01), name
    for a, b in zip(d_s, d_u):
        assert a == pytest.approx(b, rel=0.01)
    assert (d_s[1] - d_s[0]) == pytest.approx(d_u[1] - d_u[0], rel=0.01)  # the reflected pulse alone


def test_energy_balance_and_momentum(runs):
    """Requirement: the subcycled run's energy balance error stays within 0.5 % of the largest energy at every
    synchronised history row, and the total momentum at the end equals the applied impulse within 0.1 %.

    References: the ledger's balance (kinetic + stored - external work = its start value) and Newton's second law for
    the free bar (momentum = int F dt). Tolerances: BYM subcycling does not conserve energy exactly at the interface;
    its error is first order in the slow nodes' step (measured: peak 0.55 %, 0.24 %, 0.11 % for pulses of 8, 15, 30
    soft elements, the uniform step 0.05 %, 0.01 %, 0.003 %), so 0.5 % holds with margin at 15 (measured 0.24 %);
    the slow nodes receive the interface forces only at their own times, so momentum is kept to the truncation error
    of the step, not to round-off (measured 5e-6 relative, the uniform step 1.2e-6): 0.1 %."""
    problem, result, _, _ = runs["subcycled"]
    h = np.array(result.history)
    col = {c: i for i, c in enumerate(result.columns)}
    scale = np.abs(h[:, [col["kinetic_energy"], col["internal_energy"], col["external_work"]]]).max()
    assert np.abs(h[:, col["energy_balance_error"]]).max() <= 0.005 * scale
    assert len(h) > 50  # rows at synchronised times over the whole run
    impulse = F0 * np.trapezoid(*np.array(amplitude_points()).T[::-1])
    momentum = float((problem.steps[0].mass * result.final_velocities[:, 0]).sum())
    assert momentum == pytest.approx(impulse, rel=0.001)


def test_levels_steps_and_cycle_counts(runs):
    """Requirement: the soft half runs at level 3 (8x the step), no element's slowest node ever uses a step above the
    element's own stable step, each group is updated exactly once per step of its level, and the element updates
    saved match the levels.

    References: closed-form wave speeds c = sqrt(E / rho) of the two halves: an element's slowest node step
    2^m h must not exceed its own step L / c, with h = 0.9 x (1 mm / C1) (stiff elements set it), i.e.
    2^m <= C1 / c; exact integer counts for the updates (each group once at t = 0 and then N / 2^u times per major
    cycle of N minor steps, as many as its level's node steps)."""
    problem, result, _, calls = runs["subcycled"]
    sub = next(e for e in problem.effects if e.name == "subcycling")
    c_soft = math.sqrt(E1 / RATIO / RHO)
    for g, m in zip(problem.groups, sub.highest):
        c = C1 if g.section_index == 0 else c_soft
        assert (np.exp2(m) <= C1 / c).all()
    assert max(int(o.max()) for o in sub.own) == 3
    assert 0.0 < sub.step_ratio_max < 1.0  # measured, every update: slowest node step / element's current step
    assert sub.level_cycles[0] == result.cycles
    for g, u, n in zip(problem.groups, sub.group_level, calls):
        assert n == sub.level_cycles[u] + 1, g.name
    sizes = [len(g.conn) for g in problem.groups]
    assert sub.element_cycles == sum(s * (n - 1) for s, n in zip(sizes, calls))
    assert sub.element_cycles_uniform == result.cycles * sum(sizes)
    # the soft elements away from the interface (all but 3 graded ones) update every 8th cycle
    expected = (L1 + 3 + (L2 - 3) / 8) / (L1 + L2)
    assert sub.element_cycles / sub.element_cycles_uniform == pytest.approx(expected, rel=0.02)


def test_single_level_is_the_uniform_loop():
    """Requirement: when every element's own level is 0 (both halves of one material), the subcycled loop performs the
    uniform central-difference update: final positions and velocities bitwise equal, same cycle count.
    Reference: the uniform engine (``engine.solver``) on the same deck without the card; exact, because both loops
    do the same floating-point operations in the same order (one thread)."""
    out = []
    for levels in (None, 4):  # (both runs are serial: solver.run takes one thread below SERIAL_BELOW elements)
        data = bar(levels)
        data["materials"]["b"] = data["materials"]["a"]
        data["steps"][0]["duration"] = 60.0 / C1  # the pulse is in the stiff bar only: a short run suffices
        out.append(solver.run(compile_deck(Deck.model_validate(data)), solver.Sink()))
    assert out[0].cycles == out[1].cycles > 50
    assert np.array_equal(out[0].final_positions, out[1].final_positions)
    assert np.array_equal(out[0].final_velocities, out[1].final_velocities)
    assert np.abs(out[0].final_velocities).max() > 0  # the pulse has moved the bar


def test_regroup_when_steps_fall():
    """Requirement: when elements' steps fall relative to the smallest (a second step with mass scaling raises the
    stiff half's step 4x, so the soft half's own level drops from 3 to 1), the levels are re-derived and no element
    ever runs above its own stable step.

    Reference: closed form, the soft elements' own step is sqrt(70) = 8.37 stiff-element steps and the second step's
    smallest is 4 of them: own level floor(log2(8.37 / 4)) = 1; without regrouping the soft nodes would run at
    8 x 0.9 x 4 = 28.8 stiff-element steps, 3.4x their own. Tolerance on the measured step ratio: dt_safety 0.9 plus
    0.1 % for the change of the moduli within one major cycle (the check is at every group update)."""
    data = bar(4)
    first = dict(data["steps"][0], duration=20.0 / C1)
    dt1 = 0.9 / C1  # stiff element's step x dt_safety (1 mm elements)
    second = dict(data["steps"][0], name="scaled", duration=60.0 / C1, mass_scaling={"target_dt": 4 * dt1})
    data["steps"] = [first, second]
    problem = compile_deck(Deck.model_validate(data))
    result = solver.run(problem, solver.Sink())
    assert result.status == "completed", result.message
    sub = next(e for e in problem.effects if e.name == "subcycling")
    assert sub.regroups >= 1
    soft = [o for g, o in zip(problem.groups, sub.own_now) if g.section_index == 1]
    assert max(int(o.max()) for o in soft) == int(math.floor(math.log2(math.sqrt(RATIO) / 4)))
    assert sub.step_ratio_max <= 0.9 * 1.001


@pytest.mark.parametrize("change, where, words", [
    ({"damping": {"mass_proportional": 10.0}}, ("steps", 0, "subcycling"), "damping"),
    ({"mass_scaling": {"factor": 2.0, "selective": True}}, ("steps", 0, "subcycling"), "selective"),
])
def test_refused_combinations(change, where, words):
    """Requirement: a combination the subcycled loop does not integrate is a located compile error, not a wrong run.
    Reference: the card's path and the other setting named in the message."""
    data = bar(4, **change)
    with pytest.raises(CompileError) as exc:
        compile_deck(Deck.model_validate(data))
    assert any(p == where and words in m for p, m in exc.value.problems)


def test_checkpoints_refused():
    """Requirement: checkpoints with subcycling are refused at the card (the per-level state is not saved).
    Reference: the card's path and the message."""
    data = bar(4)
    data["output"]["checkpoint"] = {"every": 100}
    with pytest.raises(CompileError) as exc:
        compile_deck(Deck.model_validate(data))
    assert any(p == ("steps", 0, "subcycling") and "checkpoint" in m for p, m in exc.value.problems)


def test_levels_card_validated():
    """Requirement: fewer than two step sizes is a located validation error at steps[0].subcycling.levels.
    Reference: the card's bound (ge=2)."""
    from pydantic import ValidationError

    with pytest.raises(ValidationError) as exc:
        Deck.model_validate(bar(None, subcycling={"levels": 1}))
    assert any(e["loc"][:4] == ("steps", 0, "subcycling", "levels") for e in exc.value.errors())


# -- subcycling with fibre bending (a section add-on whose hinges cross the subcycling blocks) ---------------------

E_STIFF, SOFT = 1.6e3, 25.0  # soft half E / 25: its continuum step is 5x the stiff half's (own level 2)


def uniform_and_subcycled(deck) -> list:
    """[(problem, history array, column index)] of ``deck(None)`` (uniform step) and ``deck(3)`` (three levels)."""
    out = []
    for levels in (None, 3):
        problem = compile_deck(Deck.model_validate(deck(levels)))
        result = solver.run(problem, solver.Sink())
        assert result.status == "completed", result.message
        out.append((problem, np.array(result.history), {c: i for i, c in enumerate(result.columns)}))
    return out


def bent_strip(levels: int | None) -> dict:
    """A strip 80 x 2 x 8 mm (1 x 2 x 2 mm elements: 80 x 1 x 4), clamped at x = 0, its stiff half x < 40 and soft
    half (E / 25) each with fibre bending along x (D1 = 600 N mm, D2 = 100 mm^2 D1), loaded at its tip across the
    thickness by a 0.2 ms triangular force pulse of 10 N; blocks of 20 elements, so each half is several blocks and
    the bending hinges cross block (and level) boundaries."""
    step = {"name": "flap", "duration": 6.0e-4}
    if levels:
        step["subcycling"] = {"levels": levels, "block_elements": 20}
    bending = [{"type": "fibre_bending", "thickness": 8.0, "warp": {"D1": 600.0, "D2": 6.0e4}}]
    return {"title": "bent strip", "units": "mm-t-s-N-MPa",
            "mesh": {"block": {"size": [80, 2, 8], "divisions": [80, 1, 4]},
                     "element_sets": {"stiff": {"box": [[0, 0, 0], [40, 2, 8]]},
                                      "soft": {"box": [[40, 0, 0], [80, 2, 8]]}}},
            "materials": {"a": {"type": "linear_elastic", "density": 1.0e-9, "youngs_modulus": E_STIFF,
                                "poisson_ratio": 0.0},
                          "b": {"type": "linear_elastic", "density": 1.0e-9, "youngs_modulus": E_STIFF / SOFT,
                                "poisson_ratio": 0.0}},
            "sections": [{"elements": "stiff", "material": "a", "formulation": "fbar", "effects": bending},
                         {"elements": "soft", "material": "b", "formulation": "fbar", "effects": bending}],
            "amplitudes": {"pulse": {"type": "tabular", "points": [[0, 0], [1e-4, 1], [2e-4, 0], [1, 0]]}},
            "boundary": [{"type": "fixed", "nodes": "xmin"}],
            "loads": [{"type": "nodal_force", "nodes": "xmax", "force": [0, 0, -10.0], "distribution": "total",
                       "amplitude": "pulse"}],
            "steps": [step],
            "output": {"frames": 1, "history_points": 200,
                       "measures": [{"type": "node_displacement", "name": "tip", "nodes": "xmax", "component": "z",
                                     "reduce": "mean"}]}}


def test_fibre_bending_across_blocks_matches_the_uniform_step():
    """Requirement: fibre bending runs under subcycling (issue 10, deliverable 2: the three-point bending with fibre
    bending needs it): its hinges act across the blocks and levels of each half (a ``SectionView``), it is evaluated
    at every minor step, its own element steps lower the levels where it is stiffer than the continuum, and the
    answer is the uniform step's.
    References: the uniform-step run of the same deck: tip deflection history within 1 % of its largest value (the
    issue's tolerance for a subcycled answer; BYM's interface error is first order in the slow step: measured
    0.23 %), bending energy at the end within 1 % (measured +0.5 %); energy balance within 0.5 % of the largest
    energy (the bar's limit above); no element above its own step (ratio <= dt_safety 0.9, plus 0.1 % for the change of the moduli
    within a major cycle). Levels, closed form: the soft half's continuum step is sqrt(25) = 5x the stiff one's
    (level floor(log2 5) = 2), but its hinges make its own step (bending and continuum together) less than 4x, so
    its elements run at level floor(log2(ratio)) of that combined step (1 here), never at 2; element updates at most
    80 % of the uniform step's (halves at levels 0 and 1: about (1 + 1/2) / 2 = 75 %)."""
    (_, h0, c0), (p1, h1, c1) = uniform_and_subcycled(bent_strip)
    tip0, tip1 = h0[:, c0["tip"]], np.interp(h0[:, 0], h1[:, 0], h1[:, c1["tip"]])
    assert np.abs(tip0).max() > 1.0  # the strip bends by millimetres: the hinges are loaded
    assert np.abs(tip1 - tip0).max() <= 0.01 * np.abs(tip0).max()
    bend = [sum(h[-1, i] for n, i in c.items() if n.startswith("bending_energy")) for h, c in ((h0, c0), (h1, c1))]
    assert bend[0] > 0.05 * h0[-1, c0["internal_energy"]]  # the hinges hold a share of the stored energy
    assert bend[1] == pytest.approx(bend[0], rel=0.01)
    scale = np.abs(h1[:, [c1["kinetic_energy"], c1["internal_energy"], c1["external_work"]]]).max()
    assert np.abs(h1[:, c1["energy_balance_error"]]).max() <= 0.005 * scale
    sub = next(e for e in p1.effects if e.name == "subcycling")
    fb = {e.group.section_index: e for e in p1.effects if e.name.startswith("fibre_bending")}
    assert all(len(getattr(e.group, "parts", ())) >= 2 for e in fb.values()), "hinges span several blocks"
    dt_min = fb[0].dt_e.min()
    assert fb[1].group.dt_e.min() / dt_min >= 4.0  # the continuum alone would allow level 2 ...
    own = int(np.floor(np.log2(fb[1].dt_e.min() / dt_min)))
    assert own < 2  # ... the hinges do not
    soft = np.concatenate([o for g, o in zip(p1.groups, sub.own_now) if g.section_index == 1])
    assert soft.max() == own
    assert sub.step_ratio_max <= 0.9 * 1.001
    assert sub.element_cycles <= 0.80 * sub.element_cycles_uniform


# -- subcycling with rigid tools, contact and friction -------------------------------------------------------------

def pressed_block(levels: int | None) -> dict:
    """A block 40 x 10 x 4 mm (2 mm elements) of a stiff and a soft half (neo-Hookean, E 1000 / 40 MPa: the soft
    half's step is 5x, own level 2) on a rigid floor (linear penalty 50 MPa/mm, friction 0.3), pressed 1 mm into its
    soft half by a moving sphere (R = 10 mm, friction 0.2 / 0.15) over 5 ms with a smooth ramp; blocks of 25."""
    step = {"name": "press", "duration": 0.005}
    if levels:
        step["subcycling"] = {"levels": levels, "block_elements": 25}
    return {"title": "pressed block", "units": "mm-t-s-N-MPa",
            "mesh": {"block": {"size": [40, 10, 4], "divisions": [20, 5, 2]},
                     "element_sets": {"stiff": {"box": [[0, 0, 0], [20, 10, 4]]},
                                      "soft": {"box": [[20, 0, 0], [40, 10, 4]]}}},
            "materials": {"a": {"type": "neo_hookean", "density": 1e-9, "youngs_modulus": 1.0e3, "poisson_ratio": 0.3},
                          "b": {"type": "neo_hookean", "density": 1e-9, "youngs_modulus": 40.0, "poisson_ratio": 0.3}},
            "sections": [{"elements": "stiff", "material": "a", "formulation": "fbar"},
                         {"elements": "soft", "material": "b", "formulation": "fbar"}],
            "amplitudes": {"ramp": {"type": "smooth_step", "t1": 0.005}},
            "tools": {"floor": {"surface": {"shape": "plane"}},
                      "punch": {"surface": {"shape": "sphere", "centre": [30, 5, 14.0], "radius": 10.0},
                                "motion": {"value": 1.0, "amplitude": "ramp"}}},
            "contact": [{"tool": "floor", "nodes": "zmin", "normal": {"law": "linear", "stiffness": 50.0},
                         "friction": {"static": 0.3}},
                        {"tool": "punch", "nodes": "zmax", "normal": {"law": "linear", "stiffness": 50.0},
                         "friction": {"static": 0.2, "dynamic": 0.15}}],
            "boundary": [{"type": "fixed", "nodes": "xmin", "dofs": ["x"]}],
            "steps": [step], "output": {"history_points": 200}}


def test_contact_and_friction_match_the_uniform_step():
    """Requirement: rigid tools and contact pairs with friction run under subcycling (issue 10, deliverable 2 on a
    forming deck): the tools advance and the pairs are evaluated at every minor step, and each contact node's level
    is capped by its own spring step sqrt(m/k) (``Effect.node_dt``).
    References: the uniform-step run: punch force history within 1 % of its largest value (the issue's tolerance;
    measured 0.39 %), friction dissipation within 3 % (path-dependent: the stick-slip transitions move with the slow
    nodes' steps; measured 1.4 %); energy balance with friction within 0.5 % of the largest energy (measured
    0.0026 %); no element above its own step (dt_safety 0.9 plus 0.1 %); every contact node at or below the level
    of its spring step; the soft half really subcycled (element updates at most 85 % of uniform: halves at levels 0
    and 1-2, measured 0.775)."""
    (_, h0, c0), (p1, h1, c1) = uniform_and_subcycled(pressed_block)
    f0 = h0[:, c0["tool_punch_force_z"]]
    f1 = np.interp(h0[:, 0], h1[:, 0], h1[:, c1["tool_punch_force_z"]])
    assert np.abs(f0).max() > 100.0  # the sphere presses the block into the floor
    assert np.abs(f1 - f0).max() <= 0.01 * np.abs(f0).max()
    fr0, fr1 = h0[-1, c0["friction_dissipation"]], h1[-1, c1["friction_dissipation"]]
    assert fr0 > 0 and fr1 == pytest.approx(fr0, rel=0.03)
    scale = np.abs(h1[:, [c1["kinetic_energy"], c1["internal_energy"], c1["tool_work_punch"]]]).max()
    assert np.abs(h1[:, c1["energy_balance_error"]]).max() <= 0.005 * scale
    sub = next(e for e in p1.effects if e.name == "subcycling")
    assert sub.step_ratio_max <= 0.9 * 1.001
    dt_min = min([g.stable_dt() for g in p1.groups] + [e.stable_dt() for e in p1.effects])
    for e in p1.effects:
        if e.name.startswith("contact:"):
            nodes, dt = e.node_dt()
            allowed = np.floor(np.log2(dt / dt_min + 1e-12)).clip(0, sub.top)
            assert (sub.node[nodes] <= allowed).all()
    assert sub.element_cycles <= 0.85 * sub.element_cycles_uniform
