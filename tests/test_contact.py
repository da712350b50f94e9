"""Rigid tools and penalty contact with Coulomb friction (issue 8, first part): normal laws against their closed
forms, a block resting on a plane, a block on an inclined plane below and above the friction angle, energy balance,
both faces of a shell, and initial penetrations refused with node numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.cards.contact import Exponential, Linear
from fdeck.physics.effects.contact import normal_law, pack_law

from helpers import run_data

pytestmark = pytest.mark.verification

G = 9810.0  # mm/s^2


def test_linear_law_and_its_energy():
    """Requirement: p = k h above contact, 0 below; energy k h^2 / 2 (exact arithmetic, 1e-15)."""
    law = pack_law(Linear(law="linear", stiffness=200.0))
    assert normal_law(law, -0.1) == (0.0, 0.0, 0.0)
    p, k, e = normal_law(law, 0.01)
    assert p == pytest.approx(2.0, rel=1e-15) and k == 200.0 and e == pytest.approx(0.01, rel=1e-15)


def test_exponential_law_closed_form_cap_and_energy():
    """Requirement (MODELS 7): p(0) = p0 and p(-c0) = 0 (1e-12); beyond the cap the slope is k_max and p, dp/dh and
    the energy are continuous there (1e-6 relative over 1e-9 c0); dE/dh = p by central differences (1e-6)."""
    p0, c0, kmax = 0.1, 0.05, 50.0
    law = pack_law(Exponential(law="exponential", p0=p0, c0=c0, max_stiffness=kmax))
    assert normal_law(law, 0.0)[0] == pytest.approx(p0, rel=1e-12)
    assert normal_law(law, -c0)[0] == 0.0 and normal_law(law, -2 * c0) == (0.0, 0.0, 0.0)
    h_cap = law[4]
    assert math.isfinite(h_cap) and h_cap > -c0
    eps = 1e-9 * c0
    below, above = normal_law(law, h_cap - eps), normal_law(law, h_cap + eps)
    for a, b in zip(below, above):
        assert b == pytest.approx(a, rel=1e-6, abs=1e-12)
    assert above[1] == kmax
    for h in (-0.03, 0.0, 0.5 * h_cap, 2 * h_cap + 0.01):
        d = 1e-7
        de = (normal_law(law, h + d)[2] - normal_law(law, h - d)[2]) / (2 * d)
        assert de == pytest.approx(normal_law(law, h)[0], rel=1e-6)


def block(steps, loads, friction=None, stiffness=200.0, z0=0.0, extra=None, normal=None, springs="explicit",
          floor=None):
    """A 10 x 10 x 5 mm steel-like block (one element layer, 2 x 2 in plan) on the plane z = 0 (or the tool card
    ``floor``), its contact law linear of ``stiffness`` unless ``normal`` (a normal-law card) is given."""
    data = {
        "mesh": {"block": {"origin": [0.0, 0.0, z0], "size": [10.0, 10.0, 5.0], "divisions": [2, 2, 1]}},
        "materials": {"m": {"type": "linear_elastic", "density": 1e-6, "youngs_modulus": 1000.0,
                            "poisson_ratio": 0.3}},
        "sections": [{"material": "m", "formulation": "full"}],
        "tools": {"floor": floor or {"surface": {"shape": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}}},
        "contact": [{"tool": "floor", "normal": normal or {"law": "linear", "stiffness": stiffness},
                     "springs": springs, **({"friction": friction} if friction else {})}],
        "loads": loads,
        "steps": steps,
        "output": {"history_points": 400,
                   "measures": [{"type": "node_displacement", "name": "ux", "nodes": "all", "component": "x"},
                                {"type": "node_displacement", "name": "uz", "nodes": "zmin", "component": "z"}]},
    }
    data.update(extra or {})
    return run_data(data)


def balance(h):
    scale = max(np.abs(h[c]).max() for c in ("kinetic_energy", "internal_energy", "external_work",
                                              "tool_work_floor", "friction_dissipation", "damping_energy"))
    return float(np.abs(h["energy_balance_error"]).max() / scale)


def test_block_resting_on_a_plane_penetrates_by_load_over_penalty_stiffness():
    """Requirement: at rest, the bottom face sinks by h = m g / (k A) (k = 200 MPa/mm, A = 100 mm^2: 2.45e-4 mm) and
    the floor carries the weight. Tolerance 1 %: the damped rest leaves a residual oscillation far below that, and
    the block's own compression does not move its bottom face."""
    _, res, h = block([{"duration": 0.05, "damping": {"mass_proportional": 400.0}}],
                      [{"type": "gravity", "acceleration": [0, 0, -G]}])
    assert res.status == "completed", res.message
    m = 1e-6 * 500.0
    assert -h["uz"][-1] == pytest.approx(m * G / (200.0 * 100.0), rel=0.01)
    assert h["tool_floor_force_z"][-1] == pytest.approx(m * G, rel=0.01)
    assert balance(h) < 0.01


def tilted(theta, mu, duration=0.1, mass_scaling=None):
    """Settle on the floor under the normal part of gravity (damped), then switch on the tangential part."""
    t1 = 0.02
    loads = [{"type": "gravity", "acceleration": [0, 0, -G * math.cos(theta)]},
             {"type": "gravity", "acceleration": [G * math.sin(theta), 0, 0], "amplitude": "tilt"}]
    extra = {"amplitudes": {"tilt": {"type": "tabular", "points": [[0, 0], [t1, 0], [t1 + 1e-9, 1], [1, 1]]}}}
    steps = [{"name": "settle", "duration": t1, "damping": {"mass_proportional": 400.0}},
             {"name": "slide", "duration": duration}]
    if mass_scaling is not None:
        for s in steps:
            s["mass_scaling"] = mass_scaling
    _, res, h = block(steps, loads, friction={"static": mu}, extra=extra)
    assert res.status == "completed", res.message
    return h, t1


def test_block_on_an_incline_sticks_below_the_friction_angle():
    """Requirement: with tan(theta) = 0.2 < mu = 0.3 the block stays put: after 0.1 s it has moved less than 1e-4 of
    the 9.6 mm it would slide without friction (the stick springs' elastic slip is about 5e-5 mm)."""
    theta = math.atan(0.2)
    h, t1 = tilted(theta, 0.3)
    free = 0.5 * G * math.sin(theta) * 0.1**2
    assert abs(h["ux"][-1]) < 1e-4 * free
    assert balance(h) < 0.01


@pytest.mark.parametrize("mass_scaling", [None, {"factor": 9.0, "selective": True}],
                         ids=["lumped", "selective"])
def test_block_on_an_incline_slides_with_the_coulomb_acceleration(mass_scaling):
    """Requirement: with tan(theta) = 0.5 > mu = 0.3 the block slides with a = g (sin(theta) - mu cos(theta)): the
    travel over the last half of the slide, divided by that of the closed form, within 2 % (the issue's tolerance;
    the stick-to-slip start and the normal springs' ringing shift the travel by far less). Also with selective
    mass scaling (x9 on the deformation modes, the element step x3): the block slides as a rigid body, whose
    inertia the added mass leaves alone, so the same closed form and tolerance hold with contact and friction."""
    theta, mu = math.atan(0.5), 0.3
    h, t1 = tilted(theta, mu, mass_scaling=mass_scaling)
    a = G * (math.sin(theta) - mu * math.cos(theta))
    t = h["time"] - t1
    late = t > 0.05
    x0 = np.interp(0.05, t, h["ux"])
    expected = 0.5 * a * (t[late][-1] ** 2 - 0.05**2)
    assert (h["ux"][late][-1] - x0) == pytest.approx(expected, rel=0.02)
    assert h["friction_dissipation"][-1] > 0.0
    assert balance(h) < 0.01  # energy balance with friction within 1 % of the largest energy
    if mass_scaling is not None:  # the added mass was solved for (measured: 6.5 iterations per cycle)
        assert h["cg_iterations_mean"][-1] > 1.0 and h["added_kinetic_energy"][-1] > 0.0


def _frame(problem, res, tmp_path):
    """The point data of a frame written by ``run.Outputs`` at the run's last state, read back with meshio."""
    import meshio

    from fdeck.run import Outputs

    out = Outputs(problem, tmp_path, "b", progress=None)
    out.frame(0.0, res.final_positions, res.final_velocities)
    for series in out.series:
        series.close()
    return meshio.read(next(tmp_path.glob("b_00000.vtu"))).point_data


def test_frames_carry_contact_pressure_gap_and_status(tmp_path):
    """Requirement: each frame holds the contact fields per node. For the block resting on the plane (linear law, k =
    200 MPa/mm): the bottom face sinks by h = m g / (k A) (1 %, as the resting test), and there gap = -h (1e-9
    relative: both read the same positions), pressure = k h (1e-9), status 1 (in contact, no friction), and the
    pressures times the nodes' tributary areas (6.25 / 12.5 / 25 mm^2 for corner / edge / centre node) carry the
    weight m g (1 %, as the resting test); on the top face pressure 0, status 0 and gap 5 mm less h (the plane's
    distance, 1e-9)."""
    problem, res, _ = block([{"duration": 0.05, "damping": {"mass_proportional": 400.0}}],
                            [{"type": "gravity", "acceleration": [0, 0, -G]}])
    assert res.status == "completed", res.message
    pd = _frame(problem, res, tmp_path)
    z0 = problem.X[:, 2]
    bottom, top = z0 == 0.0, z0 == 5.0
    sink = -res.final_positions[bottom, 2]
    assert sink == pytest.approx(np.full(bottom.sum(), 1e-6 * 500.0 * G / (200.0 * 100.0)), rel=0.01)
    np.testing.assert_allclose(pd["contact_gap"][bottom], -sink, rtol=1e-9)
    np.testing.assert_allclose(pd["contact_pressure"][bottom], 200.0 * sink, rtol=1e-9)
    np.testing.assert_array_equal(pd["contact_status"][bottom], 1.0)
    x, y = problem.X[bottom, 0], problem.X[bottom, 1]
    area = 25.0 * np.where((x == 5.0), 1.0, 0.5) * np.where((y == 5.0), 1.0, 0.5)
    assert float((pd["contact_pressure"][bottom] * area).sum()) == pytest.approx(1e-6 * 500.0 * G, rel=0.01)
    np.testing.assert_array_equal(pd["contact_pressure"][top], 0.0)
    np.testing.assert_array_equal(pd["contact_status"][top], 0.0)
    np.testing.assert_allclose(pd["contact_gap"][top], res.final_positions[top, 2], rtol=1e-9)


def test_block_resting_under_the_exponential_law_sits_at_zero_clearance(tmp_path):
    """Requirement (MODELS 7): the exponential law's pressure at zero clearance is p0. A block whose weight per area m
    g / A is chosen as p0 (0.049 MPa) settles where the bottom face's gap is 0: the frame's contact_gap within 1e-3
    c0 of 0 (c0 = 0.01 mm; the slope there, p0 (2e - 1) / ((e - 1) c0) = 2.58 p0 / c0, makes 1e-3 c0 a 0.26 %
    pressure error, above the damped rest's residue) and contact_pressure within 1 % of p0 at every bottom node, and
    the floor carries the weight (1 %)."""
    weight = 1e-6 * 500.0 * G
    p0 = weight / 100.0
    extra = {"contact": [{"tool": "floor", "normal": {"law": "exponential", "p0": p0, "c0": 0.01,
                                                      "max_stiffness": 200.0}}]}
    problem, res, h = block([{"duration": 0.05, "damping": {"mass_proportional": 400.0}}],
                            [{"type": "gravity", "acceleration": [0, 0, -G]}], extra=extra)
    assert res.status == "completed", res.message
    pd = _frame(problem, res, tmp_path)
    bottom = problem.X[:, 2] == 0.0
    assert np.abs(pd["contact_gap"][bottom]).max() < 1e-3 * 0.01
    np.testing.assert_allclose(pd["contact_pressure"][bottom], p0, rtol=0.01)
    assert h["tool_floor_force_z"][-1] == pytest.approx(weight, rel=0.01)


def test_contact_fields_of_several_tools_merge_at_the_nodes_they_share(tmp_path):
    """Requirement: where several effects give a field at the same node, the frame holds the largest (pressure,
    status, slip) or the smallest (gap) of their values, a NaN wins (a failed run's last frame must show it, not
    hide it behind another tool's value), and nodes no effect gives hold the field's value elsewhere (NaN gap, 0
    for the rest). Two stand-in effects on overlapping node sets of the resting block's problem, checked exactly."""
    from fdeck.engine.effect import Effect

    class Stand(Effect):
        def __init__(self, nodes, pressure, gap):
            self.fields = {"contact_pressure": (nodes, pressure, "max", 0.0),
                           "contact_gap": (nodes, gap, "min", np.nan)}

        def node_fields(self):
            return self.fields

    problem, res, _ = block([{"duration": 1e-4}], [])
    problem.effects[:] = [Stand(np.array([0, 1, 2]), np.array([1.0, np.nan, 3.0]), np.array([0.5, 0.2, -0.1])),
                          Stand(np.array([2, 3]), np.array([2.0, 4.0]), np.array([0.3, np.nan]))]
    pd = _frame(problem, res, tmp_path)
    p, g = pd["contact_pressure"], pd["contact_gap"]
    np.testing.assert_array_equal(p[:4], [1.0, np.nan, 3.0, 4.0])
    np.testing.assert_array_equal(g[:4], [0.5, 0.2, -0.1, np.nan])
    assert np.all(p[4:] == 0.0) and np.all(np.isnan(g[4:]))


def test_frames_carry_the_slip_of_a_sliding_block(tmp_path):
    """Requirement: ``contact_slip`` is each node's travel along the tool while in contact. The block on the incline
    above the friction angle (tan 0.5 > mu = 0.3): its bottom nodes slide (status 2) and their slip equals their
    own travel along x (1e-3 relative: the stick springs' elastic slip of about 5e-5 mm at the start and the normal
    springs' ringing add tangential jitter far below it), which follows a = g (sin - mu cos) over the slide (2 %,
    the incline test's tolerance; the travel starts at the tilt, before which the block rests). Top nodes: slip 0.
    The exponential law (p0 about the weight per area, c0 = 0.01 mm) keeps the bottom nodes in contact while the
    sudden tilt sets the block ringing; with the linear law they chatter off the floor part of the time (measured:
    slip 40-60 % of the travel), and travel off contact is not slip."""
    theta, mu = math.atan(0.5), 0.3
    t1, duration = 0.02, 0.1
    loads = [{"type": "gravity", "acceleration": [0, 0, -G * math.cos(theta)]},
             {"type": "gravity", "acceleration": [G * math.sin(theta), 0, 0], "amplitude": "tilt"}]
    extra = {"amplitudes": {"tilt": {"type": "tabular", "points": [[0, 0], [t1, 0], [t1 + 1e-9, 1], [1, 1]]}}}
    steps = [{"name": "settle", "duration": t1, "damping": {"mass_proportional": 400.0}},
             {"name": "slide", "duration": duration}]
    extra["contact"] = [{"tool": "floor", "friction": {"static": mu},
                         "normal": {"law": "exponential", "p0": 0.05, "c0": 0.01, "max_stiffness": 200.0}}]
    problem, res, _ = block(steps, loads, extra=extra)
    assert res.status == "completed", res.message
    pd = _frame(problem, res, tmp_path)
    bottom, top = problem.X[:, 2] == 0.0, problem.X[:, 2] == 5.0
    travel = res.final_positions[bottom, 0] - problem.X[bottom, 0]
    np.testing.assert_allclose(pd["contact_slip"][bottom], travel, rtol=1e-3)
    a = G * (math.sin(theta) - mu * math.cos(theta))
    assert float(travel.mean()) == pytest.approx(0.5 * a * duration**2, rel=0.02)
    np.testing.assert_array_equal(pd["contact_status"][bottom], 2.0)
    np.testing.assert_array_equal(pd["contact_slip"][top], 0.0)


def test_initial_penetration_is_refused_with_node_numbers(tmp_path):
    """Requirement: blank nodes that start inside a tool are a located input error naming them, not a blow-up."""
    from fdeck.compile.errors import CompileError

    with pytest.raises(CompileError) as info:
        block([{"duration": 1e-3}], [], z0=-0.1)
    ((path, message),) = info.value.problems
    assert path == ("contact", 0) and "9 blank nodes start inside tool 'floor'" in message


def shell_plate(side):
    """A clamped 20 x 20 mm sm plate (0.23 mm) and a sphere of radius 5 mm moving 1 mm into it from `side`."""
    s = 1.0 if side == "above" else -1.0
    return {
        "mesh": {"plate": {"size": [20.0, 20.0], "element_size": 2.0}},
        "materials": {"cloth": {"type": "sm"}},
        "sections": [{"material": "cloth"}],
        "tools": {"punch": {"surface": {"shape": "sphere", "centre": [10.0, 10.0, s * 5.3], "radius": 5.0}}},
        "boundary": [{"type": "fixed", "nodes": n, "dofs": ["x", "y", "z", "rx", "ry", "rz"]}
                     for n in ("xmin", "xmax", "ymin", "ymax")],
        "contact": [{"tool": "punch", "normal": {"law": "linear", "stiffness": 2000.0}}],
        "steps": [{"duration": 0.01}],
        "output": {"history_points": 200,
                   "measures": [{"type": "node_displacement", "name": "w", "nodes": "all", "component": "z",
                                 "reduce": "min" if side == "above" else "max"}]},
    }


@pytest.mark.parametrize("side", ["above", "below"])
def test_a_sphere_pushes_a_shell_from_either_face_with_the_thickness_offset(side):
    """Requirement: a shell is touched on both faces, half its thickness from the mid-surface: a sphere pressing
    1 mm from above (below) moves the plate down (up) by about 1 mm minus the clearance of 0.3 - 0.115 mm, within
    its penetration (the force over k A with k = 2000 MPa/mm: a few um here) and of the plate's rounding under the
sphere (2 % covers both), and the energy balance closes to 1 %."""
    data = shell_plate(side)
    data["tools"]["punch"]["motion"] = {"direction": [0, 0, -1.0 if side == "above" else 1.0], "value": 1.0}
    _, res, h = run_data(data)
    assert res.status == "completed", res.message
    deflection = abs(h["w"][-1])
    assert deflection == pytest.approx(1.0 - (0.3 - 0.115), rel=0.02)
    scale = max(np.abs(h[c]).max() for c in ("kinetic_energy", "internal_energy", "tool_work_punch"))
    assert np.abs(h["energy_balance_error"]).max() < 0.01 * scale


DETERMINISM = """
import hashlib, numba
import numpy as np
from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import solver
solver.SERIAL_BELOW = 0  # use every thread even on this small model
d = Deck.model_validate({
    "mesh": {"block": {"origin": [0, 0, 0.01], "size": [40, 40, 4], "divisions": [20, 20, 2]}},
    "materials": {"m": {"type": "neo_hookean", "density": 1e-9, "youngs_modulus": 10.0, "poisson_ratio": 0.3}},
    "sections": [{"material": "m", "formulation": "fbar"}],
    "tools": {"floor": {"surface": {"shape": "plane"}},
              "punch": {"surface": {"shape": "sphere", "centre": [20, 20, 14.02], "radius": 10.0},
                        "motion": {"value": 3.0, "amplitude": "ramp"}}},
    "contact": [{"tool": "floor", "normal": {"law": "linear", "stiffness": 50.0}, "friction": {"static": 0.3}},
                {"tool": "punch", "normal": {"law": "exponential", "p0": 0.01, "c0": 0.05, "max_stiffness": 50.0},
                 "friction": {"static": 0.2, "dynamic": 0.15}}],
    "steps": [{"duration": 1e-3, "max_cycles": 150}], "output": {"history_points": 3}})
p = compile_deck(d)
r = solver.run(p, solver.Sink())
assert r.status == "completed", r.message
assert abs(np.array(r.history)[-1, r.columns.index("tool_punch_force_z")]) > 0  # the punch touched
print(numba.get_num_threads(), hashlib.sha256(r.final_positions.tobytes() + np.array(r.history).tobytes()).hexdigest())
"""


def test_contact_results_identical_on_one_and_two_threads():
    """Requirement: a blank pressed by a sphere onto a floor, with friction on both, gives bitwise the same positions
    and history (tool forces, contact and friction energies) on 1 and 2 threads (each contact node is computed by
    one iteration; the per-tool sums are taken in a fixed order)."""
    from helpers import digests_on_one_and_two_threads

    assert len(digests_on_one_and_two_threads(DETERMINISM)) == 1


def test_info_prints_tools_contact_pairs_and_their_step_bound(tmp_path):
    """Requirement: `fdeck info` lists each tool with its motion and each contact pair with its node count, laws and
    stable-step bound. All 18 nodes of the 2x2x1 block are exterior, so all are contact nodes. The bound is the
    smallest sqrt(m/k) with k = penalty x the node's surface area (a bound of its projected area on any tool): a corner
    node has m = rho V_el / 8 = 1.5625e-5 t and area 3 faces x 6.25 mm^2, k = 3750 N/mm, so 6.455e-05 s (closed form,
    to the 4 digits printed)."""
    import subprocess
    import sys

    import yaml

    data = {"mesh": {"block": {"size": [10.0, 10.0, 5.0], "divisions": [2, 2, 1]}},
            "materials": {"m": {"type": "linear_elastic", "density": 1e-6, "youngs_modulus": 1000.0,
                                "poisson_ratio": 0.3}},
            "sections": [{"material": "m", "formulation": "full"}],
            "tools": {"floor": {"surface": {"shape": "plane"}},
                      "punch": {"surface": {"shape": "sphere", "centre": [5, 5, 20], "radius": 10.0},
                                "motion": {"value": 8.0}}},
            "contact": [{"tool": "floor", "normal": {"law": "linear", "stiffness": 200.0},
                         "friction": {"static": 0.3}}],
            "steps": [{"duration": 0.01}]}
    deck = tmp_path / "d.yaml"
    deck.write_text(yaml.safe_dump(data))
    r = subprocess.run([sys.executable, "-m", "fdeck.cli", "info", str(deck)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "tool floor: plane, fixed" in r.stdout
    assert "tool punch: sphere, displacement 8 mm along [0.0, 0.0, -1.0], amplitude smooth" in r.stdout
    assert "contact with tool 'floor': 18 blank nodes, linear, 200 MPa/mm, friction 0.3/0.3" in r.stdout
    assert "step bound sqrt(m/k) = 6.455e-05 s" in r.stdout


def _turn_on_a_drum(steps: int, depth):
    """A 4 x 1 x 1 block (1 mm elements) bent onto a cylinder of radius R = 10 mm (linear law, k = 100 MPa/mm, no
    friction), its bottom nodes depth(theta + phi) mm inside it, turned about the cylinder's axis by phi = 0 ... 0.6
    rad in ``steps`` increments, the contact's force evaluated at each. Returns (X, bottom, theta, the contact's
    ledger at the first and the last call (dicts by term name), forces on the nodes at both (k, 3), the trapezoidal
    work of the forces on the nodes [mJ], the contact effect)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck

    data = {
        "mesh": {"block": {"origin": [-2.0, 0.0, DRUM + 0.1], "size": [4.0, 1.0, 1.0], "divisions": [4, 1, 1]}},
        "materials": {"m": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 10.0, "poisson_ratio": 0.3}},
        "sections": [{"material": "m"}],
        "tools": {"drum": {"surface": {"shape": "cylinder", "point": [0, 0, 0], "axis": [0, 1, 0], "radius": DRUM}}},
        "contact": [{"tool": "drum", "normal": {"law": "linear", "stiffness": DRUM_K}}],
        "steps": [{"duration": 1e-3}],
    }
    problem = compile_deck(Deck.model_validate(data))
    contact = next(e for e in problem.effects if e.name == "contact:drum")
    X = problem.X
    bottom = X[:, 2] < DRUM + 0.1 + 1e-9
    theta = X[:, 0] / DRUM  # the block's length wrapped round the cylinder
    f = np.zeros_like(X)
    work, x_old, f_old, books, forces = 0.0, None, None, [], []
    for i in range(steps + 1):
        psi = theta + DRUM_TURN * i / steps
        r = np.where(bottom, DRUM - depth(psi), DRUM + 1.0)  # top nodes 1 mm outside: no force (linear law)
        x = np.stack([r * np.sin(psi), X[:, 1], r * np.cos(psi)], axis=1)
        contact.add_force(0.0, x, np.zeros_like(x), f)
        force = np.zeros_like(X)
        force[contact.nodes] = contact.f
        if x_old is not None:
            work += 0.5 * float(((force + f_old) * (x - x_old)).sum())
        x_old, f_old = x, force
        books.append(dict(zip([t.name for t in contact.terms], contact.term_values())))
        forces.append(contact.f.copy())
    return X, bottom, theta, books[0], books[-1], forces[0], forces[-1], work, contact


DRUM, DRUM_K, DRUM_TURN = 10.0, 100.0, 0.6  # [mm], [MPa/mm], [rad]


def test_area_change_as_the_normal_turns_is_booked_so_the_contact_closes_its_balance():
    """Requirement: the contact's booked energies change by the work its forces do on the blank, also where a node's
    area A = -a . n changes because the tool's normal turns against the node's reference vector area a (a blank
    drawn over a radius). The block of ``_turn_on_a_drum``, turned by 0.6 rad:

    (i) bottom nodes a constant h = 0.05 mm inside (energy per area e = k h^2 / 2 constant). Closed forms: the area
    of a bottom node whose reference vector area has parts a_z (bottom face, -z) and a_x (an end face, along x) is
    a_z cos(psi) - a_x sin(psi) at angle psi from the cylinder's top (the faces' quarter areas, computed here from
    the block's geometry), so the booked ``contact_area_work`` is e (A_end - A_start) summed over the nodes
    (-0.081 mJ against 0.47 mJ stored at the start), to round-off (1e-9: the per-call booking telescopes); stored
    energy minus area work does not change (e is constant; 1e-12 mJ, round-off); the force on each node is radial
    and its path a circle, so the trapezoidal work over the chords is r (1 - cos d) (|F_end| - |F_start|) / 2
    (8e-6 mJ; 1e-6 relative, round-off of 600 increments).
    (ii) the depth varying along the path, h = 0.05 + 0.02 sin(3 psi): the closure, booked change plus the work of
    the forces, is the trapezoidal rule's error, second order in the increment: below 1e-3 of the area work with
    600 increments and 3 to 5 times smaller with 1 200 (a 4x fall; booking the old or the new e instead of their
    mean leaves a first-order error, a 2x fall)."""
    from fdeck.engine.ledger import WORK

    h = 0.05
    X, bottom, theta, first, last, f_first, f_last, work, contact = _turn_on_a_drum(600, lambda psi: h + 0 * psi)
    assert next(t for t in contact.terms if t.name == "contact_area_work").kind == WORK
    assert last["contact_energy"] > 0.1  # the bottom nodes are in contact throughout (0.39 mJ stored at the end)
    # independent area: quarter areas of the bottom faces (1 mm^2 each) and of the end faces (x = -2, 2)
    a_z = 0.25 * np.where(np.isclose(np.abs(X[:, 0]), 2.0), 1, 2)
    a_x = np.where(np.isclose(X[:, 0], -2.0), -0.25, np.where(np.isclose(X[:, 0], 2.0), 0.25, 0.0))

    def area(phi):
        psi = theta + phi
        return np.where(bottom, np.maximum(0.0, a_z * np.cos(psi) - a_x * np.sin(psi)), 0.0)

    e = 0.5 * DRUM_K * h * h
    expected = e * float((area(DRUM_TURN) - area(0.0)).sum())
    assert abs(expected) > 0.05  # the test moves the area: -0.081 mJ, a sixth of the energy stored at the start
    area_work = last["contact_area_work"] - first["contact_area_work"]
    assert area_work == pytest.approx(expected, rel=1e-9)
    booked = (last["contact_energy"] - first["contact_energy"]) - area_work
    assert abs(booked) < 1e-12
    d = DRUM_TURN / 600
    chord = 0.5 * (DRUM - h) * (1.0 - math.cos(d)) * float(
        (np.linalg.norm(f_last, axis=1) - np.linalg.norm(f_first, axis=1)).sum())
    assert work == pytest.approx(chord, rel=1e-6)

    closures = []
    for steps in (600, 1200):
        _, _, _, first, last, _, _, work, _ = _turn_on_a_drum(steps, lambda psi: 0.05 + 0.02 * np.sin(3.0 * psi))
        area_work = last["contact_area_work"] - first["contact_area_work"]
        closures.append((last["contact_energy"] - first["contact_energy"]) - area_work + work)
    assert abs(closures[0]) < 1e-3 * abs(area_work)
    assert 3.0 < closures[0] / closures[1] < 5.0
