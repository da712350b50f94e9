"""Regression cases: ``decks/regression/<case>/`` holds ``deck.yaml``, ``spec.yaml`` and ``gold/history.csv``.

spec.yaml:
    requirement: one sentence saying what the case protects
    columns: {history column: {rtol: r, atol: a}}   # |run - gold| <= atol + rtol * max|gold| on every row
    summary: {key: {rtol: r, atol: a}}              # optional: scalar entries of summary.json (dotted keys)
    agree:                                          # optional: physics of the fresh run against a closed form
      - {column: c, reference: r, rtol: t, where: {column: [lo, hi]}}   # |c - r| <= t |r| on rows in range
    exit_code: 0                                    # optional (default 0): the run's exit code, so the deck's own
                                                    # checks (energy balance, quasi-static) must pass as well

Gold files change only through ``fdeck regress --update`` (never as a side effect of a test run).
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
import yaml


def _get(d: dict, dotted: str):
    for k in dotted.split("."):
        d = d[k]
    return d


def run_case(case: Path, update: bool = False) -> tuple[bool, str]:
    """Run one case; compare with gold (or rewrite gold with ``update``). Returns (ok, report text)."""
    from fdeck.deck.read import read_deck
    from fdeck.io.history import read_history
    from fdeck.run import execute

    spec = yaml.safe_load((case / "spec.yaml").read_text())
    deck, _, _ = read_deck(case / "deck.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        code, summary = execute(deck, case, out, "deck", str(case / "deck.yaml"), echo=lambda *a: None)
        gold = case / "gold"
        if update:
            gold.mkdir(exist_ok=True)
            shutil.copy(out / "history.csv", gold / "history.csv")
            keep = {k: _get(summary, k) for k in spec.get("summary", {})}
            (gold / "summary.yaml").write_text(yaml.safe_dump(keep, sort_keys=True))
            return True, f"{case.name}: gold updated ({summary['cycles']} cycles, exit {code})"
        run, ref = read_history(out / "history.csv"), read_history(gold / "history.csv")
    lines, ok = [f"{case.name}: {spec['requirement']}"], True
    expected = spec.get("exit_code", 0)
    if code != expected:
        failed = [c["name"] for c in summary["checks"] if not c["passed"]]
        return False, (f"{case.name}: exit code {code}, expected {expected}: {summary['message'] or ''} "
                       f"failed checks {failed}")
    for col, tol in spec.get("columns", {}).items():
        a, g = run[col], ref[col]
        if len(a) != len(g):
            ok = False
            lines.append(f"  {col}: {len(a)} rows, gold has {len(g)}")
            continue
        err = np.abs(a - g).max()
        allowed = tol.get("atol", 0.0) + tol.get("rtol", 0.0) * np.abs(g).max()
        passed = bool(err <= allowed)
        ok &= passed
        lines.append(f"  {col:<30s} max |diff| {err:.3e} (allowed {allowed:.3e}) {'ok' if passed else 'FAIL'}")
    for rule in spec.get("agree", []):
        (wcol, (lo, hi)), = rule["where"].items()
        rows = (run[wcol] >= lo) & (run[wcol] <= hi)
        a, r = run[rule["column"]][rows], run[rule["reference"]][rows]
        worst = float(np.max(np.abs(a - r) / np.abs(r))) if rows.any() else float("inf")
        passed = worst <= rule["rtol"]
        ok &= passed
        lines.append(f"  {rule['column']} vs {rule['reference']} for {lo} <= {wcol} <= {hi}: worst relative "
                     f"difference {worst:.3f} (allowed {rule['rtol']}) {'ok' if passed else 'FAIL'}")
    if spec.get("summary"):
        gold_summary = yaml.safe_load((case / "gold" / "summary.yaml").read_text())
        for key, tol in spec["summary"].items():
            a, g = float(_get(summary, key)), float(gold_summary[key])
            allowed = tol.get("atol", 0.0) + tol.get("rtol", 0.0) * abs(g)
            passed = abs(a - g) <= allowed
            ok &= passed
            lines.append(f"  {key:<30s} {a:.6g} vs gold {g:.6g} (allowed {allowed:.2e}) {'ok' if passed else 'FAIL'}")
    return ok, "\n".join(lines)
