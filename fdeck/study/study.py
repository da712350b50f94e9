"""``fdeck study``: run a base deck's variants, compare their answers with a reference, find the cheapest accurate
one.

References: ``finest`` (one variant's answer), ``richardson`` (extrapolation of three variants refined by a constant
ratio r, with the observed order p = ln((f1 - f2) / (f2 - f3)) / ln r; L.F. Richardson, The deferred approach to
the limit, Phil. Trans. R. Soc. A 226, 1927; as used for grid convergence by P.J. Roache, Verification and
Validation in Computational Science and Engineering, 1998), ``closed_form`` or ``measured`` values given in the file.
The error of a variant is |answer - reference| / |reference| per quantity (absolute when the reference is 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from fdeck.study import models
from fdeck.study import variants as vmod
from fdeck.study.executor import Pool, run_cached

ANSWERED = ("completed", "check_failed")  # statuses whose final values are answers; a failed run's are not


class StudyError(Exception):
    """The study ran but cannot conclude (e.g. no reference could be formed); the message says why."""


@dataclass
class Reference:
    """Reference value per quantity, and how it was formed (observed order per quantity for Richardson)."""

    kind: str
    values: dict[str, float | None]
    variants: list[str] = field(default_factory=list)
    order: dict[str, float | None] = field(default_factory=dict)
    source: str = ""
    message: str = ""


def quantity(result: dict, name: str) -> float | None:
    """A named value of a run's summary: a measure, then a check value, then a final history column, then a
    top-level number (wall_time, cycles...). None when the run gave no answer or the name is unknown."""
    if result.get("status") not in ANSWERED:
        return None
    checks = {c["name"]: c["value"] for c in result.get("checks") or []}
    for source in (result.get("measures") or {}, checks, result.get("final") or {}):
        if source.get(name) is not None:
            return float(source[name])
    value = result.get(name)
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def richardson(f1: float, f2: float, f3: float, ratio: float) -> tuple[float, float]:
    """(extrapolated value, observed order p) from answers on coarse, medium and fine meshes refined by ``ratio``,
    assuming f(h) = f0 + c h^p. ValueError for non-monotone or non-converging sequences."""
    d1, d2 = f1 - f2, f2 - f3
    if d1 == 0.0 and d2 == 0.0:
        return f3, math.nan
    if d2 == 0.0 or d1 / d2 <= 0.0:
        raise ValueError(f"answers {f1:.6g}, {f2:.6g}, {f3:.6g} do not converge monotonically: no Richardson "
                         "extrapolation")
    q = d1 / d2  # = ratio^p
    if q <= 1.0:
        raise ValueError(f"answers {f1:.6g}, {f2:.6g}, {f3:.6g} do not converge (the differences grow)")
    return f3 - d2 / (q - 1.0), math.log(q) / math.log(ratio)


def _given(spec, by_name: dict, names: list[str]) -> Reference:
    ref = spec.reference
    return Reference(ref.type, dict(ref.values), source=ref.source)


def _finest(spec, by_name: dict, names: list[str]) -> Reference:
    which = spec.reference.variant or names[-1]
    return Reference("finest", dict(by_name[which]), [which])


def _extrapolated(spec, by_name: dict, names: list[str]) -> Reference:
    ref = spec.reference
    which = ref.variants or names[:len(next(iter(spec.grid.values())))][-3:]
    out = Reference("richardson", {}, list(which))
    messages = []
    for q in spec.quantities:
        f = [by_name[n][q] for n in which]
        if any(v is None for v in f):
            out.values[q], out.order[q] = None, None
            messages.append(f"{q}: a refined variant gave no answer")
            continue
        try:
            out.values[q], out.order[q] = richardson(*f, ref.ratio)
        except ValueError as exc:
            out.values[q], out.order[q] = None, None
            messages.append(f"{q}: {exc}")
    out.message = "; ".join(messages)
    return out


_FORMS = {models.Given: _given, models.Finest: _finest, models.Richardson: _extrapolated}


def reference(spec, names: list[str], answers: list[dict[str, float | None]]) -> Reference:
    """The study's reference from its card and the variants' answers (same order as ``names``)."""
    return _FORMS[type(spec.reference)](spec, dict(zip(names, answers)), names)


def relative_error(answer: float | None, ref: float | None) -> float | None:
    if answer is None or ref is None:
        return None
    return abs(answer - ref) / abs(ref) if ref != 0.0 else abs(answer - ref)


def pareto(rows: list[dict]) -> list[str]:
    """Names of the rows no other row beats in both wall time and largest error (ties by time kept once)."""
    cands = sorted((r for r in rows if r["max_error"] is not None and r["wall_time"] is not None),
                   key=lambda r: (r["wall_time"], r["max_error"]))
    front, best = [], math.inf
    for r in cands:
        if r["max_error"] < best:
            front.append(r["name"])
            best = r["max_error"]
    return front


def check_spec(spec, locs, filename: str, base_data: dict) -> list:
    """Located problems the schema cannot see: deck paths not in the base deck, repeated or unknown variant
    names."""
    from fdeck.deck.errors import unknown_name
    from fdeck.deck.read import located

    where = [(("set",), spec.set), (("grid",), spec.grid)]
    where += [(("variants", i, "set"), v.set) for i, v in enumerate(spec.variants)]
    problems = vmod.path_problems(filename, locs, base_data, where)
    names = [n for n, _ in vmod.expand(spec)]
    for dup in vmod.duplicate_names(names):
        problems.append(located(filename, locs, ("variants",), f"variant name '{dup}' is used twice"))
    ref = spec.reference
    wanted = ([("variant", ref.variant)] if getattr(ref, "variant", None) else []) + \
        [(("variants", i), n) for i, n in enumerate(getattr(ref, "variants", None) or [])]
    for key, n in wanted:
        if n not in names:
            key = key if isinstance(key, tuple) else (key,)
            problems.append(located(filename, locs, ("reference",) + key, unknown_name("variant", n, names)))
    return problems


def load_study(path: Path):
    """-> (spec, planned variants). DeckError with located problems for a bad study file or base deck."""
    from fdeck.deck.errors import DeckError
    from fdeck.deck.loader import load_file
    from fdeck.study.models import StudySpec, load

    spec, locs = load(path, StudySpec)
    base_path = (path.parent / spec.base)
    base_data, _ = load_file(base_path)
    problems = check_spec(spec, locs, str(path), base_data)
    if problems:
        raise DeckError(problems)
    planned = [vmod.plan(n, s, base_data, base_path.parent, spec.solver_options()) for n, s in vmod.expand(spec)]
    return spec, planned


def run_study(path: Path, out_dir: Path, pool: Pool, echo=print) -> dict:
    """Run a study file; returns the table {study, reference, tolerance, cheapest, pareto, rows}."""
    spec, planned = load_study(path)
    out_dir.mkdir(parents=True, exist_ok=True)
    echo(f"{path}: {len(planned)} variants on {pool.describe()}")

    def done(p, res):
        echo(f"  {p.name}: {res.get('status')} ({res.get('wall_time') or 0:.2f} s)")

    results = run_cached(pool, planned, out_dir, done)
    names = [p.name for p in planned]
    answers = [{q: quantity(r, q) for q in spec.quantities} for r in results]
    ref = reference(spec, names, answers)
    rows = []
    for p, res, ans in zip(planned, results, answers):
        errs = {q: relative_error(ans[q], ref.values.get(q)) for q in spec.quantities}
        known = [e for e in errs.values() if e is not None]
        max_err = max(known) if len(known) == len(errs) else None
        added = res.get("added_mass_percent") or []
        rows.append({
            "name": p.name, "settings": p.settings, "status": res.get("status"), "message": res.get("message", ""),
            "answers": ans, "errors": errs, "max_error": max_err,
            "within_tolerance": max_err is not None and max_err <= spec.tolerance,
            "wall_time": res.get("wall_time"), "cycles": res.get("cycles"), "elements": res.get("elements"),
            "us_per_element_cycle": res.get("us_per_element_cycle"),
            "added_mass_percent": max(added) if added else None, "reused": res.get("reused", False),
            "run_dir": res.get("run_dir"), "digest": p.digest})
    accurate = [r for r in rows if r["within_tolerance"] and r["wall_time"] is not None]
    cheapest = min(accurate, key=lambda r: r["wall_time"])["name"] if accurate else None
    return {"study": str(path), "title": spec.title, "base": spec.base, "quantities": spec.quantities,
            "tolerance": spec.tolerance,
            "reference": {"type": ref.kind, "values": ref.values, "variants": ref.variants, "order": ref.order,
                          "source": ref.source, "message": ref.message},
            "cheapest": cheapest, "pareto": pareto(rows), "rows": rows}
