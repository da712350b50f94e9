"""Running resolved decks: in a local process pool (default) or on a Dask distributed cluster, with a cache.

Each run goes through ``fdeck.run.execute``, the function behind ``fdeck run``, in the worker process itself rather
than in a subprocess per run: a subprocess would re-import fdeck and reload numba's cached kernels each time (about
2.5 s per run on the CI machine, more than a small variant's whole run), while a pool worker pays it once. Isolation
is kept where it matters: every run has its own result folder and its failure (an invalid deck, a bad geometry, a
numerical failure, any exception) comes back as a row with its status, never as a lost study; a worker that dies
is reported as status ``error`` and is not cached, so the next run of the study retries it.

Workers run each deck on one numba thread (``NUMBA_NUM_THREADS=1`` before numba is imported, and
``numba.set_num_threads(1)`` per run): parallelism is across variants, and a run's arithmetic does not depend on
where it ran, so tables from the local pool and from Dask agree bitwise. Dask is imported only when a scheduler
address is given (``--scheduler ADDRESS`` or the environment variable ``FDECK_SCHEDULER``); its workers must see the
deck folders and the output folder at the same paths (a shared file system; results are also returned to the
client, which writes the cache records).

The cache: ``<out>/runs/<digest>/`` holds a run's frames, history and summary and ``result.json``, the record the
client writes when a run ends (completed, failed, check failed, invalid). A record whose digest matches is reused.
"""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

SCHEDULER_ENV = "FDECK_SCHEDULER"
RESULT = "result.json"


def _init_worker():
    os.environ["NUMBA_NUM_THREADS"] = "1"
    _die_with_parent()


def _die_with_parent() -> None:
    """Ask Linux to send this pool worker SIGTERM when the study process that spawned it dies (prctl
    PR_SET_PDEATHSIG): a killed study must not leave workers running its variants (they would burn the cores and
    hold their run folders; SIGTERM lets a run stop as it does for ``fdeck run``, keeping its frames). Elsewhere a
    no-op. The pool spawns its workers from the study's main thread, whose exit is what the kernel watches. A run
    stopped so returns normally; ``run_task`` then ends the orphaned worker (``_exit_if_orphaned``), which would
    otherwise wait for its next task forever (it holds both ends of the pool's queues itself)."""
    import multiprocessing
    import signal
    import sys

    if not sys.platform.startswith("linux"):
        return
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    PR_SET_PDEATHSIG = 1
    libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    parent = multiprocessing.parent_process()
    if parent is not None and os.getppid() != parent.pid:  # the parent died before the request was made
        os.kill(os.getpid(), signal.SIGTERM)


_WARM: set[str] = set()  # skeletons of the decks this process has already warmed up


def _skeleton(deck) -> str:
    """The deck's structure without its numbers and mesh (types, formulations, effects present): decks with the
    same skeleton call the same kernels."""
    def strip(v):
        if isinstance(v, dict):
            return {k: strip(x) for k, x in v.items() if k != "mesh"}
        if isinstance(v, list):
            return [strip(x) for x in v[:1]]
        return v if isinstance(v, str) else type(v).__name__
    return json.dumps(strip(deck), sort_keys=True)


def _warm_up(run_mod, deck, base_dir: Path) -> None:
    """Run two cycles of every step of ``deck`` once per process and skeleton, so the variant's wall time does not
    include numba loading or compiling its kernels (seconds, against runs of seconds: the cost column would
    otherwise rank variants by the order they reached a worker)."""
    import tempfile

    key = _skeleton(deck.model_dump(mode="json"))
    if key in _WARM:
        return
    short = deck.model_copy(update={"steps": [s.model_copy(update={"max_cycles": 2}) for s in deck.steps]})
    with tempfile.TemporaryDirectory(prefix="fdeck-warm-") as tmp:
        run_mod.execute(short, base_dir, Path(tmp), "warm", "warm")
    _WARM.add(key)


def _problems_text(exc) -> str:
    from fdeck.deck.errors import format_path

    return "; ".join(f"{format_path(e['loc'])}: {e['msg']}" for e in exc.errors(include_url=False))


def _compile_problems_text(exc) -> str:
    """A CompileError's located problems on one line (a row's message)."""
    from fdeck.deck.errors import format_path

    return "; ".join(f"{format_path(p)}: {m}" for p, m in exc.problems)


def _exit_if_orphaned() -> None:
    """End this process (exit 143, as for SIGTERM) when it is a pool worker whose parent has died."""
    import multiprocessing

    parent = multiprocessing.parent_process()
    if parent is not None and not parent.is_alive():
        os._exit(143)


def run_task(task: dict) -> dict:
    """``_run_task`` in a pool worker that ends itself when its study process died during the run."""
    try:
        return _run_task(task)
    finally:
        _exit_if_orphaned()


def _run_task(task: dict) -> dict:
    """Validate and run one resolved deck (``task``: deck, base_dir, out_dir, name, static) through
    ``fdeck.run.execute``, or solve it statically (``study.static_run``) when ``task["static"]`` holds options.
    Returns the run's summary dict plus ``status`` (completed, failed, interrupted, check_failed, invalid, error)
    and ``message``; never raises for a problem of the deck or the run."""
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    t0 = time.perf_counter()
    try:
        import numba
        from pydantic import ValidationError

        import fdeck.run as run_mod
        from fdeck.compile.errors import CompileError
        from fdeck.deck.errors import format_path
        from fdeck.deck.model import Deck, cross_reference_problems

        numba.set_num_threads(1)
        try:
            deck = Deck.model_validate(task["deck"])
        except ValidationError as exc:
            return {"status": "invalid", "message": _problems_text(exc), "wall_time": time.perf_counter() - t0}
        errors = [f"{format_path(p)}: {m}" for p, m, sev in cross_reference_problems(deck) if sev == "error"]
        if errors:
            return {"status": "invalid", "message": "; ".join(errors), "wall_time": time.perf_counter() - t0}
        out = Path(task["out_dir"])
        if task.get("static") is not None:
            from fdeck.study.static_run import run_static

            try:
                return run_static(task["deck"], Path(task["base_dir"]), out, task["static"], task.get("seed"))
            except CompileError as exc:
                return {"status": "invalid", "message": _compile_problems_text(exc),
                        "wall_time": time.perf_counter() - t0}
        try:
            _warm_up(run_mod, deck, Path(task["base_dir"]))
            code, summary = run_mod.execute(deck, Path(task["base_dir"]), out, task["name"], task["name"])
        except CompileError as exc:
            return {"status": "invalid", "message": _compile_problems_text(exc),
                    "wall_time": time.perf_counter() - t0}
        summary = json.loads((out / "summary.json").read_text())  # the JSON form: what a re-run reads back
        if summary["status"] == "completed" and code == 3:
            summary["status"] = "check_failed"
            summary["message"] = "failed checks: " + ", ".join(c["name"] for c in summary["checks"] if not c["passed"])
        return summary
    except Exception as exc:  # noqa: BLE001  (a study keeps every row: the exception becomes the row's message)
        return {"status": "error", "message": f"{type(exc).__name__}: {exc}", "wall_time": time.perf_counter() - t0}


class Pool:
    """Where runs go: a local process pool of ``workers`` processes (default: the CPU count), or the Dask
    scheduler at ``scheduler`` (default: the FDECK_SCHEDULER environment variable, if set)."""

    def __init__(self, scheduler: str | None = None, workers: int | None = None):
        self.address = scheduler or os.environ.get(SCHEDULER_ENV) or None
        self.workers = workers
        self._local = None
        self._client = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def describe(self) -> str:
        return f"Dask scheduler {self.address}" if self.address else f"local pool of {self._n_local()} processes"

    def _n_local(self) -> int:
        return self.workers or os.cpu_count() or 1

    def _submit_all(self, tasks: list[dict]):
        """-> list of futures in task order, and the as_completed function fitting them."""
        if self.address:
            if self._client is None:
                from distributed import Client  # Dask only when asked for

                self._client = Client(self.address)
            from distributed import as_completed as dask_completed

            return self._client.map(run_task, tasks, pure=False), dask_completed
        if self._local is None:
            import multiprocessing

            self._local = ProcessPoolExecutor(self._n_local(), mp_context=multiprocessing.get_context("spawn"),
                                              initializer=_init_worker)
        return [self._local.submit(run_task, t) for t in tasks], as_completed

    def run(self, tasks: list[dict], on_done=None) -> list[dict]:
        """Results of ``run_task`` in task order; a lost worker gives status ``error``. ``on_done(i, result)`` is
        called as each finishes."""
        if not tasks:
            return []
        futures, completed = self._submit_all(tasks)
        index = {id(f): i for i, f in enumerate(futures)}
        out: list[dict] = [{}] * len(tasks)
        for fut in completed(futures):
            i = index[id(fut)]
            try:
                out[i] = fut.result()
            except Exception as exc:  # noqa: BLE001  (a worker died: the row says so and is not cached)
                out[i] = {"status": "error", "message": f"worker lost: {type(exc).__name__}: {exc}"}
            if on_done:
                on_done(i, out[i])
        return out

    def close(self):
        if self._local is not None:
            self._local.shutdown()
            self._local = None
        if self._client is not None:
            self._client.close()
            self._client = None


CACHEABLE = ("completed", "failed", "check_failed", "invalid")


def run_cached(pool: Pool, planned: list, out_dir: Path, on_done=None) -> list[dict]:
    """Run every Planned (``variants.Planned``) not already in the cache ``out_dir/runs/<digest>/result.json``;
    identical decks in one call run once. Each result gets ``reused`` (bool) and ``run_dir``."""
    from fdeck.io.summary import write_json_atomic

    runs = out_dir / "runs"
    results: dict[str, dict] = {}
    todo: dict[str, object] = {}
    for p in planned:
        rec = runs / p.digest / RESULT
        if p.digest in results or p.digest in todo:
            continue
        if rec.is_file():
            results[p.digest] = {**json.loads(rec.read_text()), "reused": True}
        else:
            todo[p.digest] = p
    tasks = [{"deck": p.deck, "base_dir": str(Path(p.base_dir).resolve()), "out_dir": str((runs / d).resolve()),
              "name": p.name, "static": p.solver, "seed": p.seed} for d, p in todo.items()]
    digests = list(todo)

    def done(i, res):
        if res.get("status") in CACHEABLE:
            (runs / digests[i]).mkdir(parents=True, exist_ok=True)
            write_json_atomic(runs / digests[i] / RESULT, {**res, "digest": digests[i]})
        if on_done:
            on_done(todo[digests[i]], res)

    for d, res in zip(digests, pool.run(tasks, done)):
        results[d] = {**res, "reused": False}
    return [{**results[p.digest], "run_dir": str(runs / p.digest), "digest": p.digest} for p in planned]
