"""The fitted bending laws of 3WEAVE against [P]'s cantilever measurements: one picture from `fdeck identify`'s results.

    fdeck identify decks/studies/identify_3weave_warp.yaml -o results/identify_3weave_warp
    fdeck identify decks/studies/identify_3weave_weft.yaml -o results/identify_3weave_weft
    fdeck identify decks/studies/identify_3weave_weft_bilinear.yaml -o results/identify_3weave_weft_bilinear
    python studies/cantilever_fit.py results/identify_3weave_warp results/identify_3weave_weft \
        results/identify_3weave_weft_bilinear docs/img/cantilever_3weave_fit.png
    fdeck identify decks/studies/identify_3weave_bending.yaml -o results/identify_3weave_bending   # both strips
    python studies/cantilever_fit.py results/identify_3weave_bending docs/img/cantilever_3weave_preset.png --table

Each result folder's identify.json holds, per data point, the measured tip deflection and the model's at the fitted
parameters (the strip length is the point's name, L<mm>, or warp_L<mm> / weft_L<mm> in a joint fit of both). The picture draws the measurements as markers and each
fit's model answers as a line through its points, labelled with the fitted values and the rms relative residual;
`--table` prints the same as a markdown table.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def load(folder: Path) -> list[dict]:
    """One entry per strip of the fit in ``folder``: a fit of one strip (points named L<mm>) or a joint fit of
    both (points named warp_L<mm>, weft_L<mm>: decks/studies/identify_3weave_bending.yaml), each with its lengths,
    points, the parameters of its fibre family as a label, and its own rms relative residual."""
    import math

    res = json.loads((Path(folder) / "identify.json").read_text())
    whole = "warp" if "warp" in res["identify"] else "weft"
    out = []
    for strip in ("warp", "weft"):
        points = [p for p in res["points"]
                  if p["name"].split("_")[0] == strip or ("_" not in p["name"] and strip == whole)]
        if not points:
            continue
        pars = [p for p in res["parameters"] if f".{strip}." in p["path"]] or res["parameters"]
        label = ", ".join(f"{p['path'].split('effects.0.')[-1].split('fibre_bending.')[-1]} = {p['value']:.4g}"
                          for p in pars)
        rms = math.sqrt(sum((p["model"] / p["measured"] - 1) ** 2 for p in points) / len(points))
        out.append({"strip": strip, "points": points, "label": label, "rms_residual": rms,
                    "lengths": [float(p["name"].split("_")[-1].lstrip("L")) for p in points]})
    return out


def table(results: list[dict]) -> str:
    rows = ["| strip | fitted | L [mm] | measured [mm] | model [mm] | model / measured - 1 |",
            "|---|---|---|---|---|---|"]
    for r in results:
        for L, p in zip(r["lengths"], r["points"]):
            rows.append(f"| {r['strip']} | {r['label']} | {L:g} | {-p['measured']:.2f} | {-p['model']:.2f} | "
                        f"{100 * (p['model'] / p['measured'] - 1):+.1f} % |")
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("png", type=Path)
    ap.add_argument("--table", action="store_true")
    args = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results = [r for f in args.folders for r in load(f)]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    colours = {"warp": "tab:blue", "weft": "tab:red"}
    shown = set()
    styles = iter(["-", "--", ":", "-."] * 4)
    for r in results:
        c = colours[r["strip"]]
        if r["strip"] not in shown:
            ax.plot(r["lengths"], [-p["measured"] for p in r["points"]], "o", color=c,
                    label=f"{r['strip']}, [P] measured")
            shown.add(r["strip"])
        ax.plot(r["lengths"], [-p["model"] for p in r["points"]], next(styles), color=c,
                label=f"{r['strip']}: {r['label']} (rms {100 * r['rms_residual']:.0f} %)")
    ax.set_xlabel("free length L [mm]")
    ax.set_ylabel("tip deflection [mm]")
    ax.set_title("3WEAVE strips under their own weight: fitted fibre bending laws (static, ans, 10 mm)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    args.png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.png, dpi=120)
    print(f"wrote {args.png}")
    if args.table:
        print(table(results))


if __name__ == "__main__":
    main()
