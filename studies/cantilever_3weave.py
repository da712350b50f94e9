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
DECK_ELEMENT = 5.0  # in-plane element length of the decks [mm]


def run_length(direction: str, L: int, ratio: float, duration: float | None = None, alpha: float | None = None,
               element_length: float | None = None) -> dict:
    """One strip; duration [s] and mass-proportional damping alpha [1/s] override the deck's settling step (long
    hanging strips settle slowly: their first mode is overdamped by the deck's alpha)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.loader import load_file
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    data, _ = load_file(ROOT / "decks" / f"cantilever_3weave_{direction}.yaml")
    data = copy.deepcopy(data)
    block = data["mesh"]["block"]
    h_el = element_length or block["size"][0] / block["divisions"][0]  # in-plane element length (deck's: 5 mm)
    block["size"][0] = float(L)
    block["divisions"][0] = int(round(L / h_el))
    data["mesh"]["node_sets"]["tip"]["box"] = [[L, 0, 0], [L, block["size"][1], block["size"][2]]]
    data["materials"]["3weave"]["compression_ratio"] = ratio
    step = data["steps"][0]
    step["duration"] = duration or step["duration"]
    step["damping"]["mass_proportional"] = alpha or step["damping"]["mass_proportional"]
    t0 = time.perf_counter()
    problem = compile_deck(Deck.model_validate(data), ROOT / "decks")
    res = solver.run(problem, solver.Sink())
    h = dict(zip(res.columns, zip(*res.history)))
    ke, ie = h["kinetic_energy"][-1], h["internal_energy"][-1]
    return {"direction": direction, "length": L, "compression_ratio": ratio, "element_length": h_el,
            "tip_deflection": -h["tip_deflection"][-1],
            "measured": MEASURED[direction][L], "status": res.status, "cycles": res.cycles,
            "settle_duration": step["duration"], "damping_alpha": step["damping"]["mass_proportional"],
            "wall_time": time.perf_counter() - t0, "elements": problem.n_element,
            "final_kinetic_over_internal": ke / ie if ie > 0 else None}


def load() -> list[dict]:
    return json.loads(STORE.read_text()) if STORE.exists() else []


def key(r: dict) -> tuple:
    return r["direction"], r["length"], r["compression_ratio"], r.get("element_length", DECK_ELEMENT)


def store(row: dict) -> None:
    rows = [r for r in load() if key(r) != key(row)] + [row]
    rows.sort(key=key)
    OUT.mkdir(parents=True, exist_ok=True)
    STORE.write_text(json.dumps(rows, indent=1) + "\n")


def report() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    everything = load()
    rows = [r for r in everything if r.get("element_length", DECK_ELEMENT) == DECK_ELEMENT]
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
                r = next((r for r in rows if key(r)[:3] == (direction, L, c)), None)
                cells.append(f"{r['tip_deflection']:.1f}" if r else "-")
            base = next((r for r in rows if key(r)[:3] == (direction, L, PUBLISHED_RATIO)), None)
            wall = f"{base['wall_time']:.0f}" if base else "-"
            lines.append(f"| {direction} | {L} | {MEASURED[direction][L]:.2f} | " + " | ".join(cells) + f" | {wall} |")
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "img" / "cantilever_3weave.png", dpi=120)
    finer = [r for r in everything if r.get("element_length", DECK_ELEMENT) != DECK_ELEMENT]
    for r in finer:
        ref = next((b for b in rows if key(b)[:3] == key(r)[:3]), None)
        if ref:
            lines.append(f"\nMesh check: {r['direction']} {r['length']} mm, "
                         f"compression {100 * r['compression_ratio']:g} %: {r['element_length']:g} mm elements give "
                         f"{r['tip_deflection']:.1f} mm against "
                         f"{ref['tip_deflection']:.1f} mm with {DECK_ELEMENT:g} mm.")
    (OUT / "cantilever_3weave.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("directions", nargs="*", help="warp and/or weft")
    ap.add_argument("--lengths", nargs="*", type=int)
    ap.add_argument("--compression-ratio", nargs="*", type=float, default=[PUBLISHED_RATIO])
    ap.add_argument("--duration", type=float, help="settling time [s] (default: the deck's)")
    ap.add_argument("--alpha", type=float, help="mass-proportional damping [1/s] (default: the deck's)")
    ap.add_argument("--element-length", type=float, help="in-plane element length [mm] (default: the deck's 5 mm)")
    ap.add_argument("--report", action="store_true")
    args = ap.parse_args()
    if set(args.directions) - set(MEASURED):
        ap.error(f"directions are {sorted(MEASURED)}")
    for direction in args.directions:
        for ratio in args.compression_ratio:
            for L in args.lengths or sorted(MEASURED[direction]):
                row = run_length(direction, L, ratio, args.duration, args.alpha, args.element_length)
                store(row)
                print(json.dumps(row), flush=True)
    if args.report:
        report()


if __name__ == "__main__":
    main()
