"""Regression decks: every case in decks/regression/ matches its gold history within its spec's tolerances."""

from __future__ import annotations

import pytest

from helpers import DECKS

pytestmark = [pytest.mark.regression, pytest.mark.long]
CASES = sorted(p for p in (DECKS / "regression").iterdir() if (p / "spec.yaml").exists())


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_regression_case_matches_gold(case):
    from fdeck.regression import run_case

    assert (case / "gold" / "history.csv").exists(), f"no gold: run `fdeck regress {case.name} --update` on purpose"
    ok, report = run_case(case)
    assert ok, report
