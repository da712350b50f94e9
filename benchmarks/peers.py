"""fdeck beside CalculiX's explicit solver on the same block, measured here (`python benchmarks/bench.py --peers`).

Installs nothing: where `ccx` (Debian's calculix-ccx) is on PATH, the same steel block (1 mm cubes, bottom face
fixed, top face pressed, finite strain: NLGEOM) runs in CalculiX explicit with C3D8 and C3D8R and in fdeck with
`full` and `reduced`, on 1 and 2 threads, at 10 000 and 100 000 elements. Each configuration runs twice, a short run
and a long one, and the cost per element-cycle is the difference of the two divided by the difference of their cycle
counts and by the element count: reading the input, building the model, compiling (numba's cache is warm) and writing
results cancel out. All runs of one size are interleaved (every configuration's short and long run once per round,
rounds repeated), so a drift of the machine's load falls on every code alike; the table gives the median over the
rounds and the spread (max - min over median of the long runs) as the noise.

Cycles: CalculiX picks its own stable increment (its DIRECT option hangs in 2.20 on this machine) and prints it;
its cycle count is the step duration over that increment, rounded up (its log confirms the last, shortened
increment); fdeck's come from summary.json. Both the wall time and the processor time of the child (user +
system, from `resource`) are recorded: on a machine shared with other work the processor time of a one-thread run is
the steadier figure, the wall time is what a user waits for.

Writes benchmarks/peers.json; `--report` prints the markdown table the README shows.
"""

from __future__ import annotations

import json
import math
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
STEEL = {"E": 210000.0, "nu": 0.3, "rho": 7.85e-9}  # MPa, -, t/mm^3
SIZES = {10_000: (20, 20, 25), 100_000: (40, 50, 50)}
PAIRS = (("C3D8", "full"), ("C3D8R", "reduced"))
CYCLES = {10_000: (20, 120), 100_000: (6, 30)}  # short, long: ccx's increments (C3D8 takes half as many)
# fdeck's cycles per ccx increment: its cycle is 10-30x cheaper, and the long run must outlast the start-up's noise
# (loading numba's cache, about 1-3 s) by far: at 10x the difference of a reduced run was below that noise
FDECK_SCALE = {10_000: 40, 100_000: 20}


CCX_DT = 6.38e-8  # [s] about CalculiX's Courant step of this block (it selects its own and reports it)


def _ccx_increments(stdout: str, duration: float) -> int:
    """CalculiX's increment count: it prints the increment it selected once (a fixed Courant step for the whole
    step), then cuts the last increment to the step's end and says so; 0 if the log holds no selected increment."""
    for line in stdout.splitlines():
        if "SELECTED time increment" in line:
            dt = float(line.split(":")[-1])
            return math.ceil(duration / dt - 1e-9)
    return 0


def _node(i, j, k, nx, ny):
    return 1 + i + (nx + 1) * (j + (ny + 1) * k)


def ccx_input(div, etype: str, cycles: int) -> str:
    """CalculiX input of the block: `cycles` stable increments of about 6.4e-8 s (the Courant step of 1 mm steel)."""
    nx, ny, nz = div
    out = ["*NODE, NSET=NALL"]
    for k in range(nz + 1):
        for j in range(ny + 1):
            out += [f"{_node(i, j, k, nx, ny)}, {i:.1f}, {j:.1f}, {k:.1f}" for i in range(nx + 1)]
    out.append(f"*ELEMENT, TYPE={etype}, ELSET=EALL")
    e = 1
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                c = [_node(i, j, k, nx, ny), _node(i + 1, j, k, nx, ny), _node(i + 1, j + 1, k, nx, ny),
                     _node(i, j + 1, k, nx, ny)]
                c += [n + (nx + 1) * (ny + 1) for n in c]
                out.append(f"{e}, " + ", ".join(map(str, c)))
                e += 1
    for name, k in (("BOT", 0), ("TOP", nz)):
        ids = [_node(i, j, k, nx, ny) for j in range(ny + 1) for i in range(nx + 1)]
        out.append(f"*NSET, NSET={name}")
        out += [", ".join(map(str, ids[a:a + 16])) for a in range(0, len(ids), 16)]
    dt = CCX_DT
    out += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{STEEL['E']}, {STEEL['nu']}", "*DENSITY", f"{STEEL['rho']}",
            "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL", "*BOUNDARY", "BOT, 1, 3",
            "*STEP, NLGEOM, INC=100000000", "*DYNAMIC, EXPLICIT", f"{dt:.6e}, {cycles * dt:.6e}",
            "*BOUNDARY", f"TOP, 3, 3, {-1000.0 * cycles * dt:.6e}",  # 1000 mm/s on average, as fdeck's deck
            "*NODE FILE, FREQUENCY=100000000", "U", "*END STEP"]
    return "\n".join(out) + "\n"


def fdeck_deck(div, form: str, cycles: int) -> dict:
    return {
        "title": "peer block",
        "mesh": {"block": {"size": [float(d) for d in div], "divisions": list(div)}},
        "materials": {"steel": {"type": "linear_elastic", "density": STEEL["rho"], "youngs_modulus": STEEL["E"],
                                "poisson_ratio": STEEL["nu"]}},
        "sections": [{"material": "steel", "formulation": form}],
        "boundary": [{"type": "fixed", "nodes": "zmin"},
                     {"type": "velocity", "nodes": "zmax", "dofs": ["z"], "value": -1000.0, "amplitude": "constant"}],
        "steps": [{"duration": 1.0, "max_cycles": cycles}],
        "output": {"frames": 1, "history_points": 2, "formats": ["vtu"]},
    }


def _timed(cmd, env, cwd) -> tuple[float, float, subprocess.CompletedProcess]:
    """(wall s, child processor s, completed process)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc


def run_ccx(work: Path, div, etype: str, cycles: int, threads: int) -> dict:
    job = f"{etype}_{cycles}"
    (work / f"{job}.inp").write_text(ccx_input(div, etype, cycles))
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), NUMBER_OF_CPUS=str(threads),
               CCX_NPROC_RESULTS=str(threads), CCX_NPROC_STIFFNESS=str(threads))
    wall, cpu, proc = _timed(["ccx", "-i", job], env, work)
    n = _ccx_increments(proc.stdout, cycles * CCX_DT)
    return {"wall": wall, "cpu": cpu, "cycles": n, "ok": proc.returncode == 0 and n > 0}


def run_fdeck(work: Path, div, form: str, cycles: int, threads: int) -> dict:
    import yaml

    deck = work / f"{form}_{cycles}.yaml"
    deck.write_text(yaml.safe_dump(fdeck_deck(div, form, cycles)))
    out = work / f"{form}_{cycles}_out"
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    wall, cpu, proc = _timed([sys.executable, "-m", "fdeck.cli", "run", str(deck), "-o", str(out)], env, work)
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    return {"wall": wall, "cpu": cpu, "cycles": summary.get("cycles", 0), "ok": proc.returncode in (0, 3)}


def measure(rounds: int = 2, sizes=(10_000, 100_000)) -> dict:
    rows = []
    for n_el in sizes:
        div = SIZES[n_el]
        short, long_ = CYCLES[n_el]
        configs = [(code, elem, t) for t in (1, 2) for pair in PAIRS for code, elem in zip(("ccx", "fdeck"), pair)]
        samples: dict[tuple, list] = {c: [] for c in configs}
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            run_fdeck(work, div, "reduced", 3, 1)  # warm numba's cache before anything is timed
            for r in range(rounds):
                for cfg in configs:
                    code, elem, t = cfg
                    scale = FDECK_SCALE[n_el] if code == "fdeck" else 1
                    fn = run_ccx if code == "ccx" else run_fdeck
                    a = fn(work, div, elem, short * scale, t)
                    b = fn(work, div, elem, long_ * scale, t)
                    samples[cfg].append((a, b))
                    print(f"round {r} {n_el} el {code:5s} {elem:7s} {t} thr: "
                          f"{1e6 * (b['cpu'] - a['cpu']) / max(b['cycles'] - a['cycles'], 1) / n_el:.3f} us (cpu) "
                          f"{1e6 * (b['wall'] - a['wall']) / max(b['cycles'] - a['cycles'], 1) / n_el:.3f} us (wall)"
                          f" cycles {a['cycles']}/{b['cycles']} ok {a['ok'] and b['ok']}", flush=True)
        for (code, elem, t), pairs in samples.items():
            ok = all(a["ok"] and b["ok"] and b["cycles"] > a["cycles"] for a, b in pairs)
            per = {k: [(b[k] - a[k]) / (b["cycles"] - a["cycles"]) / n_el * 1e6 for a, b in pairs] for k in
                   ("wall", "cpu")} if ok else {"wall": [], "cpu": []}
            longs = [b["wall"] for _, b in pairs]
            rows.append({"code": code, "element": elem, "threads": t, "elements": n_el, "ok": ok,
                         "cycles": [pairs[0][0]["cycles"], pairs[0][1]["cycles"]],
                         "us_wall": statistics.median(per["wall"]) if ok else None,
                         "us_cpu": statistics.median(per["cpu"]) if ok else None,
                         "noise": (max(longs) - min(longs)) / statistics.median(longs)})
    ccx = subprocess.run(["ccx", "-v"], capture_output=True, text=True).stdout.strip().splitlines()
    return {"machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                        "load_average_at_end": os.getloadavg()},
            "ccx": next(("CalculiX " + line.split("Version")[-1].strip() for line in ccx if "Version" in line),
                        "CalculiX (version unknown)"), "rounds": rounds, "rows": rows}


def report(result: dict) -> str:
    """Markdown: per size and thread count, CalculiX's element beside fdeck's, cost per element-cycle and ratio."""
    by = {(r["code"], r["element"], r["threads"], r["elements"]): r for r in result["rows"]}
    lines = [f"Measured with {result['ccx']}, {result['rounds']} interleaved rounds, on "
             f"{result['machine']['cpu_count']} cores ({result['machine']['platform']}).", "",
             "| elements | threads | CalculiX element | µs/el-cycle (wall) | fdeck | µs/el-cycle (wall) | ratio (wall) | "
             "ratio (processor time) | noise (ccx / fdeck) |", "|---|---|---|---|---|---|---|---|---|"]
    for n_el in sorted({r["elements"] for r in result["rows"]}):
        for t in (1, 2):
            for peer, ours in PAIRS:
                a, b = by.get(("ccx", peer, t, n_el)), by.get(("fdeck", ours, t, n_el))
                if not (a and b and a["ok"] and b["ok"]):
                    continue
                lines.append(f"| {n_el:,} | {t} | {peer} | {a['us_wall']:.2f} | {ours} | {b['us_wall']:.3f} | "
                             f"{a['us_wall'] / b['us_wall']:.1f}× | {a['us_cpu'] / b['us_cpu']:.1f}× | "
                             f"{100 * a['noise']:.0f} % / {100 * b['noise']:.0f} % |")
    return "\n".join(lines)


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="10 000 elements only")
    args = ap.parse_args(argv)
    path = HERE / "peers.json"
    if args.report:
        print(report(json.loads(path.read_text())))
        return 0
    if shutil.which("ccx") is None:
        print("ccx is not on PATH (Debian: apt install calculix-ccx): nothing to compare; no file written")
        return 0
    result = measure(args.rounds, (10_000,) if args.quick else (10_000, 100_000))
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(report(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
