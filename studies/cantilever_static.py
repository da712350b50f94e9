"""3WEAVE strips under their own weight, solved statically (``fdeck.engine.static``) from the shipped decks.

The static answer is the state the dynamic decks settle to (same deck, same model: groups, effects, gravity, held
dofs), without the 5-30 minutes of settling per strip, so mesh sequences and fits become affordable.

    python studies/cantilever_static.py campaign [--directions warp weft] [--forms ans fbar reduced]
    python studies/cantilever_static.py table        # markdown table of the stored campaign

Not done yet: the figure and the least_squares identification (the 3WEAVE law's 1 % compression branch keeps
Newton from converging, see fdeck.engine.static); campaign rows with converged = false are listed as such.

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
    return data


def static_tip(data: dict, **kw) -> dict:
    """Compile deck data and solve statically; tip deflection [mm] (mean -w of the tip set) and cost."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import static

    t0 = time.perf_counter()
    problem = compile_deck(Deck.model_validate(data), ROOT / "decks")
    res = static.solve(problem, **kw)
    tip = problem.node_sets["tip"]
    w = -float((res.x[tip, 2] - problem.X[tip, 2]).mean())
    return {"tip_deflection": w, "converged": res.converged, "load_factor": res.load_factor,
            "increments": res.increments, "iterations": res.iterations, "force_calls": res.force_calls,
            "colours": res.colours, "wall_time": time.perf_counter() - t0, "elements": problem.n_element}


def load() -> list[dict]:
    return json.loads(STORE.read_text()) if STORE.exists() else []


KEY = ("direction", "length", "form", "dx", "nz", "ratio", "bending")


def store(row: dict) -> None:
    k = tuple(json.dumps(row.get(f)) for f in KEY)
    rows = [r for r in load() if tuple(json.dumps(r.get(f)) for f in KEY) != k] + [row]
    OUT.mkdir(parents=True, exist_ok=True)
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
    change from the next coarser mesh, cost."""
    rows = sorted(load(), key=lambda r: (r["direction"], r["length"], r["ratio"], r["form"], r["nz"], -r["dx"]))
    out = ["| strip | L [mm] | compression | formulation | layers | element [mm] | tip [mm] | change | measured [mm] "
           "| Newton its | force calls | wall [s] |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    prev = None
    for r in rows:
        same = prev is not None and all(prev[k] == r[k] for k in ("direction", "length", "ratio", "form", "nz"))
        w = f"{r['tip_deflection']:.2f}" if r["converged"] else f"not converged (lambda {r['load_factor']:.2f})"
        ch = (f"{100 * (r['tip_deflection'] / prev['tip_deflection'] - 1):+.1f} %"
              if same and r["converged"] and prev["converged"] else "")
        out.append(f"| {r['direction']} | {r['length']} | {100 * r['ratio']:g} % | {r['form']} | {r['nz']} | "
                   f"{r['dx']:g} | {w} | {ch} | {r['measured']:.2f} | {r['iterations']} | {r['force_calls']} | "
                   f"{r['wall_time']:.0f} |")
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
