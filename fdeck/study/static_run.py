"""One study or identification run solved for static equilibrium instead of run in time (``solver: static``).

Why: a strip hanging under its own weight (the 3WEAVE cantilevers of [P]) takes 5-30 minutes to settle in an explicit
run and seconds to a few minutes by Newton (``fdeck.engine.static``, whose answer equals a settled dynamic run to 1e-6
in ``test_static_cantilever.py``). A fit that needs tens of runs per Jacobian can only afford the second.

What it does: compiles the resolved deck, solves f_int(x) = f_ext under the loads and prescribed positions at the
end of the last step (load-stepped Newton), optionally first along a continuation in one deck parameter (e.g. the
fibre compression ratio 1 -> 0.3 -> ... -> the deck's own value, ``static.continuation``), then evaluates the deck's
measures at the equilibrium (velocities zero) and writes ``summary.json`` in the shape the studies read (``status``,
``measures``, ``wall_time``) plus the solver's cost (``force_calls``, ``newton_iterations``, ``increments``,
``branch_switches``) and the final positions (``final_positions.npy``, (n_node, 3) [mm]). A run that does not
converge is ``failed`` with the load
factor or continuation value it reached: a row with its status, as for a dynamic run.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from fdeck.study import deck_paths
from fdeck.study.variants import resolve


def run_static(deck_data: dict, base_dir: Path, out_dir: Path, options: dict, seed: str | None = None) -> dict:
    """Solve ``deck_data`` (a resolved, validated deck as plain data) statically; ``options``: ``max_iterations``
    (Newton iterations per load increment) and ``continuation`` (None or {path, values}). ``seed``: the run folder
    of a neighbouring run (same mesh, nearby parameters, e.g. the base point of a Jacobian): its equilibrium is the
    first guess, solved at full load at once, with the ordinary route as the fallback when that fails (the answer
    is the same to the solver's tolerance, rtol 1e-8 of the displacement; only the cost changes). Returns the
    summary dict (also written to out_dir/summary.json). CompileError propagates (the caller makes it ``invalid``);
    so does ``io.outdir.OutdirError`` when another run is writing into out_dir (one writer per folder, as for
    ``fdeck run``)."""
    from fdeck.io.outdir import writing

    with writing(out_dir):  # makes the folder
        return _run_static(deck_data, base_dir, out_dir, options, seed)


def _run_static(deck_data: dict, base_dir: Path, out_dir: Path, options: dict, seed: str | None) -> dict:
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import static
    from fdeck.io.summary import write_json_atomic

    t0 = time.perf_counter()
    cont = options.get("continuation")

    def make(value):
        data = deck_data if value is None else resolve(deck_data, {cont["path"]: value})
        return compile_deck(Deck.model_validate(data), base_dir)

    kw = {"max_iterations": options.get("max_iterations", 20), "stable": bool(options.get("follow_stable", False))}
    attempts, reached, converged = [], None, False
    problem = make(None)
    x0 = _seed_positions(seed)
    x0 = x0 if x0 is not None and x0.shape == problem.X.shape else None  # another mesh's answer is no guess
    if x0 is not None:
        res = static.solve(problem, x0=x0, first=1.0, **kw)
        attempts, converged = [(None, problem, res)], bool(res.converged)
    if not converged and cont:
        own = float(deck_paths.get(deck_data, cont["path"]))
        before = [float(v) for v in cont["values"]]
        path = [v for v in before if (v - own) * (before[0] - own) > 0.0] + [own]
        attempts += static.continuation(lambda v: problem if v == own else make(v), path, **kw)
        reached, problem, res = attempts[-1]
        converged = bool(res.converged and reached == own)
    elif not converged:
        res = static.solve(problem, **kw)
        attempts.append((None, problem, res))
        converged = bool(res.converged)
    summary = {
        "status": "completed" if converged else "failed", "solver": "static",
        "force_calls": sum(a[2].force_calls for a in attempts),
        "newton_iterations": sum(a[2].iterations for a in attempts),
        "increments": sum(a[2].increments for a in attempts), "seeded": x0 is not None,
        "branch_switches": sum(a[2].switches for a in attempts),
        "residual": float(res.residual), "elements": int(problem.n_element),
    }
    if converged:
        zero = np.zeros_like(res.x)
        summary["measures"] = {c: float(v) for m in problem.measures
                               for c, v in zip(m.columns, m.evaluate(res.x, zero))}
        summary["final"] = final_values(problem, res.x)
        if options.get("stability", False):
            # the stable-branch solve counted them at the answer already (unless the factorisation could not tell)
            summary.update({"negative_eigenvalues": res.unstable} if res.unstable >= 0 else
                           _stability(static, problem, res.x))
        np.save(out_dir / POSITIONS, res.x)
    else:
        summary["message"] = (f"static solve stopped at load factor {res.load_factor:.3g}" if reached is None else
                              f"continuation in {cont['path']} stopped at {reached:.4g} (load factor "
                              f"{res.load_factor:.3g})")
        if options.get("stability", False) and res.load_factor > 0.0:
            # where the path ends: a negative eigenvalue at the last equilibrium says the path lost its stability
            # (a bifurcation or limit point passed), none says the solver did not find the next equilibrium
            summary["load_factor_reached"] = float(res.load_factor)
            summary.update({k + "_at_stop": v for k, v in _stability(static, problem, res.x).items()})
            np.save(out_dir / STOP_POSITIONS, res.x)
    summary["wall_time"] = time.perf_counter() - t0
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


POSITIONS = "final_positions.npy"
STOP_POSITIONS = "stop_positions.npy"  # the last equilibrium of a solve that did not reach full load


def _stability(static, problem, x: np.ndarray) -> dict:
    """{"negative_eigenvalues": count} of the tangent at x, or None and the reason when the factorisation cannot
    tell (off-diagonal pivots, an exactly singular tangent)."""
    try:
        return {"negative_eigenvalues": static.negative_eigenvalues(problem, x)}
    except (ValueError, RuntimeError) as exc:
        return {"negative_eigenvalues": None, "stability_message": str(exc)}


def final_values(problem, x: np.ndarray) -> dict:
    """The columns a dynamic run's summary keeps in ``final`` that an equilibrium x (n_node, 3) [mm] has: every
    stored energy term of the groups and internal effects [mJ] by its ledger name, their sum ``internal_energy``,
    and the reactions [N] of the sets in ``output.reactions`` as ``reaction_<set>_<x|y|z>``: the force the
    supports apply to the body, f_int - f_ext on the set's nodes (the sign of a dynamic run's reaction columns)."""
    from fdeck.engine import static

    sp_ = static.StaticProblem(problem)
    f = sp_.f_int(x)  # also leaves every group and effect evaluated at x for the terms below
    out = sp_.stored()
    out["internal_energy"] = float(sum(out.values()))
    r = f - sp_.f_ext
    for name, nodes in problem.reactions.items():
        for c, v in zip("xyz", r[nodes].sum(axis=0)):
            out[f"reaction_{name}_{c}"] = float(v)
    return out


def _seed_positions(seed: str | None) -> np.ndarray | None:
    """(n_node, 3) equilibrium positions saved by the run in folder ``seed``, or None."""
    if seed is None or not (Path(seed) / POSITIONS).is_file():
        return None
    return np.load(Path(seed) / POSITIONS)
