"""`fdeck identify`: the Young's modulus of an elastic bar fitted to synthetic end displacements at four lengths,
against the closed-form least-squares solution, on the local pool and on a Dask LocalCluster; located errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml

from helpers import DECKS, ROOT

pytestmark = pytest.mark.unit

BAR = DECKS / "studies" / "bar.yaml"  # F = 10 N along x on a 10 x 10 mm bar (A = 100 mm^2), nu = 0
F, A, E_TRUE = 10.0, 100.0, 7000.0
LENGTHS = np.array([50.0, 100.0, 150.0, 200.0])


def synthetic():
    """End displacements F L / (E A) at E_TRUE, each times 1 + 1 % Gaussian scatter (seeded)."""
    noise = 1.0 + 0.01 * np.random.default_rng(9).standard_normal(len(LENGTHS))
    return F * LENGTHS / (E_TRUE * A) * noise


def spec_text(measured) -> str:
    rows = "\n".join(f"    - [{L:g}, {float(u)!r}]" for L, u in zip(LENGTHS, measured))
    return (f"base: {BAR}\nparameters:\n  - {{path: materials.bar.youngs_modulus, initial: 1.0e4, lower: 1.0e3, "
            f"upper: 1.0e5}}\nquantity: end_displacement\ntable:\n  path: mesh.block.size.0\n  rows:\n{rows}\n"
            "tolerance: 1.0e-6\npreset: {name: bar_fit}\n")


def test_identify_recovers_the_modulus_with_a_consistent_standard_error_locally_and_on_dask(tmp_path):
    """Requirement: identify fits E of a bar (u = F L / (E A)) to synthetic displacements with 1 % scatter: the
    fit equals the closed-form least-squares optimum of the relative residuals a_i / E - 1 (a_i = F L_i / (A u_i)),
    E* = sum a^2 / sum a, within 1e-3 (the FE bar gives F L / (E A) to about 1e-5: strain 1e-5, settled to
    exp(-20); the rest is the optimiser's tolerance), its standard error equals the closed form s E*^2 /
    sqrt(sum a^2) (s^2 = sum r^2 / (m - 1)) within 3 % (finite-difference Jacobian, model within 1e-5), E_true lies
    within 3 standard errors, the preset holds the fitted value and its provenance, and the Dask path
    (LocalCluster, 2 processes x 1 thread) gives bitwise the same fit."""
    from fdeck.study.executor import Pool
    from fdeck.study.identify import run_identify

    u = synthetic()
    spec = tmp_path / "ident.yaml"
    spec.write_text(spec_text(u))
    with Pool(workers=1) as pool:  # one process: the CPU budget (the cluster below runs two)
        res = run_identify(spec, tmp_path / "local", pool, echo=lambda *a: None)
    a = F * LENGTHS / (A * u)
    e_star = np.sum(a * a) / np.sum(a)
    r_star = a / e_star - 1.0
    se_star = np.sqrt(np.sum(r_star**2) / (len(a) - 1)) * e_star**2 / np.sqrt(np.sum(a * a))
    par = res["parameters"][0]
    assert res["status"] == "converged"
    assert abs(par["value"] - e_star) <= 1e-3 * e_star, (par["value"], e_star)
    assert abs(par["standard_error"] - se_star) <= 0.03 * se_star, (par["standard_error"], se_star)
    assert abs(par["value"] - E_TRUE) <= 3 * par["standard_error"], (par, E_TRUE)
    assert np.allclose([p["residual"] for p in res["points"]], r_star, atol=1e-3, rtol=0)
    assert [p["measured"] for p in res["points"]] == [float(x) for x in u]
    preset = (tmp_path / "local" / "bar_fit.yaml").read_text()
    fields = yaml.safe_load(preset)
    assert fields == {"density": 1.0e-9, "youngs_modulus": par["value"], "poisson_ratio": 0.0}
    assert "bar.yaml" in preset and "rms relative residual" in preset and "end_displacement" in preset
    assert res["runs"] > 0 and res["runs"] + res["runs_reused"] >= 2 * len(LENGTHS)

    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      env={"NUMBA_NUM_THREADS": "1"}) as cluster:
        with Pool(scheduler=cluster.scheduler_address) as pool:
            dask = run_identify(spec, tmp_path / "dask", pool, echo=lambda *a: None)
    assert dask["runs_reused"] < dask["runs"]  # a fresh folder: the fit ran on the cluster
    assert dask["parameters"] == res["parameters"] and dask["points"] == res["points"]


def _line(path, text):
    """1-based number of the first line of a file holding ``text``."""
    return next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if text in ln)


def _identify(spec, tmp_path):
    return subprocess.run([sys.executable, "-m", "fdeck.cli", "identify", str(spec), "-o", str(tmp_path / "o")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_bad_identify_file_gives_located_errors_and_exit_2(tmp_path):
    """Requirement: an unknown key, a start value outside its bounds (schema stage), a parameter path that is
    not in the base deck and a preset asked for a fit of no material field (deck stage) are reported at their
    lines, exit 2, no traceback, nothing run."""
    spec = tmp_path / "bad.yaml"
    spec.write_text(spec_text(synthetic()).replace("lower: 1.0e3", "lower: 2.0e4")
                    .replace("quantity:", "parameters_2: 1\nquantity:"))
    r = _identify(spec, tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 2, r.stderr
    assert lines[0].startswith(f"{spec}:{_line(spec, 'youngs_modulus')}:") \
        and "initial 10000.0 lies outside [20000.0, 100000.0]" in lines[0], lines[0]
    assert lines[1] == f"{spec}:{_line(spec, 'parameters_2')}:1: parameters_2: unknown key 'parameters_2' " \
        "(did you mean 'parameters'?)", lines[1]
    spec.write_text(spec_text(synthetic()).replace("materials.bar.youngs_modulus", "materials.bars.youngs_modulus"))
    r = _identify(spec, tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"{spec}:{_line(spec, 'bars')}:") \
        and "materials has no key 'bars' (keys: bar)" in r.stderr, r.stderr
    # a fitted value that is not a material field, and a preset of no material: located at `preset`
    spec.write_text(spec_text(synthetic()).replace("materials.bar.youngs_modulus", "loads.0.force.0")
                    .replace("initial: 1.0e4, lower: 1.0e3, upper: 1.0e5", "initial: 10.0, lower: 1.0, upper: 100.0"))
    r = _identify(spec, tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"{spec}:{_line(spec, 'preset:')}:") and "preset.material" in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()


def test_static_solver_fits_the_same_modulus_and_keys_its_own_runs(tmp_path):
    """Requirement: with `solver: static` each run is an equilibrium by Newton (``study.static_run``) instead of a
    damped dynamic run, and the fit is the same closed-form optimum E* as above within 1e-3 (the static bar gives
    F L / (E A) to the St Venant-Kirchhoff law's 1e-5 at strain 1e-5, the rest is the optimiser's tolerance). A
    static run is keyed apart from the dynamic run of the same deck (its own cache digest), reports its solver cost,
    a continuation in a deck parameter (E from 1e5 down to the run's own) and a solve started from a previous
    run's equilibrium (the seed identify gives a Jacobian's runs) land on the direct solve's answer within 1e-9
    relative (all converged to rtol 1e-8 of the displacement), the seeded one with fewer force calls."""
    from fdeck.deck.loader import load_file
    from fdeck.study import variants as vmod
    from fdeck.study.executor import Pool
    from fdeck.study.identify import run_identify
    from fdeck.study.static_run import run_static

    u = synthetic()
    spec = tmp_path / "ident.yaml"
    spec.write_text(spec_text(u) + "solver: static\n")
    with Pool(workers=1) as pool:
        res = run_identify(spec, tmp_path / "static", pool, echo=lambda *a: None)
    a = F * LENGTHS / (A * u)
    e_star = np.sum(a * a) / np.sum(a)
    assert res["status"] == "converged"
    assert abs(res["parameters"][0]["value"] - e_star) <= 1e-3 * e_star, (res["parameters"][0]["value"], e_star)

    data = load_file(BAR)[0]
    dynamic = vmod.plan("d", {}, data, BAR.parent)
    static = vmod.plan("s", {}, data, BAR.parent, {"continuation": None, "max_iterations": 20})
    assert dynamic.digest != static.digest and dynamic.deck == static.deck

    direct = run_static(data, BAR.parent, tmp_path / "direct", {"max_iterations": 20})
    path = run_static(data, BAR.parent, tmp_path / "path", {"max_iterations": 20, "continuation": {
        "path": "materials.bar.youngs_modulus", "values": [1.0e5, 3.0e4]}})
    assert direct["status"] == path["status"] == "completed" and direct["solver"] == "static"
    assert direct["force_calls"] > 0 and path["force_calls"] > direct["force_calls"]
    u0, u1 = direct["measures"]["end_displacement"], path["measures"]["end_displacement"]
    assert u0 == pytest.approx(F * 100.0 / (1.0e4 * A), rel=1e-4)
    assert u1 == pytest.approx(u0, rel=1e-9)
    seeded = run_static(data, BAR.parent, tmp_path / "seeded", {"max_iterations": 20}, seed=str(tmp_path / "direct"))
    assert seeded["seeded"] and seeded["force_calls"] < direct["force_calls"]
    assert seeded["measures"]["end_displacement"] == pytest.approx(u0, rel=1e-9)
