"""3WEAVE strips under their own weight, solved statically (``fdeck.engine.static``) from the shipped decks.

The static answer is the state the dynamic decks settle to (same deck, same model: groups, effects, gravity, held
dofs), without the 5-30 minutes of settling per strip, so mesh sequences and fits become affordable.

    python studies/cantilever_static.py campaign [--directions warp weft] [--forms ans fbar] [--dx 10 5 2.5]
    python studies/cantilever_static.py table        # markdown table of the stored campaign

Route to the published 1 % compression ratio (argued; ``fdeck.engine.static`` has the references):
1. semi-smooth Newton: the finite-difference tangent's step is small enough (1e-11 of the model) that every
   integration point stays on its tension or compression branch during the difference, so each iteration solves
   with the Jacobian of the current branches and the branches are updated between iterations; with the former
   step (1e-7) the points near every neutral axis straddled the kink and Newton cycled. Chosen first: it keeps
   Newton's convergence and its cost (tens of iterations), where dynamic relaxation (Underwood 1983) would need
   thousands of force calls for a strip whose stiffness ratio (fibre tension to bending) is ~1e6;
2. continuation in the compression ratio (1, 0.3, 0.1, 0.03, 0.01, each at full load from the previous
   equilibrium, steps halved geometrically when one fails): the symmetric law has no kink, and each softer law
   starts near its answer, so its first tangents already sit on the right branches.
A row is converged when the residual (|f_int - f_ext| / |f_ext| on the free dofs) is below 1e-4 with corrections
below 1e-8 of the displacement; ``tol_change`` is the tip's change when that is re-solved with tolerances 10x
(residual) and 100x (corrections) tighter.

The identification of the bending parameters runs through `fdeck identify` with `solver: static`
(decks/studies/identify_3weave_*.yaml; the picture: studies/cantilever_fit.py). Campaign rows with
converged = false are listed as such.

Results are kept in studies/out/cantilever_static.json (one row per strip, formulation, element length, layers,
parameters; a rerun replaces the row).
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "studies" / "out"
STORE = OUT / "cantilever_static.json"
sys.path.insert(0, str(ROOT / "studies"))
from cantilever_3weave import MEASURED, PUBLISHED_RATIO  # noqa: E402


def deck_data(direction: str, L: float, dx: float = 5.0, form: str = "ans", nz: int = 4,
              ratio: float | None = PUBLISHED_RATIO, bending: dict | None = None, preset: str | None = None) -> dict:
    """Data of decks/cantilever_3weave_{direction}.yaml with length L [mm], in-plane element dx [mm], nz layers,
    formulation, compression ratio (None: the preset's), an optional ``fibre_bending`` add-on ({warp: {D1: ..},
    weft: {D1: ..}}) and material preset."""
    from fdeck.deck.loader import load_file

    data, _ = load_file(ROOT / "decks" / f"cantilever_3weave_{direction}.yaml")
    data = copy.deepcopy(data)
    block = data["mesh"]["block"]
    block["size"][0] = float(L)
    block["divisions"][0] = int(round(L / dx))
    block["divisions"][2] = nz
    data["mesh"]["node_sets"]["tip"]["box"] = [[L, 0, 0], [L, block["size"][1], block["size"][2]]]
    mat = data["materials"]["3weave"]
    if preset is not None:
        mat["preset"] = preset
    if ratio is not None:
        mat["compression_ratio"] = ratio
    sec = data["sections"][0]
    sec["formulation"] = form
    if bending:
        sec["effects"] = [{"type": "fibre_bending", **bending}]
        for step in data["steps"]:  # selective mass refuses fibre bending; a static solve has no mass anyway
            step.pop("mass_scaling", None)
    return data


RATIOS = (1.0, 0.3, 0.1, 0.03)
"""Continuation in the fibre compression ratio down to the published 1 %: the symmetric law has no kink and
converges from the flat strip; each later law starts from the previous equilibrium (``static.continuation``)."""


def _tip(problem, x) -> float:
    tip = problem.node_sets["tip"]
    return -float((x[tip, 2] - problem.X[tip, 2]).mean())


def static_tip(data: dict, continuation: bool = True, **kw) -> dict:
    """Compile deck data and solve statically; tip deflection [mm] (mean -w of the tip set) and cost.

    With ``continuation`` and a compression ratio below 1, the same deck is solved first at RATIOS above it, each
    from the previous equilibrium (cost summed). Then a tolerance check: the answer is re-solved from itself with
    rtol 100 and ftol 10 times smaller (ftol 1e-5 is near the residual's round-off floor); ``tip_tight`` is that
    answer and ``tol_change`` its relative change (a converged answer no longer moves with the solver's
    tolerance)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import static

    t0 = time.perf_counter()
    ratio = data["materials"]["3weave"].get("compression_ratio", PUBLISHED_RATIO)
    chain = [r for r in RATIOS if r > ratio] if continuation else []

    def make(r):
        d = copy.deepcopy(data)
        d["materials"]["3weave"]["compression_ratio"] = r
        return compile_deck(Deck.model_validate(d), ROOT / "decks")

    kw.setdefault("max_iterations", 20)
    attempts = static.continuation(make, chain + [ratio], **kw)
    last, problem, res = attempts[-1]
    out = {"converged": bool(res.converged and last == ratio), "load_factor": res.load_factor,
           "residual": res.residual, "increments": sum(a[2].increments for a in attempts),
           "iterations": sum(a[2].iterations for a in attempts),
           "force_calls": sum(a[2].force_calls for a in attempts), "colours": res.colours,
           "elements": problem.n_element, "continuation": [a[0] for a in attempts if a[2].converged]}
    out["tip_deflection"] = _tip(problem, res.x) if out["converged"] else None
    if out["converged"]:
        rtol, ftol = kw.get("rtol", 1e-8), kw.get("ftol", 1e-4)
        tight = static.solve(problem, x0=res.x, first=1.0, rtol=rtol / 100, ftol=ftol / 10)
        out["force_calls"] += tight.force_calls
        out["tight_converged"], out["tight_residual"] = tight.converged, tight.residual
        if tight.converged:
            out["tip_tight"] = _tip(problem, tight.x)
            out["tol_change"] = out["tip_tight"] / out["tip_deflection"] - 1.0
    out["wall_time"] = time.perf_counter() - t0
    return out


def load() -> list[dict]:
    return json.loads(STORE.read_text()) if STORE.exists() else []


KEY = ("direction", "length", "form", "dx", "nz", "ratio", "bending")


def store(row: dict) -> None:
    """Add or replace the row (under a lock file: campaigns of the two strips may run side by side)."""
    import fcntl

    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / ".cantilever_static.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        k = tuple(json.dumps(row.get(f)) for f in KEY)
        rows = [r for r in load() if tuple(json.dumps(r.get(f)) for f in KEY) != k] + [row]
        STORE.write_text(json.dumps(rows, indent=1) + "\n")


def run_one(direction, L, form, dx, nz, ratio=PUBLISHED_RATIO, bending=None) -> dict:
    row = dict(direction=direction, length=L, form=form, dx=dx, nz=nz, ratio=ratio, bending=bending,
               measured=MEASURED[direction][L])
    row.update(static_tip(deck_data(direction, L, dx, form, nz, ratio, bending)))
    store(row)
    print(json.dumps(row), flush=True)
    return row


def table() -> str:
    """Markdown table of the stored rows: strip, L, ratio, formulation, layers, element length, tip deflection,
    change from the next coarser mesh, the residual at the answer, the change of the tip when the solver's
    tolerance is tightened, cost."""
    rows = sorted(load(), key=lambda r: (r["direction"], r["length"], r["ratio"], r["form"], r["nz"], -r["dx"]))
    out = ["| strip | L [mm] | compression | formulation | layers | element [mm] | tip [mm] | change | measured [mm] "
           "| residual | tip change, tighter tolerance | Newton its | force calls | wall [s] |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    prev = None
    for r in rows:
        same = prev is not None and all(prev[k] == r[k] for k in ("direction", "length", "ratio", "form", "nz"))
        w = f"{r['tip_deflection']:.2f}" if r["converged"] else (
            f"not converged (continuation stopped at ratio {r['continuation'][-1]:.3g})" if r.get("continuation")
            else f"not converged (lambda {r['load_factor']:.2f})")
        ch = (f"{100 * (r['tip_deflection'] / prev['tip_deflection'] - 1):+.1f} %"
              if same and r["converged"] and prev["converged"] else "")
        res = f"{r['residual']:.1e}" if r.get("residual") is not None and r["converged"] else ""
        tol = f"{r['tol_change']:+.1e}" if r.get("tol_change") is not None else ""
        out.append(f"| {r['direction']} | {r['length']} | {100 * r['ratio']:g} % | {r['form']} | {r['nz']} | "
                   f"{r['dx']:g} | {w} | {ch} | {r['measured']:.2f} | {res} | {tol} | {r['iterations']} | "
                   f"{r['force_calls']} | {r['wall_time']:.0f} |")
        prev = r
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=["one", "campaign", "table"])
    ap.add_argument("--directions", nargs="*", default=["warp", "weft"])
    ap.add_argument("--lengths", nargs="*", type=int)
    ap.add_argument("--forms", nargs="*", default=["ans", "fbar", "reduced"])
    ap.add_argument("--dx", nargs="*", type=float, default=[5.0, 2.5])
    ap.add_argument("--nz", nargs="*", type=int, default=[4])
    ap.add_argument("--ratio", type=float, default=PUBLISHED_RATIO)
    args = ap.parse_args()
    if args.what in ("one", "campaign"):
        for d in args.directions:
            for L in args.lengths or sorted(MEASURED[d]):
                for form in args.forms:
                    for nz in args.nz:
                        for dx in args.dx:
                            run_one(d, L, form, dx, nz, args.ratio)
    if args.what == "table":
        print(table())


if __name__ == "__main__":
    main()
