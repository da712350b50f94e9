"""Forming results as pictures: the formed blank seen from above (or from the side), coloured by a cell field.

    python studies/forming.py render RESULT_DIR OUT.png [--field shear_angle] [--view top|side] [--title T]
                                     [--frame K] [--limits LO HI]  # frame K (default the last), colour range
    python studies/forming.py force RESULT_DIR... OUT.png [--tool punch]   # punch force against stroke
    python studies/forming.py paths PATH_NAME RESULT_DIR... OUT.png [--labels L...]  # shear along a path, runs compared
    python studies/forming.py retable DECK RESULT_DIR OUT_DIR [--set PATH=VALUE...] [--frame K...]  # tables at frames
    python studies/forming.py mirror RESULT_DIR       # full model: how far each frame's shear is from mirror symmetry
    python studies/forming.py ellipticity RESULT_DIR FRAMES [--box B] [--preset 3weave]  # elements past the law's limit
    python studies/forming.py rows PATH_NAME RESULT_DIR... [--until S]  # element-to-element alternation along a path
    python studies/forming.py waves RESULT_DIR --at Y... [--start X0] [--frame K]  # a shell flange's profile
    python studies/forming.py energies RESULT_DIR... [--frame K]  # a hexahedral blank's strain energy by law term

`render` reads a blank frame of a run's `.pvd` (the last, or ``--frame K``; the blank is part 0, tools are other
parts), draws every element as the polygon of its nodes projected on the view plane (their 2-D convex hull),
farthest first, so the visible face of a hexahedral stack or of a shell wins, and colours it by the cell field (the
fabric laws' shear angle in degrees by default; ``--limits LO HI`` fixes the colour range, to set two runs side by
side). `force` plots the history's `tool_<tool>_force_z` against the tool's travel.
`paths` plots the final shear angle along the path `PATH_NAME` (``output.paths``) of several runs (two meshes, say)
and prints, for each run after the first, the largest difference from the first at the first run's sample points
(linear interpolation in arc length; each run's angle is its elements' own, constant per element).
`retable` writes the end-of-run tables (``output.paths``, ``fibres.csv``) of DECK as they would be at the end of
the run in RESULT_DIR, from its last frame's displacements (``--frame K``: from frame K instead, to compare runs
at the same stroke; several frames: the deck compiled once, frame K's tables in OUT_DIR_K): for a path added or
changed after an hours-long run;
``--set`` changes the deck first (deck paths as in a study, values in YAML: ``--set mesh.block.divisions=[60,25,2]``
for a study variant's mesh, ``--set output.paths.2.window=10`` for another window).
Exact for hyperelastic hexahedral blanks (their fields depend on the positions only); shells with rotational
degrees of freedom are refused (the frame does not hold their directors).
`mirror` reads a full (not halved) model's hexahedral frames and prints, per frame, the largest and 95th-percentile
|gamma(x, y) + gamma(x, -y)| over element pairs mirrored about y = 0 (the shear angle is odd under that mirror when
the warp lies along x): zero for a mirror-symmetric answer. `rows` reads an element-wise path (no ``window``) and
prints, per run, the shear of each element column the path crosses in order and the rms and largest second
difference gamma[i-1] - 2 gamma[i] + gamma[i+1] of those values up to arc length S (and beyond it): about
h^2 gamma'' for a field that is smooth on the element scale h, as large as the jumps themselves where
neighbouring element rows alternate. `ellipticity` evaluates the fabric law at each element's centre deformation
gradient (from the frame's displacements; elements whose reference centroid has |x|, y < B) and counts those
whose acoustic tensor has lost strong ellipticity (smallest eigenvalue over 48 unit directions, 36 in the fibre
plane, below zero; tangent by central differences of the point kernel). `waves` takes a shell blank's
out-of-plane profile along rows of nodes (reference y nearest to each Y, from x = X0 on) and prints its rms,
dominant wavelength and the share of its variance below three node spacings: a wave from node-scale scatter.
`energies` integrates each energy density a hexahedral blank's frame holds (``strain_energy_density`` and the
fabric law's terms ``psi_*``, point averages weighted by the points' reference volumes) over the reference volume
of each element (the engine's own, ``hex8.prepare``: distorted and collapsed hexahedra count right) and prints
one column per run [mJ] with its change from the first run: which part of the energy a refinement moves.
"""

from __future__ import annotations

import argparse
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

VIEWS = {"top": (0, 1, 2), "side": (0, 2, 1)}  # (horizontal, vertical, depth) axes of the picture


def blank_frames(result_dir) -> list[Path]:
    """Paths of the blank's (part 0) VTU frames listed in the run's .pvd, in order."""
    pvd = next(Path(result_dir).glob("*.pvd"))
    return [pvd.parent / d.get("file") for d in ET.parse(pvd).getroot().iter("DataSet") if d.get("part", "0") == "0"]


def hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points (k, 2), counter-clockwise (monotone chain)."""
    pts = sorted(set(map(tuple, np.round(points, 12))))
    if len(pts) < 3:
        return np.array(pts)

    def turn(o, a, b):  # z of (a - o) x (b - o)
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and turn(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def render(result_dir, png, field: str = "shear_angle", view: str = "top", title: str | None = None,
           limits: tuple[float, float] | None = None, frame: int = -1) -> dict:
    """Draw the blank at frame ``frame`` (default the last) coloured by ``field`` (a cell field, or a point field
    drawn as the largest value at each cell's nodes, e.g. ``wrinkle``); returns {min, max, mean} of the field
    over the drawn cells. ``limits``: the colour range (default the field's), to set two runs side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import meshio
    from matplotlib.collections import PolyCollection

    mesh = meshio.read(blank_frames(Path(result_dir))[frame])
    if field not in mesh.cell_data and field in mesh.point_data:  # a nodal field: the largest at each cell's nodes
        from fdeck.run import cell_max

        values = np.asarray(mesh.point_data[field], float).reshape(len(mesh.points), -1)[:, 0]
        mesh.cell_data[field] = [cell_max(values, {b.type: b.data}) for b in mesh.cells]
    if field not in mesh.cell_data:
        raise SystemExit(f"render: no field '{field}' in the frame; it has cell fields {sorted(mesh.cell_data)} and "
                         f"point fields {sorted(mesh.point_data)}")
    x = mesh.points + (mesh.point_data["displacement"] if "displacement" in mesh.point_data else 0.0)
    h, v, d = VIEWS[view]
    polys, values, depth = [], [], []
    for k, block in enumerate(mesh.cells):
        data = mesh.cell_data[field][k]
        data = np.asarray(data, float).reshape(len(block.data), -1)[:, 0]
        for conn, val in zip(block.data, data):
            p = x[conn]
            polys.append(hull(p[:, [h, v]]))
            values.append(val)
            depth.append(p[:, d].mean())
    order = np.argsort(depth)  # farthest first: the visible side is drawn last
    values = np.asarray(values)[order]
    fig, ax = plt.subplots(figsize=(6.4, 5.4))
    coll = PolyCollection([polys[i] for i in order], array=values, cmap="viridis", edgecolors="k", linewidths=0.1)
    if limits is not None:
        coll.set_clim(*limits)
    ax.add_collection(coll)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("xyz"[h] + " [mm]")
    ax.set_ylabel("xyz"[v] + " [mm]")
    fig.colorbar(coll, ax=ax, label=field.replace("_", " ") + (" [deg]" if "angle" in field else ""))
    ax.set_title(title or Path(result_dir).name)
    fig.tight_layout()
    Path(png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=130)
    plt.close(fig)
    finite = values[np.isfinite(values)]
    return {"min": float(finite.min()), "max": float(finite.max()), "mean": float(finite.mean())} if len(finite) \
        else {}


def waves(result_dir, at, start: float, frame: int = -1, tol: float = 0.1) -> list[dict]:
    """Out-of-plane profile of the blank along reference lines y = a (a in ``at``; the nearest row of nodes) from
    x = ``start`` on, at frame
    ``frame``: per line the nodes' current z less its straight-line fit, its rms and peak-to-peak [mm], the
    dominant wavelength [mm] (largest Fourier component) and the share of the variance at wavelengths shorter than
    three node spacings (about 0 for a wave resolved by many nodes, 1 for a zig-zag from node to node, about 1/3
    for nodes scattered at random). For a flange held between tools: tells a wave from element-scale rattling,
    which the wrinkle indicator cannot (a wave longer than about 2R scores little, a zig-zag of any amplitude
    scores it)."""
    import meshio

    mesh = meshio.read(blank_frames(Path(result_dir))[frame])
    X = mesh.points
    x = X + mesh.point_data["displacement"]
    out = []
    for a in at:
        a = X[np.argmin(np.abs(X[:, 1] - a)), 1]  # the row of nodes nearest to the line asked for
        sel = np.where((np.abs(X[:, 1] - a) < tol) & (X[:, 0] >= start))[0]
        if len(sel) < 4:
            raise SystemExit(f"waves: {len(sel)} nodes at y = {a:g} mm from x = {start:g} mm on: too few for a profile")
        sel = sel[np.argsort(X[sel, 0])]
        s, z = X[sel, 0], x[sel, 2]
        step = np.diff(s)
        if np.ptp(step) > 1e-6 * step.mean() or step.min() <= 0.0:  # a stack of layers, or a graded mesh
            raise SystemExit(f"waves: the nodes at y = {a:g} mm are not one evenly spaced row (a shell blank's "
                             "mid-surface is; a hexahedral stack is not)")
        dz = z - np.polyval(np.polyfit(s, z, 1), s)
        n = len(dz)
        rms = float(np.sqrt(np.mean(dz**2)))
        power = np.abs(np.fft.rfft(dz)) ** 2
        flat = rms <= 1e-12 * (s[-1] - s[0])  # a straight line: no wavelength to speak of
        k = 1 + int(np.argmax(power[1:]))
        short = 3 * np.arange(len(power)) > n  # wavelength n h / k below three spacings h
        out.append({"y": float(a), "nodes": n, "rms": rms, "peak_to_peak": float(np.ptp(dz)),
                    "wavelength": np.nan if flat else float(n * step.mean() / k),
                    "short_share": np.nan if flat else float(power[short].sum() / power[1:].sum())})
    return out


def force(result_dirs, png, tool: str = "punch") -> None:
    """Force of ``tool`` on the blank (z component, sign so that pressing is positive) against its travel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fdeck.io.history import read_history

    fig, ax = plt.subplots(figsize=(6, 4))
    for r in result_dirs:
        hist = read_history(Path(r) / "history.csv")
        ax.plot(-hist[f"tool_{tool}_displacement_z"], -hist[f"tool_{tool}_force_z"], label=Path(r).name)
    ax.set_xlabel(f"{tool} travel [mm]")
    ax.set_ylabel(f"{tool} force [N]")
    ax.legend()
    fig.tight_layout()
    fig.savefig(png, dpi=130)
    plt.close(fig)


def read_path(result_dir, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(arc length [mm], shear angle [deg]) of ``path_<name>.csv`` in a result folder."""
    data = np.genfromtxt(Path(result_dir) / f"path_{name}.csv", delimiter=",", names=True)
    return data["arc_length"], data["shear_angle"]


def paths(name: str, result_dirs, png, labels=None) -> list[float]:
    """Plot the shear angle along path ``name`` for each run (legend: ``labels``, default the folder names);
    returns max |angle - first run's| per other run [deg], at the first run's samples."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = labels or [Path(r).name for r in result_dirs]
    s0, a0 = read_path(result_dirs[0], name)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(s0, a0, label=labels[0])
    out = []
    for r, lab in zip(result_dirs[1:], labels[1:]):
        s, a = read_path(r, name)
        out.append(float(np.abs(np.interp(s0, s, a) - a0).max()))
        ax.plot(s, a, label=f"{lab} (max diff {out[-1]:.2f} deg)")
    ax.set_xlabel(f"arc length along {name} [mm]")
    ax.set_ylabel("shear angle [deg]")
    ax.legend()
    fig.tight_layout()
    fig.savefig(png, dpi=130)
    plt.close(fig)
    return out


def element_rows(result_dir, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(arc length [mm] of the first sample in each element column, its shear angle [deg]) along the element-wise
    path ``name``: one value per column of elements crossed, in path order. A column is a run of consecutive
    samples with the same value (a through-thickness average is one value per column; the `element` column of the
    table names the element at the sample's reference point, which on a layer interface alternates between the
    layers). Two neighbouring columns with exactly the same shear merge (the rest state, an exactly symmetric
    zone): the measure is for deformed blanks."""
    s, g = read_path(result_dir, name)
    first = np.r_[True, g[1:] != g[:-1]]
    return s[first], g[first]


def rows(name: str, result_dir, until: float = np.inf, columns=None) -> tuple[float, float, float]:
    """(rms, largest |second difference| of the per-element shear [deg] up to arc length ``until``, rms beyond);
    ``columns``: ``element_rows``'s answer when already read."""
    s, g = element_rows(result_dir, name) if columns is None else columns
    d2, mid = g[2:] - 2.0 * g[1:-1] + g[:-2], s[1:-1]
    near, far = d2[mid <= until], d2[mid > until]
    rms = lambda v: float(np.sqrt(np.mean(v ** 2))) if len(v) else float("nan")  # noqa: E731
    return rms(near), float(np.abs(near).max()) if len(near) else float("nan"), rms(far)


def retable(deck_path, result_dir, out_dir, sets: dict | None = None, frame: int | list[int] = -1) -> list[str]:
    """Write DECK's end-of-run tables at blank frame ``frame`` (default the last) of ``result_dir`` into
    ``out_dir``, after setting the deck paths ``sets`` ({path: value}); returns the file names. With a list of
    frames the deck is compiled once and frame K's tables go to ``out_dir``_K."""
    import meshio

    from fdeck.compile.problem import compile_deck
    from fdeck.deck.loader import load_file
    from fdeck.deck.model import Deck
    from fdeck.physics.measures.tables import PathTable
    from fdeck.run import write_end_tables
    from fdeck.study.deck_paths import PathError, set_value

    deck_path = Path(deck_path)
    data, _ = load_file(deck_path)
    for key, value in (sets or {}).items():
        try:
            set_value(data, key, value)
        except PathError as exc:  # a bad --set is the user's input: say which, no traceback
            raise SystemExit(f"retable: --set {key}=...: {exc}") from None
    problem = compile_deck(Deck.model_validate(data), deck_path.parent)
    if problem.rotations is not None:
        raise SystemExit("retable: shells with rotations need their directors, which the frames do not hold")
    files = blank_frames(Path(result_dir))
    paths = [PathTable(c, problem.groups, problem.X, problem.cells) for c in problem.deck.output.paths]
    names = []
    for k in frame if isinstance(frame, list) else [frame]:
        u = meshio.read(files[k]).point_data["displacement"]
        if u.shape != problem.X.shape:
            raise SystemExit(f"retable: the frame has {len(u)} nodes, the deck {len(problem.X)}: not this deck's run")
        x = problem.X + u
        for g in problem.groups:
            g.update(x, np.zeros_like(x))
        out = Path(f"{out_dir}_{k}") if isinstance(frame, list) else Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        names += write_end_tables(problem, paths, out, x)
    return names


def _reference_frames(result_dir):
    """(reference points, hex connectivity, list of frame VTU paths) of a run's blank (part 0)."""
    import meshio

    files = blank_frames(result_dir)
    m0 = meshio.read(files[0])
    return m0.points - m0.point_data["displacement"], m0.cells_dict["hexahedron"], files


def mirror(result_dir) -> list[tuple[float, float]]:
    """Per frame (largest, 95th percentile) of |gamma(x, y) + gamma(x, -y)| [deg] over mirrored element pairs."""
    import meshio

    X, conn, files = _reference_frames(result_dir)
    c = np.round(X[conn].mean(axis=1), 6)
    index = {tuple(p): i for i, p in enumerate(c)}
    pair = np.array([index.get((p[0], -p[1] if p[1] else 0.0, p[2]), -1) for p in c])
    if (pair < 0).any():
        raise SystemExit(f"mirror: {int((pair < 0).sum())} elements have no mirror image about y = 0")
    out = []
    for f in files:
        g = meshio.read(f).cell_data_dict["shear_angle"]["hexahedron"]
        a = np.abs(g + g[pair])
        out.append((float(a.max()), float(np.percentile(a, 95))))
    return out


def ellipticity(result_dir, frames, box=None, preset="3weave") -> list[tuple[int, int]]:
    """Per frame index (elements whose law lost strong ellipticity at their centre F, elements examined)."""
    import math

    import meshio

    import fdeck.cards.fabric_hyper as fc
    import fdeck.physics.materials.fabric_hyper as fh
    from fdeck.physics.elements.hex8 import shape_gradients_local

    X, conn, files = _reference_frames(result_dir)
    c = X[conn].mean(axis=1)
    sel = np.arange(len(conn)) if box is None else np.nonzero((np.abs(c[:, 0]) < box) & (c[:, 1] < box))[0]
    dxi = shape_gradients_local(np.zeros((1, 3)))[0]
    J = np.einsum("eai,aj->eij", X[conn], dxi)
    dNdX = np.einsum("aj,eji->eai", dxi, np.linalg.inv(J))
    p = fh.pack(fc.FabricHyper(type="fabric_hyper", preset=preset))
    th = np.linspace(0.0, math.pi, 36, endpoint=False)
    N = np.array([[math.cos(t), math.sin(t), 0.0] for t in th]
                 + [[math.cos(t) / math.sqrt(2), math.sin(t) / math.sqrt(2), 1 / math.sqrt(2)] for t in th[::3]])
    out = []
    for k in frames:
        x = X + meshio.read(files[k]).point_data["displacement"]
        F = np.einsum("eai,eaj->eij", x[conn[sel]], dNdX[sel])
        out.append((int((fh.smallest_acoustic(F, np.eye(3), p, N, h=1e-6) < 0.0).sum()), len(sel)))
    return out


def energies(result_dirs, frame: int = -1) -> list[dict[str, float]]:
    """Per run, {field: integral over the blank's reference volume [mJ]} of its hexahedra's energy densities [MPa]
    (``strain_energy_density`` and ``psi_*``) in frame ``frame``."""
    import meshio

    from fdeck.physics.elements.hex8 import prepare

    out = []
    for d in result_dirs:
        X, conn, files = _reference_frames(d)
        if not -len(files) <= frame < len(files):
            raise SystemExit(f"energies: {d} has frames 0..{len(files) - 1}, not {frame}")
        V0 = prepare(X, conn)["V0"]  # (n_el,) [mm^3], the engine's own reference volumes
        cells = meshio.read(files[frame]).cell_data_dict
        out.append({k: float(np.nansum(v["hexahedron"] * V0)) for k, v in cells.items()  # NaN: not this group's
                    if (k == "strain_energy_density" or k.startswith("psi_")) and "hexahedron" in v})
    return out


def parser() -> argparse.ArgumentParser:
    """The command line of this script (one subcommand per function above)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render")
    r.add_argument("result_dir")
    r.add_argument("png")
    r.add_argument("--field", default="shear_angle")
    r.add_argument("--view", default="top", choices=sorted(VIEWS))
    r.add_argument("--title")
    r.add_argument("--frame", type=int, default=-1, help="blank frame index (0 = the initial one; default the last)")
    r.add_argument("--limits", type=float, nargs=2, metavar=("LO", "HI"), help="colour range (default the field's)")
    f = sub.add_parser("force")
    f.add_argument("paths", nargs="+", help="result folders, then the PNG")
    f.add_argument("--tool", default="punch")
    p = sub.add_parser("paths")
    p.add_argument("name", help="path name (output.paths[].name)")
    p.add_argument("paths", nargs="+", help="result folders (the first is the reference), then the PNG")
    p.add_argument("--labels", nargs="+", help="legend label per result folder (default: folder names)")
    t = sub.add_parser("retable")
    t.add_argument("deck")
    t.add_argument("result_dir")
    t.add_argument("out_dir")
    t.add_argument("--set", nargs="+", action="extend", default=[], metavar="PATH=VALUE",
                   help="deck path = YAML value (repeatable)")
    t.add_argument("--frame", type=int, nargs="+", default=[-1],
                   help="blank frame index (0 = the initial one; default the last); several: OUT_DIR_K for each")
    mi = sub.add_parser("mirror")
    mi.add_argument("result_dir")
    el = sub.add_parser("ellipticity")
    el.add_argument("result_dir")
    el.add_argument("frames", help="frame indices, comma-separated (0 = the initial frame)")
    el.add_argument("--box", type=float, help="only elements with reference |x|, y below this [mm]")
    el.add_argument("--preset", default="3weave")
    wa = sub.add_parser("waves")
    wa.add_argument("result_dir")
    wa.add_argument("--at", type=float, nargs="+", required=True, help="reference y of each line [mm]")
    wa.add_argument("--start", type=float, default=0.0, help="reference x where the lines start [mm]")
    wa.add_argument("--frame", type=int, default=-1)
    en = sub.add_parser("energies")
    en.add_argument("result_dirs", nargs="+")
    en.add_argument("--frame", type=int, default=-1, help="blank frame index (default the last)")
    ro = sub.add_parser("rows")
    ro.add_argument("name", help="path name (output.paths[].name), element-wise (no window)")
    ro.add_argument("result_dirs", nargs="+")
    ro.add_argument("--until", type=float, default=np.inf, help="arc length [mm] splitting the two figures")
    return ap


def main() -> None:
    a = parser().parse_args()
    if a.cmd == "render":
        print(render(a.result_dir, a.png, a.field, a.view, a.title, a.limits, a.frame))
    elif a.cmd == "mirror":
        for k, (big, p95) in enumerate(mirror(a.result_dir)):
            print(f"frame {k}: |gamma(x, y) + gamma(x, -y)| largest {big:.1f} deg, 95th percentile {p95:.1f} deg")
    elif a.cmd == "ellipticity":
        ks = [int(v) for v in a.frames.split(",")]
        for k, (lost, n) in zip(ks, ellipticity(a.result_dir, ks, a.box, a.preset)):
            print(f"frame {k}: {lost} of {n} elements past strong ellipticity at their centre")
    elif a.cmd == "retable":
        import yaml

        sets = dict((k, yaml.safe_load(v)) for k, v in (item.split("=", 1) for item in a.set))
        print(" ".join(retable(a.deck, a.result_dir, a.out_dir, sets, a.frame if len(a.frame) > 1 else a.frame[0])))
    elif a.cmd == "rows":
        for d in a.result_dirs:
            columns = element_rows(d, a.name)
            g = columns[1]
            near, big, far = rows(a.name, d, a.until, columns)
            print(f"{d}: shear per element along {a.name} " + " ".join(f"{v:.1f}" for v in g))
            print(f"  second difference up to {a.until:g} mm: rms {near:.1f} deg, largest {big:.1f} deg; "
                  f"beyond: rms {far:.1f} deg")
    elif a.cmd == "waves":
        for w in waves(a.result_dir, a.at, a.start, a.frame):
            print(f"y = {w['y']:g} mm ({w['nodes']} nodes): rms {w['rms']:.3f} mm, peak to peak "
                  f"{w['peak_to_peak']:.3f} mm, dominant wavelength {w['wavelength']:.1f} mm, "
                  f"{100 * w['short_share']:.0f} % of the variance below 3 node spacings")
    elif a.cmd == "energies":
        runs = energies(a.result_dirs, a.frame)
        print("energy [mJ]".ljust(28) + "".join(f"{Path(d).name[-22:]:>24s}" for d in a.result_dirs))
        for k in dict.fromkeys(k for r in runs for k in r):  # every run's fields, first seen first
            ref = runs[0].get(k, np.nan)
            print(k.ljust(28) + "".join(f"{r.get(k, np.nan):13.1f} ({100 * (r.get(k, np.nan) / ref - 1):+6.1f} %)"
                                        if ref else f"{r.get(k, np.nan):24.1f}" for r in runs))
    elif a.cmd == "force":
        force(a.paths[:-1], a.paths[-1], a.tool)
    else:
        for r, d in zip(a.paths[1:-1], paths(a.name, a.paths[:-1], a.paths[-1], a.labels)):
            print(f"{r}: largest difference from {a.paths[0]} along {a.name}: {d:.2f} deg")


if __name__ == "__main__":
    main()
