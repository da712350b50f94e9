"""Tip deflections of 3WEAVE strips under their own weight against [P]'s measurements (MODELS 6.2).

Runs decks/cantilever_3weave_{warp,weft}.yaml at every length of [P] (the block length and tip set rewritten),
and writes studies/out/cantilever_3weave.json and a markdown table. Usage:
    python studies/cantilever_3weave.py [warp|weft] [--lengths 200 250]
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MEASURED = {
    "warp": {200: 52.71, 250: 163.15, 300: 245.72, 350: 281.17},
    "weft": {200: 5.47, 250: 13.54, 300: 29.78, 350: 49.98, 400: 103.20, 450: 184.26, 500: 296.87},
}


def run_length(direction: str, L: float) -> dict:
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.loader import load_file
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    data, _ = load_file(ROOT / "decks" / f"cantilever_3weave_{direction}.yaml")
    data = copy.deepcopy(data)
    block = data["mesh"]["block"]
    block["size"][0] = float(L)
    block["divisions"][0] = int(round(L / 5))
    data["mesh"]["node_sets"]["tip"]["box"] = [[L, 0, 0], [L, 5, 2.54]]
    t0 = time.perf_counter()
    problem = compile_deck(Deck.model_validate(data), ROOT / "decks")
    res = solver.run(problem, solver.Sink())
    h = dict(zip(res.columns, zip(*res.history)))
    tip = -h["tip_deflection"][-1]
    ke, ie = h["kinetic_energy"][-1], h["internal_energy"][-1]
    return {"direction": direction, "length": L, "tip_deflection": tip, "measured": MEASURED[direction][L],
            "status": res.status, "cycles": res.cycles, "wall_time": time.perf_counter() - t0,
            "elements": problem.n_element, "final_kinetic_over_internal": ke / ie if ie > 0 else None}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("direction", choices=["warp", "weft"])
    ap.add_argument("--lengths", nargs="*", type=float)
    args = ap.parse_args()
    out = ROOT / "studies" / "out"
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for L in args.lengths or MEASURED[args.direction]:
        r = run_length(args.direction, int(L))
        rows.append(r)
        print(json.dumps(r), flush=True)
        (out / f"cantilever_3weave_{args.direction}.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
