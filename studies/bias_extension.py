"""Bias extension of 3WEAVE: central shear angle against the pin-jointed net, and force against clamp travel.

    python studies/bias_extension.py            # runs decks/bias_extension_3weave*.yaml, then reports
    python studies/bias_extension.py --report   # report from results/ only
    python studies/bias_extension.py --report --study results/bias_extension_formulations  # F-bar and ans_tbar

Writes studies/out/bias_extension.md, docs/img/bias_extension.png and docs/img/bias_extension_shear_map.png.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = {"bias_extension_3weave": "diagonal W/6 (11.78 mm edges)",
         "bias_extension_3weave_fine": "diagonal W/20 (3.53 mm)"}


def study_runs(folder: Path) -> dict[str, Path]:
    """Label -> run folder of every variant of a `fdeck study` of these decks, e.g.
    decks/studies/bias_extension_formulations.yaml: F-bar and `ans_tbar` on both meshes. From study.json's completed
    rows; a study stopped before it wrote study.json is read from its run folders (the frame series carries the
    variant's name), partial runs included: the table leaves out what a run has not reached."""
    import json

    def label(settings: dict) -> str:
        fine = "n20" in settings.get("file", settings.get("mesh.file", ""))
        form = settings.get("formulation", settings.get("sections.0.formulation", "fbar"))
        return f"{form}, {CASES['bias_extension_3weave_fine' if fine else 'bias_extension_3weave']}"

    if (folder / "study.json").is_file():
        rows = json.loads((folder / "study.json").read_text())["rows"]
        return {label(r["settings"]): Path(r["run_dir"]) for r in rows if r["status"] == "completed"}
    runs = {}
    for pvd in folder.glob("runs/*/*.pvd"):  # series name: file=bias_w100_n6,formulation=fbar
        runs[label(dict(kv.split("=", 1) for kv in pvd.stem.split(",")))] = pvd.parent
    order = [f"{f}, {m}" for m in CASES.values() for f in ("fbar", "ans_tbar")]
    return dict(sorted(runs.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else len(order)))


def report(runs: dict[str, Path] | None = None) -> str:
    """Central shear angle against clamp travel for each run (label -> folder holding history.csv; default the two
    shipped decks' results/ folders); writes studies/out/bias_extension.md and docs/img/bias_extension.png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fdeck.io.history import read_history

    if runs is None:
        runs = {f"fbar, {v}": ROOT / "results" / k for k, v in CASES.items()}
    hist = {label: read_history(d / "history.csv") for label, d in runs.items() if (d / "history.csv").exists()}
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    lines = ["| clamp travel [mm] | pin-jointed [deg] | " + " | ".join(f"simulated, {k} [deg]" for k in hist) + " |"]
    lines.append("|" + "---|" * (lines[0].count("|") - 1))
    for d in (5, 10, 15, 20, 25, 30, 35, 40):
        row = [f"{d}"]
        first = next(iter(hist.values()))
        row.append(f"{np.interp(d, first['clamp_travel'], first['pin_jointed_shear_angle']):.1f}")
        for h in hist.values():  # a partial run (an interrupted study) leaves the travel it did not reach out
            reached = d <= h["clamp_travel"].max() + 1e-3  # within a micron of the travel asked
            row.append(f"{np.interp(d, h['clamp_travel'], h['central_shear_angle']):.1f}" if reached else "–")
        lines.append("| " + " | ".join(row) + " |")
    for k, h in hist.items():
        a1.plot(h["clamp_travel"], h["central_shear_angle"], label=f"fdeck, {k}")
        a2.plot(h["clamp_travel"], h["reaction_GRIP_HIGH_y"], label=f"fdeck, {k}")
    h = next(iter(hist.values()))
    a1.plot(h["clamp_travel"], h["pin_jointed_shear_angle"], "k--", label="pin-jointed net")
    a1.set_xlabel("clamp travel [mm]")
    a1.set_ylabel("central shear angle [deg]")
    a1.legend()
    a2.set_xlabel("clamp travel [mm]")
    a2.set_ylabel("force [N]")
    a2.set_yscale("log")
    a2.legend()
    fig.tight_layout()
    (ROOT / "docs" / "img").mkdir(parents=True, exist_ok=True)
    fig.savefig(ROOT / "docs" / "img" / "bias_extension.png", dpi=130)
    table = "\n".join(lines)
    (ROOT / "studies" / "out").mkdir(parents=True, exist_ok=True)
    (ROOT / "studies" / "out" / "bias_extension.md").write_text(table + "\n")
    return table


def shear_map(case: str = "bias_extension_3weave_fine") -> None:
    """docs/img/bias_extension_shear_map.png: the in-plane shear angle of every element at 20 mm and 40 mm of clamp
    travel, drawn on the deformed top face (the three zones of the pin-jointed net show as plateaus)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import meshio
    from matplotlib.collections import PolyCollection

    frames = sorted((ROOT / "results" / case).glob(f"{case}_*.vtu"))
    if not frames:
        return
    picks = [frames[len(frames) // 2], frames[-1]]
    fig, axes = plt.subplots(1, 2, figsize=(8, 5.5))
    for ax, f in zip(axes, picks):
        m = meshio.read(f)
        x = m.points + m.point_data["displacement"]
        hexes = m.cells_dict["hexahedron"]
        angle = m.cell_data_dict["shear_angle"]["hexahedron"]
        top = x[hexes[:, 4:8]][:, :, :2]  # nodes 4-7: the upper face, seen from +z
        pc = PolyCollection(top, array=angle, cmap="viridis", edgecolors="k", linewidths=0.1)
        pc.set_clim(0, 60)
        ax.add_collection(pc)
        ax.autoscale_view()
        ax.set_aspect("equal")
        travel = float(np.mean(m.point_data["displacement"][:, 1].max()))
        ax.set_title(f"clamp travel {travel:.0f} mm")
        ax.set_xlabel("x [mm]")
    axes[0].set_ylabel("y [mm]")
    fig.colorbar(pc, ax=axes, label="in-plane shear angle [deg]", shrink=0.8)
    fig.savefig(ROOT / "docs" / "img" / "bias_extension_shear_map.png", dpi=130)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--study", type=Path, help="report the variants of this `fdeck study` folder instead")
    args = ap.parse_args()
    if not args.report:
        for k in CASES:
            subprocess.run([sys.executable, "-m", "fdeck.cli", "run", str(ROOT / "decks" / f"{k}.yaml"), "-o",
                            str(ROOT / "results" / k)], check=False)
    print(report(study_runs(args.study) if args.study else None))
    shear_map()


if __name__ == "__main__":
    main()
