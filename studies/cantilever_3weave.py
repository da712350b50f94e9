"""Tip deflections of 3WEAVE strips under their own weight against [P]'s measurements (MODELS 6.2).

Runs decks/cantilever_3weave_{warp,weft}.yaml at every length of [P] (block length and tip set rewritten), with the
published parameters or another fibre compression ratio, and keeps every result in
studies/out/cantilever_3weave.json (keyed by direction, length and compression ratio; re-running a key replaces
it). ``--report`` writes the markdown table studies/out/cantilever_3weave.md and the plot
docs/img/cantilever_3weave.png from the stored results only.

    python studies/cantilever_3weave.py warp weft                    # published parameters, every length
    python studies/cantilever_3weave.py warp --lengths 200 --compression-ratio 0.1 1.0
    python studies/cantilever_3weave.py --report
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "studies" / "out"
STORE = OUT / "cantilever_3weave.json"
MEASURED = {
    "warp": {200: 52.71, 250: 163.15, 300: 245.72, 350: 281.17},
    "weft": {200: 5.47, 250: 13.54, 300: 29.78, 350: 49.98, 400: 103.20, 450: 184.26, 500: 296.87},
}
PUBLISHED_RATIO = 0.01  # [P]: fibre compressive rigidity 1 % of the tensile one


def run_length(direction: str, L: int, ratio: float) -> dict:
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.loader import load_file
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    data, _ = load_file(ROOT / "decks" / f"cantilever_3weave_{direction}.yaml")
    data = copy.deepcopy(data)
    block = data["mesh"]["block"]
    h_el = block["size"][0] / block["divisions"][0]  # the deck's in-plane element length
    block["size"][0] = float(L)
    block["divisions"][0] = int(round(L / h_el))
    data["mesh"]["node_sets"]["tip"]["box"] = [[L, 0, 0], [L, block["size"][1], block["size"][2]]]
    data["materials"]["3weave"]["compression_ratio"] = ratio
    t0 = time.perf_counter()
    problem = compile_deck(Deck.model_validate(data), ROOT / "decks")
    res = solver.run(problem, solver.Sink())
    h = dict(zip(res.columns, zip(*res.history)))
    ke, ie = h["kinetic_energy"][-1], h["internal_energy"][-1]
    return {"direction": direction, "length": L, "compression_ratio": ratio, "tip_deflection": -h["tip_deflection"][-1],
            "measured": MEASURED[direction][L], "status": res.status, "cycles": res.cycles,
            "wall_time": time.perf_counter() - t0, "elements": problem.n_element,
            "final_kinetic_over_internal": ke / ie if ie > 0 else None}


def load() -> list[dict]:
    return json.loads(STORE.read_text()) if STORE.exists() else []


def store(row: dict) -> None:
    key = (row["direction"], row["length"], row["compression_ratio"])
    rows = [r for r in load() if (r["direction"], r["length"], r["compression_ratio"]) != key] + [row]
    rows.sort(key=lambda r: (r["direction"], r["compression_ratio"], r["length"]))
    OUT.mkdir(parents=True, exist_ok=True)
    STORE.write_text(json.dumps(rows, indent=1) + "\n")


def report() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = load()
    ratios = sorted({r["compression_ratio"] for r in rows})
    lines = ["| strip | L [mm] | measured [mm] | " + " | ".join(
        f"model, compression {100 * c:g} % [mm]" for c in ratios) + " | wall (1 %) [s] |",
             "|---|---|---|" + "---|" * len(ratios) + "---|"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for ax, direction in zip(axes, ("warp", "weft")):
        Ls = sorted(MEASURED[direction])
        ax.plot(Ls, [MEASURED[direction][L] for L in Ls], "ko-", label="measured [P]")
        for c in ratios:
            got = {r["length"]: r for r in rows if r["direction"] == direction and r["compression_ratio"] == c}
            xs = [L for L in Ls if L in got]
            if xs:
                ax.plot(xs, [got[L]["tip_deflection"] for L in xs], "s--", label=f"fdeck, compression {100 * c:g} %")
        ax.set_title(f"3WEAVE {direction} strips under own weight")
        ax.set_xlabel("length [mm]")
        ax.set_ylabel("tip deflection [mm]")
        ax.legend(fontsize=8)
        for L in Ls:
            cells = []
            for c in ratios:
                r = next((r for r in rows if (r["direction"], r["length"], r["compression_ratio"]) ==
                          (direction, L, c)), None)
                cells.append(f"{r['tip_deflection']:.1f}" if r else "-")
            base = next((r for r in rows if (r["direction"], r["length"], r["compression_ratio"]) ==
                         (direction, L, PUBLISHED_RATIO)), None)
            wall = f"{base['wall_time']:.0f}" if base else "-"
            lines.append(f"| {direction} | {L} | {MEASURED[direction][L]:.2f} | " + " | ".join(cells) + f" | {wall} |")
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "img" / "cantilever_3weave.png", dpi=120)
    (OUT / "cantilever_3weave.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("directions", nargs="*", choices=["warp", "weft"])
    ap.add_argument("--lengths", nargs="*", type=int)
    ap.add_argument("--compression-ratio", nargs="*", type=float, default=[PUBLISHED_RATIO])
    ap.add_argument("--report", action="store_true")
    args = ap.parse_args()
    for direction in args.directions:
        for ratio in args.compression_ratio:
            for L in args.lengths or sorted(MEASURED[direction]):
                row = run_length(direction, L, ratio)
                store(row)
                print(json.dumps(row), flush=True)
    if args.report:
        report()


if __name__ == "__main__":
    main()
