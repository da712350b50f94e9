"""The command line: located errors with exit 2, exit codes of run, signals, output that survives."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from helpers import DECKS, ROOT

pytestmark = pytest.mark.unit


def fdeck(*args, cwd=ROOT, timeout=600):
    return subprocess.run([sys.executable, "-m", "fdeck.cli", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout)


def test_validate_all_shipped_decks_exit_0():
    """Requirement: every deck in decks/ validates."""
    decks = (sorted(DECKS.glob("*.yaml")) + sorted(DECKS.glob("three_point_bending/*.yaml"))
             + sorted(DECKS.glob("coupons/*.yaml")))
    r = fdeck("validate", *decks)
    assert r.returncode == 0, r.stderr
    assert r.stdout.count(": ok") == len(decks)


SEEDED = """\
mesh:
  block: {size: [10, 1, 1], divisions: [10, 1, 1]}
materials:
  steel: {type: linear_elastic, density: -7.85e-9, youngs_modulus: 2.0e5, poisson_ratio: 0.3}
sections:
  - {elements: all, material: steel, formulation: fbar}
boundary:
  - {type: fixed, nodes: xmin, dofz: [x]}
steps:
  - {duration: 1.0e-5, dt_safty: 0.9}
"""


def test_three_seeded_mistakes_give_three_located_messages_and_exit_2(tmp_path):
    """Requirement: a deck with three mistakes gets three messages, each file:line:col: path: message, exit 2,
    and no traceback."""
    deck = tmp_path / "bad.yaml"
    deck.write_text(SEEDED)
    r = fdeck("validate", deck)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith(str(deck))]
    assert len(lines) == 3, r.stderr
    assert f"{deck}:4:" in lines[0] and "materials.steel.density" in lines[0] and "-7.85e-09" in lines[0]
    assert f"{deck}:8:" in lines[1] and "dofz" in lines[1] and "did you mean 'dofs'" in lines[1]
    assert f"{deck}:10:" in lines[2] and "dt_safty" in lines[2] and "did you mean 'dt_safety'" in lines[2]


def test_unknown_set_is_located_at_its_key(tmp_path):
    """Requirement: a set name the mesh lacks is an error at the line that names it, with a suggestion."""
    deck = tmp_path / "sets.yaml"
    deck.write_text(SEEDED.replace("-7.85e-9", "7.85e-9").replace("dofz", "dofs").replace("dt_safty", "dt_safety")
                    .replace("nodes: xmin", "nodes: xmni"))
    r = fdeck("validate", deck)
    assert r.returncode == 2
    assert f"{deck}:8:" in r.stderr and "unknown node set 'xmni'" in r.stderr and "xmin" in r.stderr


def test_run_writes_summary_history_and_both_series(tmp_path):
    """Requirement: a run writes summary.json, history.csv, a PVD series and an XDMF series; exit 0 when checks
    pass; the summary reports cost."""
    out = tmp_path / "wave"
    r = fdeck("run", DECKS / "wave_bar.yaml", "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and s["elements"] == 200 and s["cycles"] > 300
    assert s["us_per_element_cycle"] > 0 and "integrator" in s["time_per_effect"]
    assert s["checks"][0]["name"] == "energy_balance" and s["checks"][0]["passed"]
    assert (out / "history.csv").exists() and (out / "wave_bar.pvd").exists() and (out / "wave_bar.xdmf").exists()
    assert "where the time went" in r.stdout


def test_failed_check_exits_3_and_names_it(tmp_path):
    """Requirement: a failing check gives exit 3 with the check named on the last line."""
    deck = tmp_path / "strict.yaml"
    text = (DECKS / "wave_bar.yaml").read_text().replace("energy_balance: {max_error: 0.01}",
                                                         "energy_balance: {max_error: 1.0e-12}")
    deck.write_text(text)
    r = fdeck("run", deck, "-o", tmp_path / "o")
    assert r.returncode == 3
    assert r.stdout.strip().splitlines()[-1] == "CHECK FAILED: energy_balance"


def test_measure_limits_decide_pass_and_fail(tmp_path):
    """Requirement: `checks.limits` bounds a recorded measure: inside passes (exit 0), outside fails (exit 3) naming
    the bound, with the measured extreme and the limit in summary.json; an unknown measure is a located error."""
    base = (DECKS / "wave_bar.yaml").read_text().replace(
        "  reactions: [xmin]", "  reactions: [xmin]\n  measures: [{type: node_displacement, name: push, nodes: xmax, "
        "component: x}]")
    # the pushed end moves 1000 mm/s x (60 - 1) us = 0.059 mm towards -x: -0.06 < push < 0
    for limit, code in (("{measure: push, min: -0.06, max: 0.0}", 0), ("{measure: push, min: -0.05}", 3)):
        deck = tmp_path / "limited.yaml"
        deck.write_text(base.replace("checks:", f"checks:\n  limits: [{limit}]"))
        r = fdeck("run", deck, "-o", tmp_path / "o")
        assert r.returncode == code, r.stdout + r.stderr
    assert r.stdout.strip().splitlines()[-1] == "CHECK FAILED: push_min"
    check = json.loads((tmp_path / "o" / "summary.json").read_text())["checks"][-1]
    assert check["limit"] == -0.05 and -0.06 < check["value"] < -0.05 and not check["passed"]
    deck.write_text(base.replace("checks:", "checks:\n  limits: [{measure: psuh, max: 1}]"))
    r = fdeck("validate", deck)
    assert r.returncode == 2 and "checks.limits[0].measure" in r.stderr and "did you mean 'push'" in r.stderr


def test_numerical_failure_exits_4_names_element_and_keeps_frames(tmp_path):
    """Requirement: an inverted element stops the run at once (exit 4) naming the element and time, with the
    frames written so far kept."""
    deck = tmp_path / "crush.yaml"
    deck.write_text("""\
mesh:
  block: {size: [1, 1, 1], divisions: [1, 1, 1]}
materials:
  soft: {type: linear_elastic, density: 1.0e-9, youngs_modulus: 1.0, poisson_ratio: 0.0}
sections:
  - {material: soft, formulation: full}
boundary:
  - {type: fixed, nodes: zmin}
  - {type: displacement, nodes: zmax, dofs: [z], value: -2.0, amplitude: ramp}
steps:
  - {duration: 1.0}
output: {frames: 50, formats: [vtu, xdmf]}
""")
    r = fdeck("run", deck, "-o", tmp_path / "o")
    assert r.returncode == 4, r.stdout + r.stderr
    assert "element 1" in r.stdout and "inverted" in r.stdout
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["status"] == "failed" and 0.4 < s["simulated_time"] < 0.6  # height reaches zero at t = 0.5
    assert s["frames"] >= 20  # every frame up to the failure is on disk
    import meshio

    for f in sorted((tmp_path / "o").glob("crush_*.vtu")):
        meshio.read(f)


def test_deck_amplitude_named_like_a_builtin_is_a_located_error(tmp_path):
    """Requirement: a deck amplitude named `ramp`, `smooth` or `constant` would be shadowed by the built-in of that
    name wherever it is used (a user's 0.1 s smooth step silently became a ramp over the whole run): `fdeck
    validate` refuses it at its own line, exit 2."""
    deck = tmp_path / "shadow.yaml"
    deck.write_text("""\
mesh:
  block: {size: [1, 1, 1], divisions: [1, 1, 1]}
materials:
  m: {type: linear_elastic, density: 1.0e-9, youngs_modulus: 1.0, poisson_ratio: 0.0}
sections:
  - {material: m, formulation: full}
boundary:
  - {type: fixed, nodes: zmin}
  - {type: displacement, nodes: zmax, dofs: [z], value: -0.1, amplitude: ramp}
amplitudes:
  ramp: {type: smooth_step, t1: 0.1}
steps:
  - {duration: 1.0}
""")
    r = fdeck("validate", deck)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"{deck}:11:" in r.stderr and "built-in amplitude" in r.stderr, r.stderr  # the `ramp:` entry


def _wait_for(path: Path, timeout=120.0):
    t0 = time.time()
    while not path.exists():
        if time.time() - t0 > timeout:
            raise TimeoutError(path)
        time.sleep(0.05)


def _long_deck(tmp_path) -> Path:
    deck = tmp_path / "long.yaml"
    deck.write_text((DECKS / "cantilever.yaml").read_text().replace("frames: 10", "frames: 400")
                    .replace("../schemas", str(ROOT / "schemas")))
    return deck


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_sigint_sigterm_stop_within_a_cycle_with_last_frame_and_summary(tmp_path, sig, code):
    """Requirement: SIGINT/SIGTERM stop the run, write a last frame and the summary, exit 130/143."""
    out = tmp_path / "o"
    p = subprocess.Popen([sys.executable, "-m", "fdeck.cli", "run", _long_deck(tmp_path), "-o", out], cwd=ROOT,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for(out / "long_00003.vtu")
    p.send_signal(sig)
    stdout, _ = p.communicate(timeout=60)
    assert p.returncode == code, stdout
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and s["exit_code"] == code
    import meshio

    frames = sorted(out.glob("long_*.vtu"))
    last = meshio.read(frames[-1])
    assert np.isfinite(last.point_data["displacement"]).all()
    assert "INTERRUPTED" in stdout


def test_sigkill_leaves_completed_frames_and_history_readable(tmp_path):
    """Requirement: a run killed with SIGKILL half-way leaves every completed frame and the history readable."""
    import meshio

    from fdeck.io.history import read_history

    out = tmp_path / "o"
    p = subprocess.Popen([sys.executable, "-m", "fdeck.cli", "run", _long_deck(tmp_path), "-o", out], cwd=ROOT,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _wait_for(out / "long_00005.vtu")
    p.kill()
    p.wait()
    pvd = (out / "long.pvd").read_text()
    listed = [ln.split('file="')[1].split('"')[0] for ln in pvd.splitlines() if 'file="' in ln]
    assert len(listed) >= 5
    for f in listed:
        assert np.isfinite(meshio.read(out / f).point_data["displacement"]).all()
    import h5py

    with h5py.File(out / "long.h5", "r") as h5:
        assert len(h5["frames"]) >= 5
    h = read_history(out / "history.csv")
    assert len(h["time"]) >= 4 and np.all(np.diff(h["time"]) > 0)  # rows keep pace with frames


def test_info_reports_sizes_step_and_effects():
    """Requirement: `fdeck info` tells element and node counts, the stable step and the effects that will run."""
    r = fdeck("info", DECKS / "cantilever.yaml")
    assert r.returncode == 0, r.stderr
    assert "nodes 510, elements 200" in r.stdout  # 51 x 2 x 5 nodes, 50 x 1 x 4 elements
    dt = 0.9 * 2.0 / np.sqrt(1.0e4 / 1.0e-9)  # L0 = 2 mm (V / largest face), c = sqrt(E / rho) at nu = 0
    assert f"rest stable dt {dt:.4g} s" in r.stdout
    assert "fixed:xmin" in r.stdout and "nodal_force:tip" in r.stdout and "damping" in r.stdout


def test_schema_is_current(tmp_path):
    """Requirement: the committed schemas/*.schema.json (deck, study, identification) equal what `fdeck schema`
    writes now."""
    r = fdeck("schema", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    for name in ("deck.schema.json", "study.schema.json", "ident.schema.json"):
        assert (tmp_path / name).read_text() == (ROOT / "schemas" / name).read_text(), \
            f"schema is stale: run `fdeck schema` and commit schemas/{name}"


def test_decks_start_with_schema_line():
    """Requirement: every shipped deck, study and identification file names its JSON schema on its first line (an
    editor validates it as it is typed), and the schema it names is the one for its kind of file."""
    for d in list(DECKS.glob("**/*.yaml")):
        if d.name in ("spec.yaml", "summary.yaml"):
            continue
        data = yaml.safe_load(d.read_text())
        kind = "deck" if "mesh" in data else "study" if "quantities" in data else "ident"
        first = d.read_text().splitlines()[0]
        assert first.startswith("# yaml-language-server: $schema="), d
        assert first.endswith(f"schemas/{kind}.schema.json"), d


def test_progress_rate_and_eta_count_from_the_first_report_of_a_continued_run(monkeypatch):
    """A run continued from a checkpoint at 86 % reports 80 000 cycles at its first progress call. The rate and time
    remaining are this process's own: closed form from a fake clock, cycles per second = (c - c0) / (w - w0) and
    ETA = (w - w0) (T - t) / (t - t0). Before the fix the rate divided all 80 100 cycles by 10 s of this process and
    the ETA took t from 0 (about 1.6 s instead of about 816 s)."""
    from fdeck import cli

    clock = iter([100.0, 110.0])
    monkeypatch.setattr(cli.time, "perf_counter", lambda: next(clock))
    monkeypatch.setattr(cli.sys.stderr, "isatty", lambda: False, raising=False)
    lines = []
    monkeypatch.setattr(cli, "_err", lines.append)
    report, _ = cli._progress_printer(0.5916)
    report(0.50, 80000, 3.2e-6)  # the first report sets the reference and prints nothing
    report(0.51, 80100, 3.2e-6)
    assert len(lines) == 1
    rate = float(lines[0].split("cycles, ")[1].split(" cycles/s")[0].replace(",", ""))
    eta = float(lines[0].split("ETA ")[1].split(" s")[0])
    assert rate == 10.0  # (80100 - 80000) / (110 - 100), printed to the unit
    assert abs(eta - 10.0 * (0.5916 - 0.51) / 0.01) <= 0.5  # printed to the second
