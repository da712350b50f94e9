"""Cost of every full-size forming deck in decks/forming/, from a measured partial run of each (not part of the tests).

Each deck runs as a user runs it (`fdeck run DECK -o DIR --max-wall W`, 2 numba threads by default, numba's cache
warm) for W seconds of cycling; `fdeck info DECK` gives the cycles the whole run is expected to take. From the
partial run's summary.json: cycles done, simulated time, wall time of the cycles, µs per element-cycle, the share of
the cycle time spent in contact and tools (the `contact:*` and `tool:*` rows of the timing table), and the step.
Extrapolated wall of the full run = set-up (compile, first frame) + expected cycles × measured wall per cycle; two
cycle counts are given: `fdeck info`'s (from the rest step) and the duration over the mean step of the partial run
(the step follows the current tangent and contact, so the two differ; the larger is the honest bound). The first
W seconds of a forming run are its start (pre-tension, the tool's approach): contact is sparse then, so the
contact share and the wall per cycle of the rest of the run may be larger. Everything extrapolated is labelled so.
Peak resident memory comes from /usr/bin/time -v where it exists. `--max-wall` counts from before the first frame
(fdeck's own limit), so a large shell deck needs a minute or more of it to cycle at all.

The code measured is a snapshot of the commit checked out (`git archive HEAD` into <temp>/fdeck_bench_<commit>/,
reused by later invocations, put first on PYTHONPATH; its commit is recorded): fdeck keys numba's cache on the
whole source tree, so uncommitted edits (other work in the same tree) would otherwise recompile the kernels inside
the timed cycles. Before any timing, each deck runs 3 cycles (a variant with `max_cycles: 3`) to fill that
snapshot's cache. `FDECK_BENCH_COMMIT=<commit>` measures that commit instead of HEAD (to add rows to a table
measured at an earlier commit while others commit). Every row records the load average before and after its run:
on a shared machine the figures are only as steady as the load.

A deck run to the end replaces its partial row with the measured whole run (`--completed DECK RUN_DIR COMMIT DATE`:
the run's summary.json, its cycles, wall, µs per element-cycle, contact share and checks; no extrapolation). The
contact share counts the `contact:*`, `tool:*` and implicit `contact springs` rows of the timing table.

    python benchmarks/forming_cost.py                    # all eight decks, 90 s of cycling each, 2 threads
    python benchmarks/forming_cost.py --max-wall 180 --decks square_tube_sm square_tube_ts
    python benchmarks/forming_cost.py --completed tetrahedron_5mm RUN_DIR COMMIT 2026-11-30   # a whole run
    python benchmarks/forming_cost.py --report           # markdown table of benchmarks/forming_cost.json

Writes benchmarks/forming_cost.json (rows of decks measured earlier are kept unless measured again).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
DECKS = ("tetrahedron_5mm", "tetrahedron_3mm", "double_dome_090_5mm", "double_dome_090_3mm",
         "double_dome_45_4p24mm", "double_dome_45_2p12mm", "square_tube_sm", "square_tube_ts")
OUT = HERE / "forming_cost.json"
CONTACT_ROWS = ("contact:", "tool:", "contact springs")  # timing-table rows of contact (implicit springs' own row)


def load() -> str:
    """`uptime`'s load averages (1, 5, 15 min): every timing on this shared machine is stated with the load."""
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def snapshot(tmp: Path | None = None) -> tuple[Path, str]:
    """The committed tree (HEAD) extracted once to <temp dir>/fdeck_bench_<commit>/ and reused, and its commit: the
    code every timing here runs. The same folder each time, because numba's cache of a function is stored under
    the path of its source file: a fresh folder per invocation would compile every kernel again. (`tmp` unused.)"""
    pinned = os.environ.get("FDECK_BENCH_COMMIT", "HEAD")  # a commit to measure instead of HEAD
    commit = subprocess.run(["git", "rev-parse", pinned], cwd=ROOT, capture_output=True, text=True,
                            check=True).stdout.strip()
    src = Path(tempfile.gettempdir()) / f"fdeck_bench_{commit[:12]}"
    if not (src / "fdeck" / "__init__.py").exists():
        part = Path(tempfile.mkdtemp(prefix=f"{src.name}_part_"))
        archive = subprocess.run(["git", "archive", commit], cwd=ROOT, capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(part)], input=archive, check=True)
        try:
            part.rename(src)
        except OSError:  # another invocation extracted it meanwhile
            shutil.rmtree(part, ignore_errors=True)
    return src, commit


def bench_env(src: Path, threads: int) -> dict:
    return dict(os.environ, NUMBA_NUM_THREADS=str(threads),
                PYTHONPATH=os.pathsep.join([str(src)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))


def warm(deck: Path, env: dict, out: Path) -> float:
    """Run 3 cycles of `deck` (a sibling variant file with max_cycles 3 in every step) to fill numba's cache; wall s."""
    import yaml

    d = yaml.safe_load(deck.read_text())
    for step in d["steps"]:
        step["max_cycles"] = 3
    variant = deck.with_name(f"_warm_{deck.name}")
    variant.write_text(yaml.safe_dump(d))
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "fdeck.cli", "run", str(variant), "-o", str(out)], env=env,
                   cwd=deck.parent, capture_output=True, check=False, timeout=1800)
    shutil.rmtree(out, ignore_errors=True)
    variant.unlink()
    return time.perf_counter() - t0


def fdeck_info(deck: Path, env: dict) -> dict:
    """Expected cycles, element count and element-array memory [MiB] as `fdeck info` prints them."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "fdeck.cli", "info", str(deck)], env=env, cwd=deck.parent,
                          capture_output=True, text=True, check=False)
    text = proc.stdout
    cycles = re.search(r"about (\d+) cycles in all", text)
    mem = re.search(r"element arrays ([\d.]+) MiB", text)
    sizes = re.search(r"nodes (\d+), elements (\d+), duration ([\d.eE+-]+) s", text)
    return {"expected_cycles": int(cycles.group(1)) if cycles else None,
            "element_arrays_mib": float(mem.group(1)) if mem else None,
            "nodes": int(sizes.group(1)) if sizes else None, "elements": int(sizes.group(2)) if sizes else None,
            "duration": float(sizes.group(3)) if sizes else None, "info_wall": time.perf_counter() - t0,
            "info_ok": proc.returncode == 0}


def contact_share(per: dict) -> float:
    """Share of the per-cycle work [0..1] spent in contact and tools, from a run's timing table per (row -> s): the
    CONTACT_ROWS over all rows but the events (frames `output`, history `measures`)."""
    total = sum(per.values()) - per.get("output", 0.0) - per.get("measures", 0.0)
    return sum(v for k, v in per.items() if k.startswith(CONTACT_ROWS)) / (total or 1.0)


def timed_run(cmd: list[str], env: dict, cwd: Path) -> tuple[float, float | None, subprocess.CompletedProcess]:
    """(wall [s], peak resident memory [MiB] or None, process): under /usr/bin/time -v when it exists."""
    timer = shutil.which("time") or ("/usr/bin/time" if Path("/usr/bin/time").exists() else None)
    full = ([timer, "-v"] if timer else []) + cmd
    t0 = time.perf_counter()
    proc = subprocess.run(full, env=env, cwd=cwd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    cpu = [float(x) for x in re.findall(r"(?:User|System) time \(seconds\): ([\d.]+)", proc.stderr)]
    proc.cpu_seconds = sum(cpu) if len(cpu) == 2 else None  # user + system of the whole process (set-up included)
    return wall, (int(rss.group(1)) / 1024 if rss else None), proc


def partial_run(deck: Path, out: Path, max_wall: float, env: dict) -> dict:
    """Run `deck` for `max_wall` seconds of cycling; the figures of its summary.json and the process."""
    cmd = [sys.executable, "-m", "fdeck.cli", "run", str(deck), "-o", str(out), "--max-wall", f"{max_wall:g}"]
    load_before = load()
    wall, rss, proc = timed_run(cmd, env, deck.parent)
    path = out / "summary.json"
    if not path.exists():
        return {"ok": False, "exit_code": proc.returncode, "stderr_tail": proc.stderr[-2000:]}
    s = json.loads(path.read_text())
    hist = out / "history.csv"
    rows = max(sum(1 for _ in hist.open()) - 1, 1) if hist.exists() else None  # history rows written (header off)
    per = s.get("time_per_effect", {})
    return {"ok": s["cycles"] > 0 and s["status"] != "failed", "status": s["status"], "exit_code": proc.returncode,
            "cycles": s["cycles"], "simulated_time": s["simulated_time"], "loop_wall": s["wall_time"],
            "process_wall": wall, "setup_wall": wall - s["wall_time"], "compile_time": s["compile_time"],
            "us_per_element_cycle": s["us_per_element_cycle"],
            "us_per_element_cycle_elements_only": s["us_per_element_cycle_elements_only"],
            "contact_share": contact_share(per), "time_per_effect": per, "dt_min": s["dt_min"], "dt_max": s["dt_max"],
            "frames": s.get("frames"), "history_rows": rows,
            "peak_rss_mib": rss, "process_cpu": proc.cpu_seconds, "load_before": load_before,
            "load_after": load()}


def extrapolate(info: dict, run: dict, deck: dict) -> dict:
    """Full-run cycles and wall [s] from the partial run (labelled extrapolated wherever used). A partial run of a few
    dozen cycles spends much of its loop on events a full run spreads over 10^5 cycles (frames: `output`; the
    history rows' `measures`), so those are taken per event (frames written in the loop, history rows) and scaled
    to the deck's frames and history points; the rest of the loop is per cycle."""
    per = run["time_per_effect"]
    events = per.get("output", 0.0) + per.get("measures", 0.0)
    per_cycle = (run["loop_wall"] - events) / run["cycles"]
    out_cfg = deck.get("output", {})
    frames_full, rows_full = out_cfg.get("frames", 10), out_cfg.get("history_points", 100)
    frame_cost = per.get("output", 0.0) / max((run.get("frames") or 2) - 1, 1)  # the first frame is set-up
    row_cost = per.get("measures", 0.0) / (run.get("history_rows") or 2)
    events_full = frames_full * frame_cost + rows_full * row_cost
    mean_dt = run["simulated_time"] / run["cycles"] if run["simulated_time"] > 0 else None
    by_dt = int(info["duration"] / mean_dt) if mean_dt else None
    out = {"wall_per_cycle": per_cycle, "frame_cost": frame_cost, "history_row_cost": row_cost,
           "events_full": events_full, "mean_dt": mean_dt, "cycles_by_mean_dt": by_dt,
           "fraction_done": run["simulated_time"] / info["duration"],
           "us_per_element_cycle_without_events": 1e6 * per_cycle / info["elements"]}
    for key, n in (("info", info["expected_cycles"]), ("mean_dt", by_dt)):
        out[f"wall_extrapolated_{key}"] = run["setup_wall"] + n * per_cycle + events_full if n else None
    return out


def _yaml(path: Path) -> dict:
    import yaml

    return yaml.safe_load(path.read_text())


def measure(decks, max_wall: float, threads: int) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory(prefix="fdeck_forming_cost_") as tmp:
        src, commit = snapshot(Path(tmp))
        env = bench_env(src, threads)
        for name in decks:
            deck = src / "decks" / "forming" / f"{name}.yaml"
            warm_wall = warm(deck, env, Path(tmp) / f"warm_{name}")
            info = fdeck_info(deck, env)
            run = partial_run(deck, Path(tmp) / name, max_wall, env)
            row = {"deck": name, "commit": commit, "threads": threads, "max_wall": max_wall, "warm_wall": warm_wall,
                   **info, "run": run}
            if run["ok"] and info["expected_cycles"]:
                row["extrapolated"] = extrapolate(info, run, _yaml(deck))
            rows.append(row)
            print(json.dumps({k: row[k] for k in ("deck", "elements", "expected_cycles")}
                             | {k: run.get(k) for k in ("cycles", "us_per_element_cycle", "contact_share",
                                                        "load_after")}), flush=True)
            shutil.rmtree(Path(tmp) / name, ignore_errors=True)  # frames of 3 mm decks are large
    return rows


def completed(name: str, run_dir: Path, commit: str, date: str, threads: int) -> dict:
    """A row from a run of the deck taken to the end (`fdeck run DECK -o RUN_DIR`, its summary.json): measured, not
    extrapolated. The run records neither its commit nor its date, so both are given; `fdeck info`'s cycle count
    comes from the deck as it is now (the same deck the run ran, or the row is mislabelled)."""
    s = json.loads((run_dir / "summary.json").read_text())
    if s["status"] != "completed" or s["cycles_this_run"] != s["cycles"]:
        raise SystemExit(f"{run_dir}: not one run from start to end (status {s['status']}, {s['cycles_this_run']} "
                         f"of {s['cycles']} cycles in its last process)")
    per = s["time_per_effect"]
    events = per.get("output", 0.0) + per.get("measures", 0.0)
    info = fdeck_info(ROOT / "decks" / "forming" / f"{name}.yaml", dict(os.environ))
    return {"deck": name, "commit": commit, "date": date, "threads": threads, **info,
            "completed": {"cycles": s["cycles"], "loop_wall": s["wall_time"], "compile_time": s["compile_time"],
                          "us_per_element_cycle": s["us_per_element_cycle"],
                          "us_per_element_cycle_without_events": 1e6 * (s["wall_time"] - events) / s["cycles"]
                          / s["elements"],
                          "contact_share": contact_share(per),
                          "dt_min": s["dt_min"], "dt_max": s["dt_max"], "time_per_effect": per,
                          "checks": {c["name"]: c["passed"] for c in s["checks"]}}}


def _h(seconds: float | None) -> str:
    if seconds is None:
        return "–"
    return f"{seconds / 3600:.1f} h" if seconds >= 3600 else f"{seconds / 60:.0f} min"


def report(result: dict) -> str:
    lines = ["| deck | elements | measured: cycles (share of the run) in s of cycling | µs/el-cycle (all / without "
             "frames and measures) | contact + tools | step [s] (min..max) | peak RSS | `fdeck info` cycles | "
             "**extrapolated** wall, 2 cores (info / mean step) | load (1-min) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        if "completed" in r:
            c = r["completed"]
            checks = ", ".join(f"{k} {'passes' if v else 'FAILS'}" for k, v in c["checks"].items())
            lines.append(
                f"| {r['deck']} | {r['elements']:,} | **run to the end**: {c['cycles']:,} (100 %) in "
                f"{c['loop_wall']:.0f} s ({r['commit'][:7]}, {r['date']}; {checks}) | {c['us_per_element_cycle']:.2f}"
                f" / {c['us_per_element_cycle_without_events']:.2f} | {100 * c['contact_share']:.0f} % | "
                f"{c['dt_min']:.3g}..{c['dt_max']:.3g} | – | {r['expected_cycles']:,} | **measured** "
                f"{_h(c['loop_wall'] + c['compile_time'])} | – |")
            continue
        run, ex = r["run"], r.get("extrapolated")
        if not run.get("ok"):
            why = (f"no cycle within --max-wall {r['max_wall']:g} s (it includes the first frame)"
                   if run.get("cycles") == 0 else f"failed (exit {run.get('exit_code')})")
            rss = f"{run['peak_rss_mib']:.0f} MiB" if run.get("peak_rss_mib") else "–"
            loads = f"{run['load_before'].split()[0]}–{run['load_after'].split()[0]}"
            lines.append(f"| {r['deck']} | {r['elements']:,} | {why} | – | – | – | {rss} | "
                         f"{r['expected_cycles']:,} | – | {loads} |")
            continue
        rss = f"{run['peak_rss_mib']:.0f} MiB" if run.get("peak_rss_mib") else "–"
        lines.append(
            f"| {r['deck']} | {r['elements']:,} | {run['cycles']:,} ({100 * ex['fraction_done']:.2f} %) in "
            f"{run['loop_wall']:.0f} s | {run['us_per_element_cycle']:.2f} / "
            f"{ex['us_per_element_cycle_without_events']:.2f} | {100 * run['contact_share']:.0f} % | "
            f"{run['dt_min']:.3g}..{run['dt_max']:.3g} | {rss} | {r['expected_cycles']:,} | "
            f"{_h(ex['wall_extrapolated_info'])} / {_h(ex['wall_extrapolated_mean_dt'])} | "
            f"{run['load_before'].split()[0]}–{run['load_after'].split()[0]} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--decks", nargs="*", default=list(DECKS), choices=DECKS)
    ap.add_argument("--max-wall", type=float, default=90.0, help="seconds of cycling per deck (default 90)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--recompute", action="store_true", help="redo the extrapolation of the stored rows")
    ap.add_argument("--completed", nargs=4, action="append", metavar=("DECK", "RUN_DIR", "COMMIT", "DATE"),
                    help="record a run taken to the end (repeatable); its row replaces the deck's partial one")
    args = ap.parse_args(argv)
    if args.completed:
        rows = {r["deck"]: r for r in json.loads(OUT.read_text())["rows"]} if OUT.exists() else {}
        for name, run_dir, commit, date in args.completed:
            if name not in DECKS:
                raise SystemExit(f"--completed: unknown deck {name!r} (one of {', '.join(DECKS)})")
            rows[name] = completed(name, Path(run_dir), commit, date, args.threads)
        result = {"machine": {"cpu_count": os.cpu_count(), "load_at_end": load()},
                  "rows": sorted(rows.values(), key=lambda r: DECKS.index(r["deck"]))}
        OUT.write_text(json.dumps(result, indent=1) + "\n")
        print(report(result))
        return 0
    if args.recompute:  # rows measured before a change of extrapolate(): their runs are kept as measured
        result = json.loads(OUT.read_text())
        for r in result["rows"]:
            if "completed" in r:
                continue
            run = r["run"]
            run["contact_share"] = contact_share(run["time_per_effect"])
            if run.get("ok"):
                r["extrapolated"] = extrapolate(r, run, _yaml(ROOT / "decks" / "forming" / f"{r['deck']}.yaml"))
        OUT.write_text(json.dumps(result, indent=1) + "\n")
    if args.report or args.recompute:
        print(report(json.loads(OUT.read_text())))
        return 0
    old = json.loads(OUT.read_text())["rows"] if OUT.exists() else []
    new = measure(args.decks, args.max_wall, args.threads)
    done = {r["deck"] for r in new}
    rows = sorted([r for r in old if r["deck"] not in done] + new, key=lambda r: DECKS.index(r["deck"]))
    result = {"machine": {"cpu_count": os.cpu_count(), "load_at_end": load()}, "rows": rows}
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    print(report(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
