"""One run: deck file -> compile -> engine -> frames, history, summary; returns the process exit code.

Exit codes: 0 every check passed; 2 bad input (deck or geometry); 3 a check failed; 4 numerical failure
(NaN, inverted element); 130 / 143 stopped by SIGINT / SIGTERM (a last frame and the summary are written).
"""

from __future__ import annotations

import signal
import sys
import time
from pathlib import Path

import numpy as np

from fdeck import checks as checks_mod
from fdeck.engine import solver

EXIT_OK, EXIT_INPUT, EXIT_CHECK, EXIT_NUMERIC = 0, 2, 3, 4


def assemble_cells(problem) -> dict[str, np.ndarray]:
    """Cell fields of every group placed in mesh order (concatenated over cell types); NaN where a field is not
    defined for an element's group. Symmetric tensors are (n_el, 6)."""
    offsets, total = {}, 0
    for ctype, conn in problem.cells.items():
        offsets[ctype] = total
        total += len(conn)
    out: dict[str, np.ndarray] = {}
    for g in problem.groups:
        rows = offsets[g.cell_type] + g.element_index
        for name, val in g.cell_fields().items():
            if name not in out:
                out[name] = np.full((total,) + val.shape[1:], np.nan)
            out[name][rows] = val
    return out


class Outputs(solver.Sink):
    """Frame series, history file and progress reporting for one run, and the end-of-run tables
    (``output.paths``, ``output.fibre_table``).

    Each frame also carries the point fields of the measures that have some (``point_fields(x) -> {name: (n_node,)
    array}``, e.g. ``wrinkle``; two measures giving the same name are merged with fmax) and the surfaces of the
    effects that have bodies (``Effect.surfaces()``: rigid tools), written as blocks of their own."""

    def __init__(self, problem, out_dir: Path, name: str, progress):
        from fdeck.io.frames import open_series
        from fdeck.io.history import HistoryWriter
        from fdeck.physics.measures.tables import PathTable

        self.problem, self.progress_fn = problem, progress
        out_dir.mkdir(parents=True, exist_ok=True)
        self.series = open_series(problem.deck.output.formats, out_dir, name, problem.X, problem.cells)
        self.hist = HistoryWriter(out_dir / "history.csv", solver.history_columns(problem))
        self.frames_written = 0
        self.last_frame_time = -1.0
        self.out_dir = out_dir
        self.paths = [PathTable(card, problem.groups, problem.X, problem.cells) for card in problem.deck.output.paths]
        self.tables: list[str] = []  # file names of the end-of-run tables and plots

    def frame(self, t, x, v, point_fields=None):
        point = {"displacement": x - self.problem.X, "velocity": v.copy()}
        for name, val in (point_fields or {}).items():
            point[name] = np.array(val, copy=True)
        for m in self.problem.measures:
            for name, val in (m.point_fields(x) if hasattr(m, "point_fields") else {}).items():
                point[name] = np.fmax(point[name], val) if name in point else np.array(val, copy=True)
        surfaces = [s for e in self.problem.effects for s in e.surfaces()]
        with np.errstate(invalid="ignore", divide="ignore"):  # an inverted element's last frame holds NaN by design
            cells = assemble_cells(self.problem)
        for s in self.series:
            s.write(t, point, cells, surfaces=surfaces)
        self.frames_written += 1
        self.last_frame_time = t

    def tables_at_end(self, x):
        """Write the end-of-run tables at positions x (n_node, 3), the last frame's; the groups hold that state."""
        from fdeck.io.tables import plot_xy, write_table
        from fdeck.physics.measures.tables import fibre_table

        with np.errstate(invalid="ignore", divide="ignore"):
            for p in self.paths:
                cols = p.columns(x)
                self.tables.append(write_table(self.out_dir / f"path_{p.name}.csv", cols).name)
                png = self.out_dir / f"path_{p.name}.png"
                if plot_xy(png, cols["arc_length"], cols["shear_angle"], "arc length along the path [mm]",
                           "shear angle [deg]", f"path {p.name}"):
                    self.tables.append(png.name)
            if self.problem.deck.output.fibre_table:
                table = fibre_table(self.problem.cells, x, assemble_cells(self.problem))
                self.tables.append(write_table(self.out_dir / "fibres.csv", table).name)

    def history(self, row):
        self.hist.write_row(row)

    def progress(self, t, cycles, dt):
        self.progress_fn(t, cycles, dt)

    def close(self):
        for s in self.series:
            s.close()
        self.hist.close()


class _Signals:
    """SIGINT/SIGTERM set a flag the engine polls every cycle."""

    def __init__(self):
        self.received = None

    def __enter__(self):
        self.saved = {s: signal.signal(s, self._handle) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def _handle(self, signum, frame):
        self.received = signum

    def __exit__(self, *exc):
        for s, h in self.saved.items():
            signal.signal(s, h)


def execute(deck, base: Path, out_dir: Path, name: str, deck_path: str, progress=lambda *a: None,
            echo=print) -> tuple[int, dict]:
    """Compile and run a validated deck; returns (exit code, summary dict). Raises CompileError on bad geometry."""
    from fdeck.compile.problem import compile_deck
    from fdeck.io.summary import write_json_atomic

    t_compile = time.perf_counter()
    problem = compile_deck(deck, base)
    t_compile = time.perf_counter() - t_compile
    out = Outputs(problem, out_dir, name, progress)
    with _Signals() as sig:
        first = None if problem.rotations is None else {"director": problem.rotations.d0}
        out.frame(0.0, problem.X.copy(), np.zeros_like(problem.X), first)
        result = solver.run(problem, out, should_stop=lambda: sig.received is not None)
        if (result.status in ("interrupted", "failed") or result.stopped_steps) and result.t > out.last_frame_time:
            last = None if result.final_directors is None else {"director": result.final_directors}
            out.frame(result.t, result.final_positions, result.final_velocities, last)
        out.tables_at_end(result.final_positions)
    out.close()
    hist = np.array(result.history) if result.history else np.zeros((0, len(result.columns)))
    verdicts = checks_mod.evaluate(deck.checks, hist, result.columns, problem.duration)
    summary = make_summary(deck_path, deck, problem, result, verdicts, t_compile, out.frames_written)
    if result.status == "interrupted":
        code = 130 if sig.received == signal.SIGINT else 143
    elif result.status == "failed":
        code = EXIT_NUMERIC
    else:
        code = EXIT_CHECK if any(not c["passed"] for c in verdicts) else EXIT_OK
    summary["tables"] = out.tables
    summary["exit_code"] = code
    write_json_atomic(out_dir / "summary.json", summary)
    return code, summary


def make_summary(deck_path, deck, problem, result, verdicts, t_compile, frames) -> dict:
    n_el = problem.n_element
    element_time = sum(v for k, v in result.timings.items() if k.startswith("section"))
    loop_time = sum(result.timings.values())
    per = max(result.cycles, 1) * max(n_el, 1)
    last = dict(zip(result.columns, result.history[-1])) if result.history else {}
    return {
        "deck": str(deck_path),
        "title": deck.title,
        "units": deck.units,
        "status": result.status,
        "message": result.message,
        "elements": n_el,
        "nodes": problem.n_node,
        "cycles": result.cycles,
        "simulated_time": result.t,
        "wall_time": result.wall,
        "compile_time": t_compile,
        "us_per_element_cycle": 1e6 * loop_time / per,
        "us_per_element_cycle_elements_only": 1e6 * element_time / per,
        "time_per_effect": dict(sorted(result.timings.items(), key=lambda kv: -kv[1])),
        "dt_min": result.dt_min if result.cycles else None,
        "dt_max": result.dt_max if result.cycles else None,
        "added_mass_percent": [100.0 * a for a in result.added_mass],
        **({"added_rotational_inertia_percent": {g.name: 100.0 * g.added_rotational_inertia for g in problem.groups
                                                 if g.rotational}}
           if problem.rotations is not None else {}),
        "steps_stopped_at_max_cycles": result.stopped_steps,
        "frames": frames,
        "final": last,
        "measures": {c: last.get(c) for m in problem.measures for c in m.columns},
        "checks": verdicts,
    }


def timing_table(summary: dict) -> str:
    """Where the time went, one line per effect."""
    total = sum(summary["time_per_effect"].values()) or 1.0
    lines = [f"  {k:<40s} {v:9.3f} s  {100 * v / total:5.1f} %" for k, v in summary["time_per_effect"].items()]
    return "\n".join(lines)


def _stderr(msg):
    print(msg, file=sys.stderr)
