"""Every forming deck validates, and `fdeck info` prints its tools, its contact pairs and their step bounds (issue 8,
"Done when": every forming deck validates; `fdeck info` on each prints its tools, contact pairs and stable-step
bound). The coarse and medium decks in the default tier; the eight full-size decks (up to 80 656 hexahedra and
78 400 shells, tens of CPU-seconds of set-up each) nightly. `fdeck info` is called in-process (typer's runner), so
the interpreter and the compiled kernels are loaded once."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from fdeck.cli import app

FORMING = Path(__file__).resolve().parents[1] / "decks" / "forming"
DECKS = sorted(d for d in FORMING.glob("*.yaml") if not d.name.startswith("_"))  # "_NAME": a resolved study deck
SMALL = [d for d in DECKS if d.stem.endswith(("_coarse", "_medium"))]
NUMBER = r"([0-9.]+(?:e[-+]?\d+)?)"


def test_the_deck_list_is_the_issue_s():
    """Requirement: the forming decks are the three families at full size (tetrahedron 5 / 3 mm, double dome 0/90
    5 / 3 mm and +-45 4.24 / 2.12 mm, square tube sm / ts) plus their coarse (and the tubes' medium) variants:
    15 decks, 7 of them small (exact counts: a deck added or renamed must be added here)."""
    assert len(DECKS) == 15 and len(SMALL) == 7


@pytest.mark.parametrize("deck", [pytest.param(d, id=d.stem, marks=() if d in SMALL else pytest.mark.nightly)
                                  for d in DECKS])
def test_validates_and_info_prints_tools_pairs_and_step_bounds(deck):
    """Requirement: `fdeck validate` exits 0 with "ok"; `fdeck info` exits 0 and prints one line per tool of the deck
    ("tool NAME: ..."), one per contact pair ("contact with tool 'NAME': N blank nodes, ..., step bound sqrt(m/k) =
    DT s", or "step bound 2 sqrt(m/k_t) = DT s" for implicit springs) with N > 0 and DT finite, and the rest stable
    step of each step, which includes those bounds (at most the smallest, to the 4 digits printed); the deck's tool
    and contact names are read from its YAML, independently of the compiler."""
    runner = CliRunner()
    r = runner.invoke(app, ["validate", str(deck)])
    assert r.exit_code == 0 and ": ok" in r.output, r.output
    r = runner.invoke(app, ["info", str(deck)])
    assert r.exit_code == 0, r.output
    data = yaml.safe_load(deck.read_text())
    for tool in data["tools"]:
        assert re.search(rf"^  tool {tool}: ", r.output, re.M), (tool, r.output)
    bounds = []
    for pair in data["contact"]:
        # explicit springs bound the step at sqrt(m/k); implicit ones only by their stick springs, 2 sqrt(m/k_t)
        bound = r"step bound 2 sqrt\(m/k_t\)" if pair.get("springs") == "implicit" else r"step bound sqrt\(m/k\)"
        m = re.search(rf"contact with tool '{pair['tool']}': (\d+) blank nodes, .*{bound} = {NUMBER} s", r.output)
        assert m and int(m.group(1)) > 0, (pair["tool"], r.output)
        bounds.append(float(m.group(2)))
        assert math.isfinite(bounds[-1]) and bounds[-1] > 0.0
    rests = [float(v) for v in re.findall(rf"rest stable dt {NUMBER} s", r.output)]
    assert len(rests) == len(data["steps"]), r.output
    assert max(rests) <= min(bounds) * (1 + 1e-3), (rests, bounds)
