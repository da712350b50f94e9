"""Spring grips (issue 8, deliverable 4): a bar held by a compliant grip and pulled settles to the series-spring
displacement, a moving anchor pre-tensions the blank with the energy balance closed by the grip's stored energy
and the anchor's work, the step respects the grip's bound sqrt(m/k), and bad grip cards are refused."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.cards.grip import SpringGrip

from helpers import run_data

pytestmark = pytest.mark.verification

E, L, B, RHO = 1000.0, 100.0, 10.0, 1e-9  # [MPa], bar length and side [mm], [t/mm^3]


def bar(boundary, loads=(), steps=None, history_points=100, amplitudes=None):
    """A 100 x 10 x 10 mm linear-elastic bar along x, four elements long and one across (so that a uniform axial
    stress gives equal nodal forces on its end faces), rollers on ymin (y) and zmin (z) that leave the Poisson
    contraction free."""
    return run_data({
        "mesh": {"block": {"size": [L, B, B], "divisions": [4, 1, 1]}},
        "materials": {"m": {"type": "linear_elastic", "density": RHO, "youngs_modulus": E, "poisson_ratio": 0.3}},
        "sections": [{"material": "m", "formulation": "full"}],
        "boundary": [{"type": "fixed", "nodes": "ymin", "dofs": ["y"]},
                     {"type": "fixed", "nodes": "zmin", "dofs": ["z"]}] + list(boundary),
        "loads": list(loads),
        "amplitudes": amplitudes or {},
        "steps": steps or [{"duration": 1e-3}],
        "output": {"history_points": history_points, "measures": [
            {"type": "node_displacement", "name": "u_end", "nodes": "xmax", "component": "x"},
            {"type": "node_displacement", "name": "u_grip", "nodes": "xmin", "component": "x"}]}})


def test_gripped_bar_settles_to_the_series_spring_displacement():
    """Requirement: a bar held at x = 0 by a grip of k = 250 N/mm per node in x (4 nodes: 1000 N/mm) and pulled by
    F = 10 N at x = L, brought to rest by mass-proportional damping (alpha = 1.4e4 1/s, about twice the first
    angular frequency: every mode decays at least like exp(-alpha t / 2), 1e-15 after 5 ms), ends at
    u = F / k_grip + F L / (E A) = 0.01 + 0.01 mm. Tolerance 5e-4 relative: St Venant-Kirchhoff's geometric
    nonlinearity shortens the bar's share by 1.5 eps = 1.5e-4 at eps = 1e-4; the grip's share is exact (the held
    face moves by F / k_grip to 1e-9), and the grip force equals -F (1e-9)."""
    k, F = 250.0, 10.0
    _, res, h = bar([{"type": "spring_grip", "nodes": "xmin", "stiffness": k, "dofs": ["x"]}],
                    [{"type": "nodal_force", "nodes": "xmax", "force": [F, 0, 0], "distribution": "total",
                      "amplitude": "constant"}],
                    [{"duration": 5e-3, "damping": {"mass_proportional": 1.4e4}}])
    assert res.status == "completed", res.message
    k_grip = 4 * k
    assert h["u_grip"][-1] == pytest.approx(F / k_grip, rel=1e-9)
    assert h["grip_xmin_force_x"][-1] == pytest.approx(-F, rel=1e-9)
    assert h["u_end"][-1] == pytest.approx(F / k_grip + F * L / (E * B * B), rel=5e-4)


def balance(h, *work):
    """Largest |energy balance error| over the run, relative to the largest energy term (engine.ledger)."""
    scale = max(np.abs(h[c]).max() for c in ("kinetic_energy", "internal_energy", "external_work") + work)
    return float(np.abs(h["energy_balance_error"]).max() / scale)


def test_moving_anchor_pretensions_the_bar_and_the_energy_balance_closes():
    """Requirement: a bar between a fixed grip (x = 0, x y z) and a grip whose anchors travel 1 mm along +x
    (x = L, smooth amplitude over 1 ms, a few periods of the gripped bar's first mode of about 0.45 ms, undamped) is
    stretched dynamically; the energy balance kinetic + strain + grip energy - anchor work stays within 1 % of the
    largest energy term over the run (the ledger's central-difference error is of order (omega dt)^2 / 8, far
    below 1 %); the anchor follows value * smooth(t / T) (1e-12), its work is a sizeable share of the energy, and
    the two grips pull the bar apart at the end (opposite forces)."""
    moving = {"type": "spring_grip", "nodes": "xmax", "stiffness": 250.0, "direction": [1.0, 0.0, 0.0],
              "value": 1.0, "amplitude": "smooth"}
    _, res, h = bar([{"type": "spring_grip", "nodes": "xmin", "stiffness": 250.0}, moving], history_points=400)
    assert res.status == "completed", res.message
    t = h["time"] / 1e-3
    assert np.allclose(h["grip_xmax_anchor_x"], t**3 * (10 - 15 * t + 6 * t**2), rtol=1e-12, atol=1e-15)
    assert h["grip_work_xmax"][-1] > 0.1 * h["internal_energy"].max()
    assert np.abs(h["grip_energy"]).max() > 0.1 * h["internal_energy"].max()  # the grips take part in the balance
    assert balance(h, "grip_work_xmax", "grip_work_xmin") < 0.01
    pull, hold = h["grip_xmax_force_x"][-1], h["grip_xmin_force_x"][-1]
    assert pull > 0 and hold < 0


def test_moving_anchor_settles_to_the_series_spring_pretension():
    """Requirement: the anchors of the grip at x = L travel delta = 1 mm along x (smooth over the first 2 ms, then
    held; grips of 250 N/mm per node in x at both ends, 1000 N/mm a face), brought to rest by mass-proportional
    damping (alpha = 2e4 1/s for 6 ms): the bar carries the pre-tension F = delta / (2 / k_face + L / (E A)) =
    333.3 N, read as the pull of the moving grip and, opposite, the hold of the fixed one. Tolerance 1 %: St
    Venant-Kirchhoff's geometric nonlinearity changes the bar's share of the compliance (a third) by about
    1.5 eps = 0.5 % at eps = 3.3e-3; the residual motion after 4 ms of damping is far below that."""
    k_face, delta = 4 * 250.0, 1.0
    grips = [{"type": "spring_grip", "nodes": "xmin", "stiffness": 250.0, "dofs": ["x"]},
             {"type": "spring_grip", "nodes": "xmax", "stiffness": 250.0, "dofs": ["x"], "direction": [1, 0, 0],
              "value": delta, "amplitude": "pull"}]
    _, res, h = bar(grips, steps=[{"duration": 6e-3, "damping": {"mass_proportional": 2e4}}],
                    amplitudes={"pull": {"type": "smooth_step", "t1": 2e-3}})
    assert res.status == "completed", res.message
    F = delta / (2 / k_face + L / (E * B * B))
    assert h["grip_xmax_force_x"][-1] == pytest.approx(F, rel=0.01)
    assert h["grip_xmin_force_x"][-1] == pytest.approx(-F, rel=0.01)


def test_stiff_grip_sets_the_stable_step_to_sqrt_m_over_k():
    """Requirement: with a grip of 1e6 N/mm per node the step is dt_safety sqrt(m / k) of the gripped nodes'
    smallest lumped mass, m = rho V_el / 8 = 3.125e-7 t (each end node belongs to one 25 x 10 x 10 mm element):
    0.9 sqrt(3.125e-13) s = 5.03e-7 s, ten times below the elements' own step (1e-12: the same arithmetic); and the
    run stays stable (energy balance within 1 %)."""
    k = 1e6
    _, res, h = bar([{"type": "spring_grip", "nodes": "xmin", "stiffness": k}],
                    [{"type": "nodal_force", "nodes": "xmax", "force": [10.0, 0, 0], "distribution": "total"}],
                    [{"duration": 2e-4}])
    assert res.status == "completed", res.message
    m = RHO * (L / 4 * B * B) / 8
    assert res.dt_max == pytest.approx(0.9 * math.sqrt(m / k), rel=1e-12)
    assert balance(h, "grip_work_xmin") < 0.01


@pytest.mark.parametrize("fields, message", [
    ({"value": 1.0}, "needs `direction`"),
    ({"direction": [0, 0, 0]}, "zero vector"),
    ({"dofs": ["x"], "direction": [0, 1, 0], "value": 2.0}, "no component along the gripped dofs"),
    ({"dofs": ["x", "x"]}, "repeats"),
    ({"dofs": ["rx"]}, "rx"),
    ({"stiffness": 0.0}, "greater than 0"),
])
def test_bad_grip_cards_are_refused(fields, message):
    """Requirement: a moving grip without a direction, a zero direction, a travel with no component along the
    gripped dofs, a repeated dof, a rotational dof and a non-positive stiffness are validation errors."""
    card = {"type": "spring_grip", "nodes": "xmin", "stiffness": 10.0, **fields}
    with pytest.raises(ValidationError, match=message):
        SpringGrip.model_validate(card)
