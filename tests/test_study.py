"""`fdeck study`: deck paths, Richardson extrapolation, located errors in study files, and a small mesh study of
the elastic cantilever run on the local process pool, re-run from its cache and run again on a Dask LocalCluster."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import DECKS, ROOT

pytestmark = pytest.mark.unit

# Timoshenko tip deflection of decks/cantilever.yaml (P = 1 N, L = 100 mm, 10 x 10 mm, E = 1e4 MPa, nu = 0):
# P L^3 / (3 E I) + P L / (k G A) with I = 10^4 / 12, k = 5/6, G = E / 2.
TIMOSHENKO = 1.0 * 100**3 / (3 * 1e4 * 1e4 / 12) + 1.0 * 100 / (5 / 6 * 5e3 * 100)

STUDY = f"""\
base: {DECKS / 'cantilever.yaml'}
set:
  output.frames: 1
  output.history_points: 50
  output.measures: [{{type: node_displacement, name: tip_deflection, nodes: tip, component: z}}]
grid:
  mesh.block.divisions: [[5, 1, 1], [10, 1, 2], [20, 1, 4]]
variants:
  - name: diverges
    set: {{mesh.block.divisions: [5, 1, 1], loads.0.force: [0, 0, -1.0e7]}}
  - name: invalid
    set: {{materials.polymer.youngs_modulus: -1.0}}
  - name: strict_check
    set: {{mesh.block.divisions: [5, 1, 1], checks.energy_balance.max_error: 1.0e-15}}
quantities: [tip_deflection]
"""
GRID = ["divisions=[5,1,1]", "divisions=[10,1,2]", "divisions=[20,1,4]"]


def fdeck(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "fdeck.cli", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=600)


def test_deck_paths_read_set_and_refuse_paths_that_lead_nowhere():
    """Requirement: a deck path reads and sets list items and mapping keys (creating a missing last key only), and
    a path that leaves the deck is refused with a message naming where it stops."""
    from fdeck.study import deck_paths as dp

    data = {"sections": [{"formulation": "fbar"}], "mesh": {"block": {"divisions": [5, 1, 1]}}, "steps": [{}]}
    assert dp.get(data, "mesh.block.divisions.0") == 5
    dp.set_value(data, "sections.0.formulation", "reduced")
    dp.set_value(data, "steps.0.mass_scaling", {"factor": 4.0})
    assert data["sections"][0]["formulation"] == "reduced" and data["steps"][0]["mass_scaling"] == {"factor": 4.0}
    for bad, words in [("sections.1.formulation", "has 1 items, no item 1"), ("mesh.blok.size", "no key 'blok'"),
                       ("steps.0.damping.mass_proportional", "no key 'damping'"),
                       ("mesh.block.divisions.x", "not a mapping"), ("sections..material", "empty part")]:
        with pytest.raises(dp.PathError, match=words):
            dp.check_settable(data, bad)


def test_grid_names_are_file_names_even_for_paths_and_mappings():
    """Requirement: a grid over mesh files or mapping values names its variants with what the frame series accept
    (the variant name is the series name): a path stands as its stem, other characters become '_'. Before, a grid
    over `mesh.file` failed every variant at its first frame ("series name ... must be a plain file name")."""
    import re

    from fdeck.io.frames import _check_name
    from fdeck.study.models import _NAME
    from fdeck.study.variants import grid_name

    cases = {"file=bias_w100_n20,formulation=ans_tbar": {"mesh.file": "meshes/bias_w100_n20.inp",
                                                          "sections.0.formulation": "ans_tbar"},
             "clamp=_box_[[-10,0,0],[0,5,2.54]]_": {"mesh.node_sets.clamp": {"box": [[-10, 0, 0], [0, 5, 2.54]]}},
             "file=plate": {"mesh.file": "C:\\meshes\\plate.msh"}}
    for expected, settings in cases.items():
        name = grid_name(settings)
        assert name == expected and _check_name(name) == name and re.match(_NAME, name)


def test_richardson_recovers_the_limit_and_order_of_a_power_law():
    """Requirement: Richardson extrapolation of f(h) = f0 + c h^p sampled at h, h/r, h/r^2 returns f0 and p (to
    1e-9 relative: only rounding of three subtractions), and refuses oscillating or diverging sequences."""
    from fdeck.study.study import richardson

    for f0, c, p, r, h in [(-0.0402, 3e-4, 2.0, 2.0, 1.0), (5.0, -1.2, 1.3, 1.5, 0.4), (1e3, 7.0, 0.7, 3.0, 2.0)]:
        f = [f0 + c * (h / r**k) ** p for k in range(3)]
        got, order = richardson(*f, r)
        assert abs(got - f0) <= 1e-9 * abs(f0) and abs(order - p) <= 1e-9 * p
    with pytest.raises(ValueError, match="monotonically"):
        richardson(1.0, 2.0, 1.5, 2.0)
    with pytest.raises(ValueError, match="do not converge"):
        richardson(1.0, 1.1, 1.3, 2.0)


def _line(path, text):
    """1-based number of the first line of a file holding ``text``."""
    return next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if text in ln)


def test_bad_study_file_gives_located_errors_and_exit_2(tmp_path):
    """Requirement: a study file with an unknown key, a deck path that is not in the base deck, a misspelt deck
    field and an unknown reference variant gets one located file:line:col message each, exit 2, no traceback and
    no run."""
    spec = tmp_path / "bad.yaml"
    spec.write_text(STUDY.replace("quantities:", "quantitys: [x]\nquantities:") + "reference: {type: finest}\n"
                    "tolerance: 0.1\n")
    r = fdeck("study", spec, "-o", tmp_path / "out")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    expected = f"{spec}:{_line(spec, 'quantitys:')}:1: quantitys: unknown key 'quantitys' (did you mean 'quantities'?)"
    assert expected in r.stderr, r.stderr
    spec.write_text(STUDY.replace("loads.0.force", "loads.1.force").replace("youngs_modulus", "youngs_modulos")
                    + "reference: {type: finest, variant: fine}\ntolerance: 0.1\n")
    r = fdeck("study", spec, "-o", tmp_path / "out")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 3, r.stderr
    assert lines[0].startswith(f"{spec}:{_line(spec, 'loads.1.force')}:"), lines[0]
    assert "variants[0].set.loads.1.force" in lines[0] and "loads has 1 items, no item 1" in lines[0], lines[0]
    assert lines[1].startswith(f"{spec}:{_line(spec, 'youngs_modulos')}:"), lines[1]
    assert "unknown key 'youngs_modulos' (did you mean 'youngs_modulus'?)" in lines[1], lines[1]
    assert lines[2].startswith(f"{spec}:{_line(spec, 'variant: fine')}:"), lines[2]
    assert "unknown variant 'fine'" in lines[2], lines[2]
    assert not (tmp_path / "out").exists()
    v = fdeck("validate", spec)  # validate recognises a study file and reports the same located problems
    assert v.returncode == 2 and v.stderr.strip().splitlines() == lines, v.stderr


def test_validate_checks_the_shipped_study_and_identification_files():
    """Requirement: `fdeck validate` checks study and identification files as such (their schema, their base deck,
    the deck paths they set), not as decks: every file in decks/studies/ passes, each named with its kind."""
    files = sorted((DECKS / "studies").glob("*.yaml"))
    r = fdeck("validate", *files)
    assert r.returncode == 0, r.stderr
    kinds = {Path(ln.split(":")[0]).name: ln for ln in r.stdout.splitlines()}
    assert "(study file)" in kinds["cantilever_convergence.yaml"] and "(ident file)" in kinds["identify_bar.yaml"]
    assert kinds["bar.yaml"].endswith(": ok"), kinds


def _rows(table):
    return {r["name"]: r for r in table["rows"]}


def _summary_answer(row):
    return json.loads((Path(row["run_dir"]) / "summary.json").read_text())["measures"]["tip_deflection"]


def test_study_local_rerun_and_dask(tmp_path):
    """Requirement: a study runs every variant in its own folder through `fdeck run`'s code path on the local
    pool; a diverged, an invalid and a check-failing variant are rows with their status; each answer is the run's
    summary value, bitwise; the Richardson reference and errors follow from the rows; the cheapest variant is the
    fastest within the tolerance; a second study on the same decks and a re-run reuse the finished runs (a lost
    record is re-run to the same bits); on a Dask LocalCluster (2 processes, 1 thread each) the answers are
    bitwise those of the local pool."""
    from fdeck.study import report
    from fdeck.study.executor import Pool
    from fdeck.study.study import richardson, run_study

    spec = tmp_path / "study.yaml"
    spec.write_text(STUDY + "reference: {type: richardson, ratio: 2}\ntolerance: 0.5\n")
    out = tmp_path / "local"
    with Pool(workers=2) as pool:
        table = run_study(spec, out, pool, echo=lambda *a: None)
    report.write(table, out)
    rows = _rows(table)
    assert [r["name"] for r in table["rows"]] == GRID + ["diverges", "invalid", "strict_check"]
    assert {n: rows[n]["status"] for n in rows} == {**{g: "completed" for g in GRID}, "diverges": "failed",
                                                      "invalid": "invalid", "strict_check": "check_failed"}
    assert "inverted" in rows["diverges"]["message"] and rows["diverges"]["answers"]["tip_deflection"] is None
    assert "youngs_modulus" in rows["invalid"]["message"]
    assert "energy_balance" in rows["strict_check"]["message"]
    answers = [rows[g]["answers"]["tip_deflection"] for g in GRID]
    assert answers == [_summary_answer(rows[g]) for g in GRID]  # bitwise: the table carries the run's value
    # refinement converges towards Timoshenko's closed form: each halving of the element reduces the error
    errs = [abs(a + TIMOSHENKO) / TIMOSHENKO for a in answers]
    assert errs[0] > errs[1] > errs[2], errs
    ref, order = richardson(*answers, 2.0)
    assert table["reference"]["values"]["tip_deflection"] == ref and table["reference"]["order"]["tip_deflection"] \
        == order
    for g, a in zip(GRID, answers):
        assert rows[g]["errors"]["tip_deflection"] == abs(a - ref) / abs(ref)
    accurate = [r for r in table["rows"] if r["max_error"] is not None and r["max_error"] <= 0.5]
    assert table["cheapest"] == min(accurate, key=lambda r: r["wall_time"])["name"]
    with open(out / "study.csv") as f:
        csv_rows = {r["variant"]: r for r in csv.DictReader(f)}
    assert [float(csv_rows[g]["tip_deflection"]) for g in GRID] == answers
    assert json.loads((out / "study.json").read_text())["cheapest"] == table["cheapest"]
    assert (out / "study.png").stat().st_size > 0 and len(set(r["run_dir"] for r in table["rows"])) == 6

    # the same decks under a closed-form reference: nothing runs again; errors against Timoshenko
    spec2 = tmp_path / "closed.yaml"
    spec2.write_text(STUDY + f"reference: {{type: closed_form, values: {{tip_deflection: {-TIMOSHENKO!r}}}}}\n"
                     "tolerance: 0.2\n")
    with Pool(workers=1) as pool:
        closed = run_study(spec2, out, pool, echo=lambda *a: None)
    assert all(r["reused"] for r in closed["rows"] if r["status"] != "invalid")
    assert [_rows(closed)[g]["errors"]["tip_deflection"] for g in GRID] == errs

    # an interrupted study: one record lost; the re-run runs that variant only, to the same bits
    (Path(rows[GRID[1]]["run_dir"]) / "result.json").unlink()
    with Pool(workers=1) as pool:
        again = run_study(spec, out, pool, echo=lambda *a: None)
    reran = [r["name"] for r in again["rows"] if not r["reused"] and r["status"] != "invalid"]
    assert reran == [GRID[1]]
    assert [_rows(again)[g]["answers"] for g in GRID] == [rows[g]["answers"] for g in GRID]

    # Dask: same answers bitwise, same statuses
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      env={"NUMBA_NUM_THREADS": "1"}) as cluster:
        with Pool(scheduler=cluster.scheduler_address) as pool:
            dask = run_study(spec, tmp_path / "dask", pool, echo=lambda *a: None)
    assert not any(r["reused"] for r in dask["rows"])
    assert [(r["name"], r["status"], r["answers"]) for r in dask["rows"]] == \
        [(r["name"], r["status"], r["answers"]) for r in table["rows"]]
    assert dask["reference"]["values"] == table["reference"]["values"]


def test_static_study_gives_the_cantilevers_equilibrium(tmp_path):
    """Requirement: `solver: static` makes every variant a static equilibrium (``study.static_run``) in the same
    table, cost columns empty rather than made up. Checked on the elastic cantilever with the locking-free `ans`
    element: every mesh of the grid within 3 % of Timoshenko's tip deflection (the dynamic study above needs a
    damped settling run per variant for the same answers; 3 %: the coarse 5-element mesh's discretisation error of
    linear elements in bending, -1/(4 n^2) = 1 %, plus the mesh's one-element width)."""
    from fdeck.study.executor import Pool
    from fdeck.study.study import run_study

    spec = tmp_path / "study.yaml"
    spec.write_text(STUDY.split("variants:")[0].replace("set:\n", "set:\n  sections.0.formulation: ans\n")
                    + "quantities: [tip_deflection]\nsolver: static\n"
                    "reference: {type: closed_form, source: Timoshenko, "
                    f"values: {{tip_deflection: {-TIMOSHENKO!r}}}}}\n"
                    "tolerance: 0.03\n")
    with Pool(workers=1) as pool:
        table = run_study(spec, tmp_path / "out", pool, echo=lambda *a: None)
    rows = _rows(table)
    assert all(rows[g]["status"] == "completed" and rows[g].get("cycles") is None for g in GRID)
    w = [-rows[g]["answers"]["tip_deflection"] for g in GRID]
    assert w == pytest.approx([TIMOSHENKO] * 3, rel=0.03), (w, TIMOSHENKO)


def test_killed_study_takes_its_pool_workers_with_it(tmp_path):
    """Requirement: when the study process is killed (SIGKILL: no clean-up of its own can run), its pool workers
    stop too, instead of running their variants on into the result folders a re-run would use (found when an
    orphaned worker and a re-run's worker wrote one history.csv). Reference: the worker's pid, read from the write
    lock of the run folder it holds (``io.outdir.writing``), must vanish within 30 s of the kill (a run notices
    SIGTERM at its next cycle, well below a second here; 30 s covers a loaded CI machine), and the lock must then be
    free."""
    import fcntl
    import signal
    import time

    study = tmp_path / "long.yaml"
    study.write_text(f"base: {DECKS / 'cantilever.yaml'}\n"
                     "set: {output.frames: 1, output.history_points: 10, steps.0.duration: 100.0}\n"
                     "variants: [{name: long, set: {}}]\nquantities: [energy_balance]\n"
                     "reference: {type: finest}\ntolerance: 0.01\n")  # ~10^7 cycles: it outlives the test by far
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "fdeck.cli", "study", str(study), "-o", str(out), "--workers",
                             "1"], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline, worker, lock = time.time() + 240, None, None
        while worker is None and time.time() < deadline and proc.poll() is None:
            for lock in out.glob("runs/*/.fdeck-lock"):
                text = lock.read_text().split()
                if len(text) == 2 and text[1].isdigit():
                    worker = int(text[1])
            time.sleep(0.5)
        assert worker is not None, f"no variant started (study exit {proc.poll()})"
        assert worker != proc.pid
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        deadline = time.time() + 30
        while time.time() < deadline and Path(f"/proc/{worker}").exists() and \
                "zombie" not in Path(f"/proc/{worker}/status").read_text(errors="replace"):
            time.sleep(0.2)
        alive = Path(f"/proc/{worker}").exists() and "zombie" not in Path(f"/proc/{worker}/status").read_text()
        assert not alive, f"pool worker {worker} still runs 30 s after its study was killed"
        with open(lock, "a+") as f:  # the kernel released the dead worker's lock
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    finally:
        if proc.poll() is None:
            proc.kill()


def test_static_run_refuses_a_folder_another_run_is_writing(tmp_path):
    """Requirement: a static study run takes the same one-writer lock as `fdeck run` (``io.outdir.writing``): into
    a folder whose lock another run holds it raises OutdirError naming the writer and writes nothing there
    (reference: the folder's file list before); with the lock free it solves (status completed)."""
    import yaml

    from fdeck.io.outdir import OutdirError, writing
    from fdeck.study.static_run import run_static

    data = yaml.safe_load((DECKS / "cantilever.yaml").read_text())
    data["mesh"]["block"]["divisions"] = [5, 1, 1]
    out = tmp_path / "run"
    with writing(out):
        before = sorted(p.name for p in out.iterdir())
        with pytest.raises(OutdirError, match=f"pid {os.getpid()}"):
            run_static(data, DECKS, out, {})
        assert sorted(p.name for p in out.iterdir()) == before
    assert run_static(data, DECKS, out, {})["status"] == "completed"
