"""fdeck at scale on this machine: 10^6 hexahedra and the 313 600-shell square-tube blank (not part of the tests).

Measured (each figure with the machine's load when it was taken, `os.getloadavg`):
- a block of 100 x 100 x 100 = 10^6 hexahedra (steel, 1 mm, bottom fixed, top pressed: the peer block of
  benchmarks/peers.py), `reduced` and `full`, linear elastic, a partial run of a few hundred cycles (`max_cycles`):
  peak resident memory (/usr/bin/time -v), set-up time (process wall minus the wall of the cycles: reading the deck,
  building the mesh and model, loading numba's cache, the first frame), wall per cycle and µs per element-cycle
  (summary.json);
- the same block at 50^3 = 125 000 hexahedra, so memory per element is the slope between the two sizes (the
  interpreter, numpy and numba's compiled code are the intercept);
- a plate of 560 x 560 = 313 600 `sm` shells (the full square-tube blank at 0.5 mm; the decks in decks/forming/ run
  its quarter, 78 400 shells, by symmetry), pulled along x, no tools: memory and cost of the full blank;
- the square-tube decks themselves (quarter model, tools and contact): their rows of benchmarks/forming_cost.json
  (`python benchmarks/forming_cost.py --decks square_tube_sm square_tube_ts`), copied here with the full run's
  wall **extrapolated** from `fdeck info`'s cycle estimate.
The code measured is a snapshot of HEAD (see benchmarks/forming_cost.py: uncommitted edits would recompile the
kernels inside the timed cycles); kernels are compiled by a small warm-up run first.

    python benchmarks/scale.py              # about 10 minutes on 2 idle cores
    python benchmarks/scale.py --report     # markdown of benchmarks/scale.json

Writes benchmarks/scale.json.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))  # the fdeck beside this file, not an installed one
import forming_cost as fc  # noqa: E402  (snapshot, environment and timed runs shared with the forming table)
import peers  # noqa: E402  (the peer block deck)

OUT = HERE / "scale.json"
# (name, divisions, formulation, cycles): cycles chosen so each run takes a few minutes on 2 shared cores (load ~10)
BLOCKS = (("block_1e6_reduced", (100, 100, 100), "reduced", 60), ("block_1e6_full", (100, 100, 100), "full", 30),
          ("block_125k_reduced", (50, 50, 50), "reduced", 60))
PLATE = ("plate_313600_sm", 560, 30)


def plate_deck(n: int, cycles: int) -> dict:
    """n x n `sm` shells of 0.5 mm (T300-3K), x = 0 held, x = end pulled at 1 mm/s, as the square-tube blank."""
    return {"title": "full square-tube blank, no tools",
            "mesh": {"plate": {"size": [0.5 * n, 0.5 * n], "divisions": [n, n]}},
            "materials": {"t300": {"type": "sm"}},
            "sections": [{"elements": "all", "material": "t300", "orientation": {"warp_angle": 0}}],
            "boundary": [{"type": "fixed", "nodes": "xmin", "dofs": ["x", "y", "z", "rx", "ry", "rz"]},
                         {"type": "velocity", "nodes": "xmax", "dofs": ["x"], "value": 1.0,
                          "amplitude": "constant"}],
            "steps": [{"duration": 1.0, "max_cycles": cycles, "mass_scaling": {"factor": 10}}],
            "output": {"frames": 1, "history_points": 2, "formats": ["vtu"]}}


def one(work: Path, name: str, deck: dict, env: dict, elements: int) -> dict:
    import yaml

    path = work / f"{name}.yaml"
    path.write_text(yaml.safe_dump(deck))
    out = work / f"{name}_out"
    load_before = fc.load()
    wall, rss, proc = fc.timed_run([sys.executable, "-m", "fdeck.cli", "run", str(path), "-o", str(out)], env, work)
    s = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else None
    row = {"name": name, "elements": elements, "exit_code": proc.returncode, "process_wall": wall,
           "process_cpu": proc.cpu_seconds,
           "peak_rss_mib": rss, "load_before": load_before, "load_after": fc.load()}
    if s:
        row |= {"cycles": s["cycles"], "loop_wall": s["wall_time"], "setup_wall": wall - s["wall_time"],
                "wall_per_cycle": s["wall_time"] / max(s["cycles"], 1), "us_per_element_cycle":
                s["us_per_element_cycle"], "us_per_element_cycle_elements_only":
                s["us_per_element_cycle_elements_only"], "dt_min": s["dt_min"], "nodes": s["nodes"]}
    else:
        row["stderr_tail"] = proc.stderr[-2000:]
    print(json.dumps({k: row.get(k) for k in ("name", "cycles", "us_per_element_cycle", "setup_wall",
                                              "peak_rss_mib", "load_after")}), flush=True)
    return row


def triad_bandwidth(n: int = 20_000_000, repeats: int = 5) -> dict:
    """STREAM-like triad a = b + s c with numpy on float64 arrays of `n` (160 MB each, far beyond the caches), one
    thread: the best of `repeats` counts 3 x 8 n bytes moved (the write-allocate read of `a` not counted, as
    STREAM does). The bytes a memory-bound kernel can stream per second on one core here, [GB/s]."""
    import time

    import numpy as np

    b, c = np.ones(n), np.full(n, 2.0)
    a = np.empty(n)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.multiply(c, 3.0, out=a)
        np.add(a, b, out=a)  # two passes over a: counted as 5 x 8 n bytes below
        best = min(best, time.perf_counter() - t0)
    return {"gb_per_s": 5 * 8 * n / best / 1e9, "load": fc.load()}


def measure(threads: int, which) -> dict:
    rows = []
    with tempfile.TemporaryDirectory(prefix="fdeck_scale_") as tmp:
        work = Path(tmp)
        src, commit = fc.snapshot(work)
        env = fc.bench_env(src, threads)
        for form in ("reduced", "full"):  # compile the kernels on a tiny block before anything is timed
            one(work, f"warm_{form}", peers.fdeck_deck((4, 4, 4), form, 3), env, 64)
        one(work, "warm_sm", plate_deck(8, 3), env, 64)
        for name, div, form, cycles in BLOCKS:
            if name in which:
                rows.append(one(work, name, peers.fdeck_deck(div, form, cycles), env, div[0] * div[1] * div[2]))
        if PLATE[0] in which:
            rows.append(one(work, PLATE[0], plate_deck(PLATE[1], PLATE[2]), env, PLATE[1] ** 2))
    return {"commit": commit, "threads": threads, "rows": rows, "triad_one_thread": triad_bandwidth()}


def derived(result: dict) -> dict:
    """Memory per hexahedron: slope of peak RSS between the 125 000- and the 10^6-element reduced blocks."""
    by = {r["name"]: r for r in result["rows"]}
    a, b = by.get("block_125k_reduced"), by.get("block_1e6_reduced")
    if a and b and a.get("peak_rss_mib") and b.get("peak_rss_mib"):
        slope = (b["peak_rss_mib"] - a["peak_rss_mib"]) * 2**20 / (b["elements"] - a["elements"])
        return {"bytes_per_hexahedron_reduced": slope,
                "rss_intercept_mib": a["peak_rss_mib"] - slope * a["elements"] / 2**20}
    return {}


def report(result: dict) -> str:
    lines = [f"Commit {result['commit'][:10]}, NUMBA_NUM_THREADS={result['threads']}, {os.cpu_count()} cores.", "",
             "| run | elements | cycles measured | set-up [s] | wall per cycle [s] | µs/el-cycle | peak RSS [MiB] | "
             "load (1-min) |", "|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        if "cycles" not in r:
            lines.append(f"| {r['name']} | {r['elements']:,} | failed (exit {r['exit_code']}) ||||||")
            continue
        lines.append(f"| {r['name']} | {r['elements']:,} | {r['cycles']} | {r['setup_wall']:.0f} | "
                     f"{r['wall_per_cycle']:.3f} | {r['us_per_element_cycle']:.3f} | {r['peak_rss_mib']:.0f} | "
                     f"{r['load_before'].split()[0]}–{r['load_after'].split()[0]} |")
    tri = result.get("triad_one_thread")
    if tri:
        lines += ["", f"numpy triad, one thread: {tri['gb_per_s']:.1f} GB/s (load {tri['load'].split()[0]})."]
    d = result.get("derived", {})
    if d:
        lines += ["", f"Memory per hexahedron (`reduced`, slope of peak RSS 125 k -> 10^6): "
                      f"{d['bytes_per_hexahedron_reduced']:.0f} bytes; intercept {d['rss_intercept_mib']:.0f} MiB."]
    tube = result.get("square_tube", [])
    if tube:
        lines += ["", "Square tube decks (quarter model, 78 400 shells, tools and contact), from "
                      "benchmarks/forming_cost.json:", "", fc.report({"rows": tube})]
    return "\n".join(lines)


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = [b[0] for b in BLOCKS] + [PLATE[0]]
    ap.add_argument("--runs", nargs="*", default=names, choices=names)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--report", action="store_true")
    args = ap.parse_args(argv)
    if args.report:
        print(report(json.loads(OUT.read_text())))
        return 0
    result = measure(args.threads, set(args.runs))
    if OUT.exists():  # keep rows of runs not repeated this time (of the same commit)
        old = json.loads(OUT.read_text())
        old["rows"] = [r for r in old["rows"] if old.get("commit") == result["commit"]]
        done = {r["name"] for r in result["rows"]}
        result["rows"] = [r for r in old["rows"] if r["name"] not in done] + result["rows"]
    result["derived"] = derived(result)
    costs = fc.OUT
    if costs.exists():
        result["square_tube"] = [r for r in json.loads(costs.read_text())["rows"] if r["deck"].startswith("square")]
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    print(report(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
