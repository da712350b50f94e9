"""The stable step follows a fall at once and grows by at most STEP_GROWTH per cycle (engine.solver): a bound that
flickers from cycle to cycle (an element entering and leaving a stiff branch) must not make the run alternate
between a short and a long step."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import solver
from fdeck.engine.effect import Effect

pytestmark = pytest.mark.verification

DECK = {"mesh": {"block": {"size": [1.0, 1.0, 1.0], "divisions": [1, 1, 1]}},
        "materials": {"m": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 1000.0,
                            "poisson_ratio": 0.3}},
        "sections": [{"material": "m", "formulation": "reduced"}],
        "steps": [{"duration": 1.0, "max_cycles": 300}], "output": {"history_points": 2}}


class Flicker(Effect):
    """A bound of 0.4 x the element step on every other call between calls 50 and 150, none otherwise; records the
    time of every force call (one per cycle), so the steps the engine took are the differences."""

    name = "flicker"
    forces = "internal"

    def __init__(self, short: float):
        self.short, self.calls, self.times = short, 0, []

    def add_force(self, t, x, v, f):
        self.times.append(t)

    def stable_dt(self):
        self.calls += 1
        return self.short if 50 <= self.calls < 150 and self.calls % 2 == 0 else math.inf


def run_flickered(deck: dict, kind, growth: float, monkeypatch):
    """Run ``deck`` with STEP_GROWTH = growth and a flicker of class ``kind`` at 0.4 x the smallest element step:
    (result, flicker, the smallest element step x dt_safety, the flicker's short bound x dt_safety)."""
    monkeypatch.setattr(solver, "STEP_GROWTH", growth)
    problem = compile_deck(Deck.model_validate(deck))
    own = min(g.stable_dt() for g in problem.groups)
    flicker = kind(0.4 * own)
    problem.effects.append(flicker)
    res = solver.run(problem, solver.Sink())
    safety = problem.steps[0].dt_safety
    return res, flicker, safety * own, safety * flicker.short


def steps_taken(growth: float, monkeypatch) -> tuple[np.ndarray, float, float]:
    """(steps (n,) [s], the element's own step x dt_safety, the flicker's short bound x dt_safety)."""
    res, flicker, own, short = run_flickered(DECK, Flicker, growth, monkeypatch)
    assert res.cycles == 300, res.message
    return np.diff(flicker.times), own, short


def test_a_flickering_bound_keeps_the_step_short_and_it_regrows_by_two_percent_per_cycle(monkeypatch):
    """Requirement: while the bound flickers, no step exceeds the short step times STEP_GROWTH (relative 1e-12: the
    step is the short one or one growth after it); afterwards the step regrows geometrically, each step at most 1.02
    times the last, and reaches the element's own step within ceil(ln(1 / 0.4) / ln 1.02) = 47 cycles of the last
    short bound (exact count plus one for the cycle the bound is read); never above the element's own. Without the
    limit (growth = inf) the steps alternate between the two (the failure this guards against)."""
    steps, own, short = steps_taken(solver.STEP_GROWTH, monkeypatch)
    ratio = steps[1:] / steps[:-1]
    assert ratio.max() <= solver.STEP_GROWTH * (1 + 1e-12)
    during = steps[60:145]  # well inside the flicker (calls 50-149; a call precedes its cycle)
    assert during.max() <= short * solver.STEP_GROWTH * (1 + 1e-12) and during.min() == pytest.approx(short, rel=1e-12)
    regrow = math.ceil(math.log(own / short) / math.log(solver.STEP_GROWTH))
    assert np.all(steps[150 + regrow + 1:] == pytest.approx(own, rel=1e-12))
    assert steps.max() <= own * (1 + 1e-12)
    free, own, short = steps_taken(math.inf, monkeypatch)
    assert free[60:150].max() == pytest.approx(own, rel=1e-12) and free[60:150].min() == pytest.approx(short, rel=1e-12)


# a stiff element (E 16x) beside two soft ones: the soft elements' steps are 4x the stiff one's, so the subcycling
# engine runs major cycles of 4 minor steps (levels 0 and 2) and reads the bounds once per major cycle
SUBCYCLED = {"mesh": {"block": {"size": [3.0, 1.0, 1.0], "divisions": [3, 1, 1]},
                      "element_sets": {"stiff": {"box": [[0, 0, 0], [1, 1, 1]]},
                                       "soft": {"box": [[1, 0, 0], [3, 1, 1]]}}},
             "materials": {"a": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 16000.0,
                                 "poisson_ratio": 0.3},
                           "b": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 1000.0,
                                 "poisson_ratio": 0.3}},
             "sections": [{"elements": "stiff", "material": "a", "formulation": "full"},
                          {"elements": "soft", "material": "b", "formulation": "full"}],
             "steps": [{"duration": 1.0, "max_cycles": 900, "subcycling": {"levels": 3}}],
             "output": {"history_points": 2}}


class MajorFlicker(Flicker):
    """The flicker, also noting how many minor steps (force calls) preceded each of its reads (one per major cycle),
    and, as a tool would, the (dt, dt_avg) the engine advances it with at every minor step."""

    moves = True

    def __init__(self, short: float):
        super().__init__(short)
        self.read_at, self.advanced = [], []

    def advance(self, t_next, dt, dt_avg):
        self.advanced.append((dt, dt_avg))

    def stable_dt(self):
        self.read_at.append(len(self.times))
        return super().stable_dt()


def minor_steps(growth: float, monkeypatch) -> tuple[np.ndarray, np.ndarray, float, float]:
    """As ``steps_taken`` for the subcycling engine: (minor steps (n,) [s], the minor step index at which each
    major cycle starts, the stiff element's step x dt_safety, the flicker's short bound x dt_safety)."""
    res, flicker, own, short = run_flickered(SUBCYCLED, MajorFlicker, growth, monkeypatch)
    assert res.cycles > 0, res.message
    # the first force call is the initial one at t = 0, so minor step i ends at force call i + 1
    steps = np.diff(flicker.times)
    dt, dt_avg = np.array(flicker.advanced).T
    # a force-driven tool's velocity update needs the central-difference mean of the last and the next minor step
    assert dt == pytest.approx(steps, rel=1e-9) and dt_avg[0] == dt[0]  # steps: differences of times (round-off)
    assert dt_avg[1:] == pytest.approx(0.5 * (dt[:-1] + dt[1:]), rel=1e-12)
    return steps, np.array(flicker.read_at) - 1, own, short


def test_the_subcycling_engine_limits_growth_per_major_cycle(monkeypatch):
    """Requirement: the subcycling engine follows a fall of the smallest step at once and lets its minor step grow
    by at most STEP_GROWTH from one major cycle to the next (relative 1e-12), so a flickering bound keeps it short
    (every minor step while the bound flickers within STEP_GROWTH of the short one) and it regrows to the stiff
    element's own step afterwards. The major cycles really hold several minor steps (the soft elements run at
    2 or 4 times the minor step) and the step changes only where one starts, so the limit is per major cycle, not
    compounded over its minor steps; tools are advanced with the mean of the last and the next minor step (1e-12,
    checked in ``minor_steps``). Without the limit the minor step alternates between the two bounds."""
    steps, starts, own, short = minor_steps(solver.STEP_GROWTH, monkeypatch)
    assert len(steps) > 1.5 * len(starts)
    changes = np.flatnonzero(np.abs(np.diff(steps)) > 1e-12 * own) + 1
    assert len(changes) and set(changes) <= set(starts)
    ratio = steps[1:] / steps[:-1]
    assert ratio.max() <= solver.STEP_GROWTH * (1 + 1e-12)
    during = steps[starts[60]:starts[145]]  # reads 60-144: inside the flicker (reads 50-149)
    assert during.max() <= short * solver.STEP_GROWTH * (1 + 1e-12) and during.min() == pytest.approx(short, rel=1e-12)
    assert steps[-2:] == pytest.approx(own, rel=1e-12) and steps.max() <= own * (1 + 1e-12)
    free, starts, own, short = minor_steps(math.inf, monkeypatch)
    assert free[starts[60]:starts[145]].max() == pytest.approx(own, rel=1e-12)
    assert free[starts[60]:starts[145]].min() == pytest.approx(short, rel=1e-12)
