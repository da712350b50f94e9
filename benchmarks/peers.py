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

At 100 000 elements one round takes several minutes (a C3D8 increment of CalculiX costs about 0.8 s there), so
rounds can be gathered by separate invocations: each row keeps its per-round samples, and `--add` pools the rounds
of this invocation with those already in peers.json for the same configuration (the code measured, a snapshot of
HEAD as in benchmarks/forming_cost.py, must be the same commit, or the old rounds are dropped). `--sizes 100000`
measures one size and keeps the rows of the other in peers.json. The load average before and after each
configuration's pair of runs is recorded with it: on a shared machine the figures are only as steady as the load.

    python benchmarks/bench.py --peers                                   # 10 k and 100 k, 2 rounds
    python benchmarks/peers.py --sizes 100000 --rounds 1 [--add]         # one round of 100 k, pooled with --add
    python benchmarks/peers.py --sizes 100000 --threads 1 --rounds 1     # one thread count only
    python benchmarks/peers.py --report

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
# (loading numba's cache, about 1-3 s) by far: at 10x the difference of a reduced run was below that noise. At
# 100 000 elements 5x gives as many element-cycles per increment as 40x at 10 000 (a 100 k round then fits in about
# 7 minutes on one loaded thread)
FDECK_SCALE = {10_000: 40, 100_000: 5}


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


SNAPSHOT: dict = {}  # {"src": folder of HEAD's tree, "commit": its hash} once measure() has made it


def run_fdeck(work: Path, div, form: str, cycles: int, threads: int) -> dict:
    import yaml

    deck = work / f"{form}_{cycles}.yaml"
    deck.write_text(yaml.safe_dump(fdeck_deck(div, form, cycles)))
    out = work / f"{form}_{cycles}_out"
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    if SNAPSHOT:
        env["PYTHONPATH"] = os.pathsep.join([SNAPSHOT["src"]] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    wall, cpu, proc = _timed([sys.executable, "-m", "fdeck.cli", "run", str(deck), "-o", str(out)], env, work)
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    return {"wall": wall, "cpu": cpu, "cycles": summary.get("cycles", 0), "ok": proc.returncode in (0, 3)}


def _row(code, elem, t, n_el, pairs, loads) -> dict:
    """One configuration's row from its rounds: per round the cost per element-cycle (wall and processor time)
    from the short/long difference, and the long run's wall (its spread is the noise)."""
    ok = all(a["ok"] and b["ok"] and b["cycles"] > a["cycles"] for a, b in pairs)
    samples = [{"us_wall": (b["wall"] - a["wall"]) / (b["cycles"] - a["cycles"]) / n_el * 1e6,
                "us_cpu": (b["cpu"] - a["cpu"]) / (b["cycles"] - a["cycles"]) / n_el * 1e6,
                "long_wall": b["wall"], "cycles": [a["cycles"], b["cycles"]], "load": load}
               for (a, b), load in zip(pairs, loads)] if ok else []
    return _summarise({"code": code, "element": elem, "threads": t, "elements": n_el, "ok": ok,
                       "samples": samples})


def _summarise(row: dict) -> dict:
    """Median over the row's rounds, and the noise: (max - min) / median of the long runs' wall."""
    smp = row["samples"]
    if not (row["ok"] and smp):
        return row | {"us_wall": None, "us_cpu": None, "noise": None}
    longs = [x["long_wall"] for x in smp]
    return row | {"cycles": smp[0]["cycles"], "us_wall": statistics.median(x["us_wall"] for x in smp),
                  "us_cpu": statistics.median(x["us_cpu"] for x in smp),
                  "noise": (max(longs) - min(longs)) / statistics.median(longs), "rounds": len(smp)}


def measure(rounds: int = 2, sizes=(10_000, 100_000), threads=(1, 2)) -> dict:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        try:  # the committed tree, so numba's cache (keyed on the source tree) is not invalidated by others' edits
            sys.path.insert(0, str(HERE))
            from forming_cost import snapshot

            src, commit = snapshot(work)
            SNAPSHOT.update(src=str(src), commit=commit)
        except (subprocess.CalledProcessError, FileNotFoundError):
            SNAPSHOT.clear()  # not a git checkout: measure the installed fdeck
        for n_el in sizes:
            div = SIZES[n_el]
            short, long_ = CYCLES[n_el]
            configs = [(code, elem, t) for t in threads for pair in PAIRS for code, elem in zip(("ccx", "fdeck"), pair)]
            samples: dict[tuple, list] = {c: [] for c in configs}
            loads: dict[tuple, list] = {c: [] for c in configs}
            run_fdeck(work, div, "reduced", 3, 1)  # warm numba's cache before anything is timed
            run_fdeck(work, div, "full", 3, 1)
            for r in range(rounds):
                for cfg in configs:
                    code, elem, t = cfg
                    scale = FDECK_SCALE[n_el] if code == "fdeck" else 1
                    fn = run_ccx if code == "ccx" else run_fdeck
                    before = os.getloadavg()[0]
                    a = fn(work, div, elem, short * scale, t)
                    b = fn(work, div, elem, long_ * scale, t)
                    samples[cfg].append((a, b))
                    loads[cfg].append([before, os.getloadavg()[0]])
                    print(f"round {r} {n_el} el {code:5s} {elem:7s} {t} thr: "
                          f"{1e6 * (b['cpu'] - a['cpu']) / max(b['cycles'] - a['cycles'], 1) / n_el:.3f} us (cpu) "
                          f"{1e6 * (b['wall'] - a['wall']) / max(b['cycles'] - a['cycles'], 1) / n_el:.3f} us (wall)"
                          f" cycles {a['cycles']}/{b['cycles']} ok {a['ok'] and b['ok']} load {loads[cfg][-1]}",
                          flush=True)
            rows += [_row(code, elem, t, n_el, pairs, loads[(code, elem, t)])
                     for (code, elem, t), pairs in samples.items()]
    ccx = subprocess.run(["ccx", "-v"], capture_output=True, text=True).stdout.strip().splitlines()
    return {"machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                        "load_average_at_end": os.getloadavg()},
            "ccx": next(("CalculiX " + line.split("Version")[-1].strip() for line in ccx if "Version" in line),
                        "CalculiX (version unknown)"), "rounds": rounds, "commit": SNAPSHOT.get("commit"),
            "rows": rows}


def merge(old: dict, new: dict, add: bool) -> dict:
    """Rows of configurations not measured now are kept from `old`; with `add`, rounds of the same configuration
    and commit are pooled (the old rows' samples first)."""
    keys = {(r["code"], r["element"], r["threads"], r["elements"]) for r in new["rows"]}
    kept = [r if "rounds" in r else r | {"rounds": old.get("rounds")} for r in old.get("rows", [])
            if (r["code"], r["element"], r["threads"], r["elements"]) not in keys]
    rows = []
    for r in new["rows"]:
        prev = next((o for o in old.get("rows", []) if (o["code"], o["element"], o["threads"], o["elements"]) ==
                     (r["code"], r["element"], r["threads"], r["elements"])), None)
        if add and prev and prev.get("samples") and prev.get("commit") == new["commit"] and r["ok"] and prev["ok"]:
            r = _summarise(r | {"samples": prev["samples"] + r["samples"]})
        rows.append(r | {"commit": new["commit"]})
    return new | {"rows": sorted(kept + rows, key=lambda r: r["elements"])}


def report(result: dict) -> str:
    """Markdown: per size and thread count, CalculiX's element beside fdeck's, cost per element-cycle and ratio."""
    by = {(r["code"], r["element"], r["threads"], r["elements"]): r for r in result["rows"]}
    lines = [f"Measured with {result['ccx']}, interleaved rounds (per row), on "
             f"{result['machine']['cpu_count']} cores ({result['machine']['platform']}).", "",
             "| elements | threads | CalculiX element | µs/el-cycle (wall) | fdeck | µs/el-cycle (wall) | ratio (wall) | "
             "ratio (processor time) | noise (ccx / fdeck) | rounds | load (1-min) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for n_el in sorted({r["elements"] for r in result["rows"]}):
        for t in (1, 2):
            for peer, ours in PAIRS:
                a, b = by.get(("ccx", peer, t, n_el)), by.get(("fdeck", ours, t, n_el))
                if not (a and b and a["ok"] and b["ok"]):
                    continue
                lines.append(f"| {n_el:,} | {t} | {peer} | {a['us_wall']:.2f} | {ours} | {b['us_wall']:.3f} | "
                             f"{a['us_wall'] / b['us_wall']:.1f}× | {a['us_cpu'] / b['us_cpu']:.1f}× | "
                             f"{_noise(a, b)} | {_rounds(a)} | "
                             f"{_loads(a, b)} |")
    return "\n".join(lines)


def _noise(a: dict, b: dict) -> str:
    """The two rows' spread of the long runs, or '–' when a row has one round (no spread to state)."""
    if any(r.get("rounds") == 1 for r in (a, b)):
        return "– (one round)"
    return f"{100 * a['noise']:.0f} % / {100 * b['noise']:.0f} %"


def _rounds(row: dict) -> str:
    return str(row.get("rounds") or len(row.get("samples", [])) or "–")


def _loads(*rows) -> str:
    """Range of the 1-minute load average over the rows' rounds ('–' for rows measured before it was recorded)."""
    vals = [v for r in rows for x in r.get("samples", []) for v in x["load"]]
    return f"{min(vals):.1f}–{max(vals):.1f}" if vals else "–"


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="10 000 elements only")
    ap.add_argument("--sizes", nargs="*", type=int, choices=sorted(SIZES), default=None,
                    help="element counts to measure (default both); rows of the others are kept")
    ap.add_argument("--add", action="store_true", help="pool these rounds with those in peers.json")
    ap.add_argument("--threads", nargs="*", type=int, choices=(1, 2), default=(1, 2))
    args = ap.parse_args(argv)
    path = HERE / "peers.json"
    if args.report:
        print(report(json.loads(path.read_text())))
        return 0
    if shutil.which("ccx") is None:
        print("ccx is not on PATH (Debian: apt install calculix-ccx): nothing to compare; no file written")
        return 0
    sizes = tuple(args.sizes) if args.sizes else (10_000,) if args.quick else (10_000, 100_000)
    old = json.loads(path.read_text()) if path.exists() else {}
    result = merge(old, measure(args.rounds, sizes, tuple(args.threads)), args.add)
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(report(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
