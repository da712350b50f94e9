"""Requirement: fabric_membrane's block path (``fabric_membrane_blocks``: the in-plane fabric law over blocks of
points, lanes innermost) gives the same bits as the point law (``fabric_membrane.point`` through
``evaluate_points``) in every regime the law has (fibre tension and compression, the rounded tension/compression
junction at zero strain, the rounded kinks of the curves, shear on both sides, past the locking angle), with point
counts that leave the last block partly empty; the section's broadcast parameters take it, anything else the
point path; and a whole `sm` shell run's history is the same bits with it on and off.

Reference: the point law itself. Tolerance: zero, compared as bit patterns (every value is formed by the same
operations in the same order; a last-bit difference or a signed zero would mean the block path computes something
else), except that where the point law gives NaN (a degenerate point: the warp collapsed) the block path must
too, but the NaN's sign bit may differ (``fabric_hyper_blocks``'s docstring says why)."""

from __future__ import annotations

import numpy as np
import pytest

import fdeck.physics.materials.fabric_membrane as fm
from fdeck.physics.materials import fabric_membrane_blocks as fb

from helpers import block_path_taken, runs_with_and_without, same_bits_where_not_nan

pytestmark = pytest.mark.verification

CARDS = ("t300_3k", "t300_3k_ts")


def points(n_pt, n_qp, seed):
    """F (n_pt, n_qp, 3, 3) across the law's regimes and in-plane frames (n_pt, 3, 3) (rows warp, weft, normal)."""
    rng = np.random.default_rng(seed)
    F = np.eye(3) + 0.02 * rng.standard_normal((n_pt, n_qp, 3, 3))
    flat = F.reshape(-1, 3, 3)
    flat[0::6] = np.eye(3)  # rest: zero strain, inside the junction band
    flat[2::6, 1, 1] = 0.97  # weft in compression
    flat[3::6, 0, 1] = 1.2  # large shear, past the locking angle
    flat[4::6, 0, 1] = -0.5  # shear of the other sign
    angle = rng.uniform(0.0, np.pi, n_pt)
    warp = np.stack([np.cos(angle), np.sin(angle), np.zeros(n_pt)], axis=1)
    weft = np.stack([-np.sin(angle), np.cos(angle), np.zeros(n_pt)], axis=1)
    frame = np.ascontiguousarray(np.stack([warp, weft, np.broadcast_to([0.0, 0.0, 1.0], warp.shape)], axis=1))
    frame[1::3] = frame[1::3][:, [1, 0, 2]] * [[1.0], [1.0], [-1.0]]  # some frames mirrored (weft, warp, -normal)
    for k in range(1, len(flat), 6):  # warp stretched onto a kink of the tension curve (E = 0.002)
        m = frame[k // n_qp, 0]
        flat[k] = np.eye(3) + (np.sqrt(1.0 + 2.0 * 0.002) - 1.0) * np.outer(m, m)
    for k in range(5, len(flat), 12):  # the warp collapsed to a point (I1 = 0): NaN shear
        m = frame[k // n_qp, 0]
        flat[k] = np.eye(3) - np.outer(m, m)
    return F, frame


def run(path, F, frame, p):
    n_pt, n_qp = F.shape[:2]
    P = np.full((n_pt, n_qp, 3, 3), np.nan)
    psi, modulus = np.full((n_pt, n_qp), np.nan), np.full((n_pt, n_qp, 3), np.nan)
    params = np.broadcast_to(p, (n_pt, len(p)))
    state = np.zeros((n_pt, n_qp, 0))
    if path == "blocks":
        assert fb.evaluate(F, frame, params, state, P, psi, modulus)
    else:
        fm.evaluate_points(F, frame, params, state, P, psi, modulus)
    return P, psi, modulus


@pytest.mark.parametrize("preset", CARDS)
@pytest.mark.parametrize("n_pt, n_qp", [(1, 1), (37, 9), (130, 1)])
def test_block_path_is_the_point_law_bit_for_bit(preset, n_pt, n_qp):
    p = fm.pack(fm.FabricMembrane(type="fabric_membrane", preset=preset))
    F, frame = points(n_pt, n_qp, seed=n_pt)
    fast, ref = run("blocks", F, frame, p), run("points", F, frame, p)
    for a, b in zip(fast, ref):
        assert same_bits_where_not_nan(a, b)
    # the regimes meant are reached (diagnostics of the point law: shear angle [deg], fibre strains)
    if n_pt * n_qp > 6:
        d = np.array([fm.diagnose(f, frame[i // n_qp], p) for i, f in enumerate(F.reshape(-1, 3, 3))])
        assert (np.abs(d[:, 0]) > 45.0).any() and (d[:, 0] < -5.0).any()  # past locking; negative shear
        assert (d[:, 2] < -1e-3).any() and (d[:, 1] == 0.0).any()  # compression; the junction at zero strain
        assert np.isclose(d[:, 1], 0.002, rtol=0, atol=1e-12).any()  # on a kink of the tension curve
        assert np.isnan(ref[1].reshape(-1)[5::12]).any()  # the collapsed warp (round-off leaves some finite)


def test_only_a_broadcast_row_takes_the_block_path():
    p = fm.pack(fm.FabricMembrane(type="fabric_membrane", preset="t300_3k"))
    assert block_path_taken(fb, p, *points(5, 4, seed=1)) == (False, True)


def test_a_shell_run_on_the_block_path_gives_the_bits_of_the_point_path(monkeypatch):
    """A whole run (an `sm` T300 strip pulled and sheared at one end, the other clamped, 2 threads as the engine
    runs): every history column and the final positions identical with the block path on and off."""
    data = {
        "mesh": {"plate": {"size": [20.0, 6.0], "divisions": [10, 3]}},
        "materials": {"carbon": {"type": "fabric_membrane", "preset": "t300_3k"}},
        "sections": [{"material": "carbon", "formulation": "sm", "preset": "t300_3k"}],
        "boundary": [{"type": "fixed", "nodes": "xmin", "dofs": ["x", "y", "z", "rx", "ry", "rz"]},
                     {"type": "displacement", "nodes": "xmax", "dofs": ["x"], "value": 0.2},
                     {"type": "displacement", "nodes": "xmax", "dofs": ["y"], "value": 1.0}],
        "steps": [{"duration": 1e-3}],
        "output": {"history_points": 50},
    }

    taken, (fast_h, fast_x), (point_h, point_x) = runs_with_and_without(monkeypatch, fb, data)
    assert len(taken) > 100 and all(taken)  # every update of the run took the block path
    assert same_bits_where_not_nan(fast_h, point_h) and same_bits_where_not_nan(fast_x, point_x)
    assert fast_x[:, 1].max() > 6.0 + 0.99  # it did shear
