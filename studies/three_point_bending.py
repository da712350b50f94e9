"""Three-point bending of the interlock: run the variants of decks/three_point_bending/ and tabulate what each cure
buys (spurious-mode indicator, end rise) against what it costs (wall time, us per element-cycle).

    python studies/three_point_bending.py [VARIANT ...]   # default: every deck in decks/three_point_bending/
    python studies/three_point_bending.py --report        # table + pictures from existing results only
    python studies/three_point_bending.py --static DIR    # table + pictures of a finished static study, DIR from
    fdeck study decks/studies/three_point_bending_static*.yaml -o DIR
    python studies/three_point_bending.py --onset DECK OUT [--set PATH=VALUE ...]  # where the static path loses
                                                          # stability, and why (deck paths set as in a study)

Results go to results/three_point_bending/<variant>/; the table to studies/out/three_point_bending.md (rows of
variants not run this time are kept, so the 3 mm and 1 mm variants can be run separately) and the side views
(half model mirrored about mid-span, final frame) to docs/img/three_point_bending_<variant>.png.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks" / "three_point_bending"
RESULTS = ROOT / "results" / "three_point_bending"


def side_view(variant: str, out: Path) -> None:
    """Side view of a dynamic run's last frame (results/three_point_bending/<variant>/)."""
    import meshio

    frames = sorted((RESULTS / variant).glob(f"{variant}_*.vtu"))
    m = meshio.read(frames[-1])
    draw(m.points + m.point_data["displacement"], m.cells_dict["hexahedron"], variant, out)


def draw(x, hexes, variant: str, out: Path) -> None:
    """The y = 0 faces of the half model at positions x (n_node, 3) [mm], mirrored about mid-span, into out."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 2.6))
    for sign in (1, -1):  # the model is the half x >= 100; mirror it
        for c in hexes:
            face = x[c[[0, 1, 5, 4, 0]]]  # the y = 0 face: x-z outline
            ax.plot(100 + sign * (face[:, 0] - 100), face[:, 2], lw=0.3, color="k")
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    ax.set_title(variant.replace("_", " "))
    fig.tight_layout()
    fig.savefig(out, dpi=150)
    plt.close(fig)


HEADER = ["| variant | elements | spurious-mode indicator [mm] | end rise [mm] | punch force at 40 mm [N] | "
          "energy balance | cycles | wall [s] | us / element-cycle |", "|---|---|---|---|---|---|---|---|---|"]


def previous_rows(table: Path) -> dict[str, str]:
    """variant -> its row in an existing table (empty if there is none)."""
    if not table.exists():
        return {}
    rows = [r for r in table.read_text().splitlines()[len(HEADER):] if r.startswith("| ")]
    return {r.split("|")[1].strip(): r for r in rows}


def report(variants: list[str]) -> str:
    img = ROOT / "docs" / "img"
    img.mkdir(parents=True, exist_ok=True)
    out = ROOT / "studies" / "out"
    out.mkdir(parents=True, exist_ok=True)
    rows = previous_rows(out / "three_point_bending.md")
    for v in variants:
        f = RESULTS / v / "summary.json"
        if not f.exists():
            continue
        s = json.loads(f.read_text())
        bal = next((c["value"] for c in s["checks"] if c["name"] == "energy_balance"), float("nan"))
        # half model, one slice wide: the punch force on the whole 30 mm wide sample is 2 x 30 / width x the slice's
        import yaml

        width = yaml.safe_load((DECKS / f"{v}.yaml").read_text())["mesh"]["block"]["size"][1]
        force = -2.0 * (30.0 / width) * s["final"]["reaction_load_line_z"]
        rows[v] = (f"| {v} | {s['elements']} | {s['measures']['spurious_mode_indicator']:.4f} | "
                   f"{s['measures']['end_rise']:.2f} | {force:.0f} | {bal:.1e} | {s['cycles']} | "
                   f"{s['wall_time']:.0f} | {s['us_per_element_cycle']:.2f} |")
        side_view(v, img / f"three_point_bending_{v}.png")
    table = "\n".join(HEADER + list(rows.values()))
    (out / "three_point_bending.md").write_text(table + "\n")
    return table


STATIC_HEADER = ["| variant | elements | spurious-mode indicator [mm] | end rise [mm] | punch force at 40 mm [N] | "
                 "bending / internal energy | negative eigenvalues | Newton iterations | wall [s] |",
                 "|---|---|---|---|---|---|---|---|---|"]


def static_report(study_dir: Path) -> str:
    """Table of a static study's variants (three_point_bending_static*.yaml; punch force of the whole 30 mm wide
    sample from the half slice's load strip reaction, as ``report``) and the side view of each equilibrium to
    docs/img/three_point_bending_static_*."""
    import numpy as np
    import yaml

    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.study.variants import resolve

    study = json.loads((study_dir / "study.json").read_text())
    spec = Path(study["study"])
    spec = spec if spec.is_absolute() else ROOT / spec
    base = (spec.parent / study["base"]).resolve()
    base_data = yaml.safe_load(base.read_text())
    img = ROOT / "docs" / "img"
    rows = []
    for row in study["rows"]:
        if row["status"] != "completed":
            rows.append(f"| {row['name']} | {row['elements']} | {row['status']}: {row['message']} | | | | | | |")
            continue
        run = Path(row["run_dir"])
        s = json.loads((run / "summary.json").read_text())
        data = resolve(base_data, row["settings"])
        width = data["mesh"]["block"]["size"][1]
        force = -2.0 * (30.0 / width) * s["final"]["reaction_load_line_z"]
        share = s["final"].get("bending_energy", 0.0) / s["final"]["internal_energy"]
        rows.append(f"| {row['name']} | {s['elements']} | {s['measures']['spurious_mode_indicator']:.4f} | "
                    f"{s['measures']['end_rise']:.2f} | {force:.0f} | {share:.3f} | "
                    f"{s.get('negative_eigenvalues', '')} | {s['newton_iterations']} | {s['wall_time']:.0f} |")
        problem = compile_deck(Deck.model_validate(data), base.parent)
        x = np.load(run / "final_positions.npy")
        draw(x, np.asarray(problem.groups[0].conn), row["name"], img / f"three_point_bending_static_{row['name']}.png")
    return "\n".join(STATIC_HEADER + rows)


class _Unstable(Exception):
    """Raised by ``onset``'s watcher at the first increment whose tangent has a negative eigenvalue."""


def onset(deck: Path, out: Path, sets: dict | None = None, modes: int = 4, dense_limit: int = 12000) -> dict:
    """Static path of a three-point-bending deck watched increment by increment: the tangent's negative eigenvalues
    (``static.inertia``) and the elements whose law has lost strong ellipticity in the x-z slice at their centre F
    (``fabric_hyper.smallest_acoustic``, 72 directions, x-z polarisations: the slice holds y). Stops at the first
    increment with a negative eigenvalue; writes out/onset.json (per increment: load factor, stroke [mm],
    negative eigenvalues (-1 where the factorisation cannot tell), elements past ellipticity; at the onset the
    lowest eigenvalues, dense; without an onset whether the solve reached the end) and, at an onset, out/onset.png
    (elements past ellipticity at the last stable and the first unstable increment; the lowest mode drawn on the
    latter, largest entry 3 mm). ``sets``: {deck path: value} applied first. The eigenvalues are dense, so only
    up to ``dense_limit`` free dofs (the 1 mm slice has about 6 400). One element group with one fibre frame and
    one parameter set (the three-point-bending decks), checked."""
    import math

    import numpy as np
    import scipy.linalg as sla
    import yaml

    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import static
    from fdeck.physics.elements.hex8 import shape_gradients_local
    from fdeck.physics.materials.fabric_hyper import smallest_acoustic
    from fdeck.study.deck_paths import set_value

    out.mkdir(parents=True, exist_ok=True)
    data = yaml.safe_load(deck.read_text())
    for key, value in (sets or {}).items():
        set_value(data, key, value)
    problem = compile_deck(Deck.model_validate(data), deck.parent)
    sp_ = static.StaticProblem(problem)
    S = sp_.dof_pattern(sp_.pattern())
    colours, h = static.StaticProblem.colour(S), 1e-11 * sp_.size
    g = problem.groups[0]
    if len(problem.groups) != 1 or not (np.allclose(g.frame, g.frame[0]) and np.allclose(g.params, g.params[0])):
        raise SystemExit("--onset: one element group with a uniform fibre frame and material expected")
    conn, X = np.asarray(g.conn), sp_.X
    dxi = shape_gradients_local(np.zeros((1, 3)))[0]
    dNdX = np.einsum("aj,eji->eai", dxi, np.linalg.inv(np.einsum("eai,aj->eij", X[conn], dxi)))
    N = np.array([[math.cos(t), 0.0, math.sin(t)] for t in np.linspace(0.0, math.pi, 72, endpoint=False)])
    stroke = float(np.abs(sp_.x_held - X.ravel()[sp_.held]).max())
    log, states = [], []

    frame = np.asarray(g.frame)[0]  # (the decks' uniform fibre frame, rows f1, f2, f3)

    def lost(x):
        """(elements past strong ellipticity (n_el,) bool, their median warp strain, median transverse shear [deg])"""
        F = np.einsum("eai,eaj->eij", x[conn], dNdX)
        bad = smallest_acoustic(F, frame, np.asarray(g.params)[0], N, components=(0, 2)) < 0.0
        C = np.einsum("ia,eki,ekj,jb->eab", frame.T, F, F, frame.T)  # C in the fibre frame
        warp = 0.5 * np.log(C[:, 0, 0])
        shear = np.degrees(np.arcsin(C[:, 0, 2] / np.sqrt(C[:, 0, 0] * C[:, 2, 2])))
        med = (float(np.median(warp[bad])), float(np.median(np.abs(shear[bad])))) if bad.any() else (None, None)
        return bad, *med

    def watch(lam, x):
        K = sp_.tangent(x, S, colours, h)
        try:
            n_neg = static.inertia(K)
        except (ValueError, RuntimeError):  # off-diagonal pivots, a singular tangent: stability unknown
            n_neg = -1
        bad, warp, shear = lost(x)
        log.append({"load_factor": lam, "stroke": lam * stroke, "negative_eigenvalues": n_neg,
                    "past_ellipticity": int(bad.sum()), "their_median_warp_strain": warp,
                    "their_median_transverse_shear_deg": shear})
        print(f"stroke {lam * stroke:6.2f} mm: {n_neg} negative eigenvalues, {int(bad.sum())} of {len(conn)} "
              f"elements past strong ellipticity" + (f" (median warp strain {warp:.4f}, transverse shear "
                                                     f"{shear:.1f} deg)" if bad.any() else ""), flush=True)
        states.append((x.copy(), bad, K))
        del states[:-2]
        if n_neg > 0:
            raise _Unstable

    result = {"deck": str(deck), "set": sets or {}, "elements": len(conn), "increments": log}
    try:
        r = static.solve(problem, max_iterations=30, on_increment=watch)
        result["converged"], result["stopped_at_load_factor"] = r.converged, r.load_factor  # stable throughout
    except _Unstable:
        x, bad, K = states[-1]
        mode = None
        if K.shape[0] <= dense_limit:
            Kd = K.toarray()
            w, v = sla.eigh(0.5 * (Kd + Kd.T), subset_by_index=[0, modes - 1])
            result["lowest_eigenvalues"] = w.tolist()
            mode = np.zeros(X.size)
            mode[sp_.free] = v[:, 0]
            mode = mode.reshape(-1, 3)
        _draw_onset(states, conn, mode, log, out / "onset.png")
    (out / "onset.json").write_text(json.dumps(result, indent=1))
    return result


def _draw_onset(states, conn, mode, log, png: Path) -> None:
    """One panel per increment kept (the last two, y = 0 faces): elements past ellipticity (red), the lowest mode
    on the last when it is known."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.collections import PolyCollection

    faces = conn[:, [0, 1, 5, 4]]
    fig, axes = plt.subplots(len(states), 1, figsize=(8, 3.2 * len(states)))
    for ax, (x, bad, _), rec in zip(np.atleast_1d(axes), states, log[-len(states):]):
        ax.add_collection(PolyCollection(x[faces][:, :, [0, 2]], array=bad.astype(float), cmap="coolwarm",
                                         clim=(0, 1), edgecolors="0.6", linewidths=0.1))
        title = (f"stroke {rec['stroke']:.1f} mm: {rec['past_ellipticity']} elements past strong ellipticity (red), "
                 f"{rec['negative_eigenvalues']} negative eigenvalues")
        if rec is log[-1] and rec["negative_eigenvalues"] > 0 and mode is not None:
            y = x + 3.0 * mode / np.abs(mode).max()
            for f in y[faces]:
                ax.plot(f[[0, 1, 2, 3, 0], 0], f[[0, 1, 2, 3, 0], 2], lw=0.3, color="k")
            title += "; black: + the lowest mode"
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("variants", nargs="*")
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--static", type=Path, help="folder of a finished three_point_bending_static study")
    ap.add_argument("--onset", type=Path, nargs=2, metavar=("DECK", "OUT"), help="where the static path of DECK "
                    "loses stability: per increment negative eigenvalues and elements past strong ellipticity")
    ap.add_argument("--set", nargs="+", default=[], metavar="PATH=VALUE", help="with --onset: deck path = YAML value")
    args = ap.parse_args()
    if args.onset:
        import yaml

        onset(*args.onset, sets=dict((k, yaml.safe_load(v)) for k, v in (i.split("=", 1) for i in args.set)))
        return
    if args.static:
        print(static_report(args.static))
        return
    variants = args.variants or sorted(p.stem for p in DECKS.glob("*.yaml"))
    if not args.report:
        for v in variants:
            subprocess.run([sys.executable, "-m", "fdeck.cli", "run", str(DECKS / f"{v}.yaml"), "-o",
                            str(RESULTS / v)], check=False)
    print(report(variants))


if __name__ == "__main__":
    main()
