"""Checkpoints and restart (issue 11, part 1): a run continued from a checkpoint at half time ends bitwise equal to
the uninterrupted run; checkpoints of another deck or version are refused; a finished run continues with an added
step; a damaged newest checkpoint is skipped; ``--max-wall`` stops with a checkpoint (exit 124).

Every comparison here is bitwise (SHA-256 of the bytes): the restart replays exactly the operations of the
uninterrupted run from exactly the saved state, so the only correct tolerance is zero.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import numba
import pytest

from fdeck.engine import solver

HEX = """title: tiny hex
mesh:
  block: {size: [10, 10, 10], divisions: [3, 3, 3]}
materials:
  rubber: {type: neo_hookean, density: 1.0e-9, youngs_modulus: 10.0, poisson_ratio: 0.45}
sections:
  - {elements: all, material: rubber, formulation: fbar}
boundary:
  - {type: fixed, nodes: xmin, dofs: [x]}
  - {type: fixed, nodes: ymin, dofs: [y]}
  - {type: fixed, nodes: zmin, dofs: [z]}
  - {type: velocity, nodes: zmax, dofs: [z], value: -800.0, amplitude: constant}
steps:
  - {name: compress, duration: 8.0e-4}
output:
  frames: 6
  formats: [vtu, xdmf]
  history_points: 40
  reactions: [zmax]
  checkpoint: {every: 10, keep: 100}
"""

SHELL = """title: tiny shell
mesh:
  plate: {size: [40, 16], element_size: 4.0}
materials:
  t300: {type: sm}
sections:
  - {elements: all, material: t300}
boundary:
  - {type: fixed, nodes: xmin, dofs: [x, y, z, rx, ry, rz]}
  - {type: velocity, nodes: xmax, dofs: [z], value: 2000.0, amplitude: constant}
steps:
  - {name: pull, duration: 1.0e-4}
output:
  frames: 5
  formats: [vtu, xdmf]
  history_points: 40
  reactions: [xmax]
  checkpoint: {every: 10, keep: 100}
"""

BEND = """title: tiny fibre bending with damping
mesh:
  block: {origin: [100, 0, 0], size: [60, 3.0, 15], divisions: [10, 1, 3]}
  node_sets:
    load_line: {box: [[100, 0, 15], [106, 3.0, 15]], tolerance: 1.0e-3}
materials:
  interlock: {type: interlock}
sections:
  - elements: all
    material: interlock
    formulation: fbar
    effects:
      - {type: fibre_bending, thickness: 15.0, warp: {D1: 2000.0, D2: 2.0e+5}, weft: {D1: 1600.0, D2: 1.6e+5}}
boundary:
  - {type: fixed, nodes: all, dofs: [y]}
  - {type: fixed, nodes: xmax, dofs: [x, z]}
  - {type: velocity, nodes: load_line, dofs: [z], value: -2000.0, amplitude: constant}
steps:
  - {name: bend, duration: 8.0e-5, damping: {mass_proportional: 2000}}
output:
  frames: 5
  formats: [vtu, xdmf]
  history_points: 40
  reactions: [load_line]
  checkpoint: {every: 10, keep: 100}
"""

CONTACT = """title: tiny block pressed and dragged by a moving tool, with friction
mesh:
  block: {size: [10, 10, 5], divisions: [2, 2, 1]}
materials:
  m: {type: linear_elastic, density: 1.0e-6, youngs_modulus: 1000.0, poisson_ratio: 0.3}
sections:
  - {material: m, formulation: full}
boundary:
  - {type: fixed, nodes: zmin}
tools:
  pad:
    surface: {shape: plane, point: [0, 0, 5.0], normal: [0, 0.3, -1]}
    motion: {kind: velocity, value: 200.0, direction: [0.3, 0, -1], amplitude: constant}
contact:
  - {tool: pad, normal: {law: linear, stiffness: 200.0}, friction: {static: 0.3}}
steps:
  - {name: press, duration: 8.0e-3, damping: {mass_proportional: 500}}
output:
  frames: 4
  formats: [vtu, xdmf]
  history_points: 40
  checkpoint: {every: 10, keep: 100}
"""

# The contact deck on a finer block with one measure of every kind that holds state or constants in tuples
# (the wrinkle indicator's regions are (name, node indices) pairs: a full-size forming restart once failed on them).
MEASURES = CONTACT.replace("title: tiny block pressed", "title: block with every measure, pressed").replace(
    "divisions: [2, 2, 1]", "divisions: [4, 4, 1]") + """  measures:
    - {type: wrinkles, name: wrinkles, nodes: zmax, radius: 6.0, regions: [xmax]}
    - {type: draw_in, name: draw, nodes: xmax}
    - {type: node_displacement, name: top, nodes: zmax}
    - {type: surface_waviness, name: wave, nodes: zmax}
"""

# The contact deck with its springs integrated implicitly (engine.springs: the pairs' spring forces of the last
# cycle are state) under the selective mass's solve
IMPLICIT = CONTACT.replace("title: tiny block pressed", "title: implicit springs, pressed").replace(
    "normal: {law: linear, stiffness: 200.0}", "normal: {law: exponential, p0: 0.05, c0: 0.1, max_stiffness: 200.0}, "
    "springs: implicit").replace("damping: {mass_proportional: 500}",
                                 "damping: {mass_proportional: 500}, mass_scaling: {factor: 4, selective: true}")

DECKS = {"hex": HEX, "shell": SHELL, "bend": BEND, "contact": CONTACT, "measures": MEASURES, "implicit": IMPLICIT}


def write_deck(folder: Path, text: str, name: str = "deck") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.yaml"
    path.write_text(text)
    return path


def run(path: Path, out: Path, restart=None, max_wall=None):
    """``fdeck run`` in-process: (exit code, summary); messages collected in the summary's '_echo'."""
    from fdeck.deck.read import read_deck
    from fdeck.run import execute

    deck, _, _ = read_deck(path)
    said = []
    code, summary = execute(deck, path.parent, out, path.stem, str(path), echo=said.append, restart=restart,
                            max_wall=max_wall)
    summary["_echo"] = said
    return code, summary


def final_state(out: Path) -> dict:
    """The engine arrays of the newest checkpoint (the one a completed run writes at its end)."""
    from fdeck.io.checkpoint import checkpoint_files, read_checkpoint

    return read_checkpoint(checkpoint_files(out)[-1])["engine"]


def digest(out: Path) -> dict[str, str]:
    """SHA-256 of the final positions, velocities and directors, and of history.csv and both indexes."""
    eng = final_state(out)
    state = hashlib.sha256(eng["arrays"]["x"].tobytes() + eng["arrays"]["v"].tobytes())
    if eng["directors"] is not None:
        state.update(eng["directors"].tobytes())
    files = {f: hashlib.sha256((out / f).read_bytes()).hexdigest()
             for f in ("history.csv", "deck.pvd", "deck.xdmf")}
    return {"state": state.hexdigest(), **files}


def middle_checkpoint(out: Path) -> Path:
    from fdeck.io.checkpoint import checkpoint_files

    files = checkpoint_files(out)
    return files[len(files) // 2 - 1]


@pytest.fixture
def parallel_below_2000(monkeypatch):
    """Problems below ``solver.SERIAL_BELOW`` elements run on one thread whatever is asked; lowering it makes the
    2-thread case of these tiny decks run the parallel kernels on 2 threads for real."""
    monkeypatch.setattr(solver, "SERIAL_BELOW", 0)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("kind", sorted(DECKS))
def test_restart_from_half_time_is_bitwise(tmp_path, kind, threads, parallel_below_2000):
    """Requirement: a run restarted from a checkpoint at half of its cycles ends bitwise identical to the
    uninterrupted run (SHA-256 of final x, v, directors, of history.csv and of the .pvd/.xdmf indexes), in a copy
    of the result folder whose original is gone (every frame file written there, none where the checkpoint was
    written: a restart in a copied folder once sent its VTU frames to the original), for a
    hexahedral deck, a shell deck, a deck with fibre bending and damping, and a block pressed and dragged by a
    moving rigid tool with Coulomb friction (tool position and stick springs are state), the same with one
    measure of every kind that keeps state (wrinkles with a region, draw-in, displacement, waviness), the pressed
    block with implicit contact springs under selective mass scaling, on 1 and 2 threads
    (tolerance zero: the same operations on the same bits)."""
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip(f"NUMBA_NUM_THREADS={numba.config.NUMBA_NUM_THREADS}")
    saved = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        path = write_deck(tmp_path, DECKS[kind])
        full = tmp_path / "full"
        code, summary = run(path, full)
        assert code == 0 and summary["status"] == "completed"
        ck = middle_checkpoint(full)
        half = tmp_path / "half"
        shutil.copytree(full, half)
        for later in sorted(half.glob("checkpoint_*.fdck")):  # only what a run killed at half time would leave
            if later.name > ck.name:
                later.unlink()
        (half / "history.csv").write_text("damaged\n")  # the restart rewrites it from the checkpoint
        from fdeck.io.checkpoint import read_checkpoint

        written = read_checkpoint(ck)["outputs"]["frames_written"]
        for f in half.glob("*.vtu"):  # frames after the checkpoint's: the restart must write them again, here
            if int(f.stem.rsplit("_", 1)[1]) >= written:
                f.unlink()
        frames = sorted(f.name for f in full.glob("*.vtu"))
        expected = digest(full)
        # the checkpoint names `full`: the restart must write every frame into its own folder, not there
        shutil.move(full, tmp_path / "moved")
        code2, summary2 = run(path, half, restart=True)
        assert code2 == 0 and summary2["status"] == "completed"
        assert 0.3 * summary["cycles"] < summary2["checkpoints"]["restarted_from_cycle"] < 0.7 * summary["cycles"]
        assert summary2["cycles"] == summary["cycles"]
        assert digest(half) == expected
        assert not full.exists() and sorted(f.name for f in half.glob("*.vtu")) == frames
    finally:
        numba.set_num_threads(saved)


# step settings held per step by effects (engine.snapshot's ``deck_settings``), in the first step and the added one
PER_STEP = ("damping: {mass_proportional: 1000}, deformation_damping: {rate: 200}, bulk_viscosity: {}, "
            "mass_scaling: {factor: 4, selective: true}")


SELECTIVE = "mass_scaling: {factor: 4, selective: true}"


@pytest.mark.parametrize("first, hold", [
    ("", "damping: {mass_proportional: 3000}"),
    # the added step halves the selective mass: its kinetic energy is booked at the boundary (engine.step_mass)
    (PER_STEP, "damping: {mass_proportional: 3000}, mass_scaling: {factor: 2, selective: true}"),
    # deformation damping is built before the selective mass: an effect placed among the checkpoint's
    (SELECTIVE, "deformation_damping: {rate: 200}, " + SELECTIVE)],
    ids=["effect_added", "effects_in_both", "effect_inserted"])
def test_added_step_continues_a_finished_run(tmp_path, first, hold):
    """Requirement: a deck that adds a step after the last one restarts from the end of the finished 1-step run
    and ends bitwise equal (SHA-256 of x and v) to the 2-step run from scratch; the history rows after the
    restart point are equal too (the rows before it are sampled over the 1-step duration, by design). When the
    added step asks for an effect the first did not (also one built before the checkpoint's effects: a full-size
    forming restart whose dwell added deformation damping once restored the selective mass into it), and when
    effects hold a setting per step (one once failed on the selective mass's per-step list, restored shorter)."""
    base = HEX if not first else HEX.replace("duration: 8.0e-4}", "duration: 8.0e-4, " + first + "}")
    one = write_deck(tmp_path, base)
    step = next(line for line in base.splitlines(keepends=True) if "name: compress" in line)
    two_text = base.replace(step, step + "  - {name: hold, duration: 5.0e-4, " + hold + "}\n")
    assert two_text.index("name: compress") < two_text.index("name: hold")
    two = write_deck(tmp_path / "b", two_text)
    out = tmp_path / "run"
    assert run(one, out)[0] == 0
    t1 = final_state(out)["scalars"]["t"]
    code, summary = run(two, out, restart=True)
    assert code == 0 and summary["checkpoints"]["restarted_from_cycle"] > 0
    ref = tmp_path / "scratch"
    assert run(two, ref)[0] == 0
    a, b = final_state(out), final_state(ref)
    for name in ("x", "v"):
        assert hashlib.sha256(a["arrays"][name].tobytes()).digest() == \
            hashlib.sha256(b["arrays"][name].tobytes()).digest()
    ha, hb = a["result"]["history"], b["result"]["history"]
    later_a, later_b = ha[ha[:, 0] > t1], hb[hb[:, 0] > t1]
    assert len(later_a) > 5 and later_a.tobytes() == later_b.tobytes()
    if first == PER_STEP:
        assert later_a[-1, a["result"]["columns"].index("step_mass_work")] != 0.0


def test_refuses_other_deck_version_and_changed_steps(tmp_path):
    """Requirement: a checkpoint of another deck (a changed material), of another fdeck version or build, or whose steps
    were changed (not only appended), or one whose 'smooth' amplitude would be stretched by an added step, is
    refused with a message naming the reason, and the CLI exits 2."""
    from typer.testing import CliRunner

    from fdeck.cli import app
    from fdeck.io.checkpoint import checkpoint_files, read_checkpoint, write_checkpoint
    from fdeck.run import RestartError

    path = write_deck(tmp_path, HEX)
    out = tmp_path / "out"
    assert run(path, out)[0] == 0
    other = write_deck(tmp_path / "o", HEX.replace("youngs_modulus: 10.0", "youngs_modulus: 11.0"))
    with pytest.raises(RestartError, match="another deck"):
        run(other, out, restart=True)
    changed = write_deck(tmp_path / "c", HEX.replace("duration: 8.0e-4", "duration: 1.6e-3"))
    with pytest.raises(RestartError, match="step 0 differs"):
        run(changed, out, restart=True)
    result = CliRunner().invoke(app, ["run", str(other), "-o", str(out), "--restart"])
    assert result.exit_code == 2 and "another deck" in result.output
    # another version: the same payload stamped with another version number
    last = checkpoint_files(out)[-1]
    payload = read_checkpoint(last)
    payload["digests"]["version"] = "0.0.0-other"
    write_checkpoint(out, 10**9 - 1, payload, keep=100)
    with pytest.raises(RestartError, match="fdeck 0.0.0-other"):
        run(path, out, restart=True)
    # another build of the same version (source files edited since the checkpoint: its state layout may differ)
    payload["digests"]["version"] = read_checkpoint(last)["digests"]["version"]
    payload["digests"]["build"] = "0123456789abcdef"
    write_checkpoint(out, 10**9 - 1, payload, keep=100)
    with pytest.raises(RestartError, match="another build"):
        run(path, out, restart=True)
    # a smooth amplitude spans the whole run: an added step would change the loads already applied
    smooth = HEX.replace("value: -800.0, amplitude: constant", "value: -1.0, amplitude: smooth")
    out2 = tmp_path / "out2"
    assert run(write_deck(tmp_path / "s", smooth), out2)[0] == 0
    longer = smooth.replace("  - {name: compress, duration: 8.0e-4}\n",
                            "  - {name: compress, duration: 8.0e-4}\n  - {name: hold, duration: 1.0e-4}\n")
    with pytest.raises(RestartError, match="amplitudes 'ramp'/'smooth'"):
        run(write_deck(tmp_path / "l", longer), out2, restart=True)


def test_damaged_newest_checkpoint_is_skipped(tmp_path):
    """Requirement: a truncated newest checkpoint is skipped with a message and the run continues from the one
    before, ending bitwise equal to the uninterrupted run (SHA-256 of state, history and indexes); the folder
    keeps exactly ``keep`` checkpoints."""
    from fdeck.io.checkpoint import checkpoint_files

    path = write_deck(tmp_path, HEX.replace("keep: 100", "keep: 3"))
    full = tmp_path / "full"
    assert run(path, full)[0] == 0
    assert len(checkpoint_files(full)) == 3
    half = tmp_path / "half"
    shutil.copytree(full, half)
    newest = checkpoint_files(half)[-1]
    newest.write_bytes(newest.read_bytes()[:-100])
    code, summary = run(path, half, restart=True)
    assert code == 0
    assert any("skipping" in m and newest.name in m for m in summary["_echo"])
    assert digest(half) == digest(full)


def test_max_wall_stops_with_a_checkpoint_and_restart_completes(tmp_path):
    """Requirement: ``--max-wall 0`` stops the run at its first cycle with exit 124, a checkpoint, the summary
    (status interrupted, one checkpoint counted); ``--restart`` then completes it bitwise equal to the
    uninterrupted run, and reports its cost per element-cycle over the cycles it ran itself."""
    from typer.testing import CliRunner

    from fdeck.cli import app

    path = write_deck(tmp_path, HEX)
    full = tmp_path / "full"
    assert run(path, full)[0] == 0
    cut = tmp_path / "cut"
    result = CliRunner().invoke(app, ["run", str(path), "-o", str(cut), "--max-wall", "0"])
    assert result.exit_code == 124, result.output
    import json

    summary = json.loads((cut / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["exit_code"] == 124
    assert summary["checkpoints"]["written"] == 1 and summary["checkpoints"]["time"] > 0
    first = summary["cycles"]
    result = CliRunner().invoke(app, ["run", str(path), "-o", str(cut), "--restart"])
    assert result.exit_code == 0, result.output
    assert digest(cut) == digest(full)
    # the cost of the continued run is per cycle run in this process: its timings over its own cycles (an
    # identity, to round-off), not over every cycle since the start (which understated it on long restarted runs)
    summary = json.loads((cut / "summary.json").read_text())
    assert summary["checkpoints"]["restarted_from_cycle"] == first
    assert summary["cycles_this_run"] == summary["cycles"] - first > 0
    loop = sum(summary["time_per_effect"].values())
    assert summary["us_per_element_cycle"] == pytest.approx(
        1e6 * loop / (summary["cycles_this_run"] * summary["elements"]), rel=1e-12)


def test_checkpoint_card_errors_are_located(tmp_path):
    """Requirement: a wrong checkpoint interval (an unknown unit, zero cycles, a float without unit) or keep < 1
    is a located deck error (line and column of the key), not a traceback."""
    from fdeck.deck.errors import DeckError, format_problems
    from fdeck.deck.read import read_deck

    for bad, key in (("{every: '10 years'}", "every"), ("{every: 0}", "every"), ("{every: 2.5}", "every"),
                     ("{every: 10, keep: 0}", "keep")):
        path = write_deck(tmp_path, HEX.replace("{every: 10, keep: 100}", bad))
        with pytest.raises(DeckError) as exc:
            read_deck(path)
        text = format_problems(exc.value.problems)
        line = HEX.splitlines().index("  checkpoint: {every: 10, keep: 100}") + 1
        assert f"{path}:{line}:" in text and f"output.checkpoint.{key}" in text, text
