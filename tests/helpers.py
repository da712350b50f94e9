"""Shared helpers for tests: build decks from dicts or files and run them in-process."""

from __future__ import annotations

import copy
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks"


def deck_data(name: str) -> dict:
    """The plain data of a deck in decks/ (through fdeck's own loader)."""
    from fdeck.deck.loader import load_file

    data, _ = load_file(DECKS / name)
    return copy.deepcopy(data)


def run_data(data: dict, base: Path = DECKS):
    """Validate, compile and run deck data; returns (problem, result, history dict of columns)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    deck = Deck.model_validate(data)
    problem = compile_deck(deck, base)
    result = solver.run(problem, solver.Sink())
    h = np.array(result.history)
    return problem, result, {c: h[:, i] for i, c in enumerate(result.columns)}


def merge(data: dict, **changes) -> dict:
    """Copy of data with top-level keys replaced."""
    out = copy.deepcopy(data)
    out.update(changes)
    return out


def digests_on_one_and_two_threads(script: str, *args: str) -> set:
    """Run ``python -c script *args`` from the repository root with NUMBA_NUM_THREADS=1, then 2; the script prints
    its thread count and a digest of its results. Each run must succeed on the threads asked for; returns the set of
    digests (one element when the runs are bitwise equal)."""
    digests = set()
    for threads in ("1", "2"):
        env = dict(os.environ, NUMBA_NUM_THREADS=threads)
        r = subprocess.run([sys.executable, "-c", script, *args], cwd=ROOT, env=env, capture_output=True, text=True,
                           timeout=600)
        assert r.returncode == 0, r.stderr
        n, digest = r.stdout.split()
        assert n == threads, f"asked for {threads} threads, ran on {n}"
        digests.add(digest)
    return digests


def central_gradient(f, x: np.ndarray, h: float) -> np.ndarray:
    """df/dx of a scalar function of an array by central differences: (f(x + h e) - f(x - h e)) / 2h, entry by
    entry (x + h e evaluated before x - h e); shaped as x."""
    g = np.zeros(np.shape(x))
    for idx in np.ndindex(g.shape):
        xp, xm = x.copy(), x.copy()
        xp[idx] += h
        xm[idx] -= h
        g[idx] = (f(xp) - f(xm)) / (2 * h)
    return g


def central_stiffness(force, x: np.ndarray, h: float) -> np.ndarray:
    """Symmetrised tangent (3 n x 3 n) of nodal forces force(x) (n, 3) -> (n, 3) at positions x (n, 3) by central
    differences, column j = (force(x + h e_j) - force(x - h e_j)) / 2h, then (K + K^T) / 2."""
    n = x.size
    K = np.zeros((n, n))
    for j in range(n):
        xp, xm = x.copy(), x.copy()
        xp.flat[j] += h
        xm.flat[j] -= h
        K[:, j] = (np.ravel(force(xp)) - np.ravel(force(xm))) / (2 * h)
    return 0.5 * (K + K.T)


def symmetric_central_gradient(f, C: np.ndarray, h: float) -> np.ndarray:
    """df/dC of a scalar function of a symmetric 3 x 3 C by central differences, with the symmetric convention:
    C_ij and C_ji perturbed together by h/2 each (by h on the diagonal)."""
    g = np.zeros((3, 3))
    for i, j in np.ndindex(3, 3):
        E = np.zeros((3, 3))
        E[i, j] += 0.5 * h
        E[j, i] += 0.5 * h
        g[i, j] = (f(C + E) - f(C - E)) / (2 * h)
    return g


def stored_energy(source) -> float:
    """Sum of the stored ledger terms of a group or effect [mJ] (``engine.ledger``)."""
    return sum(v for t, v in zip(source.terms, source.term_values()) if t.kind == "stored")


def term(source, name: str) -> float:
    """Value of one named ledger term of a group or effect."""
    return dict(zip((t.name for t in source.terms), source.term_values()))[name]


def run_once_per_session(tmp_path_factory, name: str, deck: Path, timeout: float = 1800):
    """``fdeck run DECK -o FOLDER`` (one numba thread) once per test session, whichever pytest-xdist worker asks
    first; the others wait for it and get the same folder. Why: a module-scoped fixture runs once per *worker*, and
    with ``--dist worksteal`` the tests of one module may land on both workers, which ran the coarse tetrahedron
    twice (2 x 100 s of CI). Returns (folder, SimpleNamespace(returncode, stdout, stderr))."""
    import fcntl
    import json
    from types import SimpleNamespace

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # shared by the workers of this session
    folder, record = root / f"shared_{name}", root / f"shared_{name}.json"
    with open(root / f"shared_{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not record.is_file():
            folder.mkdir(parents=True, exist_ok=True)
            r = subprocess.run([sys.executable, "-m", "fdeck.cli", "run", str(deck), "-o", str(folder)], cwd=ROOT,
                               env=dict(os.environ, NUMBA_NUM_THREADS="1"), capture_output=True, text=True,
                               timeout=timeout)
            record.write_text(json.dumps({"returncode": r.returncode, "stdout": r.stdout, "stderr": r.stderr}))
    return folder, SimpleNamespace(**json.loads(record.read_text()))


def same_bits_where_not_nan(a, b) -> bool:
    """Equal to the last bit (signed zeros included) where a is not NaN, and NaN at the same places (a NaN's sign
    and payload not compared): the block paths' promise against the point laws (``fabric_hyper_blocks``)."""
    a, b = np.ascontiguousarray(a, float), np.ascontiguousarray(b, float)
    nan = np.isnan(a)
    return (a.shape == b.shape and np.array_equal(nan, np.isnan(b))
            and np.array_equal(a[~nan].view(np.uint64), b[~nan].view(np.uint64)))


def block_path_taken(module, p, F, frame) -> tuple[bool, bool]:
    """Whether ``module.evaluate`` (a law's block path, through ``blocks.run``) takes the points F (n_el, n_qp, 3, 3)
    with the parameter row p given per element (tiled: not what a section compiles to), then as a broadcast row."""
    n_el, n_qp = F.shape[:2]
    out = np.zeros((n_el, n_qp, 3, 3)), np.zeros((n_el, n_qp)), np.zeros((n_el, n_qp, 3))
    state = np.zeros((n_el, n_qp, 0))
    rows = np.tile(p, (n_el, 1))
    return module.evaluate(F, frame, rows, state, *out), module.evaluate(F, frame, np.broadcast_to(p, rows.shape),
                                                                         state, *out)


def runs_with_and_without(monkeypatch, module, data: dict):
    """Run the deck ``data`` through the solver twice: first with ``module.evaluate`` (a law's block path) as it is,
    recording whether each call took it, then with it declining every call (the point path).
    -> (taken: list of bool, (history, final positions) with it, the same without it)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    def run():
        res = solver.run(compile_deck(Deck.model_validate(data)), solver.Sink())
        assert res.status == "completed", res.message
        return np.array(res.history), res.final_positions

    taken = []
    block_path = module.evaluate
    monkeypatch.setattr(module, "evaluate", lambda *a: taken.append(block_path(*a)) or taken[-1])
    with_path = run()
    monkeypatch.setattr(module, "evaluate", lambda *a: False)
    return taken, with_path, run()
