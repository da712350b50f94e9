"""One run: deck file -> compile -> engine -> frames, history, summary; returns the process exit code.

Exit codes: 0 every check passed; 2 bad input (deck or geometry, or a checkpoint that does not belong to the deck);
3 a check failed; 4 numerical failure (NaN, inverted element); 124 the wall-time limit (``--max-wall``) was spent,
as ``timeout`` reports it; 130 / 143 stopped by SIGINT / SIGTERM. A stopped run (124, 130, 143) writes a
checkpoint, a last frame and the summary, and ``fdeck run --restart`` continues it.

Checkpoints and restart: ``output.checkpoint`` saves the state (``engine.solver``'s state, the output writers'
bookkeeping, the history rows) through ``io.checkpoint``, with digests of the deck's canonical content (without
its output settings, checks and title), of the mesh arrays and of each step, and the fdeck version. A restart
refuses a checkpoint whose digests or version differ, except that steps may have been ADDED after the
checkpoint's ones (continue a finished forming with a second step). The restarted run rewrites history.csv with
the checkpoint's rows, keeps the frames the checkpoint had written and continues both indexes.
"""

from __future__ import annotations

import hashlib
import json
import signal
import threading
import sys
import time
from pathlib import Path

import numpy as np

from fdeck import checks as checks_mod
from fdeck.engine import solver

EXIT_OK, EXIT_INPUT, EXIT_CHECK, EXIT_NUMERIC, EXIT_WALL = 0, 2, 3, 4, 124


class RestartError(Exception):
    """A restart that cannot be done (no valid checkpoint, one of another deck or version); exit 2."""


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def deck_digests(deck, problem) -> dict:
    """What ties a checkpoint to a deck: SHA-256 of the deck's canonical content without its steps, output settings
    (but with the reactions and measures, which make the history columns), checks and title, and of the mesh
    arrays; one SHA-256 per step; the fdeck version and the digest of its source files (the build: the engine's
    state layout that a checkpoint saves is the code's, not the version number's); the run's duration when a built-in
    amplitude spans it (then adding a step changes the loads of the steps before)."""
    from fdeck import __version__

    data = deck.model_dump(mode="json")
    steps = data.pop("steps")
    output = data.pop("output")
    for key in ("checks", "title"):
        data.pop(key, None)
    data["output"] = {"reactions": output["reactions"], "measures": output["measures"]}
    h = hashlib.sha256(json.dumps(data, sort_keys=True).encode())
    h.update(np.ascontiguousarray(problem.X).tobytes())
    for ctype, conn in problem.cells.items():
        h.update(ctype.encode() + np.ascontiguousarray(conn, dtype=np.int64).tobytes())

    def relative(node) -> bool:
        if isinstance(node, dict):
            return any((("amplitude" in k) and v in ("ramp", "smooth")) or relative(v) for k, v in node.items())
        return isinstance(node, list) and any(relative(v) for v in node)

    from fdeck.jit import BUILD

    return {"version": __version__, "build": BUILD, "base": h.hexdigest(),
            "steps": [_sha(json.dumps(st, sort_keys=True).encode()) for st in steps],
            "duration": problem.duration if relative(data) else None}


def check_compatible(saved: dict, now: dict, where: str) -> None:
    """RestartError unless a checkpoint with digests ``saved`` may continue under a deck with digests ``now``."""
    if saved["version"] != now["version"]:
        raise RestartError(f"{where} was written by fdeck {saved['version']}, this is fdeck {now['version']}: "
                           "a restart needs the same version")
    if saved.get("build") != now["build"]:
        raise RestartError(f"{where} was written by another build of fdeck {now['version']} (source digest "
                           f"{saved.get('build') or 'not recorded'}, this one {now['build']}): the state it saves is "
                           "laid out by the code that wrote it; a restart needs the same source files")
    if saved["base"] != now["base"]:
        raise RestartError(f"{where} belongs to another deck or mesh (materials, sections, mesh, boundary, loads, "
                           "tools, contact, reactions or measures differ)")
    n = len(saved["steps"])
    if now["steps"][:n] != saved["steps"]:
        changed = next((i for i in range(n) if i >= len(now["steps"]) or now["steps"][i] != saved["steps"][i]), n)
        raise RestartError(f"{where}: step {changed} differs from the checkpoint's (steps may only be added after "
                           "the last one)")
    if saved["duration"] is not None and saved["duration"] != now["duration"]:
        raise RestartError(f"{where}: the built-in amplitudes 'ramp'/'smooth' span the whole run, so adding steps "
                           "changes the loads already applied; use a tabular amplitude or 'constant' to extend a run")


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


def cell_max(point_field: np.ndarray, cells: dict[str, np.ndarray]) -> np.ndarray:
    """Per cell (concatenated over cell types in ``cells`` order), the largest finite value of point_field (n_node,)
    at its nodes; NaN where every node is NaN (off the surface the field covers)."""
    return np.concatenate([np.fmax.reduce(point_field[conn], axis=1) for conn in cells.values()])


def write_end_tables(problem, paths, out_dir: Path, x) -> list[str]:
    """Write the path tables (``paths``: PathTable list) and, if the deck asks, fibres.csv at positions x
    (n_node, 3) into out_dir; the groups must hold the state at x. Returns the file names written."""
    from fdeck.io.tables import plot_xy, write_table
    from fdeck.physics.measures.tables import fibre_table

    written = []
    with np.errstate(invalid="ignore", divide="ignore"):
        for p in paths:
            cols = p.columns(x)
            written.append(write_table(out_dir / f"path_{p.name}.csv", cols).name)
            png = out_dir / f"path_{p.name}.png"
            if plot_xy(png, cols["arc_length"], cols["shear_angle"], "arc length along the path [mm]",
                       "shear angle [deg]", f"path {p.name}"):
                written.append(png.name)
        if problem.deck.output.fibre_table:
            table = fibre_table(problem.cells, x, assemble_cells(problem))
            written.append(write_table(out_dir / "fibres.csv", table).name)
    return written


class Outputs(solver.Sink):
    """Frame series, history file and progress reporting for one run, and the end-of-run tables
    (``output.paths``, ``output.fibre_table``).

    Each frame also carries the point fields of the measures that have some (``point_fields(x) -> {name: (n_node,)
    array}``, e.g. ``wrinkle``; two measures giving the same name are merged with fmax), each also as the cell field
    ``<name>_element`` (the largest value at the element's nodes, ``cell_max``), the effects' nodal fields
    (``Effect.node_fields``: contact pressure, gap, status and slip), and the surfaces of the
    effects that have bodies (``Effect.surfaces()``: rigid tools), written as blocks of their own."""

    def __init__(self, problem, out_dir: Path, name: str, progress, digests: dict | None = None,
                 resume: dict | None = None):
        from fdeck.io.frames import open_series
        from fdeck.io.history import HistoryWriter
        from fdeck.physics.measures.tables import PathTable

        self.problem, self.progress_fn = problem, progress
        out_dir.mkdir(parents=True, exist_ok=True)
        formats = problem.deck.output.formats
        if resume is None:
            self.series = open_series(formats, out_dir, name, problem.X, problem.cells)
            from fdeck.io.checkpoint import checkpoint_files

            for stale in checkpoint_files(out_dir):  # an earlier run's: --restart must not pick them up
                stale.unlink()
        else:
            self.series = _resume_series(formats, out_dir, name, problem, resume)
        self.hist = HistoryWriter(out_dir / "history.csv", solver.history_columns(problem))
        self.frames_written = 0 if resume is None else resume["outputs"]["frames_written"]
        self.last_frame_time = -1.0 if resume is None else resume["outputs"]["last_frame_time"]
        if resume is not None:  # history.csv back to the checkpoint's rows, then continued by the run
            for row in resume["engine"]["result"]["history"]:
                self.hist.write_row(row)
        self.out_dir = out_dir
        self.digests = digests
        self.card = problem.deck.output.checkpoint
        self.checkpoints, self.checkpoint_time, self.last_checkpoint = 0, 0.0, time.perf_counter()
        self.checkpoint_path: Path | None = None
        self.paths = [PathTable(card, problem.groups, problem.X, problem.cells) for card in problem.deck.output.paths]
        self.tables: list[str] = []  # file names of the end-of-run tables and plots

    def frame(self, t, x, v, point_fields=None):
        point = {"displacement": x - self.problem.X, "velocity": v.copy()}
        for name, val in (point_fields or {}).items():
            point[name] = np.array(val, copy=True)
        measured = {}  # names in the measures' order (a set's order would vary with the hash seed)
        for m in self.problem.measures:
            for name, val in (m.point_fields(x) if hasattr(m, "point_fields") else {}).items():
                point[name] = np.fmax(point[name], val) if name in point else np.array(val, copy=True)
                measured[name] = None
        covered = {}  # name -> (n_node,) bool: nodes some effect gave a value of that field
        for e in self.problem.effects:  # an effect's nodal fields (contact pressure, ...), merged at shared nodes
            for name, (nodes, val, merge, elsewhere) in e.node_fields().items():
                if name not in covered:
                    point[name] = np.full(len(self.problem.X), elsewhere, float)
                    covered[name] = np.zeros(len(self.problem.X), bool)
                join = np.maximum if merge == "max" else np.minimum  # a NaN wins: a failed run's frame shows it
                seen = covered[name][nodes]
                point[name][nodes] = np.where(seen, join(point[name][nodes], val), val)
                covered[name][nodes] = True
        surfaces = [s for e in self.problem.effects for s in e.surfaces()]
        with np.errstate(invalid="ignore", divide="ignore"):  # an inverted element's last frame holds NaN by design
            cells = assemble_cells(self.problem)
        for name in measured:  # a measure's nodal field also per element (the largest of its nodes), "<name>_element"
            cells[f"{name}_element"] = cell_max(point[name], self.problem.cells)
        for s in self.series:
            s.write(t, point, cells, surfaces=surfaces)
        self.frames_written += 1
        self.last_frame_time = t

    def tables_at_end(self, x):
        """Write the end-of-run tables at positions x (n_node, 3), the last frame's; the groups hold that state."""
        self.tables += write_end_tables(self.problem, self.paths, self.out_dir, x)

    def history(self, row):
        self.hist.write_row(row)

    def checkpoint_due(self, cycles):
        if self.card is None:
            return False
        if self.card.cycles is not None:
            return cycles % self.card.cycles == 0
        return time.perf_counter() - self.last_checkpoint >= self.card.seconds

    def checkpoint(self, state, reason):
        """Save the engine's ``state()`` with the writers' bookkeeping (every series' attributes: file lists and index
        entries) and the digests; a completed run saves one only when the deck asks for checkpoints."""
        from fdeck.io.checkpoint import write_checkpoint

        if reason == "completed" and self.card is None:
            return
        t0 = time.perf_counter()
        state = state()
        payload = {"digests": self.digests, "reason": reason, "engine": state,
                   "outputs": {"frames_written": self.frames_written, "last_frame_time": self.last_frame_time,
                               "out_dir": str(self.out_dir),
                               "series": {type(s).__name__: dict(vars(s)) for s in self.series}}}
        keep = self.card.keep if self.card is not None else 2
        self.checkpoint_path = write_checkpoint(self.out_dir, state["result"]["cycles"], payload, keep)
        self.last_checkpoint = time.perf_counter()
        self.checkpoints += 1
        self.checkpoint_time += self.last_checkpoint - t0

    def progress(self, t, cycles, dt):
        self.progress_fn(t, cycles, dt)

    def close(self):
        for s in self.series:
            s.close()
        self.hist.close()


def _resume_series(formats, out_dir: Path, name: str, problem, resume: dict) -> list:
    """The frame series of the checkpoint's run, continued: each writer rebuilt from its saved attributes (paths
    moved to ``out_dir``, where the restarted run writes), its index rewritten to the frames the checkpoint had
    written (a frame written after the checkpoint, e.g. an interrupted run's last one, drops out); a format the
    checkpoint's run did not write starts a new series."""
    from fdeck.io import frames
    from fdeck.io.frames import open_series

    saved = resume["outputs"]["series"]
    old_dir = Path(resume["outputs"]["out_dir"])

    def moved(value):
        if isinstance(value, Path) and value == old_dir:  # the series' own folder, where its frames go
            return out_dir
        if isinstance(value, Path) and value.parent == old_dir:
            return out_dir / value.name
        if isinstance(value, list):
            return [moved(v) for v in value]
        return value

    out = []
    for fmt in formats:
        cls = {"vtu": frames.VtuSeries, "xdmf": frames.XdmfSeries}[fmt]
        if cls.__name__ in saved:
            series = cls.__new__(cls)
            series.__dict__.update({k: moved(v) for k, v in saved[cls.__name__].items()})
            series._write_index()
            out.append(series)
        else:
            out += open_series([fmt], out_dir, name, problem.X, problem.cells)
    return out


class _Signals:
    """SIGINT/SIGTERM set a flag the engine polls every cycle. Off the main thread (a Dask worker runs tasks in
    threads, where Python refuses ``signal.signal``) nothing is installed: the worker process owns its signals."""

    def __init__(self):
        self.received = None
        self.saved = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.saved = {s: signal.signal(s, self._handle) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def _handle(self, signum, frame):
        self.received = signum

    def __exit__(self, *exc):
        for s, h in self.saved.items():
            signal.signal(s, h)


def fit_history(result: dict, columns: list[str], where: str) -> None:
    """The checkpoint's history rows (``result["history"]``, (n_row, n_saved)) under the run's ``columns``: a column
    that steps added after the checkpoint bring (an effect's work that starts with them, ``step_mass_work``) is 0.0 in
    the earlier rows. RestartError when the checkpoint has a column the run has not."""
    rows, saved = result["history"], result.get("columns")
    if saved is None or list(saved) == list(columns):
        if rows.shape[1] != len(columns):
            raise RestartError(f"{where}: its history has {rows.shape[1]} columns, this run {len(columns)}")
        return
    gone = [c for c in saved if c not in columns]
    if gone:
        raise RestartError(f"{where}: its history has columns this run has not ({', '.join(gone)})")
    fitted = np.zeros((len(rows), len(columns)))
    for j, c in enumerate(saved):
        fitted[:, columns.index(c)] = rows[:, j]
    result["history"], result["columns"] = fitted, list(columns)


def find_restart(out_dir: Path, restart: str | bool, digests: dict, columns: list[str], echo=print) -> dict:
    """The checkpoint payload to continue from: the file ``restart`` names, or (``restart`` True or "") the newest
    intact one in ``out_dir`` (damaged newer ones are skipped with a message through ``echo``), its history fitted
    to the run's ``columns``. RestartError when there is none or it does not belong to the deck
    (``check_compatible``)."""
    from fdeck.io.checkpoint import CheckpointError, latest_valid, read_checkpoint

    if isinstance(restart, str) and restart:
        path = Path(restart)
        try:
            payload = read_checkpoint(path)
        except CheckpointError as exc:
            raise RestartError(str(exc)) from None
    else:
        found = latest_valid(out_dir, report=echo)
        if found is None:
            raise RestartError(f"no valid checkpoint in {out_dir}/ to restart from")
        path, payload = found
    if "digests" not in payload or "engine" not in payload:
        raise RestartError(f"{path}: not an fdeck run checkpoint")
    check_compatible(payload["digests"], digests, str(path))
    fit_history(payload["engine"]["result"], columns, str(path))
    echo(f"restarting from {path} (cycle {payload['engine']['result']['cycles']}, "
         f"t = {payload['engine']['scalars']['t']:.6g} s)")
    return payload


def execute(deck, base: Path, out_dir: Path, name: str, deck_path: str, progress=lambda *a: None,
            echo=print, restart: str | bool | None = None, max_wall: float | None = None,
            compiled: tuple | None = None) -> tuple[int, dict]:
    """Compile and run a validated deck; returns (exit code, summary dict). Raises CompileError on bad geometry,
    RestartError when ``restart`` (a checkpoint file, or True/"" for the newest valid one in ``out_dir``) cannot be
    used. ``max_wall`` [s]: stop with a checkpoint (exit 124) once the run has taken that long. ``compiled``:
    (problem, compile time [s]) of this deck compiled by the caller and not yet run (``fdeck run`` compiles before it
    touches the result folder, to refuse absurd decks), so it is not compiled twice. OutdirError when another run
    is writing into ``out_dir`` (``io.outdir.writing``)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.io.outdir import writing

    if compiled is not None:
        problem, t_compile = compiled
    else:
        t_compile = time.perf_counter()
        problem = compile_deck(deck, base)
        t_compile = time.perf_counter() - t_compile
    with writing(out_dir):  # one writer per result folder (OutdirError when another run is writing there)
        return _execute(deck, problem, t_compile, out_dir, name, deck_path, progress, echo, restart, max_wall)


def _execute(deck, problem, t_compile, out_dir, name, deck_path, progress, echo, restart, max_wall):
    """``execute`` once the deck is compiled and the folder's write lock is held."""
    from fdeck.io.summary import write_json_atomic

    digests = deck_digests(deck, problem)
    resume = None if restart is None or restart is False else find_restart(out_dir, restart, digests,
                                                                           solver.history_columns(problem), echo)
    out = Outputs(problem, out_dir, name, progress, digests, resume)
    start = time.perf_counter()
    walled = []

    def should_stop():
        if sig.received is not None:
            return True
        if max_wall is not None and time.perf_counter() - start >= max_wall:
            walled.append(True)
            return f"wall-time limit of {max_wall:g} s spent (--max-wall)"
        return False

    with _Signals() as sig:
        if resume is None:
            first = None if problem.rotations is None else {"director": problem.rotations.d0}
            out.frame(0.0, problem.X.copy(), np.zeros_like(problem.X), first)
        result = solver.run(problem, out, should_stop=should_stop, resume=None if resume is None else resume["engine"])
        good = {"index": out.frames_written - 1, "time": out.last_frame_time}  # before a failure's own frame
        if (result.status in ("interrupted", "failed") or result.stopped_steps) and result.t > out.last_frame_time:
            last = None if result.final_directors is None else {"director": result.final_directors}
            out.frame(result.t, result.final_positions, result.final_velocities, last)
        out.tables_at_end(result.final_positions)
    out.close()
    hist = np.array(result.history) if result.history else np.zeros((0, len(result.columns)))
    verdicts = checks_mod.evaluate(deck.checks, hist, result.columns, problem.duration)
    resumed = 0 if resume is None else resume["engine"]["result"]["cycles"]
    summary = make_summary(deck_path, deck, problem, result, verdicts, t_compile, out.frames_written, resumed)
    summary["checkpoints"] = {"written": out.checkpoints, "time": out.checkpoint_time,
                              "last": None if out.checkpoint_path is None else out.checkpoint_path.name,
                              "restarted_from_cycle": None if resume is None else resumed}
    if result.status == "failed":
        # the last frame the engine wrote on its schedule holds a state every monitor accepted; the frame written
        # at the failure (if any) shows the state that failed them
        summary["last_good_frame"] = good
        summary["failure_frame"] = ({"index": out.frames_written - 1, "time": out.last_frame_time}
                                    if out.frames_written - 1 > good["index"] else None)
    if result.status == "interrupted":
        code = EXIT_WALL if walled and sig.received is None else 130 if sig.received == signal.SIGINT else 143
    elif result.status == "failed":
        code = EXIT_NUMERIC
    else:
        code = EXIT_CHECK if any(not c["passed"] for c in verdicts) else EXIT_OK
    summary["tables"] = out.tables
    summary["exit_code"] = code
    write_json_atomic(out_dir / "summary.json", summary)
    return code, summary


def make_summary(deck_path, deck, problem, result, verdicts, t_compile, frames, resumed: int = 0) -> dict:
    """summary.json's content. ``resumed``: the cycle a restart continued from; wall time and the timings are this
    process's, so the cost per element-cycle divides them by the cycles run here (``cycles_this_run``)."""
    n_el = problem.n_element
    element_time = sum(v for k, v in result.timings.items() if k.startswith("section"))
    loop_time = sum(result.timings.values())
    per = max(result.cycles - resumed, 1) * max(n_el, 1)
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
        "cycles_this_run": result.cycles - resumed,
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
