"""Deformation damping (``steps[].deformation_damping``): no force on rigid motion, momentum kept, power never
positive and equal to the closed form, element-scale modes damped as (h / lambda)^2, energy booked, step bound."""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import deck_data, run_data

pytestmark = pytest.mark.verification


def _rigid_fit(x, v, w, spin=None, j=None, d=None):
    """Weighted least-squares rigid motion (translation t, spin omega) of nodes x (n, 3) with velocities v and,
    when given, angular velocities spin (n, 3) of rotational weights j about axes normal to the directors d (n, 3):
    the independent reference, by numpy's lstsq on the rows sqrt(w_a) [1 | -[x_a]x] (t, omega) = sqrt(w_a) v_a and
    sqrt(j_a) [0 | P_a] (t, omega) = sqrt(j_a) P_a spin_a, P_a = 1 - d_a d_a^T. Returns (the fitted velocities
    (n, 3), omega)."""
    rows, rhs = [], []
    for xa, va, wa in zip(x, v, w):
        # omega x r = cross @ omega
        cross = np.array([[0.0, xa[2], -xa[1]], [-xa[2], 0.0, xa[0]], [xa[1], -xa[0], 0.0]])
        rows.append(math.sqrt(wa) * np.hstack([np.eye(3), cross]))
        rhs.append(math.sqrt(wa) * va)
    if spin is not None:
        for sa, ja, da in zip(spin, j, d):
            proj = np.eye(3) - np.outer(da, da)
            rows.append(math.sqrt(ja) * np.hstack([np.zeros((3, 3)), proj]))
            rhs.append(math.sqrt(ja) * proj @ sa)
    sol = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    return sol[:3] + np.cross(sol[3:], x), sol[3:]


@pytest.mark.parametrize("n, rotations", [(8, False), (4, False), (4, True)])
def test_rigid_motion_is_free_and_the_forces_keep_momentum(n, rotations):
    """Requirement: on a distorted element (8 nodes, or 4 nearly coplanar ones as a shell, with nodal rotations
    or without) with unequal nodal weights, a rigid motion (any translation plus any spin; with rotations the nodes'
    angular velocities equal to the spin up to any drilling part along their directors, which has no stiffness
    and is not driven) gets no force or moment (below 1e-12 of the scale: round-off of the fit), and a random one
    gets f_a = -c w_a (v_a - fit) and m_a = -c j_a P_a (spin_a - omega) with the fit computed independently by
    least squares (1e-10 relative), zero resultant and zero total moment sum r x f + m (1e-12 of the force scale),
    and power sum f.v + m.spin = -c (sum w |v - fit|^2 + sum j |P (spin - omega)|^2) < 0 (1e-10)."""
    from fdeck.physics.effects.deformation_damping import relative_forces

    rng = np.random.default_rng(3)
    x = rng.standard_normal((n, 3))
    if n == 4:
        x[:, 2] *= 1e-3  # a shell's four nodes: nearly in a plane
    conn = np.arange(n)[None, :]
    w = rng.uniform(0.5, 2.0, n)
    j = rng.uniform(0.5, 2.0, n) if rotations else np.zeros(n)
    d = np.zeros((n, 3))
    if rotations:  # directors near the element's normal, each tilted its own way
        d = np.array([0.0, 0.0, 1.0]) + 0.2 * rng.standard_normal((n, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
    c = 250.0
    fe, me, power = np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros(1)
    omega = np.array([0.7, -1.1, 2.3])
    rigid = np.array([4.0, -2.0, 1.0]) + np.cross(omega, x)
    spin = omega + rng.standard_normal(n)[:, None] * d if rotations else np.zeros((n, 3))  # any drilling part
    relative_forces(x, rigid, spin, d, conn, w, j, c, fe, me, power)
    assert np.abs(fe).max() < 1e-12 * c * w.max() * np.abs(rigid).max()
    assert np.abs(me).max() <= 1e-12 * c * max(j.max(), 1.0) * np.abs(omega).max()
    v = rng.standard_normal((n, 3))
    spin = rng.standard_normal((n, 3)) if rotations else np.zeros((n, 3))
    relative_forces(x, v, spin, d, conn, w, j, c, fe, me, power)
    f, m = fe[0], me[0]
    fit, om = _rigid_fit(x, v, w, spin if rotations else None, j, d)
    expected = -c * w[:, None] * (v - fit)
    assert np.allclose(f, expected, rtol=1e-10, atol=1e-10 * np.abs(expected).max())
    rel = np.array([(np.eye(3) - np.outer(da, da)) @ (sa - om) for sa, da in zip(spin, d)])
    if rotations:
        assert np.allclose(m, -c * j[:, None] * rel, rtol=1e-10, atol=1e-10 * np.abs(m).max())
    else:
        assert not m.any()
    scale = np.abs(f).max()
    assert np.abs(f.sum(axis=0)).max() < 1e-12 * scale * n
    total_moment = np.cross(x - x.mean(axis=0), f).sum(axis=0) + m.sum(axis=0)
    assert np.abs(total_moment).max() < 1e-12 * scale * n * np.abs(x).max()
    assert power[0] == pytest.approx(float((f * v).sum() + (m * spin).sum()), rel=1e-10) and power[0] < 0.0
    reference = -c * float((w[:, None] * (v - fit) ** 2).sum() + (j[:, None] * rel ** 2).sum())
    assert power[0] == pytest.approx(reference, rel=1e-10)


def test_degenerate_elements_keep_momentum_and_dissipate():
    """Requirement: an element whose nodes lie on a line (no spin can be fitted) keeps only its translation: a
    uniform velocity gets no force (1e-12), any other field forces with zero resultant (1e-12 of their scale) and a
    negative power equal to -c sum w |v - mean|^2 (1e-10, the weighted mean by hand); an element without mass (all
    weights zero) gets no force at all."""
    from fdeck.physics.effects.deformation_damping import relative_forces

    rng = np.random.default_rng(5)
    x = np.outer(np.arange(4.0), [1.0, 2.0, -0.5])  # four collinear nodes
    conn = np.arange(4)[None, :]
    w = rng.uniform(0.5, 2.0, 4)
    zeros = np.zeros((4, 3))
    fe, me, power = np.zeros((1, 4, 3)), np.zeros((1, 4, 3)), np.zeros(1)
    relative_forces(x, np.tile([1.0, -2.0, 3.0], (4, 1)), zeros, zeros, conn, w, np.zeros(4), 100.0, fe, me, power)
    assert np.abs(fe).max() < 1e-12 * 100.0 * w.max() * 3.0
    v = rng.standard_normal((4, 3))
    relative_forces(x, v, zeros, zeros, conn, w, np.zeros(4), 100.0, fe, me, power)
    mean = (w[:, None] * v).sum(axis=0) / w.sum()
    assert np.abs(fe[0].sum(axis=0)).max() < 1e-12 * np.abs(fe).max() * 4
    assert power[0] == pytest.approx(-100.0 * float((w[:, None] * (v - mean) ** 2).sum()), rel=1e-10)
    relative_forces(x, v, zeros, zeros, conn, np.zeros(4), np.zeros(4), 100.0, fe, me, power)
    assert not fe.any() and not me.any() and power[0] == 0.0


def test_a_wave_decays_as_mass_damping_of_rate_c_pi2_h2_over_lambda2():
    """Requirement: the module's rates. On a bar of 1 mm cubes (h = 1 mm) with the velocity sin(2 pi x / lambda
    + 0.3), the decay rate of the kinetic energy, power / E_kin, is what mass-proportional damping alpha gives,
    2 alpha, with alpha = c pi^2 (h / lambda)^2 for a stretching (longitudinal) wave and half that for a
    transverse one (within 1 % at lambda = 64 h: the next term is O((h / lambda)^2) relative, 0.24 % there), and
    for the node-to-node zig-zag (lambda = 2 h) alpha = c and c / 2 exactly (every element's nodes move as +-u:
    a pure stretch, or a shear whose spin part the fit removes; 1e-9 for round-off)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck

    n_el, c = 256, 100.0
    data = {"mesh": {"block": {"size": [float(n_el), 1.0, 1.0], "divisions": [n_el, 1, 1]}},
            "materials": {"m": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 1000.0,
                                "poisson_ratio": 0.25}},
            "sections": [{"material": "m", "formulation": "reduced"}],
            "steps": [{"duration": 1.0, "deformation_damping": {"rate": c}}]}
    p = compile_deck(Deck.model_validate(data))
    eff = next(e for e in p.effects if e.name == "deformation damping")
    eff.begin_step(0, p.steps[0])
    m = p.steps[0].mass
    for axis, share in ((0, 1.0), (1, 0.5)):  # longitudinal, transverse
        for lam, alpha, tol in ((64.0, c * share * (np.pi / 64.0) ** 2, 0.01), (2.0, c * share, 1e-9)):
            v = np.zeros_like(p.X)
            v[:, axis] = np.sin(2 * np.pi * p.X[:, 0] / lam + 0.3)
            f = np.zeros_like(p.X)
            eff.add_force(0.0, p.X, v, f)
            rate = -float((f * v).sum()) / (0.5 * float((m[:, None] * v * v).sum()))
            assert rate == pytest.approx(2.0 * alpha, rel=tol), (axis, lam)


def _final_drop(data: dict) -> float:
    """Mean downward displacement [mm] of every node at the end of a run of deck data."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    class Last(solver.Sink):
        def frame(self, t, x, v, point_fields=None):
            self.x = x.copy()

    problem, sink = compile_deck(Deck.model_validate(data)), Last()
    assert solver.run(problem, sink).status == "completed"
    return float(np.mean(problem.X[:, 2] - sink.x[:, 2]))


def test_free_fall_is_not_dragged_and_a_ringing_bar_books_its_dissipation():
    """Requirement: a free block under gravity with deformation damping falls as 1/2 g t^2 (closed form, 1e-9:
    rigid translation is not damped; the same block with mass-proportional damping at the same rate falls
    measurably less, so the check can fail), as does a plate of shells with nodal rotations, and on the wave bar
    the dissipated energy is in the ledger (balance error < 1e-3 of the largest energy, as for bulk viscosity), the
    damping energy is positive and the step is dt_e (sqrt(1 + xi^2) - xi) with xi = c dt_e / 4 (closed form,
    1e-12), c chosen so that xi = 0.5."""
    block = {"mesh": {"block": {"size": [2.0, 2.0, 2.0], "divisions": [2, 2, 2]}},
             "materials": {"m": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 1000.0,
                                 "poisson_ratio": 0.25}},
             "sections": [{"material": "m", "formulation": "full"}],
             "loads": [{"type": "gravity", "acceleration": [0.0, 0.0, -9810.0]}],
             "steps": [{"duration": 0.01, "deformation_damping": {"rate": 500.0}}],
             "output": {"history_points": 20}}
    drop = _final_drop(block)
    assert drop == pytest.approx(0.5 * 9810.0 * 0.01**2, rel=1e-9)
    block["steps"][0] = {"duration": 0.01, "damping": {"mass_proportional": 500.0}}
    assert _final_drop(block) < 0.9 * drop
    plate = {"mesh": {"plate": {"size": [10.0, 10.0], "divisions": [2, 2]}},
             "materials": {"t300": {"type": "fabric_membrane", "preset": "t300_3k"}},
             "sections": [{"material": "t300", "formulation": "sm", "preset": "t300_3k"}],
             "loads": [{"type": "gravity", "acceleration": [0.0, 0.0, -9810.0]}],
             "steps": [{"duration": 0.01, "deformation_damping": {"rate": 500.0}}],
             "output": {"history_points": 20}}
    assert _final_drop(plate) == pytest.approx(0.5 * 9810.0 * 0.01**2, rel=1e-9)  # shells with rotations too

    data = deck_data("wave_bar.yaml")
    _, _, h0 = run_data(data)
    dt_e = h0["dt"][1] / data["steps"][0].get("dt_safety", 0.9)
    c = 2.0 / dt_e  # xi = c dt_e / 4 = 0.5
    data["steps"][0]["deformation_damping"] = {"rate": c}
    _, result, h = run_data(data)
    assert result.status == "completed"
    assert h["dt"][1] == pytest.approx(h0["dt"][1] * (math.sqrt(1.25) - 0.5), rel=1e-12)
    scale = max(np.abs(h["kinetic_energy"]).max(), np.abs(h["external_work"]).max())
    assert np.abs(h["energy_balance_error"]).max() < 1e-3 * scale
    # that it dissipates at all (measured 2.1 % of the largest energy; the ledger's round-off is 1e-12 of it)
    assert h["damping_energy"][-1] > 1e-2 * scale and h0["damping_energy"][-1] == 0.0


def test_a_ringing_shell_plate_books_the_damping_of_its_rotations():
    """Requirement: a cantilevered plate of sm shells (nodal rotations) whose free edge is pulled down to 500 mm/s
    within 50 us, damped by deformation damping alone (so the nodes' spins relative to their elements are damped by
    moments into the rotational ledger as well as the forces), closes its energy balance within 1e-3 of the largest
    energy (measured 3.4e-4; without damping the same deck gives 9e-4, with mass damping 3e-5) and dissipates (over
    1 % of the work; measured 14 %). A moment applied but not booked would show in the balance; the rotations here
    are small (their kinetic energy 0.15 % of the translational), so this holds the bookkeeping, not its size."""
    data = {"mesh": {"plate": {"size": [20, 20], "divisions": [10, 10]}},
            "materials": {"f": {"type": "fabric_membrane", "preset": "t300_3k"}},
            "sections": [{"material": "f", "formulation": "sm", "preset": "t300_3k",
                          "orientation": {"warp_angle": 30}}],
            "boundary": [{"type": "fixed", "nodes": "xmin", "dofs": ["x", "y", "z", "rx", "ry", "rz"]},
                         {"type": "velocity", "nodes": "xmax", "dofs": ["x", "z"], "value": -500.0,
                          "amplitude": "jerk"}],
            "amplitudes": {"jerk": {"type": "smooth_step", "t1": 5e-5}},
            "steps": [{"duration": 3e-4, "deformation_damping": {"rate": 20000.0}}],
            "output": {"history_points": 60}}
    _, result, h = run_data(data)
    assert result.status in ("completed", "stopped"), result.message
    scale = max(np.abs(h[k]).max() for k in ("kinetic_energy", "internal_energy", "external_work"))
    assert np.abs(h["energy_balance_error"]).max() < 1e-3 * scale
    assert h["damping_energy"][-1] > 1e-2 * h["external_work"][-1] > 0.0


def test_a_membrane_strips_contact_chatter_is_rigid_element_motion_it_leaves_alone(tmp_path):
    """Known limit, pinned (README, Known limits): the capstan strip of ``test_contact_capstan.py`` (membrane
    quadrilaterals, one across the width, mu = 0.3) chatters while sliding when it is not damped: each node's
    radial contact mode turns the elements next to it about their neighbours. Mass damping removes that (the
    capstan test); deformation damping, even at 20 000 1/s, does not, because each element moves nearly rigidly:
    the tension ratio stays about as low as undamped (measured 2.14 against exp(0.3 pi) = 2.57, -16 %; undamped
    -20 %), so the test requires it below 0.9 exp(mu pi), while the balance still closes within 1 %. When a
    damping that cures it comes, this test fails and the README's limit goes."""
    import test_contact_capstan as capstan

    mesh = tmp_path / "strip.inp"
    capstan.strip_mesh(mesh)
    data = capstan.capstan_deck(mesh, 0.3, alpha=0.0)
    data["steps"][1] = {"name": "pull", "duration": capstan.T_PULL, "deformation_damping": {"rate": 20000.0}}
    _, res, h = run_data(data, base=tmp_path)
    assert res.status == "completed", res.message
    steady = h["time"] > capstan.T_LOAD + 0.5 * capstan.T_PULL
    ratio = float((-h["reaction_pulled_z"][steady]).mean()) / capstan.T0
    assert ratio < 0.9 * math.exp(0.3 * math.pi)
    assert capstan.balance_ratio(h) < 0.01
