"""Requirement: a flexible strip sliding over a fixed rough cylinder obeys the capstan equation (Euler-Eytelwein),
T_pulled / T_held = exp(mu theta), with the friction dissipation booked in the energy ledger.

Set-up (closed form in `capstan_tension`): a membrane strip (`formulation: membrane`, a linear fabric of 1000 MPa
along both yarns, 0.2 mm thick, 2 mm wide, no bending stiffness, so the tension is the only force along it and the
capstan equation holds exactly) wrapped over half a cylinder of radius 10 mm (theta = pi, nodes on the radius
R + h/2 where the two-sided shell contact starts), with two vertical 12 mm tails. The held end carries a constant
force T0 = 1 N (smooth ramp in a damped first step), the other end is then pulled down at a constant 55.6 mm/s so
that the whole strip slides 5 mm over the cylinder.

Why a membrane and why a light mass-proportional damping in the sliding step:
- membranes have no bending stiffness, so the tension is exactly the strip's force and the only other forces are
  the contact's; thin hexahedra would add a bending term (EI / R^2 per unit length) and cost 20x more;
- without any damping the sliding contact chatters: the radial penalty mode of each node (omega = sqrt(k / rho h)
  = 2.2e4 rad/s here) couples through the friction (f_t = mu f_n) with the strip's axial modes, a mode-coupling
  (flutter) instability of friction (Hoffmann, Fischer, Starosta, Wagner & Gaul, "A minimal model for studying
  properties of the mode-coupling type instability in friction induced oscillations", Mech. Res. Commun. 2002):
  the nodes lift off at up to 1 m/s and the measured ratio falls by 20 % (the test without damping below keeps
  only the requirement that the energy is still booked). A mass-proportional damping alpha = 2000
  1/s suppresses it; its drag on the sliding strip, q = alpha rho h b v per unit length, is a known uniform
  tangential load and enters the closed form exactly: dT/dphi = mu T + q R on the arc (T(phi) = (T_in + q R / mu)
  exp(mu phi) - q R / mu), T grows by q L along each tail. The correction is +1.7 % of T_pulled (mu = 0.3).

Tolerances: the issue's 3 % on the pure ratio exp(mu theta) (the drag correction stays below 2.5 %, so the pure
ratio holds within 3 %), and 1 % against the closed form with the drag: the polygonal wrap (24 chords over pi)
changes the ratio by prod (1 + mu tan(dphi/2)) / (1 - mu tan(dphi/2)) / exp(mu pi) - 1 = 0.2 %, the penalty
overclosure (1e-2 mm) moves the radius by 0.1 %, and the kinetic energy of the strip is 1-4e-3 of its strain energy.
Measured (T_pulled / T0, closed form with drag): mu = 0: 1.0246 / 1.0248; 0.2: 1.9091 / 1.9082 (exp 1.8745);
0.3: 2.6091 / 2.6066 (exp 2.5663); booked / friction work 1.003 and 1.004; balance below 1e-5.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import run_data
from shell_helpers import linear_fabric, one_thread  # noqa: F401

pytestmark = [pytest.mark.verification, pytest.mark.usefixtures("one_thread")]

R, H, B = 10.0, 0.2, 2.0  # cylinder radius, strip thickness and width [mm]
RC = R + H / 2  # radius of the strip's mid-surface on the cylinder [mm]
LT, N_ARC, N_TAIL = 12.0, 24, 8  # tail length [mm], elements over the half turn and along each tail
T0, E, RHO = 1.0, 1000.0, 1e-8  # held force [N], yarn modulus [MPa], density [t/mm^3] (fabric 1.5e-9, scaled x7)
ALPHA = 2000.0  # mass-proportional damping while sliding [1/s]
T_LOAD, T_PULL, TRAVEL = 0.01, 0.1, 5.0  # [s], [s], [mm]
SPEED = TRAVEL / (0.9 * T_PULL)  # constant pulling speed after a smooth start over the first 20 % [mm/s]


def strip_mesh(path) -> None:
    """Quadrilaterals of the strip (one across the width) along the held tail, the half turn and the pulled tail."""
    import meshio

    line = [(-RC, -LT + LT * k / N_TAIL) for k in range(N_TAIL)]
    line += [(RC * math.cos(math.pi * (1 - k / N_ARC)), RC * math.sin(math.pi * (1 - k / N_ARC)))
             for k in range(N_ARC + 1)]
    line += [(RC, -LT * k / N_TAIL) for k in range(1, N_TAIL + 1)]
    pts = np.array([[x, y, z] for x, z in line for y in (0.0, B)])
    conn = np.array([[2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1] for i in range(len(line) - 1)])
    meshio.write(path, meshio.Mesh(pts, [("quad", conn)]))


def capstan_deck(mesh, mu: float, alpha: float = ALPHA) -> dict:
    t1 = T_LOAD + T_PULL
    return {
        "mesh": {"file": str(mesh), "node_sets": {"held": {"box": [[-RC, 0, -LT], [-RC, B, -LT]]},
                                                  "pulled": {"box": [[RC, 0, -LT], [RC, B, -LT]]}}},
        "materials": {"strip": linear_fabric(E, G=1.0, density=RHO)},
        "sections": [{"material": "strip", "formulation": "membrane", "thickness": H,
                      "orientation": {"reference": [0, 1, 0]}}],  # yarns across and along the strip
        "amplitudes": {"load": {"type": "smooth_step", "t0": 0.0, "t1": T_LOAD},
                       "pull": {"type": "smooth_step", "t0": T_LOAD, "t1": T_LOAD + 0.2 * T_PULL}},
        # plane motion (y fixed) and ends kept on their vertical lines; the held end is free along z
        "boundary": [{"type": "fixed", "nodes": "all", "dofs": ["y"]},
                     {"type": "fixed", "nodes": "held", "dofs": ["x"]},
                     {"type": "fixed", "nodes": "pulled", "dofs": ["x"]},
                     {"type": "velocity", "nodes": "pulled", "dofs": ["z"], "value": -SPEED, "amplitude": "pull"}],
        "loads": [{"type": "nodal_force", "nodes": "held", "force": [0, 0, -T0], "distribution": "total",
                   "amplitude": "load"}],
        "tools": {"drum": {"surface": {"shape": "cylinder", "point": [0, 0, 0], "axis": [0, 1, 0], "radius": R}}},
        "contact": [{"tool": "drum", "normal": {"law": "linear", "stiffness": 10.0},
                     **({"friction": {"static": mu}} if mu > 0 else {})}],
        "steps": [{"name": "load", "duration": T_LOAD, "damping": {"mass_proportional": 500.0}},
                  {"name": "pull", "duration": T_PULL, "damping": {"mass_proportional": alpha}}],
        "output": {"history_points": 221, "reactions": ["pulled"],
                   "measures": [{"type": "node_displacement", "name": "u_held", "nodes": "held", "component": "z"}]},
        "checks": {},
        "title": f"capstan mu={mu} to {t1} s",
    }


def capstan_tension(mu: float, held_rise: float, pulled_drop: float) -> float:
    """T_pulled [N] of the steady sliding strip: T0 plus the drag q over the held tail (LT - held_rise), the capstan
    growth with drag over the half turn, plus the drag over the pulled tail (LT + pulled_drop)."""
    q = ALPHA * RHO * H * B * SPEED  # [N/mm]
    t_in = T0 + q * (LT - held_rise)
    if mu > 0:
        t_out = (t_in + q * RC / mu) * math.exp(mu * math.pi) - q * RC / mu
    else:
        t_out = t_in + q * RC * math.pi
    return t_out + q * (LT + pulled_drop)


def balance_ratio(h) -> float:
    scale = max(np.abs(h[k]).max() for k in ("kinetic_energy", "internal_energy", "external_work",
                                              "damping_energy", "friction_dissipation"))
    return float(np.abs(h["energy_balance_error"]).max() / scale)


@pytest.mark.parametrize("mu", [0.0, 0.2, 0.3])
def test_strip_sliding_over_a_cylinder_follows_the_capstan_equation(tmp_path, mu):
    """Requirement: T_pulled / T_held = exp(mu pi) within 3 % (1 when frictionless) and within 1 % of the closed
    form with the known damping drag (module docstring); quasi-static (kinetic < 1 % of the strain energy over the
    steady window, measured 0.1 %); the friction dissipation booked over the window equals the friction's work,
    (T_out - T_in - q pi R) times the distance slid, within 2 % (the drag terms are 1-2 % of it, the rest is exact
    bookkeeping); energy balance within 1 % of the largest energy term."""
    mesh = tmp_path / "strip.inp"
    strip_mesh(mesh)
    _, res, h = run_data(capstan_deck(mesh, mu), base=tmp_path)
    assert res.status == "completed", res.message
    assert all(np.isfinite(v).all() for v in h.values())
    t = h["time"]
    steady = t > T_LOAD + 0.5 * T_PULL  # constant speed since 0.2 T_PULL, steady sliding well before half-way
    assert steady.sum() > 50
    tension = -h["reaction_pulled_z"][steady]
    ratio = float(tension.mean()) / T0
    assert ratio == pytest.approx(math.exp(mu * math.pi), rel=0.03)
    rise, drop = float(h["u_held"][steady].mean()), SPEED * float(t[steady].mean() - T_LOAD - 0.1 * T_PULL)
    assert rise > 1.0  # the strip does slide over the cylinder (held end rises by as much as the pulled end drops)
    assert ratio == pytest.approx(capstan_tension(mu, rise, drop) / T0, rel=0.01)
    # quasi-static
    assert (h["kinetic_energy"][steady] < 0.01 * h["internal_energy"][steady]).all()
    # friction booked = friction work over the window
    if mu > 0:
        q = ALPHA * RHO * H * B * SPEED
        t_in = T0 + q * (LT - rise)
        friction_force = capstan_tension(mu, rise, drop) - q * (LT + drop) - t_in - q * math.pi * RC
        slid = float(h["u_held"][steady][-1] - h["u_held"][steady][0])
        booked = float(h["friction_dissipation"][steady][-1] - h["friction_dissipation"][steady][0])
        assert booked == pytest.approx(friction_force * slid, rel=0.02)
    else:
        assert "friction_dissipation" not in h or np.abs(h["friction_dissipation"]).max() == 0.0
    assert balance_ratio(h) < 0.01


def test_undamped_sliding_books_the_friction_it_dissipates(tmp_path):
    """Requirement: the same strip pulled without any damping (mu = 0.3), where the sliding contact chatters (nodes
    lift off and land, their normal force jumps from cycle to cycle), still closes its energy balance within 1 % of
    the largest energy term: every joule the pull puts in is kinetic, strain, contact or friction energy. No physics
    check on the tension here (the chatter is real for this penalty system, see the module docstring); the
    requirement is the bookkeeping, whatever the contact does.

    With the friction return map booking |f_t| x (plastic slip) at the new limit mu f_n(t_n), while the engine's
    central-difference work pairs the node's force with its motion trapezoidally (the mean of the old and the new
    tangential force), the balance loses (|T| - mu f_n) (t_old . T/|T| - mu f_n) / (2 k_t) per slipping node per
    cycle whenever the normal force falls while sliding: measured -5.7 % of the friction dissipation here."""
    mesh = tmp_path / "strip.inp"
    strip_mesh(mesh)
    _, res, h = run_data(capstan_deck(mesh, 0.3, alpha=0.0), base=tmp_path)
    assert res.status == "completed", res.message
    assert all(np.isfinite(v).all() for v in h.values())
    assert h["friction_dissipation"][-1] > 1.0  # it slid: more than 1 mJ dissipated by friction
    assert balance_ratio(h) < 0.01
