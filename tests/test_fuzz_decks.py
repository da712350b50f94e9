"""Decks fuzzed with hypothesis: mutations of every shipped deck never crash `fdeck validate` or `fdeck run`.

Profiles (env FDECK_FUZZ): ``fast`` (default run, derandomized, some 40 CPU-seconds) and ``nightly`` (>= 500
examples of validation, random seeds, marked nightly). Mutations: a value replaced by one of the wrong type or sign,
NaN, +-inf, a huge or tiny number, an empty list or mapping; a key deleted; an unknown key added; a key misspelt; a
name replaced by an unknown one; text-level: an anchor and an alias, merge keys, non-UTF-8 bytes, a truncated file,
an empty file, an alias bomb.

The reference is the contract of the command line (README, "A deck"): exit 0 (ok) or 2, no exception escaping
(CliRunner's ``exception`` is None or SystemExit), and every stderr line of a refused deck located as
``file:line:col:``; decks that validate, run with every step capped at 3 cycles, end with 0, 3 or 4 within a time
limit.
"""

from __future__ import annotations

import copy
import math
import os
import re
import signal
import subprocess
import tempfile
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from fdeck.cli import app
from fdeck.compile.sanity import estimated_elements
from fdeck.deck.errors import DeckError
from fdeck.deck.loader import load_file
from fdeck.deck.read import read_deck
from helpers import DECKS

pytestmark = pytest.mark.unit

PROFILE = os.environ.get("FDECK_FUZZ", "fast")
settings.register_profile("fast", max_examples=60, derandomize=True, deadline=None, database=None,
                          suppress_health_check=list(HealthCheck))
settings.register_profile("nightly", max_examples=500, deadline=None, database=None,
                          suppress_health_check=list(HealthCheck))
FAST = settings.get_profile(PROFILE)  # FDECK_FUZZ=nightly turns the default tests into the long ones too
NIGHTLY = settings.get_profile("nightly")



def _shipped() -> list[Path]:
    """Tracked YAML files under decks/ (git ls-files; every file when git is not there) that are decks: a
    top-level `mesh` (not study files or regression specs)."""
    try:
        names = subprocess.run(["git", "ls-files", "*.yaml"], cwd=DECKS, capture_output=True, text=True,
                               check=True).stdout.split()
        files = [DECKS / n for n in names]
    except (OSError, subprocess.CalledProcessError):
        files = list(DECKS.rglob("*.yaml"))
    return sorted(p for p in files if isinstance(d := yaml.safe_load(p.read_text()), dict) and "mesh" in d)


DECK_FILES = _shipped()
TINY = 500  # elements: above this a mutated deck is only read and checked, not compiled (CI time)
RUN_SECONDS = 120  # time limit of one fuzzed run of at most 3 cycles per step (compile + frames), generous on a
#                   loaded 2-core machine; a hang is what it catches
LOCATED = re.compile(r"^(?P<file>.+?):(?P<line>\d+):(?P<col>\d+): ")
COUNT = {"validated": 0, "refused": 0, "run": 0}


def _absolute_files(data, base: Path):
    """Mesh and tool files made absolute, so the mutated deck can live in a temporary folder."""
    if isinstance(data, dict):
        mesh = data.get("mesh")
        if isinstance(mesh, dict) and isinstance(mesh.get("file"), str):
            mesh["file"] = str(base / mesh["file"])
        for tool in (data.get("tools") or {}).values() if isinstance(data.get("tools"), dict) else ():
            surf = tool.get("surface") if isinstance(tool, dict) else None
            if isinstance(surf, dict) and isinstance(surf.get("file"), str):
                surf["file"] = str(base / surf["file"])
    return data


ORIGINALS = {p: _absolute_files(load_file(p)[0], p.parent) for p in DECK_FILES}


def _paths(node, prefix=()):
    """Every path to a value of the document (mappings, lists and leaves)."""
    out = [prefix]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, prefix + (i,))
    return out


BAD_VALUES = st.sampled_from([None, "", "nosuch", True, False, 0, -1, -1.0, 1e300, -1e300, 1e-300, 10**30,
                              math.nan, math.inf, -math.inf, [], {}, [1, 2], {"a": 1}, "1e999", "-.inf", 2**63])


@st.composite
def mutated(draw):
    """(deck file, YAML bytes of a mutation of it)."""
    src = draw(st.sampled_from(DECK_FILES))
    data = copy.deepcopy(ORIGINALS[src])
    kind = draw(st.sampled_from(["value", "value", "delete", "unknown", "misspell", "name", "anchor", "bytes",
                                 "truncate", "empty", "bomb"]))
    paths = _paths(data)
    path = draw(st.sampled_from(paths[1:]))
    parent = data
    for el in path[:-1]:
        parent = parent[el]
    if kind == "value":
        parent[path[-1]] = draw(BAD_VALUES | st.floats() | st.integers() | st.text(max_size=20))
    elif kind == "delete":
        del parent[path[-1]]
    elif kind == "unknown" and isinstance(parent, dict):
        parent[draw(st.text(min_size=1, max_size=12))] = draw(BAD_VALUES)
    elif kind == "misspell" and isinstance(parent, dict) and isinstance(path[-1], str) and path[-1]:
        key = path[-1]
        i = draw(st.integers(0, len(key) - 1))
        parent[key[:i] + key[i + 1:] + "x"] = parent.pop(key)
    elif kind == "name" and isinstance(parent[path[-1]], str):
        parent[path[-1]] = parent[path[-1]] + "_typo"
    text = yaml.safe_dump(data, sort_keys=False).encode()
    if kind == "anchor":  # a mapping value anchored, then the same node aliased and merged elsewhere
        text = b"base: &b {duration: 1.0e-4, name: s}\n" + text.replace(b"steps:\n", b"steps:\n- *b\n- <<: *b\n", 1)
    elif kind == "bytes":
        at = draw(st.integers(0, len(text)))
        text = text[:at] + draw(st.sampled_from([b"\xff", b"\xc3\x28", b"\x00", b"\x80\x80", b"\xed\xa0\x80"])) \
            + text[at:]
    elif kind == "truncate":
        text = text[:draw(st.integers(0, len(text)))]
    elif kind == "empty":
        text = draw(st.sampled_from([b"", b"\n", b"---\n", b"~\n", b"[]\n", b"42\n"]))
    elif kind == "bomb":
        text = b"a: &a [x, x, x, x, x, x, x, x, x, x]\n" + b"".join(
            b"%c: &%c [%s]\n" % (c, c, b", ".join([b"*" + bytes([c - 1])] * 10)) for c in range(ord("b"), ord("h")))
    return src, text


def _located(stderr: str, path: Path) -> None:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert lines, "a refused deck must say why"
    for ln in lines:
        m = LOCATED.match(ln)
        assert m and m["file"] == str(path), f"not located as file:line:col: {ln!r}"


TINY_FILE = 64 * 1024  # bytes: mesh files up to this size are compiled too (the 3WEAVE bias mesh, 20 kB, some
#                       200 elements; the bias shell coupon, 57 kB)


def _small(path: Path) -> bool:
    """The mutated deck reads, and its mesh is tiny (so compiling it costs little): a built-in mesh of at most
    TINY elements, or a mesh file of at most TINY_FILE bytes (or a missing one)."""
    try:
        deck, _, _ = read_deck(path)
    except DeckError:
        return True  # refused before compiling: as cheap as it gets
    if deck.mesh.file is not None:
        mesh = Path(deck.mesh.file)
        return not mesh.is_file() or mesh.stat().st_size <= TINY_FILE
    n = estimated_elements(deck)
    return n is not None and n <= TINY


def _validate(path: Path) -> int:
    """`fdeck validate` in-process on a small deck; the deck layer (read, schema, names, absurd figures that need
    no mesh) for a big one. Checks the contract and returns the exit code."""
    if _small(path):
        r = CliRunner().invoke(app, ["validate", str(path)])
        assert r.exception is None or isinstance(r.exception, SystemExit), r.output
        assert "Traceback" not in r.output
        assert r.exit_code in (0, 2), r.output
        if r.exit_code == 2:
            _located(r.stderr, path)
        return r.exit_code
    from fdeck.compile.sanity import deck_figures
    from fdeck.deck.errors import format_problems

    try:
        deck, locs, _ = read_deck(path)
    except DeckError as exc:
        _located(format_problems(exc.problems), path)
        return 2
    deck_figures(deck)
    return 0


def _fuzz_validate(case):
    src, text = case
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"fuzz_{src.stem}.yaml"
        path.write_bytes(text)
        code = _validate(path)
    COUNT["validated" if code == 0 else "refused"] += 1


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout()


def _fuzz_run(case):
    """A mutated tiny deck that validates runs 3 cycles per step to exit 0, 3 or 4 within RUN_SECONDS."""
    src, text = case
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"fuzz_{src.stem}.yaml"
        path.write_bytes(text)
        if not _small(path) or _validate(path) != 0:
            return
        data = yaml.safe_load(text)
        for step in data["steps"]:
            step["max_cycles"] = 3
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        old = signal.signal(signal.SIGALRM, _alarm)
        signal.setitimer(signal.ITIMER_REAL, RUN_SECONDS)
        try:
            r = CliRunner().invoke(app, ["run", str(path), "-o", str(Path(tmp) / "out")])
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
        assert not isinstance(r.exception, _Timeout), f"{src}: run of 3 cycles per step exceeded {RUN_SECONDS} s"
        assert r.exception is None or isinstance(r.exception, SystemExit), r.output
        assert r.exit_code in (0, 3, 4), f"{src}: exit {r.exit_code}\n{r.output}"
        COUNT["run"] += 1


@settings(FAST)
@given(mutated())
def test_fuzz_validate_never_crashes(case):
    """Requirement: `fdeck validate` of any mutation of a shipped deck exits 0 or 2, raises nothing, and locates
    every problem as file:line:col (fast profile: 60 derandomized examples)."""
    _fuzz_validate(case)


TINY_DECKS = [p for p in DECK_FILES if (estimated_elements(read_deck(p)[0]) or math.inf) <= TINY]


@st.composite
def tiny_value_mutation(draw):
    """A value mutation of a tiny deck (the kind that may still validate and so reach the engine)."""
    src = draw(st.sampled_from(TINY_DECKS))
    data = copy.deepcopy(ORIGINALS[src])
    leaves = [p for p in _paths(data)[1:] if not isinstance(_get(data, p), (dict, list))]
    path = draw(st.sampled_from(leaves))
    old = _get(data, path)
    if isinstance(old, (int, float)) and not isinstance(old, bool):
        new = draw(st.sampled_from([0, -old, 10 * old, old / 10, 1e6 * old, 1e-6 * old, old + 1]))
    else:
        new = draw(BAD_VALUES)
    _get(data, path[:-1])[path[-1]] = new
    return src, yaml.safe_dump(data, sort_keys=False).encode()


def _get(data, path):
    for el in path:
        data = data[el]
    return data


def _scaled(name: str, path: tuple, factor: float):
    """A shipped deck with one number multiplied: an explicit example that validates, so the run path is always
    exercised whatever the derandomized draws are."""
    data = copy.deepcopy(ORIGINALS[DECKS / name])
    _get(data, path[:-1])[path[-1]] = _get(data, path) * factor
    return DECKS / name, yaml.safe_dump(data, sort_keys=False).encode()


@settings(FAST, max_examples=8 if PROFILE == "fast" else 100)
@example(_scaled("wave_bar.yaml", ("boundary", 1, "value"), 1e3))
@example(_scaled("coupons/tension_sm.yaml", ("steps", 0, "duration"), 10.0))
@given(tiny_value_mutation())
def test_fuzz_run_ends_with_an_exit_code(case):
    """Requirement: a mutated tiny deck that validates, run with every step capped at 3 cycles, ends with exit 0, 3
    or 4 within RUN_SECONDS, never an exception (fast profile: 8 derandomized examples and 2 explicit ones that
    validate: a 1000x faster push of the wave bar, a
    10x longer shell coupon)."""
    _fuzz_run(case)


@pytest.mark.nightly
@settings(NIGHTLY)
@given(mutated())
def test_fuzz_validate_nightly(case):
    """Requirement: as test_fuzz_validate_never_crashes with >= 500 random examples (FDECK_FUZZ=nightly)."""
    _fuzz_validate(case)


@pytest.mark.nightly
@settings(NIGHTLY, max_examples=100)
@given(tiny_value_mutation())
def test_fuzz_run_nightly(case):
    """Requirement: as test_fuzz_run_ends_with_an_exit_code with 100 random examples."""
    _fuzz_run(case)


def test_huge_deck_file_refused_located(tmp_path):
    """Requirement: a deck file above the size limit (17 MiB of comments) is refused at 1:1, exit 2, without
    being parsed (the reference: the limit MAX_DECK_BYTES = 16 MiB)."""
    path = tmp_path / "huge.yaml"
    with open(path, "wb") as f:
        f.write(b"# padding\n" * (17 * 2**20 // 10 + 1))
    r = CliRunner().invoke(app, ["validate", str(path)])
    assert r.exit_code == 2 and r.exception is None or isinstance(r.exception, SystemExit)
    _located(r.stderr, path)
    assert f"{path}:1:1:" in r.stderr and "MiB" in r.stderr


def test_non_utf8_byte_located_at_its_line_and_column(tmp_path):
    """Requirement: a byte that is not UTF-8 is reported at its own line and column (reference: the position where
    it was written, line 3 column 7)."""
    path = tmp_path / "bytes.yaml"
    path.write_bytes(b"title: a\nunits: mm-t-s-N-MPa\nmesh: \xff\n")
    r = CliRunner().invoke(app, ["validate", str(path)])
    assert r.exit_code == 2
    assert r.stderr.startswith(f"{path}:3:7: "), r.stderr
