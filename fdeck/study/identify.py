"""``fdeck identify``: least-squares fit of deck parameters (by path) to measured values of one quantity.

Residuals r_i = (model_i - measured_i) / s_i with s_i the point's sigma, else |measured_i| (relative) or 1
(absolute). scipy's ``least_squares`` (trust-region reflective, bounds) works on parameters scaled by their start
values, x = p / p0, so a relative finite-difference step is a plain step in x. The Jacobian is ours, not scipy's
'2-point': every column (one run per data point at p + h_j e_j, h_j = rel_step |p_j|, stepping back at an upper
bound) is sent to the pool at once, so the runs of a column and of all columns go in parallel, locally or on Dask;
every run goes through the digest cache, so the base point of a Jacobian is never run twice.

Statistics at the solution (linearised, Gauss-Newton): with J = d r / d p (n_data, n_param) and the residual
variance s^2 = |r|^2 / (n_data - n_param), the covariance is s^2 (J^T J)^-1, the standard errors its diagonal's
roots and the correlations cov_jk / (se_j se_k) (e.g. Seber and Wild, Nonlinear Regression, 1989, ch. 2). With as
many data as parameters there is no residual variance: standard errors are not given.
"""

from __future__ import annotations

import datetime
import math
import time
from pathlib import Path

import numpy as np

from fdeck.study import deck_paths
from fdeck.study import variants as vmod
from fdeck.study.executor import Pool, run_cached
from fdeck.study.study import quantity


class IdentifyError(Exception):
    """The fit cannot go on (a run gave no answer); the message names the run and its status."""


def load_ident(path: Path):
    """-> (spec, points, {deck file: (data, folder)}). DeckError with located problems (deck paths that lead
    nowhere, parameters that are not numbers in the base deck)."""
    from fdeck.deck.errors import DeckError
    from fdeck.deck.loader import load_file
    from fdeck.deck.read import located
    from fdeck.study.models import IdentSpec, load

    spec, locs = load(path, IdentSpec)
    decks, problems = {}, []
    for key, name in [(("base",), spec.base)] + [(("points", i, "deck"), p.deck) for i, p in enumerate(spec.points)
                                                 if p.deck]:
        if name not in decks:
            file = path.parent / name
            if not file.is_file():
                problems.append(located(str(path), locs, key, f"deck file '{file}' not found"))
                continue
            decks[name] = (load_file(file)[0], file.parent)
    if problems:
        raise DeckError(problems)
    base = decks[spec.base][0]
    where = [(("set",), spec.set)] + [(("points", i, "set"), p.set) for i, p in enumerate(spec.points)]
    if spec.table:
        where.append((("table",), {spec.table.path: None}))
    problems += vmod.path_problems(str(path), locs, base, where)
    for i, par in enumerate(spec.parameters):
        try:
            value = deck_paths.get(vmod.resolve(base, spec.set), par.path)
            if par.initial is None and (not isinstance(value, (int, float)) or isinstance(value, bool) or value == 0):
                problems.append(located(str(path), locs, ("parameters", i, "path"), f"'{par.path}' is {value!r} in "
                                        "the base deck: give a nonzero number as `initial`"))
        except deck_paths.PathError:
            try:  # a key the deck leaves to its default may still be set: then `initial` is needed
                deck_paths.check_settable(base, par.path)
                if par.initial is None:
                    problems.append(located(str(path), locs, ("parameters", i, "path"), f"'{par.path}' is not in "
                                            "the base deck: give its start value as `initial`"))
            except deck_paths.PathError as exc:
                problems.append(located(str(path), locs, ("parameters", i, "path"), str(exc)))
    if spec.preset is not None:
        name = _material_of(spec)
        if name is None:
            problems.append(located(str(path), locs, ("preset",), f"'{spec.parameters[0].path}' is not a material "
                                    "field: name the material whose preset is written with `preset.material` (the "
                                    "fitted values outside it go to the preset's header)"))
        elif name not in vmod.resolve(base, spec.set).get("materials", {}):
            problems.append(located(str(path), locs, ("preset", "material"), f"the base deck has no material "
                                    f"'{name}'"))
    if problems:
        raise DeckError(problems)
    return spec, spec.data_points(), decks


def _start(spec, base) -> np.ndarray:
    resolved = vmod.resolve(base, spec.set)
    return np.array([p.initial if p.initial is not None else float(deck_paths.get(resolved, p.path))
                     for p in spec.parameters])


class Fit:
    """The residual function and our parallel Jacobian, on scaled parameters x = p / p0."""

    def __init__(self, spec, points, decks, out_dir: Path, pool: Pool, echo):
        self.spec, self.points, self.decks, self.out, self.pool, self.echo = spec, points, decks, out_dir, pool, echo
        self.p0 = _start(spec, decks[spec.base][0])
        self.scale = np.array([p.sigma if p.sigma else (abs(p.value) if spec.residual == "relative" else 1.0)
                               for p in points])
        if np.any(self.scale == 0.0):
            raise IdentifyError("a measured value is 0: give it a `sigma` or use `residual: absolute`")
        self.measured = np.array([p.value for p in points])
        self.runs = self.reused = 0
        self.evaluations: list[dict] = []
        self.last_run: dict[str, str] = {}  # point -> folder of its latest completed run (static solves start there)

    def params(self, x: np.ndarray) -> np.ndarray:
        return self.p0 * x

    def _plan(self, p: np.ndarray):
        out = []
        for k, pt in enumerate(self.points):
            data, folder = self.decks[pt.deck or self.spec.base]
            settings = {**self.spec.set, **pt.set, **{par.path: float(v) for par, v in zip(self.spec.parameters, p)}}
            q = vmod.plan(f"{pt.name}", settings, data, folder, self.spec.solver_options())
            if q.solver is not None:
                q.seed = self.last_run.get(pt.name)
            out.append(q)
        return out

    def model(self, ps: list[np.ndarray]) -> list[np.ndarray]:
        """Model answers (n_data,) at each parameter vector of ``ps``; all runs in one batch."""
        planned = [q for p in ps for q in self._plan(p)]
        results = run_cached(self.pool, planned, self.out)
        self.runs += sum(not r["reused"] for r in results)
        self.reused += sum(r["reused"] for r in results)
        out = []
        for i in range(len(ps)):
            chunk = results[i * len(self.points):(i + 1) * len(self.points)]
            vals = []
            for pt, q, res in zip(self.points, planned[i * len(self.points):], chunk):
                v = quantity(res, self.spec.quantity)
                if v is not None and i == 0:  # the first vector of a batch is the residual's or Jacobian's base
                    self.last_run[pt.name] = res["run_dir"]
                if v is None:
                    raise IdentifyError(f"point {pt.name} at {dict(zip([p.path for p in self.spec.parameters], ps[i]))}"
                                        f": run {res.get('run_dir')} gave no '{self.spec.quantity}' (status "
                                        f"{res.get('status')}{': ' + res['message'] if res.get('message') else ''})")
                vals.append(v)
            out.append(np.array(vals))
        return out

    def residuals(self, x: np.ndarray) -> np.ndarray:
        m = self.model([self.params(x)])[0]
        r = (m - self.measured) / self.scale
        self.evaluations.append({"parameters": self.params(x).tolist(), "rms_residual": float(np.sqrt(np.mean(r * r)))})
        self.echo(f"  evaluation {len(self.evaluations)}: " + ", ".join(
            f"{par.path} = {v:.6g}" for par, v in zip(self.spec.parameters, self.params(x)))
            + f"; rms residual {self.evaluations[-1]['rms_residual']:.4g}")
        return r

    def steps(self, x: np.ndarray, ub: np.ndarray) -> np.ndarray:
        h = self.spec.rel_step * np.maximum(np.abs(x), 1e-12)
        return np.where(x + h > ub, -h, h)

    def jacobian(self, x: np.ndarray, ub: np.ndarray) -> np.ndarray:
        """d r / d x (n_data, n_param) by forward (or, at an upper bound, backward) differences, runs in parallel."""
        h = self.steps(x, ub)
        xs = [x] + [x + np.eye(len(x))[j] * h[j] for j in range(len(x))]
        ms = self.model([self.params(xi) for xi in xs])
        return np.column_stack([(ms[j + 1] - ms[0]) / self.scale / h[j] for j in range(len(x))])


def statistics(J: np.ndarray, r: np.ndarray) -> dict:
    """Standard errors and correlations of parameters from J = d r / d p (n_data, n_param) and residuals r."""
    m, n = J.shape
    if m <= n:
        return {"residual_variance": None, "standard_errors": [None] * n, "correlations": None}
    s2 = float(r @ r) / (m - n)
    cov = s2 * np.linalg.pinv(J.T @ J)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    return {"residual_variance": s2, "standard_errors": se.tolist(), "correlations": corr.tolist()}


def run_identify(path: Path, out_dir: Path, pool: Pool, echo=print) -> dict:
    """Fit, report and write the preset; returns the result dict (also written as identify.json)."""
    from scipy.optimize import least_squares

    spec, points, decks = load_ident(path)
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    fit = Fit(spec, points, decks, out_dir, pool, echo)
    echo(f"{path}: {len(spec.parameters)} parameters, {len(points)} data points, runs on {pool.describe()}")
    lo = np.array([p.lower for p in spec.parameters]) / fit.p0
    hi = np.array([p.upper for p in spec.parameters]) / fit.p0
    lb, ub = np.minimum(lo, hi), np.maximum(lo, hi)  # a negative start value flips the scaled bounds
    sol = least_squares(fit.residuals, np.ones(len(fit.p0)), jac=lambda x: fit.jacobian(x, ub), bounds=(lb, ub),
                        method="trf", ftol=spec.tolerance, xtol=spec.tolerance, gtol=spec.tolerance,
                        max_nfev=spec.max_evaluations)
    p = fit.params(sol.x)
    r = (fit.model([p])[0] - fit.measured) / fit.scale
    J = fit.jacobian(sol.x, ub) / fit.p0  # d r / d p in the parameters' own units
    stats = statistics(J, r)
    model = r * fit.scale + fit.measured
    result = {
        "identify": str(path), "title": spec.title, "base": spec.base, "quantity": spec.quantity,
        "residual_kind": spec.residual, "status": "converged" if sol.success else "stopped", "message": sol.message,
        "parameters": [{"path": par.path, "initial": float(p0), "value": float(v), "standard_error": se,
                        "lower": par.lower, "upper": par.upper}
                       for par, p0, v, se in zip(spec.parameters, fit.p0, p, stats["standard_errors"])],
        "correlations": stats["correlations"], "residual_variance": stats["residual_variance"],
        "points": [{"name": pt.name, "settings": pt.set, "measured": pt.value, "model": float(mv),
                    "residual": float(ri)} for pt, mv, ri in zip(points, model, r)],
        "rms_residual": float(np.sqrt(np.mean(r * r))), "evaluations": fit.evaluations,
        "runs": fit.runs, "runs_reused": fit.reused, "wall_time": time.perf_counter() - t0,
    }
    if spec.preset is not None:
        result["preset"] = str(write_preset(spec, decks[spec.base][0], result, path, out_dir))
    return result


def _material_of(spec) -> str | None:
    if spec.preset.material:
        return spec.preset.material
    keys = deck_paths.parts(spec.parameters[0].path)
    return keys[1] if len(keys) > 2 and keys[0] == "materials" else None


def write_preset(spec, base: dict, result: dict, ident_path: Path, out_dir: Path) -> Path:
    """<out_dir>/<preset name>.yaml: the fitted material's complete fields (its preset, the deck's keys, then the
    fitted values), with the provenance in the header and under `identified:`-free comments, in the format of
    ``fdeck/cards/presets/<kind>/``. Parameters outside that material are listed in the header only."""
    import yaml

    from fdeck import registry
    import fdeck.cards  # noqa: F401  (fills the card tables)

    name = _material_of(spec)
    resolved = vmod.resolve(base, spec.set)
    card = dict(resolved["materials"][name])
    entry = registry.CARDS["material"][card["type"]]
    cls = entry.card
    preset_name = card.get("preset") or getattr(cls, "default_preset", None)
    fields = dict(cls.preset_loader(preset_name)) if preset_name and hasattr(cls, "preset_loader") else {}
    fields.update({k: v for k, v in card.items() if k not in ("type", "preset") and v is not None})
    prefix = ("materials", name)
    outside = []
    for par in result["parameters"]:
        keys = deck_paths.parts(par["path"])
        if keys[:2] == prefix:
            deck_paths.set_value(fields, ".".join(map(str, keys[2:])), par["value"])
        else:
            outside.append(par)
    kind = entry.kind or card["type"]
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    head = [f"{spec.preset.name}: {kind} parameters identified by `fdeck identify {ident_path}` on {when}.",
            f"Base deck: {spec.base} (material '{name}', type {card['type']}"
            + (f", preset {preset_name}" if preset_name else "") + ").",
            f"Data: {len(result['points'])} measured values of '{spec.quantity}' ("
            + ", ".join(f"{p['name']} {p['measured']:.6g}" for p in result["points"]) + ").",
            f"Fit: {result['status']}, rms {spec.residual} residual {result['rms_residual']:.4g}, "
            f"{result['runs']} runs, {result['wall_time']:.1f} s."]
    for par in result["parameters"]:
        se = par["standard_error"]
        head.append(f"  {par['path']} = {par['value']:.6g}" + (f" +- {se:.3g} (standard error)" if se is not None
                                                                 else " (no standard error: as many data as "
                                                                 "parameters)")
                    + (" [not a field of this material: not in the preset]" if par in outside else ""))
    head.append(f"Use: copy to fdeck/cards/presets/{kind}/{spec.preset.name}.yaml and name it with "
                f"`preset: {spec.preset.name}`.")
    text = "".join(f"# {line}\n" for line in head) + "\n" + yaml.safe_dump(_plain(fields), sort_keys=False)
    out = out_dir / f"{spec.preset.name}.yaml"
    out.write_text(text)
    return out


def _plain(v):
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, float) and math.isfinite(v):
        return float(v)
    return v


def text(result: dict) -> str:
    """The printed report: fitted values with standard errors, correlations, residual per point, cost."""
    lines = [f"fit {result['status']}: {result['message']}"]
    for par in result["parameters"]:
        se = par["standard_error"]
        lines.append(f"  {par['path']:<44s} {par['value']:.6g}" + (f" +- {se:.3g}" if se is not None else "")
                     + (f" ({100 * se / abs(par['value']):.2g} %)" if se is not None and par["value"] else "")
                     + f"   (start {par['initial']:.6g})")
    if result["correlations"] is not None and len(result["parameters"]) > 1:
        lines.append("  correlations:")
        width = max(len(par["path"]) for par in result["parameters"])  # whole paths: a cut one can be ambiguous
        for par, row in zip(result["parameters"], result["correlations"]):
            lines.append(f"    {par['path']:<{width}s} " + " ".join(f"{c:7.3f}" for c in row))
    lines.append(f"  {'point':<24s} {'measured':>12s} {'model':>12s} {'residual':>10s}")
    for pt in result["points"]:
        lines.append(f"  {pt['name'][:24]:<24s} {pt['measured']:12.6g} {pt['model']:12.6g} {pt['residual']:10.3e}")
    lines.append(f"  rms residual {result['rms_residual']:.4g}; {result['runs']} runs made, {result['runs_reused']} "
                 f"more answers taken from the cache, {result['wall_time']:.1f} s wall")
    if result.get("preset"):
        lines.append(f"preset written: {result['preset']}")
    return "\n".join(lines)
