"""The ``fdeck`` command: run, validate, info, schema, regress, study, identify.

User mistakes never print a traceback: they are reported as ``file:line:col: path: message`` and exit 2.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Optional

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Explicit FE forming of dry textile reinforcements, driven by YAML decks.")


def _err(msg: str) -> None:
    typer.echo(msg, err=True)


def _read(path: Path):
    """-> (deck, locations) or exit 2 with every located problem."""
    from fdeck.deck.errors import DeckError, format_problems
    from fdeck.deck.read import read_deck

    try:
        deck, locs, warnings = read_deck(path)
    except DeckError as exc:
        _err(format_problems(exc.problems))
        raise typer.Exit(2)
    if warnings:
        _err(format_problems(warnings))
    return deck, locs


def _compile_problems(exc, path: Path, locs):
    from fdeck.deck.read import located

    return [located(str(path), locs, p, m) for p, m in exc.problems]


@app.command()
def validate(decks: list[Path] = typer.Argument(..., help="Deck files (study and identification files too).")):
    """Check decks (schema, names, mesh sets, element geometry, physically absurd figures: cycles, memory, stable
    step floor, travel per cycle) and report every problem at once; a study or identification file (``fdeck
    study``/``identify``) is checked as such, with the deck paths it sets."""
    from fdeck.compile.check import check_deck
    from fdeck.deck.errors import DeckError, format_problems

    bad = False
    for path in decks:
        try:
            kind = _file_kind(path)
            if kind == "study":
                from fdeck.study.study import load_study

                load_study(path)
            elif kind == "ident":
                from fdeck.study.identify import load_ident

                load_ident(path)
            else:
                *_, warnings = check_deck(path)
                if warnings:
                    _err(format_problems(warnings))
            typer.echo(f"{path}: ok" + ("" if kind == "deck" else f" ({kind} file)"))
        except DeckError as exc:
            _err(format_problems(exc.problems))
            bad = True
    raise typer.Exit(2 if bad else 0)


def _file_kind(path: Path) -> str:
    """'study', 'ident' or 'deck': by the schema a file names on its first line (``fdeck schema``), else by its
    top-level keys (a study or identification file names a `base` deck; an identification file its `parameters`)."""
    try:
        with open(path, "rb") as fh:
            first = fh.readline(4096).decode("utf-8", "replace")
    except OSError:
        return "deck"  # check_deck reports the unreadable file, located
    for kind in ("study", "ident"):
        if f"{kind}.schema.json" in first:
            return kind
    if "deck.schema.json" in first:
        return "deck"
    try:
        from fdeck.deck.loader import load_file

        data, _ = load_file(path)
    except Exception:  # noqa: BLE001 -- whatever is wrong, check_deck reports it located
        return "deck"
    if isinstance(data, dict) and "base" in data:
        return "ident" if "parameters" in data else "study"
    return "deck"


def _progress_printer(total: float):
    """Progress: a rich bar on a terminal, plain periodic lines otherwise (CI logs). Rate and time remaining are
    measured from the first report this process sees, so a run continued from a checkpoint (t and cycles far from
    zero at its first report) is not credited with the cycles of the process that wrote the checkpoint."""
    first: list = []  # (wall [s], t [s], cycles) of the first report

    def since_first(t, cycles):
        """-> (wall since the first report [s], cycles per second, time remaining [s]); nan where not yet known."""
        now = time.perf_counter()
        if not first:
            first.append((now, t, cycles))
        w0, t0, c0 = first[0]
        el = now - w0
        rate = (cycles - c0) / el if el > 0 else float("nan")
        eta = el * (total - t) / (t - t0) if t > t0 else float("nan")
        return el, rate, eta

    if sys.stderr.isatty():
        from rich.progress import BarColumn, Progress, TextColumn

        bar = Progress(TextColumn("t = {task.fields[t]:.4g} s"), BarColumn(), TextColumn("{task.fields[rate]}"),
                       transient=True)
        task = bar.add_task("run", total=total, t=0.0, rate="")
        bar.start()

        def update(t, cycles, dt):
            _, rate, eta = since_first(t, cycles)
            bar.update(task, completed=t, t=t, rate=f"{rate:,.0f} cycles/s  dt {dt:.3g} s  ETA {eta:.0f} s")

        return update, bar.stop
    last = [0.0]  # wall of the last line printed, since the first report

    def plain(t, cycles, dt):
        el, rate, eta = since_first(t, cycles)
        if el - last[0] >= 5.0:
            last[0] = el
            _err(f"  t = {t:.4g} / {total:.4g} s ({100 * t / total:5.1f} %), {cycles} cycles, "
                 f"{rate:,.0f} cycles/s, dt {dt:.3g} s, ETA {eta:.0f} s")

    return plain, lambda: None


def _claim_output(deck: Path, out: Path, overwrite: bool, keep: bool):
    """Before a run: read and compile the deck, refusing (exit 2) what ``fdeck validate`` refuses (absurd figures
    included), then claim the result folder unless another deck owns it (``fdeck.io.outdir``). -> (deck card,
    locations, (problem, compile time [s]), ``Claim`` on ``out``); the problem goes to ``execute`` unrun.
    ``keep``: a restart continues the folder's run, so none of its files are stale."""
    import time

    from fdeck.compile.check import check_deck
    from fdeck.deck.errors import DeckError, format_problems
    from fdeck.io.outdir import OutdirError, claim

    t0 = time.perf_counter()
    try:
        d, locs, problem, warnings = check_deck(deck)
    except DeckError as exc:
        _err(format_problems(exc.problems))
        raise typer.Exit(2)
    t_compile = time.perf_counter() - t0
    if warnings:
        _err(format_problems(warnings))
    try:
        return d, locs, (problem, t_compile), claim(out, deck, overwrite, restart=keep)
    except OutdirError as exc:
        _err(f"{deck}: {exc}")
        raise typer.Exit(2)


def _after_first_frame(progress, hook):
    """``progress`` that calls ``hook()`` (which acts once) before each report: the engine reports progress only
    after the initial frame is written."""
    def wrapped(*args):
        hook()
        return progress(*args)

    return wrapped


@app.command()
def run(deck: Path = typer.Argument(..., help="Deck file."),
        out: Optional[Path] = typer.Option(None, "-o", "--out", help="Result folder (default results/<deck name>/)."),
        checkpoint: Optional[Path] = typer.Argument(None, metavar="[FILE]",
                                                    help="With --restart: the checkpoint to continue from."),
        restart: bool = typer.Option(
            False, "--restart",
            help="Continue from a checkpoint: FILE (`fdeck run DECK --restart FILE`), or without it the newest valid "
                 "one in the result folder (a damaged newer one is skipped with a message). The deck may add steps "
                 "after the checkpoint's last one; a checkpoint of another deck or fdeck version is refused "
                 "(exit 2)."),
        max_wall: Optional[float] = typer.Option(
            None, "--max-wall", min=0.0, metavar="SECONDS",
            help="Stop after this much wall time with a checkpoint, a last frame and the summary; exit 124 (as "
                 "timeout); continue with --restart."),
        overwrite: bool = typer.Option(
            False, "--overwrite",
            help="Write into a result folder that holds another deck's results (or files no fdeck run marked); "
                 "that run's files are removed once the new run has written its first frame, other files are kept.")):
    """Run a deck: frames (VTU/PVD, XDMF/HDF5), history.csv and summary.json in the result folder."""
    from fdeck.compile.errors import CompileError
    from fdeck.deck.errors import format_problems
    from fdeck.io.outdir import OutdirError
    from fdeck.run import RestartError, execute, timing_table

    if checkpoint is not None and not restart:
        _err(f"{checkpoint}: a checkpoint file is only read with --restart")
        raise typer.Exit(2)
    out = out or Path("results") / deck.stem
    d, locs, compiled, claim = _claim_output(deck, out, overwrite, keep=restart)
    if restart:
        restart = str(checkpoint) if checkpoint is not None else True
    progress, stop = _progress_printer(d.duration)
    progress = _after_first_frame(progress, claim.first_frame)
    try:
        code, summary = execute(d, deck.parent, out, deck.stem, str(deck), progress, echo=_err,
                                restart=restart or None, max_wall=max_wall, compiled=compiled)
    except CompileError as exc:
        stop()
        _err(format_problems(_compile_problems(exc, deck, locs)))
        raise typer.Exit(2)
    except RestartError as exc:
        stop()
        _err(f"{deck}: cannot restart: {exc}")
        raise typer.Exit(2)
    except OutdirError as exc:
        stop()
        _err(f"{deck}: {exc}")
        raise typer.Exit(2)
    stop()
    claim.finish()
    typer.echo(f"{deck}: {summary['status']} after {summary['cycles']} cycles, {summary['wall_time']:.2f} s wall, "
               f"{summary['us_per_element_cycle']:.3f} us per element-cycle, "
               f"{summary['elements']} elements, dt {summary['dt_min'] or 0:.3g}..{summary['dt_max'] or 0:.3g} s")
    typer.echo("where the time went:\n" + timing_table(summary))
    for c in summary["checks"]:
        typer.echo(f"  check {c['name']:<15s} {c['value']:.4g} (limit {c['limit']:.4g}): "
                   f"{'pass' if c['passed'] else 'FAIL'}")
    typer.echo(f"results in {out}/")
    if summary["status"] == "failed":
        typer.echo(f"FAILED: {summary['message']}")
    elif summary["status"] == "interrupted":
        typer.echo(f"INTERRUPTED: {summary['message']}; continue with --restart"
                   + (f" (checkpoint {summary['checkpoints']['last']})" if summary["checkpoints"]["last"] else ""))
    elif code == 3:
        failed = [c["name"] for c in summary["checks"] if not c["passed"]]
        typer.echo(f"CHECK FAILED: {', '.join(failed)}")
    raise typer.Exit(code)


@app.command()
def info(deck: Path = typer.Argument(..., help="Deck file.")):
    """What a deck will do: sizes, stable time step, cycles, memory, the effects that will run, the files it
    reads (resolved paths)."""
    from fdeck.compile.check import check_deck
    from fdeck.compile.problem import rest_dt
    from fdeck.deck.errors import DeckError, format_problems

    try:
        d, locs, p, warnings = check_deck(deck)
    except DeckError as exc:
        _err(format_problems(exc.problems))
        raise typer.Exit(2)
    if warnings:
        _err(format_problems(warnings))
    typer.echo(f"{deck}: {d.title}")
    from fdeck.compile.check import read_paths

    for what, where in read_paths(d, deck.parent):
        typer.echo(f"  reads {what}: {where}")
    typer.echo(f"  nodes {p.n_node}, elements {p.n_element}, duration {p.duration:.4g} s, units {d.units}")
    from fdeck import registry

    for name, card in d.materials.items():
        entry = registry.CARDS["material"][card.type]
        if entry.kind:  # a named card: say what it expands to
            implies = f", implies section formulation {entry.formulation}" if entry.formulation else ""
            typer.echo(f"  material {name}: {card.type} = {entry.kind} with preset {card.preset}{implies}")
    cycles, mem = 0, 0
    for k, (plan, step) in enumerate(zip(p.steps, d.steps)):
        alpha = step.damping.mass_proportional if step.damping else 0.0
        on = " (on M + dM: the added mass too)" if alpha > 0 and step.damping.added_mass else ""
        deform = f", deformation damping {step.deformation_damping.rate:g} 1/s" if step.deformation_damping else ""
        dts = []
        for i, (g, rho) in enumerate(zip(p.groups, plan.rho)):
            dts.append(plan.dt_safety * float(np.min(rest_dt(g, rho, p.effects, plan.translational(i)))))
            g.set_density(rho)  # as the engine does at the step's start, before the effects' bounds below
        dt, by = min(dts), ""
        for e in p.effects:  # effects' own bounds at the step's start (contact springs, a tool's travel, ...)
            e.begin_step(k, plan)
            if plan.dt_safety * e.stable_dt() < dt:
                dt, by = plan.dt_safety * e.stable_dt(), f" (set by {e.name})"
        cycles += int(np.ceil(plan.duration / dt))
        typer.echo(f"  step {plan.name}: rest stable dt {dt:.4g} s{by}, ~{int(np.ceil(plan.duration / dt))} cycles, "
                   f"added mass {100 * plan.added_mass:.3g} %, damping alpha {alpha:g} 1/s{on}{deform}"
                   + (f", max_cycles {plan.max_cycles}" if plan.max_cycles else ""))
    for g in p.groups:
        mem += sum(a.nbytes for a in vars(g).values() if isinstance(a, np.ndarray) and a.base is None)
        typer.echo(f"  group {g.name}: {len(g.conn)} {g.cell_type}, {g.formulation}, material {g.material.name}"
                   + (f", rotational inertia +{100 * g.added_rotational_inertia:.3g} % over rho h^3/12 (so rotations "
                      "do not set the step)" if g.rotational else ""))
    typer.echo(f"  effects: {', '.join(e.name for e in p.effects) or 'none'}")
    for name, tool in d.tools.items():
        mo = tool.motion
        unit = {"displacement": "mm", "velocity": "mm/s", "force": "N"}
        motion = "fixed" if mo is None else (
            f"{mo.kind} {mo.value:g} {unit[mo.kind]} along {list(mo.direction)}, amplitude {mo.amplitude_name}"
            + (f", mass {mo.mass:g} t" if mo.mass is not None else ""))
        where = f" '{tool.surface.file}'" if tool.surface.shape == "mesh" else ""
        typer.echo(f"  tool {name}: {tool.surface.shape}{where}, {motion}")
    for e in p.effects:
        line = e.describe(p.steps[0])
        if line:
            typer.echo(f"  {line}")
    typer.echo(f"  about {cycles} cycles in all (the step follows the current tangent, so it may differ); "
               f"element arrays {mem / 2**20:.1f} MiB")


@app.command()
def schema(out: Path = typer.Option(Path("schemas"), "--out", help="Folder for the *.schema.json files.")):
    """Write the JSON schemas of decks, study files and identification files (for editors: yaml-language-server)."""
    from fdeck.deck.schema import deck_schema
    from fdeck.study.models import json_schemas

    out.mkdir(parents=True, exist_ok=True)
    for name, schema_dict in {"deck.schema.json": deck_schema(), **json_schemas()}.items():
        (out / name).write_text(json.dumps(schema_dict, indent=1, sort_keys=True) + "\n")
        typer.echo(f"wrote {out / name}")


@app.command()
def regress(cases: list[str] = typer.Argument(None, help="Case names (default: all)."),
            update: bool = typer.Option(False, "--update", help="Rewrite the gold files from a fresh run."),
            root: Path = typer.Option(Path("decks/regression"), help="Folder of regression cases.")):
    """Run regression cases and compare with gold; --update rewrites gold (on purpose only)."""
    from fdeck.regression import run_case

    names = cases or sorted(p.name for p in root.iterdir() if (p / "spec.yaml").exists())
    bad = 0
    for name in names:
        ok, report = run_case(root / name, update=update)
        typer.echo(report)
        bad += not ok
    raise typer.Exit(1 if bad else 0)


_SCHEDULER_HELP = "Dask scheduler address (default: env FDECK_SCHEDULER; none: a local process pool)."


def _pool_or_exit(scheduler, workers):
    """The run pool, or exit 2 when Dask is asked for but not installed."""
    import os

    from fdeck.study.executor import SCHEDULER_ENV, Pool

    if (scheduler or os.environ.get(SCHEDULER_ENV)) and importlib.util.find_spec("distributed") is None:
        _err("a Dask scheduler was given but the 'distributed' package is not installed (pip install 'fdeck[dask]')")
        raise typer.Exit(2)
    return Pool(scheduler, workers)


@app.command()
def study(spec: Path = typer.Argument(..., help="Study file (STUDY.yaml)."),
          out: Optional[Path] = typer.Option(None, "-o", "--out", help="Folder (default results/<study name>/)."),
          scheduler: Optional[str] = typer.Option(None, "--scheduler", help=_SCHEDULER_HELP),
          workers: Optional[int] = typer.Option(None, "--workers", min=1, help="Local pool size (default: CPUs).")):
    """Run a deck's variants; study.csv, study.json, study.png (error against wall time) and the cheapest variant
    within the study's tolerance. Exit 0, 2 bad input, 3 no variant within the tolerance or no reference."""
    from fdeck.deck.errors import DeckError, format_problems
    from fdeck.study import report
    from fdeck.study.study import run_study

    out = out or Path("results") / spec.stem
    try:
        with _pool_or_exit(scheduler, workers) as pool:
            table = run_study(spec, out, pool, echo=typer.echo)
    except DeckError as exc:
        _err(format_problems(exc.problems))
        raise typer.Exit(2)
    files = report.write(table, out)
    typer.echo(report.text(table))
    typer.echo("wrote " + ", ".join(str(f) for f in files))
    raise typer.Exit(0 if table["cheapest"] else 3)


@app.command()
def identify(spec: Path = typer.Argument(..., help="Identification file (IDENT.yaml)."),
             out: Optional[Path] = typer.Option(None, "-o", "--out", help="Folder (default results/<file name>/)."),
             scheduler: Optional[str] = typer.Option(None, "--scheduler", help=_SCHEDULER_HELP),
             workers: Optional[int] = typer.Option(None, "--workers", min=1, help="Local pool size (default: CPUs).")):
    """Fit deck parameters to measured values (least squares); identify.json, the fitted preset. Exit 0, 2 bad
    input, 4 a run gave no answer, 3 the fit stopped before converging."""
    from fdeck.deck.errors import DeckError, format_problems
    from fdeck.io.summary import write_json_atomic
    from fdeck.study.identify import IdentifyError, run_identify, text

    out = out or Path("results") / spec.stem
    try:
        with _pool_or_exit(scheduler, workers) as pool:
            result = run_identify(spec, out, pool, echo=typer.echo)
    except DeckError as exc:
        _err(format_problems(exc.problems))
        raise typer.Exit(2)
    except IdentifyError as exc:
        _err(f"{spec}: {exc}")
        raise typer.Exit(4)
    write_json_atomic(out / "identify.json", result)
    typer.echo(text(result))
    typer.echo(f"wrote {out / 'identify.json'}")
    raise typer.Exit(0 if result["status"] == "converged" else 3)


import importlib.util  # noqa: E402  (used by `study` and `identify`)

import numpy as np  # noqa: E402  (used by `info`; kept below the commands so --help stays fast to read)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
