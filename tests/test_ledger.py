"""The energy ledger, the element-group protocol and the step contract (issue 13)."""

from __future__ import annotations

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.engine.effect import Effect
from fdeck.engine.group import ElementGroup, RotationalGroup
from fdeck.engine.ledger import CORE, DISSIPATED, PART, STORED, VALUE, WORK, Ledger, Term

from helpers import run_data

pytestmark = pytest.mark.unit


class Source:
    def __init__(self, terms, values):
        self.terms, self.values = tuple(terms), list(values)

    def term_values(self):
        return tuple(self.values)


def test_terms_are_summed_by_name_and_by_kind():
    """Requirement: same-named terms of two sources are one column (their sum); stored terms make the internal energy,
    parts and values are shown but not summed, and the balance is kinetic + stored + dissipated - work - E0.
    Exact arithmetic on small integers, so equality is exact."""
    a = Source([Term("strain_energy", STORED), Term("bending_energy", PART), Term("tool_force", VALUE)],
               [5.0, 2.0, 9.0])
    b = Source([Term("bending_energy", PART), Term("friction_dissipation", DISSIPATED), Term("tool_work", WORK)],
               [1.0, 3.0, 20.0])
    book = Ledger([a, b], extra=("rotational_kinetic_energy",))
    assert book.columns[:len(CORE)] == list(CORE)
    assert book.columns[len(CORE):] == ["rotational_kinetic_energy", "bending_energy", "tool_force",
                                        "friction_dissipation", "tool_work"]
    row, err = book.row(t=1.0, dt=0.1, kinetic=4.0, external_work=6.0, damping=1.0, energy0=0.0, extra=[0.5])
    named = dict(zip(book.columns, row))
    assert named["internal_energy"] == 5.0 and named["strain_energy"] == 5.0 and named["hourglass_energy"] == 0.0
    assert named["bending_energy"] == 3.0 and named["tool_force"] == 9.0
    assert err == 4.0 + 5.0 + 3.0 + 1.0 - 6.0 - 20.0
    assert named["energy_balance_error"] == err


def test_rate_terms_are_integrated_once_per_cycle():
    """Requirement: a dissipation given as a power P(t) = 2 t is integrated with the cycle's averaged step; over
    1000 equal steps of 1e-3 from t = 1e-3 the rectangle sum is sum 2 t_i dt = 1.001 (closed form, 1e-12)."""
    s = Source([Term("viscous", DISSIPATED, rate=True)], [0.0])
    book = Ledger([s])
    for i in range(1, 1001):
        s.values[0] = 2.0 * i * 1e-3
        book.integrate(1e-3)
    assert book.totals()["viscous"] == pytest.approx(1.001, rel=1e-12)


def test_a_term_reported_with_two_kinds_or_as_an_engine_column_is_refused():
    """Requirement: the ledger refuses ambiguous bookkeeping instead of guessing a kind."""
    with pytest.raises(ValueError, match="stored and dissipated"):
        Ledger([Source([Term("x", STORED)], [0]), Source([Term("x", DISSIPATED)], [0])])
    with pytest.raises(ValueError, match="engine column"):
        Ledger([Source([Term("external_work", WORK)], [0])])
    with pytest.raises(ValueError, match="rate"):
        Term("x", STORED, rate=True)


SOLID = {"mesh": {"block": {"size": [4.0, 2.0, 2.0], "divisions": [2, 1, 1]}},
         "materials": {"m": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 1000.0,
                             "poisson_ratio": 0.3}}}


@pytest.mark.parametrize("formulation", ["full", "fbar", "reduced"])
def test_every_hexahedral_group_follows_the_protocol(formulation):
    """Requirement: groups are used only through engine.group.ElementGroup; mass(rho) is a pure function of the
    density it is given (linear in rho, total = rho V to 1e-12) and does not change the group's own density."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck

    data = dict(SOLID, sections=[{"material": "m", "formulation": formulation}], steps=[{"duration": 1e-3}])
    p = compile_deck(Deck.model_validate(data))
    (g,) = p.groups
    assert isinstance(g, ElementGroup) and not isinstance(g, RotationalGroup) and g.solid and not g.rotational
    rho0 = g.rho.copy()
    m = g.mass(np.full(len(g.conn), 3e-9))
    assert m.sum() == pytest.approx(3e-9 * 16.0, rel=1e-12)
    assert np.array_equal(g.rho, rho0)


def test_shell_group_follows_the_rotational_protocol():
    """Requirement: shell groups add directors and rotational inertia to the protocol; inertia(rho) is linear in
    the density it is given (ratio 2 to 1e-12)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck

    data = {"mesh": {"plate": {"size": [10.0, 10.0], "divisions": [2, 2]}},
            "materials": {"m": {"type": "fabric_membrane", "preset": "t300_3k"}},
            "sections": [{"elements": "all", "material": "m", "formulation": "sm", "preset": "t300_3k"}],
            "steps": [{"duration": 1e-4}]}
    p = compile_deck(Deck.model_validate(data))
    (g,) = p.groups
    assert isinstance(g, RotationalGroup) and g.rotational and not g.solid
    r = g.rho
    assert np.allclose(g.inertia(2 * r), 2 * g.inertia(r), rtol=1e-12, atol=0)


def test_max_cycles_stops_its_step_and_the_next_step_runs():
    """Requirement: `max_cycles` ends its step (as documented), the next step then runs its whole duration from
    there, and the run names the stopped step: it ends after the first step's 10 cycles plus the whole second step
    (2e-4 s), not at the planned 1.2e-3 s and not after the 10 cycles (1e-12: the same float sums)."""
    data = dict(SOLID, sections=[{"material": "m", "formulation": "reduced"}],
                boundary=[{"type": "fixed", "nodes": "xmin"}],
                steps=[{"name": "cut", "duration": 1e-3, "max_cycles": 10}, {"name": "rest", "duration": 2e-4}],
                output={"history_points": 50})
    _, res, _ = run_data(data)
    assert res.status == "completed" and res.stopped_steps == ["cut"]
    assert 2e-4 < res.t <= 2e-4 + 10 * res.dt_max * (1 + 1e-12)


class _Counter(Effect):
    """An effect that records the engine's calls, to test the order of the contract."""

    name = "counter"
    moves = True

    def __init__(self):
        self.calls = []

    def begin_step(self, index, plan):
        self.calls.append(("begin_step", index, float(plan.mass.sum())))

    def advance(self, t_next, dt, dt_avg):
        self.calls.append(("advance", t_next))


def test_effects_get_each_step_and_advance_every_cycle():
    """Requirement: begin_step is called once per step with that step's plan (the second step's mass scaled by its
    factor 4, to 1e-12), and advance once per cycle with t_next = t + dt."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    data = dict(SOLID, sections=[{"material": "m", "formulation": "reduced"}],
                steps=[{"duration": 1.0, "max_cycles": 3}, {"duration": 1.0, "max_cycles": 2,
                                                            "mass_scaling": {"factor": 4.0}}])
    p = compile_deck(Deck.model_validate(data))
    c = _Counter()
    p.effects.append(c)
    res = solver.run(p, solver.Sink())
    begins = [x for x in c.calls if x[0] == "begin_step"]
    assert [b[1] for b in begins] == [0, 1]
    assert begins[1][2] == pytest.approx(4 * begins[0][2], rel=1e-12)
    assert sum(x[0] == "advance" for x in c.calls) == res.cycles == 5
