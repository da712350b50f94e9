"""Physically absurd but schema-valid decks are refused (exit 2) or warned about before any run, with the figure
that makes them absurd (``fdeck.compile.sanity``).

Reference deck: a 10 x 1 x 1 mm steel bar of 1 mm cubes. Its stable step is checked against the closed form of the
lumped cube's dilatation mode, dt = h / c with c = sqrt((3 lam + 2 mu) / rho) = sqrt(E / ((1 - 2 nu) rho)) (the
exact critical step of a free 1 mm cube, tests/test_stable_step.py), times dt_safety 0.9; every figure below is then
derived from that closed form, not read from a run.
"""

from __future__ import annotations

import math
import re

import pytest
import yaml
from typer.testing import CliRunner

from fdeck.cli import app
from fdeck.compile.sanity import BYTES_PER_ELEMENT

pytestmark = pytest.mark.unit

E, NU, RHO, H = 2.0e5, 0.3, 7.85e-9, 1.0
C = math.sqrt(E / ((1 - 2 * NU) * RHO))  # mm/s: 3 lam + 2 mu = 3 K = E / (1 - 2 nu)
DT = 0.9 * H / C  # s, 1.13e-7
# The element's own step uses its characteristic length (h for a cube) and the rest modulus 3 lam + 2 mu, so on this
# mesh it equals the closed form to rounding (measured 1 - 7e-16); the figures are printed to 3 significant
# digits, so each is compared to its reference within half a unit of the third digit: a relative 5e-3.
REL = 5e-3


def bar(**step) -> dict:
    return {
        "mesh": {"block": {"size": [10, 1, 1], "divisions": [10, 1, 1]}},
        "materials": {"steel": {"type": "linear_elastic", "density": RHO, "youngs_modulus": E,
                                "poisson_ratio": NU}},
        "sections": [{"elements": "all", "material": "steel", "formulation": "fbar"}],
        "boundary": [{"type": "fixed", "nodes": "xmin"}],
        "steps": [{"duration": 1e-5, **step}],
        "output": {"frames": 1, "history_points": 2},
    }


def cli(tmp_path, data, *args, name="deck.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    r = CliRunner().invoke(app, [*args, str(path)] if args[0] != "run" else ["run", str(path), *args[1:]])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.output
    return r, path


def figure(text: str, pattern: str) -> float:
    m = re.search(pattern, text)
    assert m, text
    return float(m.group(1))


def test_duration_of_1e9_s_refused_with_expected_cycles(tmp_path):
    """Requirement: a duration of 1e9 s is refused by validate and info (exit 2) with the expected cycles,
    duration / dt = 1e9 / 1.13e-7 = 8.9e15 within REL (closed-form step, see module docstring)."""
    data = bar(duration=1e9)
    for command in ("validate", "info"):
        r, path = cli(tmp_path, data, command)
        assert r.exit_code == 2, r.output
        cycles = figure(r.stderr, r"about ([0-9.e+]+) cycles expected")
        assert cycles == pytest.approx(1e9 / DT, rel=REL)
        assert re.match(rf"{re.escape(str(path))}:\d+:\d+: steps: ", r.stderr)


def test_cycles_between_warn_and_limit_warned_and_limit_overridable(tmp_path, monkeypatch):
    """Requirement: 3e8 expected cycles (duration 3e8 dt) pass validate with a warning giving the figure (3e8 within
    REL); FDECK_MAX_CYCLES=1e8 turns the same deck into a refusal (the limit is overridable)."""
    data = bar(duration=3e8 * DT)
    r, _ = cli(tmp_path, data, "validate")
    assert r.exit_code == 0, r.output
    cycles = figure(r.stderr, r"warning: about ([0-9.e+]+) cycles expected")
    assert cycles == pytest.approx(3e8, rel=REL)
    monkeypatch.setenv("FDECK_MAX_CYCLES", "1e8")
    r, _ = cli(tmp_path, data, "validate")
    assert r.exit_code == 2 and "above the limit 1e+08" in r.stderr, r.output


def test_max_cycles_caps_the_expected_cycles(tmp_path):
    """Requirement: the same 1e9 s step with max_cycles 1000 is not absurd (the guard bounds the cycles): exit 0."""
    r, _ = cli(tmp_path, bar(duration=1e9, max_cycles=1000), "validate")
    assert r.exit_code == 0, r.output


def test_mesh_of_1e11_elements_refused_before_compiling(tmp_path):
    """Requirement: a block of 1e5 x 1e5 x 10 = 1e11 elements is refused (exit 2) with its element count and the
    memory estimate n x BYTES_PER_ELEMENT (to the 3 digits printed), before any array is built (the test would
    otherwise exhaust the memory)."""
    data = bar()
    data["mesh"]["block"]["divisions"] = [100000, 100000, 10]
    r, _ = cli(tmp_path, data, "validate")
    assert r.exit_code == 2, r.output
    assert figure(r.stderr, r"the mesh has ([0-9.e+]+) elements") == pytest.approx(1e11, rel=5e-3)
    gib = figure(r.stderr, r"about ([0-9.e+]+) GiB")
    assert gib == pytest.approx(1e11 * BYTES_PER_ELEMENT / 2**30, rel=5e-3)


def test_velocity_of_1e12_mm_s_refused_with_travel_per_cycle(tmp_path):
    """Requirement: a boundary velocity of 1e12 mm/s is refused with the travel in one stable step in element edges,
    v dt / h = 1e12 x 1.13e-7 / 1 = 1.1e5 within REL."""
    data = bar()
    data["boundary"].append({"type": "velocity", "nodes": "xmax", "dofs": ["x"], "value": 1e12})
    r, _ = cli(tmp_path, data, "validate")
    assert r.exit_code == 2, r.output
    travel = figure(r.stderr, r"mm/s, ([0-9.e+]+) smallest element edges")
    assert travel == pytest.approx(1e12 * DT / H, rel=REL)
    assert "boundary[1].value" in r.stderr


def test_fast_tool_refused_with_travel_per_cycle(tmp_path):
    """Requirement: a rigid plane tool driven at 1e10 mm/s toward the bar crosses 1e10 x 1.13e-7 = 1.1e3 element
    edges in one rest stable step (within REL): refused."""
    data = bar()
    data["tools"] = {"punch": {"surface": {"shape": "plane", "point": [0, 0, 1.5], "normal": [0, 0, -1]},
                               "motion": {"kind": "velocity", "value": 1e10, "direction": [0, 0, -1],
                                          "amplitude": "constant"}}}
    data["contact"] = [{"tool": "punch", "normal": {"law": "linear", "stiffness": 1e3}}]
    r, _ = cli(tmp_path, data, "validate")
    assert r.exit_code == 2, r.output
    travel = figure(r.stderr, r"tool 'punch' moves up to [0-9.e+]+ mm/s, ([0-9.e+]+) smallest")
    assert travel == pytest.approx(1e10 * DT / H, rel=REL)


def test_density_of_1e_300_refused_below_the_step_floor(tmp_path):
    """Requirement: a density of 1e-300 gives a rest step of dt sqrt(1e-300 / 7.85e-9) = 1.3e-153 s, below the
    1e-12 s floor: refused with that step (within REL)."""
    data = bar()
    data["materials"]["steel"]["density"] = 1e-300
    r, _ = cli(tmp_path, data, "validate")
    assert r.exit_code == 2, r.output
    dt = figure(r.stderr, r"rest stable time step ([0-9.e+-]+) s is below the floor")
    ref = DT * math.sqrt(1e-300 / RHO)
    assert dt == pytest.approx(ref, rel=REL)


def test_run_refuses_an_absurd_deck_before_writing_anything(tmp_path):
    """Requirement: `fdeck run` of the 1e9 s deck exits 2 and creates no result folder."""
    out = tmp_path / "out"
    r, _ = cli(tmp_path, bar(duration=1e9), "run", "-o", str(out))
    assert r.exit_code == 2 and "cycles expected" in r.stderr, r.output
    assert not out.exists()
