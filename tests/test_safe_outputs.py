"""Safe outputs (``fdeck.io.outdir``): a run never takes another deck's result folder without --overwrite, replaces
its own earlier results only once it has written its first frame, touches nothing outside its folder, and reads the
files a deck names only from where the deck says (printed by `fdeck info`)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from fdeck.cli import app
from fdeck.io.outdir import MARKER, claim

pytestmark = pytest.mark.unit


def bar(frames: int) -> dict:
    """A 10-element steel bar pushed at one end (decks/wave_bar.yaml, shortened): 1e-5 s, some 60 cycles."""
    return {
        "mesh": {"block": {"size": [10, 1, 1], "divisions": [10, 1, 1]}},
        "materials": {"steel": {"type": "linear_elastic", "density": 7.85e-9, "youngs_modulus": 2e5,
                                "poisson_ratio": 0.0}},
        "sections": [{"elements": "all", "material": "steel", "formulation": "full"}],
        "amplitudes": {"push": {"type": "smooth_step", "t1": 2e-6}},
        "boundary": [{"type": "fixed", "nodes": "xmin", "dofs": ["x"]},
                     {"type": "velocity", "nodes": "xmax", "dofs": ["x"], "value": -100.0, "amplitude": "push"}],
        "steps": [{"duration": 1e-5}],
        "output": {"frames": frames, "history_points": 10},
    }


def write(path: Path, data: dict) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(data))
    return path


def run(deck: Path, out: Path, *extra):
    r = CliRunner().invoke(app, ["run", str(deck), "-o", str(out), *extra])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.output
    return r


def tree(root: Path, skip: Path | None = None) -> dict:
    """{relative path: sha256 of the bytes, or 'dir'} of everything under root except ``skip``."""
    out = {}
    for p in sorted(root.rglob("*")):
        if skip is not None and (p == skip or skip in p.parents):
            continue
        out[str(p.relative_to(root))] = "dir" if p.is_dir() else hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def test_nothing_outside_the_output_folder_is_written_or_removed(tmp_path):
    """Requirement: a run, a refused run and an --overwrite run leave every file and folder outside the result
    folder byte-identical (reference: the tree hashed before), sentinels beside and above the folder included."""
    work = tmp_path / "work"
    a, b = write(work / "a.yaml", bar(3)), write(work / "b.yaml", bar(2))
    for name in ("sentinel.txt", "sub/sentinel.bin", "out_sibling/x.vtu"):
        (work / name).parent.mkdir(parents=True, exist_ok=True)
        (work / name).write_bytes(name.encode() * 3)
    (tmp_path / "above.txt").write_text("above")
    out = work / "out"
    before = tree(tmp_path)
    assert run(a, out).exit_code == 0
    assert tree(tmp_path, skip=out) == before
    r = run(b, out)
    assert r.exit_code == 2 and str(a.resolve()) in r.stderr, r.output  # names the other deck
    assert run(b, out, "--overwrite").exit_code == 0
    assert tree(tmp_path, skip=out) == before


def test_another_decks_results_refused_then_overwritten_keeping_foreign_files(tmp_path):
    """Requirement: running deck b into deck a's folder exits 2 naming a and leaves the folder byte-identical;
    with --overwrite a's frames are removed once b has written its own, a file fdeck did not write is kept, and
    the marker names b."""
    a, b = write(tmp_path / "a.yaml", bar(3)), write(tmp_path / "b.yaml", bar(2))
    out = tmp_path / "out"
    assert run(a, out).exit_code == 0
    (out / "notes.txt").write_text("mine")
    snap = tree(out)
    r = run(b, out)
    assert r.exit_code == 2 and f"another deck, {a.resolve()}" in r.stderr
    assert tree(out) == snap
    assert run(b, out, "--overwrite").exit_code == 0
    names = {p.name for p in out.iterdir()}
    assert not any(n.startswith("a_") or n == "a.pvd" for n in names), names
    assert {"b.pvd", "b_00000.vtu", "notes.txt", "summary.json"} <= names
    assert json.loads((out / MARKER).read_text())["deck"] == str(b.resolve())


def test_same_deck_rerun_replaces_its_results_without_stale_frames(tmp_path):
    """Requirement: re-running the same deck with fewer frames (4 -> 1) leaves exactly the frames the new index
    (a.pvd) lists (reference: the file names in the pvd), none of the first run's extra frames."""
    import re

    a = write(tmp_path / "a.yaml", bar(4))
    out = tmp_path / "out"
    assert run(a, out).exit_code == 0
    first = sorted(p.name for p in out.glob("a_*.vtu"))
    write(a, bar(1))
    assert run(a, out).exit_code == 0
    listed = sorted(re.findall(r'file="([^"]+)"', (out / "a.pvd").read_text()))
    assert len(listed) < len(first)
    assert sorted(p.name for p in out.glob("a_*.vtu")) == listed


def test_old_results_kept_until_the_first_frame(tmp_path):
    """Requirement: a claim by the same deck removes nothing until first_frame(); then exactly the earlier run's
    files not rewritten are removed (a_00001.vtu rewritten is kept, a_00002.vtu is removed, notes.txt that no run
    listed is kept). A same-deck rerun that fails validation leaves the folder byte-identical."""
    a = write(tmp_path / "a.yaml", bar(2))
    out = tmp_path / "out"
    assert run(a, out).exit_code == 0
    (out / "notes.txt").write_text("mine")
    snap = tree(out, skip=out / MARKER)
    c = claim(out, a)
    assert tree(out, skip=out / MARKER) == snap
    (out / "a_00001.vtu").write_text("rewritten by the new run")
    c.first_frame()
    names = {p.name for p in out.iterdir()}
    assert "a_00001.vtu" in names and "a_00002.vtu" not in names and "notes.txt" in names
    bad = bar(2)
    bad["boundary"][0]["nodes"] = "nosuch"
    write(a, bad)
    snap = tree(out)
    assert run(a, out).exit_code == 2
    assert tree(out) == snap


def test_folder_of_unknown_files_refused(tmp_path):
    """Requirement: a folder holding files no fdeck run marked (here the deck's own folder) is refused, exit 2,
    and nothing in it changes."""
    a = write(tmp_path / "a.yaml", bar(2))
    snap = tree(tmp_path)
    r = run(a, tmp_path)
    assert r.exit_code == 2 and "no fdeck run marked" in r.stderr
    assert tree(tmp_path) == snap


def test_files_read_from_where_the_deck_says_and_printed_by_info(tmp_path, monkeypatch):
    """Requirement: a mesh file named by a deck is read relative to the deck's folder, not the working folder: a
    file of that name in the working folder only is a located error; once beside the deck, `fdeck info` prints
    its resolved path (reference: Path.resolve of deck folder / name)."""
    src = Path(__file__).resolve().parents[1] / "decks" / "meshes"
    mesh = src / "bias_w100_n6.inp"
    deck_dir, cwd = tmp_path / "deck", tmp_path / "cwd"
    cwd.mkdir()
    (cwd / "m.inp").write_bytes(mesh.read_bytes())
    data = yaml.safe_load((Path(__file__).resolve().parents[1] / "decks" / "bias_extension_3weave.yaml").read_text())
    data["mesh"]["file"] = "m.inp"
    deck = write(deck_dir / "d.yaml", data)
    monkeypatch.chdir(cwd)
    r = CliRunner().invoke(app, ["info", str(deck)])
    assert r.exit_code == 2 and "mesh.file" in r.stderr and str(deck_dir / "m.inp") in r.stderr, r.output
    (deck_dir / "m.inp").write_bytes(mesh.read_bytes())
    r = CliRunner().invoke(app, ["info", str(deck)])
    assert r.exit_code == 0, r.output
    assert f"reads mesh file: {(deck_dir / 'm.inp').resolve()}" in r.stdout
    assert "reads material 3weave preset 3weave: " in r.stdout and "presets/fabric_hyper/3weave.yaml" in r.stdout


def test_results_without_marker_recognised_by_their_summary(tmp_path):
    """Requirement: results written before the marker existed (no .fdeck-run) belong to the deck their summary.json
    names: another deck is refused naming it; the same deck replaces them, its stale frames removed (reference: the
    new a.pvd's file list) and a file fdeck did not write kept."""
    import re

    a, b = write(tmp_path / "a.yaml", bar(4)), write(tmp_path / "b.yaml", bar(1))
    out = tmp_path / "out"
    assert run(a, out).exit_code == 0
    (out / MARKER).unlink()
    (out / "notes.txt").write_text("mine")
    r = run(b, out)
    assert r.exit_code == 2 and str(a.resolve()) in r.stderr, r.output
    write(a, bar(1))
    assert run(a, out).exit_code == 0
    listed = sorted(re.findall(r'file="([^"]+)"', (out / "a.pvd").read_text()))
    assert sorted(p.name for p in out.glob("a_*.vtu")) == listed and (out / "notes.txt").exists()


def test_a_folder_another_run_is_writing_is_refused_untouched(tmp_path):
    """Requirement: while a run writes into a folder (its lock held, ``outdir.writing``), `fdeck run` of the same
    deck into it exits 2 naming the writer and changes nothing there (reference: the folder's bytes before);
    once the writer is done the run goes ahead. Before, a study re-run beside a worker left over from its killed
    predecessor let two processes write one history.csv (NUL-filled rows)."""
    import os

    from fdeck.io.outdir import writing

    a = write(tmp_path / "a.yaml", bar(2))
    out = tmp_path / "out"
    assert run(a, out).exit_code == 0
    before = tree(out)
    with writing(out):
        r = run(a, out)
        assert r.exit_code == 2 and f"pid {os.getpid()}" in r.output and "is writing into" in r.output
        assert tree(out) == {**before, ".fdeck-lock": tree(out)[".fdeck-lock"]}
    assert run(a, out).exit_code == 0
