"""Requirement: hard cases of node-to-analytic-surface contact stay physical: a tool faster than a shell's
thickness (and than an element) per cycle never passes through it silently; a 3WEAVE block pinched between two
plates to the fabric's compaction carries the compaction stress of its law times its area; a strip dragged off a
tool's edge by friction and gravity creates no energy and no force spike; a sphere smaller than two elements pressed
into a shell keeps its nodes outside. Each: no NaN, energy balance within 1 % of the largest energy term (the
issue's tolerance; the runs below measure 1e-6 to 1e-3), plus the physics check stated in its docstring.

Sizes: 16 to 100 elements and a few thousand to 40 000 cycles each, so every test runs in seconds on one core."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from fdeck.compile.errors import CompileError

from helpers import run_data
from shell_helpers import linear_fabric, one_thread  # noqa: F401

pytestmark = [pytest.mark.verification, pytest.mark.usefixtures("one_thread")]

G = 9810.0  # mm/s^2


def finite(h) -> bool:
    return all(np.isfinite(v).all() for v in h.values())


def balance_ratio(h) -> float:
    keys = [k for k in h if k in ("kinetic_energy", "internal_energy", "external_work", "damping_energy",
                                   "friction_dissipation") or k.startswith("tool_work_")]
    scale = max(np.abs(h[k]).max() for k in keys)
    return float(np.abs(h["energy_balance_error"]).max() / scale)


# -- 2. tunnelling -----------------------------------------------------------------------------------------------
H_SHELL = 0.2


def free_membrane(tool: dict, contact_law=None) -> dict:
    """A free 10 x 10 mm membrane (1 mm elements, 0.2 mm thick) in the plane z = 0 and one tool above it."""
    return {
        "mesh": {"plate": {"size": [10.0, 10.0], "element_size": 1.0}},
        "materials": {"sheet": linear_fabric(1000.0, G=1.0, density=1.5e-9)},
        "sections": [{"material": "sheet", "formulation": "membrane", "thickness": H_SHELL}],
        "tools": {"punch": tool},
        "contact": [{"tool": "punch", "normal": contact_law or {"law": "linear", "stiffness": 100.0}}],
        "steps": [{"duration": 1e-3}],
        "output": {"history_points": 50},
    }


TOOLS = {
    "plane": {"shape": "plane", "point": [0.0, 0.0, 0.15], "normal": [0.0, 0.0, -1.0]},
    "sphere": {"shape": "sphere", "centre": [5.0, 5.0, 3.15], "radius": 3.0},
}


@pytest.mark.parametrize("shape", ["plane", "sphere"])
@pytest.mark.parametrize("per_cycle", [0.01, 1.5])
def test_a_tool_faster_than_the_shell_per_cycle_is_refused_or_pushes_the_shell(shape, per_cycle):
    """Requirement: a plane (sphere) tool moving down at 1.5 element lengths (7.5 shell thicknesses) per stable
    cycle onto a free membrane must either be refused as input (CompileError naming the tool) or push the membrane
    ahead of it, never pass through it silently (the two-sided shell contact would then hold it on the wrong face).
    Pushed means, at the end: every node's mid-surface below the plane (z < plane); for the sphere, no node inside
    it and the plate's centre node (under the apex) below the sphere. The speed is set from the run's own stable
    step (probed with the tool at rest), so the case stays a tunnelling case whatever the step is; 0.01 mm per
    cycle (a twentieth of the thickness, 9 m/s) is the control that the same check passes where the penalty can
    act. No energy-balance bound here: the free membrane is struck at 9 to 1400 m/s, and a penalty impact's ledger
    error is of order (omega dt)^2 / 8 of the impact energy (5 % at this step), not a tunnelling matter."""
    probe = free_membrane({"surface": TOOLS[shape]})
    probe["steps"] = [{"duration": 1e-3, "max_cycles": 3}]
    _, res, h = run_data(probe)
    assert res.status == "completed", res.message
    dt = float(h["dt"][-1])
    travel = 12.0  # [mm]; elements 1 mm, thickness 0.2 mm
    data = free_membrane({"surface": TOOLS[shape], "motion": {"direction": [0, 0, -1], "value": travel,
                                                                "amplitude": "ramp"}})
    data["steps"] = [{"duration": travel / per_cycle * dt}]
    try:
        _, res, h = run_data(data)
    except CompileError as exc:
        assert per_cycle > H_SHELL, "a tool slower than the thickness per cycle must run"
        messages = " ".join(m for _, m in exc.problems)
        assert "punch" in messages, messages  # a located, named refusal
        return
    assert res.status == "completed", res.message
    assert finite(h)
    x = res.final_positions
    if shape == "plane":
        behind = x[:, 2] >= 0.15 - travel
        assert not behind.any(), f"{int(behind.sum())} of {len(x)} nodes left behind the plane"
    else:
        c = np.array([5.0, 5.0, 3.15 - travel])
        inside = np.linalg.norm(x - c, axis=1) < 3.0
        centre = np.argmin(np.linalg.norm(x[:, :2] - 5.0, axis=1))  # the node under the apex (z = 0 at rest)
        assert not inside.any(), f"{int(inside.sum())} of {len(x)} nodes inside the sphere"
        assert x[centre, 2] < c[2] - 3.0, f"centre node at z = {x[centre, 2]:.3g}, sphere bottom {c[2] - 3:.3g}"


# -- 3a. 3WEAVE pinched to half its thickness -------------------------------------------------------------------
H0, WB, GAP = 2.54, 10.0, 0.01  # ply thickness, block side, initial clearance to each plate [mm]
K_COMP, I0_COMP, P_COMP = 0.008, -1.675, 8.613  # [P]'s compaction constants of the 3weave preset [MPa, -, -]


def compaction_force(lam: float) -> float:
    """Force [N] on a WB x WB ply of the law under F = diag(1, 1, lam) (fibres unstretched, c = ln lam):
    psi = K [(1 - c/I0)^-p - p c/I0 - 1], nominal stress P33 = dpsi/dlam = psi'(c) / lam, times the reference
    area (MODELS 2, [P] Pazmino et al., Composites A 72, 2015)."""
    c = math.log(lam)
    dpsi = K_COMP * P_COMP / I0_COMP * ((1.0 - c / I0_COMP) ** (-P_COMP - 1.0) - 1.0)
    return -dpsi / lam * WB * WB


def pinch_deck(travel: float) -> dict:
    """The block between two plates that each travel ``travel`` mm towards it (smooth amplitude, 0.02 s), linear
    penalty 1000 MPa/mm, friction 0.2; history of the top and bottom faces' mean z displacement."""

    def tool(z, n):
        return {"shape": "plane", "point": [0, 0, z], "normal": [0, 0, n]}

    return {
        "mesh": {"block": {"size": [WB, WB, H0], "divisions": [2, 2, 2]},
                 "node_sets": {"top": {"box": [[0, 0, H0], [WB, WB, H0]]},
                               "bottom": {"box": [[0, 0, 0], [WB, WB, 0]]}}},
        "materials": {"f": {"type": "3weave"}},
        "sections": [{"material": "f", "formulation": "fbar"}],
        "tools": {"upper": {"surface": tool(H0 + GAP, -1), "motion": {"direction": [0, 0, -1], "value": travel}},
                  "lower": {"surface": tool(-GAP, 1), "motion": {"direction": [0, 0, 1], "value": travel}}},
        "contact": [{"tool": t, "normal": {"law": "linear", "stiffness": 1000.0}, "friction": {"static": 0.2}}
                    for t in ("upper", "lower")],
        "steps": [{"duration": 0.02}],
        "output": {"history_points": 200, "measures": [
            {"type": "node_displacement", "name": "top", "nodes": "top", "component": "z"},
            {"type": "node_displacement", "name": "bottom", "nodes": "bottom", "component": "z"}]},
    }


def test_3weave_block_pinched_to_half_its_thickness_carries_the_compaction_stress():
    """Requirement: a 3WEAVE block (10 x 10 mm, one 2.54 mm ply, 2 x 2 x 2 F-bar hexahedra) squeezed between two
    plates moving towards each other (smooth amplitude, 0.02 s, to a thickness ratio of 0.5, where the compaction
    law has stiffened 130-fold and locks at 0.19) is homogeneously compacted: each plate's force equals the law's
    P33(lam) times the area with lam measured from the plies' faces, within 3 % at the end (a quasi-static point:
    the plates stop there; the force fluctuates by about 1 % from the ringing of the stiff compacted block, and
    dlnF/dln(lam) is about 10 there, so 0.1 % of thickness is 1 % of force); the two plates' forces balance to 3 %;
    kinetic energy below 1e-3 of the internal energy at the end; friction (mu = 0.2, holding the free block) does
    nothing (the law has no in-plane compaction stress, so the faces do not slide): below 1e-4 of the tools' work;
    energy balance within 1 %. Measured: lam 0.509, upper / law 0.995, lower / law 0.997 (1146 N), balance
    4.6e-4."""
    lam = 0.5
    travel = GAP + H0 * (1.0 - lam) / 2.0

    _, res, h = run_data(pinch_deck(travel))
    assert res.status == "completed", res.message
    assert finite(h)
    end = slice(-5, None)  # the last 2.5 % of the run, where the plates have (nearly) stopped
    lam_end = (H0 + h["top"][end] - h["bottom"][end]) / H0
    assert lam_end.mean() == pytest.approx(lam, abs=0.02)  # reached (the penalty overclosure takes the rest)
    law = np.array([compaction_force(v) for v in lam_end])
    upper, lower = -h["tool_upper_force_z"][end], h["tool_lower_force_z"][end]
    print(f"pinch: lam {lam_end.mean():.4f}, upper / law {upper.mean() / law.mean():.4f}, lower / law "
          f"{lower.mean() / law.mean():.4f}, law {law.mean():.4g} N, balance {balance_ratio(h):.3g}")
    assert upper.mean() == pytest.approx(law.mean(), rel=0.03)
    assert lower.mean() == pytest.approx(law.mean(), rel=0.03)
    assert h["kinetic_energy"][-1] < 1e-3 * h["internal_energy"][-1]
    work = h["tool_work_upper"][-1] + h["tool_work_lower"][-1]
    assert h["friction_dissipation"][-1] < 1e-4 * work
    assert balance_ratio(h) < 0.01


LOCK = math.exp(I0_COMP)  # the thickness ratio at which the compaction energy becomes infinite (c = I0): 0.187


def test_3weave_block_pinched_towards_the_lock_stops_where_the_law_loses_ellipticity():
    """Known limit, pinned: the block above with the plates closing to 0.15 of its thickness, below the law's lock at
    exp(I0) = 0.187 (the penalty springs, 1000 MPa/mm, would take the travel the block cannot: the equilibrium with
    the springs lies near lam = 0.37). The published law, free to expand sideways, loses strong ellipticity (README,
    *Known limits*: near c = -1.1 for a homogeneous state): here a non-uniform mode of the 2 x 2 x 2 mesh grows
    (faces wrinkle at element scale, local thickness ratios down to about 0.3) once the mean thickness ratio passes
    about 0.4 (c = -0.9), with the steps tried (dt_safety 0.9 and 0.5, full and F-bar alike), until the forces
    overflow or an element inverts. Required: the run stops with one of the engine's located messages (non-finite
    energy naming a node, or an inverted element naming it, and the time), not silently and not with a traceback;
    the instability's onset, the first history row past 10 mJ of internal energy whose kinetic energy exceeds 1 % of
    it, lies deep in the stiff branch and short of the lock (mean thickness ratio between 0.187 and 0.45; the law's
    force at 0.4 is about 4 000 times that at 0.9). Measured: onset at 0.39 (these history rows), stop at t = 0.0144
    s (non-finite energy) before the step's growth limit (engine.solver.STEP_GROWTH), at t = 0.0190 s (element 7
    inverted) with it. This is not the issue's hard case (no NaN up to the compaction limit), which stays open."""
    lam = 0.15
    travel = GAP + H0 * (1.0 - lam) / 2.0

    _, res, h = run_data(pinch_deck(travel))
    assert res.status == "failed"
    located = (r"non-finite energy .* at node \d+ .* at t = [0-9.e-]+ s",
               r"element inverted .* in element \d+ at t = [0-9.e-]+ s")
    assert any(re.search(pattern, res.message) for pattern in located), res.message
    loaded = h["internal_energy"] > 10.0  # [mJ]: past the first contact (at rest any motion beats 1 % of ~0)
    onset = int(np.argmax(loaded & (h["kinetic_energy"] > 0.01 * h["internal_energy"])))
    assert onset > 0
    lam_onset = (H0 + h["top"][onset] - h["bottom"][onset]) / H0
    print(f"pinch to the lock: {res.message}; onset at thickness ratio {lam_onset:.3f}, t = {h['time'][onset]:.4g} s")
    assert LOCK < lam_onset < 0.45


def test_3weave_block_in_a_die_pinched_past_the_lock_is_held_by_the_contact_springs():
    """Requirement (issue 8's hard case, a blank pinched between punch and die to the compaction limit): the block
    above, 4 x 4 x 2 F-bar hexahedra, inside a die (four wall planes, contact and friction as the plates), with
    the plates closing to 0.15 of its thickness, past the law's lock at exp(I0) = 0.187. Nothing can compact the
    fabric to the lock (its energy is infinite there); the tools' penalty springs (1000 MPa/mm) take the travel
    the block cannot, so the block must come to rest where its compaction stress equals the springs' pressure:
    (i) completed, no NaN, energy balance within 1 %; (ii) each plate's force equals the law's P33(lam) times the
    area, lam measured from the plies' faces, within 1 % (a quasi-static point; measured 4e-6 and 7e-6); (iii) and
    equals k delta A, delta = (lam H0 - 0.15 H0) / 2 the overclosure of each plate (1 %; measured 1e-6); (iv) the block
    ends deep in the stiff branch and short of the lock: 0.187 < lam < 0.45 (measured 0.389, c = -0.94, 30 kN,
    about 7 700 times the force at lam = 0.9); (v) kinetic energy below 1e-3 of the internal energy at the end.
    The free block of the test above loses strong ellipticity from lam = 0.39 and stops; the walls hold its faces.
    Not covered (README, Known limits): a stiffer penalty (1e4 MPa/mm) drives this walled block to lam = 0.35
    (c = -1.06), where it goes unstable and an element inverts: the law's interior shear modes, not the walls."""
    lam_tools = 0.15
    k = 1000.0
    data = pinch_deck(GAP + H0 * (1.0 - lam_tools) / 2.0)
    data["mesh"]["block"]["divisions"] = [4, 4, 2]

    def wall(point, normal):
        return {"surface": {"shape": "plane", "point": point, "normal": normal}}

    data["tools"].update({"x0": wall([0, 0, 0], [1, 0, 0]), "x1": wall([WB, 0, 0], [-1, 0, 0]),
                          "y0": wall([0, 0, 0], [0, 1, 0]), "y1": wall([0, WB, 0], [0, -1, 0])})
    data["contact"] += [{"tool": t, "normal": {"law": "linear", "stiffness": k}, "friction": {"static": 0.2}}
                        for t in ("x0", "x1", "y0", "y1")]

    _, res, h = run_data(data)
    assert res.status == "completed", res.message
    assert finite(h)
    assert balance_ratio(h) < 0.01
    lam = (H0 + h["top"][-1] - h["bottom"][-1]) / H0
    law = compaction_force(lam)
    springs = k * (lam * H0 - lam_tools * H0) / 2.0 * WB * WB
    upper, lower = -h["tool_upper_force_z"][-1], h["tool_lower_force_z"][-1]
    print(f"pinch in a die: lam {lam:.4f}, upper / law {upper / law:.6f}, lower / law {lower / law:.6f}, "
          f"springs / law {springs / law:.6f}, law {law:.5g} N, balance {balance_ratio(h):.3g}")
    assert LOCK < lam < 0.45
    assert upper == pytest.approx(law, rel=0.01)
    assert lower == pytest.approx(law, rel=0.01)
    assert springs == pytest.approx(law, rel=0.01)
    assert h["kinetic_energy"][-1] < 1e-3 * h["internal_energy"][-1]


# -- 3c. a sharp sphere pressed into a shell ----------------------------------------------------------------------
def test_sphere_smaller_than_two_elements_keeps_the_shell_nodes_outside():
    """Requirement: a sphere of radius 1.5 mm (0.75 element lengths) pressed 1.5 mm into a clamped 20 x 20 mm sm
    plate (2 mm elements, 0.23 mm), centred over an element's middle so that it meets no node first:
    (i) no node's mid-surface comes closer to the sphere than R + h/2 - delta, with delta = F / (k A) the
    overclosure if one node carried the whole tool force F on its tributary area A (k = 2000 MPa/mm); (ii) the
    node-to-surface limit, documented: the sphere passes between the element's four nodes, so the element face
    under its apex is penetrated; the depth is bounded by the sag of a sphere over the half diagonal d of the
    element, (R + h/2) - sqrt((R + h/2)^2 - d^2), plus delta (+ 2 %: the punch stretches the plate and moves
    the four nodes apart by a fraction of a percent of d, which deepens the sag by up to 2 %); (iii) energy
    balance within 1 %. Measured: node overclosure 2.6e-4 mm (bound 1.9e-3), face penetrated by 0.842 mm (bound
    0.837 + 2 %): the sphere's apex sits 0.84 mm below the shell's upper face, 3.7 thicknesses, between nodes that
    hold."""
    R, h_s, L, k = 1.5, 0.23, 2.0, 2000.0
    c0 = np.array([11.0, 11.0, R + h_s / 2 + 0.05])  # over the middle of the element [10, 12] x [10, 12]
    travel = 1.5
    data = {
        "mesh": {"plate": {"size": [20.0, 20.0], "element_size": L}},
        "materials": {"cloth": {"type": "sm"}},
        "sections": [{"material": "cloth"}],
        "tools": {"punch": {"surface": {"shape": "sphere", "centre": c0.tolist(), "radius": R},
                            "motion": {"direction": [0, 0, -1], "value": travel}}},
        "boundary": [{"type": "fixed", "nodes": n, "dofs": ["x", "y", "z", "rx", "ry", "rz"]}
                     for n in ("xmin", "xmax", "ymin", "ymax")],
        "contact": [{"tool": "punch", "normal": {"law": "linear", "stiffness": k}}],
        "steps": [{"duration": 0.01}],
        "output": {"history_points": 200},
    }
    _, res, hist = run_data(data)
    assert res.status == "completed", res.message
    assert finite(hist)
    x = res.final_positions
    c = c0 - np.array([0.0, 0.0, travel])
    force = abs(hist["tool_punch_force_z"][-1])
    assert force > 0.0  # the sphere does press the plate
    delta = force / (k * (L * L / 4.0))  # tributary area of a node of the four around the apex: a quarter element
    gap = np.linalg.norm(x - c, axis=1) - R - h_s / 2
    assert gap.min() > -delta, f"node overclosure {-gap.min():.3g} mm above {delta:.3g} mm"
    # face under the apex: bilinear mid-surface of the element [10, 12]^2 at its centre (its four nodes' mean)
    corners = [np.argmin(np.linalg.norm(x[:, :2] - p, axis=1)) for p in ([10, 10], [12, 10], [12, 12], [10, 12])]
    face_z = x[corners, 2].mean() + h_s / 2  # upper face under the apex, the one the sphere presses on
    depth = face_z - (c[2] - R)  # > 0: the sphere's apex is below the face it presses on
    d = L / math.sqrt(2.0)
    sag = (R + h_s / 2) - math.sqrt((R + h_s / 2) ** 2 - d * d)
    print(f"sharp sphere: node overclosure {-gap.min():.4g} mm (bound {delta:.4g}), face penetrated by {depth:.4g} mm "
          f"(node-to-surface bound {sag + delta:.4g} mm), tool force {force:.4g} N")
    assert depth < 1.02 * (sag + delta)
    assert balance_ratio(hist) < 0.01


# -- 3b. a strip sliding off a tool's edge -------------------------------------------------------------------------
def test_strip_sliding_off_a_rounded_edge_creates_no_energy_and_no_force_spike():
    """Requirement: a soft strip (neo-Hookean, E = 5 MPa, 40 x 4 x 1 mm, 20 x 2 x 2 F-bar hexahedra) laid 0.01 mm
    above a rounded edge (a cylinder of radius 5 mm, friction mu = 0.2) with three quarters of its length
    overhanging tips over the edge under gravity, slides over it against friction and falls off. (i) No energy
    created: the energy balance error stays within 1 % of the largest energy term (the work of gravity);
    (ii) no force spike as it slides and leaves: the tool's force, averaged over 1 ms windows (8 history rows,
    several periods of the penalty's contact vibration), never exceeds 3 m g, the largest support force a body
    released from rest can demand by swinging about a support (the point pendulum released horizontally,
    T = 3 m g at the bottom; a distributed strip demands less); (iii) it does leave: over the last 20 % of the run
    no node touches the edge (tool force 0, friction dissipation constant) and the free end has passed the
    edge's top.

    A shell strip was the first choice; it is not used because an sm strip whipping free after it leaves the edge
    creates energy in free flight (a shell matter, reported separately, not the contact's: the contact's own
    work and ledger agree to 1e-6 mJ there). Measured: 1 ms mean peak 1.72 m g, balance 3.8e-5, free end at
    x = 12.7 mm; the raw history rows peak at 7.1 m g: the strip chatters on the edge (no damping, penalty
    bounces), which the 1 ms mean removes."""
    R, L, B, T = 5.0, 40.0, 4.0, 1.0
    x0 = -L / 4
    data = {
        "mesh": {"block": {"origin": [x0, 0.0, R + 0.01], "size": [L, B, T], "divisions": [20, 2, 2]},
                 "node_sets": {"free_end": {"box": [[x0, 0, R], [x0, B, R + 2 * T]]}}},
        "materials": {"m": {"type": "neo_hookean", "density": 1e-9, "youngs_modulus": 5.0, "poisson_ratio": 0.3}},
        "sections": [{"material": "m", "formulation": "fbar"}],
        "loads": [{"type": "gravity", "acceleration": [0, 0, -G]}],
        "tools": {"edge": {"surface": {"shape": "cylinder", "point": [0, 0, 0], "axis": [0, 1, 0], "radius": R}}},
        "contact": [{"tool": "edge", "normal": {"law": "linear", "stiffness": 10.0}, "friction": {"static": 0.2}}],
        "steps": [{"duration": 0.1}],
        "output": {"history_points": 800, "measures": [
            {"type": "node_displacement", "name": "end_x", "nodes": "free_end", "component": "x"}]},
    }
    problem, res, h = run_data(data)
    assert res.status == "completed", res.message
    assert finite(h)
    weight = float(problem.physical_mass.sum()) * G
    force = np.sqrt(h["tool_edge_force_x"] ** 2 + h["tool_edge_force_y"] ** 2 + h["tool_edge_force_z"] ** 2)
    rows = max(1, int(round(1e-3 / (h["time"][1] - h["time"][0]))))
    averaged = np.convolve(force, np.ones(rows) / rows, mode="valid")
    print(f"slide-off: peak tool force {force.max() / weight:.3g} m g (row), {averaged.max() / weight:.3g} m g "
          f"(1 ms mean), balance {balance_ratio(h):.3g}, friction {h['friction_dissipation'][-1]:.3g} mJ of "
          f"gravity work {h['external_work'][-1]:.3g} mJ, free end at x = {x0 + h['end_x'][-1]:.3g} mm")
    assert averaged.max() < 3.0 * weight
    late = h["time"] > 0.8 * h["time"][-1]
    assert h["friction_dissipation"][-1] > 0.0  # it did slide under friction
    assert (force[late] == 0.0).all() and np.ptp(h["friction_dissipation"][late]) == 0.0  # off the edge
    assert x0 + h["end_x"][-1] > R  # its free end has passed the edge
    assert balance_ratio(h) < 0.01
