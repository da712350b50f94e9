"""Performance harness (not part of the test suite).

Measures, per hexahedron formulation and material (and the two fabric shells, on square plates of as many
elements), on structured blocks of about 10 k and 100 k elements:
microseconds per element-cycle of the whole explicit cycle (elements, gather, integrator, monitors) after a
warm-up, on one thread and on all threads; element-array memory per element; cost per element-cycle from 2.5 k
to 410 k elements (linearity); numba compile time (cold cache) and cached start-up of `fdeck run` on a small deck,
and the flagship deck's compile time. Writes benchmarks/results.json.

    python benchmarks/bench.py            # full run (about 10 minutes on 2 cores)
    python benchmarks/bench.py --quick    # 10 k elements only
    python benchmarks/bench.py --report   # markdown table of benchmarks/results.json (what the README shows)
    python benchmarks/bench.py --startup  # only the start-up and compile times, into results.json
    python benchmarks/bench.py --peers    # CalculiX explicit beside fdeck on the same block (benchmarks/peers.py)
    python benchmarks/bench.py --only ans_tbar:fabric_hyper_3weave fbar:fabric_hyper_3weave \
        --results benchmarks/results_ans_tbar.json     # these cases only, side by side (both sizes, 1 and 2 threads)
    python benchmarks/bench.py --report --results benchmarks/results_ans_tbar.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))  # the fdeck beside this file, not whichever one is installed (worktrees)
ENV = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, (str(ROOT), os.environ.get("PYTHONPATH")))))
"""Environment of the `fdeck` subprocesses: they import the fdeck beside this file, as the in-process cases do."""

MATERIALS = {
    "linear_elastic": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 1.0e4, "poisson_ratio": 0.3},
    "neo_hookean": {"type": "neo_hookean", "density": 1e-9, "youngs_modulus": 1.0e4, "poisson_ratio": 0.3},
    "fabric_hyper_3weave": {"type": "fabric_hyper", "preset": "3weave"},
    "fabric_membrane_t300": {"type": "fabric_membrane", "preset": "t300_3k"},
    "fabric_membrane_t300_ts": {"type": "fabric_membrane", "preset": "t300_3k_ts"},
}
CASES = [("reduced", "linear_elastic"), ("full", "linear_elastic"), ("fbar", "linear_elastic"),
         ("fbar", "neo_hookean"), ("fbar", "fabric_hyper_3weave"), ("reduced", "fabric_hyper_3weave"),
         ("sm", "fabric_membrane_t300"), ("ts", "fabric_membrane_t300_ts"),
         ("ans_tbar", "linear_elastic"), ("ans_tbar", "fabric_hyper_3weave")]
SHELLS = ("sm", "ts", "membrane")


def shell_deck(form: str, mat: str, divisions, cycles: int) -> dict:
    """A square plate of n x n shells (n * n = the hexahedral block's element count), pulled along x."""
    n = int(round((divisions[0] * divisions[1] * divisions[2]) ** 0.5))
    return {
        "mesh": {"plate": {"size": [float(n), float(n)], "divisions": [n, n]}},
        "materials": {"m": MATERIALS[mat]},
        "sections": [{"material": "m", "formulation": form, "preset": "t300_3k"}],
        "boundary": [{"type": "fixed", "nodes": "xmin", "dofs": ["x", "y", "z", "rx", "ry", "rz"]},
                     {"type": "velocity", "nodes": "xmax", "dofs": ["x"], "value": 1.0, "amplitude": "constant"}],
        "steps": [{"duration": 1.0, "max_cycles": cycles}],
        "output": {"frames": 1, "history_points": 2},
    }


def deck(form: str, mat: str, divisions, cycles: int) -> dict:
    if form in SHELLS:
        return shell_deck(form, mat, divisions, cycles)
    return {
        "mesh": {"block": {"size": [float(d) for d in divisions], "divisions": list(divisions)}},
        "materials": {"m": MATERIALS[mat]},
        "sections": [{"material": "m", "formulation": form}],
        "boundary": [{"type": "fixed", "nodes": "zmin"},
                     {"type": "velocity", "nodes": "zmax", "dofs": ["z"], "value": -1.0, "amplitude": "constant"}],
        "steps": [{"duration": 1.0, "max_cycles": cycles}],
        "output": {"frames": 1, "history_points": 2},
    }


def measure(form: str, mat: str, divisions, cycles: int, threads: int) -> dict:
    """Time `cycles` cycles after a 3-cycle warm-up of the same problem in this process."""
    import numba
    import numpy as np

    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    numba.set_num_threads(threads)
    problem = compile_deck(Deck.model_validate(deck(form, mat, divisions, cycles)))
    # warm-up on the same problem: compiles (or loads the cache) and touches every element buffer once, so the
    # timed cycles see neither compilation nor first-touch page faults (which weigh on short runs of big models)
    problem.steps[0].max_cycles = 3
    solver.run(problem, solver.Sink())
    problem.steps[0].max_cycles = cycles
    t0 = time.perf_counter()
    res = solver.run(problem, solver.Sink())
    wall = time.perf_counter() - t0
    n = problem.n_element
    elements = sum(v for k, v in res.timings.items() if k.startswith("section"))
    mem = sum(a.nbytes for g in problem.groups for a in vars(g).values()
              if isinstance(a, np.ndarray) and a.base is None)
    mem += 12 * 8 * problem.n_node * 3  # engine's nodal arrays (x, v, forces, ...) ~ 12 (n_node, 3) arrays
    return {"formulation": form, "material": mat, "elements": n, "threads": threads, "cycles": res.cycles,
            "us_per_element_cycle": 1e6 * wall / (res.cycles * n),
            "us_per_element_cycle_elements_only": 1e6 * elements / (res.cycles * n),
            "bytes_per_element": mem / n, "status": res.status}


def _commit() -> str:
    """The commit of the measured tree (with "+changes" when it differs from it), or "" outside git."""
    r = subprocess.run(["git", "describe", "--always", "--dirty=+changes"], capture_output=True, text=True, cwd=ROOT)
    return r.stdout.strip() if r.returncode == 0 else ""


def compile_times() -> dict:
    """Cold numba compile (empty cache dir) and cached start-up of `fdeck run` on the wave-bar deck; the flagship
    deck's compile time cold and cached."""
    out = {}
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as res:
        env = dict(ENV, NUMBA_CACHE_DIR=cache)
        cmd = [sys.executable, "-m", "fdeck.cli", "run", str(ROOT / "decks" / "wave_bar.yaml"), "-o", res]
        for label in ("cold_run_s", "cached_run_s"):
            t0 = time.perf_counter()
            subprocess.run(cmd, env=env, capture_output=True, check=False)
            out[label] = time.perf_counter() - t0
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "fdeck.cli", "validate", str(ROOT / "decks" / "wave_bar.yaml")],
                       env=env, capture_output=True, check=False)
        out["cached_validate_s"] = time.perf_counter() - t0
    out["compile_time_s"] = out["cold_run_s"] - out["cached_run_s"]
    # the flagship deck (F-bar, the 3WEAVE law's packed block kernel): the compilation while its deck is compiled, as
    # the run reports it (summary.json's compile_time: mostly the law's kernel; the kernels first called in the run
    # add a few seconds to its first cycles), with a cache of its own, then cached; two whole flagship runs
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as res:
        env = dict(ENV, NUMBA_CACHE_DIR=cache)
        cmd = [sys.executable, "-m", "fdeck.cli", "run", str(ROOT / "decks" / "bias_extension_3weave.yaml"), "-o",
               res, "--overwrite"]
        summary = Path(res) / "summary.json"
        for label in ("flagship_cold_compile_s", "flagship_cached_compile_s"):
            summary.unlink(missing_ok=True)
            r = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
            if r.returncode != 0 or not summary.exists():
                raise SystemExit(f"the flagship run failed (exit {r.returncode}): {r.stderr[-2000:]}")
            out[label] = json.loads(summary.read_text())["compile_time"]
    return out


def report(result: dict) -> str:
    """Markdown: one row per formulation x material x size, 1 and 2 threads side by side, and the start-up times."""
    rows = {}
    for r in result["runs"]:
        rows.setdefault((r["formulation"], r["material"], r["elements"]), {})[r["threads"]] = r
    lines = ["| formulation | material | elements | us/element-cycle, 1 thread | 2 threads | speed-up | "
             "bytes/element |", "|---|---|---|---|---|---|---|"]
    for (form, mat, n), by in sorted(rows.items(), key=lambda kv: (kv[0][2], kv[0][0], kv[0][1])):
        one, two = by.get(1), by.get(2)
        t1 = f"{one['us_per_element_cycle']:.3f}" if one else "-"
        t2 = f"{two['us_per_element_cycle']:.3f}" if two else "-"
        sp = f"{one['us_per_element_cycle'] / two['us_per_element_cycle']:.2f}" if one and two else "-"
        mem = (one or two)["bytes_per_element"]
        lines.append(f"| {form} | {mat} | {n} | {t1} | {t2} | {sp} | {mem:.0f} |")
    sc = result.get("scaling", [])
    if sc:
        lines.append("")
        lines.append("Cost per element-cycle against model size (reduced, linear elastic, 1 thread): " + ", ".join(
            f"{r['elements']:,} el. {r['us_per_element_cycle']:.3f} us" for r in sc) + ".")
    s = result.get("startup", {})
    if s:
        lines.append("")
        lines.append(f"Start-up of `fdeck run` on the wave-bar deck: {s['cold_run_s']:.1f} s with an empty numba cache "
                     f"({s['compile_time_s']:.1f} s of compilation), {s['cached_run_s']:.1f} s cached; "
                     f"`fdeck validate` {s['cached_validate_s']:.1f} s.")
        if "flagship_cold_compile_s" in s:
            lines.append(f"The flagship deck (`decks/bias_extension_3weave.yaml`, F-bar with the 3WEAVE law): "
                         f"{s['flagship_cold_compile_s']:.1f} s of compilation while its deck is compiled (mostly "
                         f"the law's kernel) with an empty numba cache, {s['flagship_cached_compile_s']:.1f} s "
                         f"cached (`compile_time` in its summary.json).")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--report", action="store_true", help="print the markdown table of results.json and exit")
    ap.add_argument("--peers", action="store_true", help="CalculiX beside fdeck where ccx is on PATH (peers.py); "
                    "with --report, print its table")
    ap.add_argument("--only", nargs="+", metavar="FORM:MATERIAL",
                    help="measure only these cases (both sizes, 1 and 2 threads), written to --results alone")
    ap.add_argument("--results", default=str(HERE / "results.json"), help="results file (default results.json)")
    ap.add_argument("--startup", action="store_true",
                    help="measure only the start-up and compile times, into the results file's 'startup' (about "
                         "1.5 min: two wave-bar runs and two flagship runs)")
    ap.add_argument("--one", nargs=5, help=argparse.SUPPRESS)  # form mat nx,ny,nz cycles threads (subprocess)
    args = ap.parse_args()
    if args.peers:
        sys.path.insert(0, str(HERE))
        import peers

        sys.exit(peers.main(["--report"] if args.report else (["--quick"] if args.quick else [])))
    if args.report:
        print(report(json.loads(Path(args.results).read_text())))
        return
    if args.startup:
        path = Path(args.results)
        result = json.loads(path.read_text()) if path.exists() else {"machine": {}, "runs": [], "scaling": []}
        result["startup"] = compile_times()
        print(json.dumps(result["startup"]))
        path.write_text(json.dumps(result, indent=1) + "\n")
        return
    if args.one:
        form, mat, div, cycles, threads = args.one
        print(json.dumps(measure(form, mat, tuple(map(int, div.split(","))), int(cycles), int(threads))))
        return
    sizes = [((50, 50, 4), 200)] + ([] if args.quick else [((160, 160, 4), 40)])  # 10 000 and 102 400 elements
    cases = [tuple(c.split(":")) for c in args.only] if args.only else CASES
    rows = []
    for div, cycles in sizes:
        for form, mat in cases:
            for threads in (1, 2):
                # a fresh process per measurement: no cross-talk of caches or thread pools
                r = subprocess.run([sys.executable, __file__, "--one", form, mat, ",".join(map(str, div)),
                                    str(cycles), str(threads)], capture_output=True, text=True, cwd=ROOT)
                if r.returncode:
                    print(r.stderr, file=sys.stderr)
                    continue
                row = json.loads(r.stdout.strip().splitlines()[-1])
                rows.append(row)
                print(f"{form:8s} {mat:22s} {row['elements']:7d} el  {threads} thr  "
                      f"{row['us_per_element_cycle']:.3f} us/el-cycle  ({row['us_per_element_cycle_elements_only']:.3f}"
                      f" in elements)  {row['bytes_per_element']:.0f} B/el", flush=True)
    machine = {"cpu_count": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version(),
               "commit": _commit()}
    if args.only:  # a side-by-side comparison of a few cases, measured in the same minutes
        Path(args.results).write_text(json.dumps({"machine": machine, "runs": rows, "scaling": [], "startup": {}},
                                                 indent=1) + "\n")
        return
    scaling = []
    if not args.quick:  # is the cost per cycle linear in the element count (constant per element-cycle)?
        for div, cycles in (((25, 25, 4), 200), ((50, 50, 4), 200), ((100, 100, 4), 60), ((320, 320, 4), 20)):
            r = subprocess.run([sys.executable, __file__, "--one", "reduced", "linear_elastic",
                                ",".join(map(str, div)), str(cycles), "1"], capture_output=True, text=True, cwd=ROOT)
            if r.returncode == 0:
                scaling.append(json.loads(r.stdout.strip().splitlines()[-1]))
    result = {"machine": machine, "runs": rows, "scaling": scaling, "startup": compile_times()}
    print(json.dumps(result["startup"]))
    Path(args.results).write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
