"""Regression decks: every case in decks/regression/ matches its gold history within its spec's tolerances."""

from __future__ import annotations

import pytest

from helpers import DECKS

pytestmark = [pytest.mark.regression, pytest.mark.long]
CASES = sorted(p for p in (DECKS / "regression").iterdir() if (p / "spec.yaml").exists())
# Cases whose physics another default-tier case already holds, run nightly for CI's 15 min: the 3 mm three-point
# bending without fibre bending is the same deck, mesh and F-bar kernel as the case with it (about 100 CPU-s).
NIGHTLY = {"three_point_bending_3mm"}


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.nightly) if c.name in NIGHTLY else c
                                  for c in CASES], ids=[c.name for c in CASES])
def test_regression_case_matches_gold(case):
    from fdeck.regression import run_case

    assert (case / "gold" / "history.csv").exists(), f"no gold: run `fdeck regress {case.name} --update` on purpose"
    ok, report = run_case(case)
    assert ok, report
