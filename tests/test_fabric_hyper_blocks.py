"""Requirement: fabric_hyper's block path (``fabric_hyper_blocks``: the point law over blocks of points, lanes
innermost) gives the same bits as the point law (``fabric_hyper.point`` through ``evaluate_points``) for every
energy form and every branch of each (stretch and compression, the two polynomial branches, the cubic and locking
branches of in-plane shear, compaction, a table walked both ways, positive, negative and exactly zero shear), with
point counts that leave the last block partly empty, and NaN at the same places at degenerate points (inverted,
flattened past the compaction lock, fibres made parallel, an infinite stretch); the section's broadcast parameters
take it, anything else the point path; and a whole F-bar 3WEAVE run's history is the same bits with it on and off.

Reference: the point law itself. Tolerance: zero, compared as bit patterns wherever the value is not NaN (every
value is formed by the same operations in the same order; a last-bit difference or a signed zero would mean the
block path computes something else); where the point law gives NaN the block path must too, but the NaN's sign bit
may differ (the module docstring says why)."""

from __future__ import annotations

import numpy as np
import pytest

import fdeck.cards.fabric_hyper as fc
import fdeck.physics.materials.fabric_hyper as fh
from fdeck.physics.materials import fabric_hyper_blocks as fb

from helpers import block_path_taken, runs_with_and_without, same_bits_where_not_nan

pytestmark = pytest.mark.verification

# tabulated (6) warp and compaction (the latter walked both ways: c < 0 and c > 0), quadratic (5) weft, locking
# shear (3), polynomial (1) and two-branch polynomial (2) on the transverse shears; compaction's own form (4) comes
# with the published 3WEAVE and interlock presets
MIXED = dict(density=1e-9, compression_ratio=0.01,
             warp={"form": "tabulated", "table": [[-0.05, -20.0], [0.0, 0.0], [0.01, 5.0], [0.03, 40.0]]},
             weft={"form": "quadratic", "K": 300.0},
             compaction={"form": "tabulated", "table": [[-1.0, -3.0], [-0.2, -0.2], [0.0, 0.0], [0.1, 0.5]]},
             in_plane_shear={"form": "locking_shear", "K_ps0": 0.4, "K_ps1": 0.07, "I0": 0.08},
             transverse_shear_warp={"form": "polynomial", "coefficients": [0.0, 0.8, 0.5]},
             transverse_shear_weft={"form": "two_branch_polynomial", "x0": 0.02, "below": [0.0, 2.0],
                                    "above": [0.01, 1.0, 3.0]})
CARDS = {"3weave": dict(preset="3weave"), "interlock": dict(preset="interlock"), "mixed": MIXED}


def points(n_el, n_qp, seed):
    """F (n_el, n_qp, 3, 3) over the law's regimes, frames (n_el, 3, 3) rotated at random."""
    rng = np.random.default_rng(seed)
    F = np.eye(3) + 0.08 * rng.standard_normal((n_el, n_qp, 3, 3))
    flat = F.reshape(-1, 3, 3)
    flat[0::7] = np.eye(3)  # rest: zero strain and shear (the derivatives' x == 0 branch)
    flat[1::7, 0, 0] = 0.97  # warp in compression
    flat[2::7, :, 1] = [0.9, 0.6, 0.0]  # large in-plane shear, past the locking branch point
    flat[3::7, 2, 2] = 0.35  # strong compaction
    flat[4::7, :, 1] *= -1.0  # inverted (J < 0): the compaction invariant is NaN
    q, _ = np.linalg.qr(rng.standard_normal((n_el, 3, 3)))
    frame = np.ascontiguousarray(q.transpose(0, 2, 1))
    frame[0] = np.eye(3)  # the first point at rest in its own frame: every invariant exactly zero
    for k in range(5, len(flat), 7):  # flattened to 0.1 of the thickness, past 3WEAVE's lock (exp(-1.675) = 0.19)
        f3 = frame[k // n_qp, 2]
        flat[k] = np.eye(3) - 0.9 * np.outer(f3, f3)
    for k in range(6, len(flat), 7):  # warp and weft made parallel: s = 1, J = 0
        f1, f2, f3 = frame[k // n_qp]
        flat[k] = np.outer(f1, f1) + np.outer(f1, f2) + np.outer(f3, f3)
    if len(flat) > 20:
        flat[20] = np.diag([1e300, 1.0, 1.0])  # an infinite stretch energy
    return F, frame


def run(path, F, frame, p):
    n_el, n_qp = F.shape[:2]
    P = np.full((n_el, n_qp, 3, 3), np.nan)
    psi, modulus = np.full((n_el, n_qp), np.nan), np.full((n_el, n_qp, 3), np.nan)
    params = np.broadcast_to(p, (n_el, len(p)))
    if path == "blocks":
        assert fb.evaluate(F, frame, params, np.zeros((n_el, n_qp, 0)), P, psi, modulus)
    else:
        fh.evaluate_points(F, frame, params, np.zeros((n_el, n_qp, 0)), P, psi, modulus)
    return P, psi, modulus


@pytest.mark.parametrize("name", sorted(CARDS))
@pytest.mark.parametrize("n_el, n_qp", [(1, 1), (37, 8), (200, 1)])
def test_block_path_is_the_point_law_bit_for_bit(name, n_el, n_qp):
    p = fh.pack(fc.FabricHyper(type="fabric_hyper", **CARDS[name]))
    F, frame = points(n_el, n_qp, seed=n_el)
    fast, ref = run("blocks", F, frame, p), run("points", F, frame, p)
    for a, b in zip(fast, ref):
        assert same_bits_where_not_nan(a, b)
    # the cases above reach the branches they are meant to (invariants from the point law's diagnostics)
    psi = ref[1].reshape(-1)
    assert np.isfinite(psi[0::7]).all() and psi[0] == 0.0  # rest, zero shear exactly
    if n_el * n_qp > 7:
        assert np.isnan(psi[4::7]).all() and not np.isfinite(psi[6::7]).any()  # inverted; parallel fibres
        assert name != "3weave" or not np.isfinite(psi[5::7]).any()  # 3WEAVE's compaction locked
        d = np.array([fh.diagnose(f, frame[i // n_qp], p) for i, f in enumerate(F.reshape(-1, 3, 3))])
        s_ok = np.isfinite(d[:, 0])
        assert (np.abs(d[s_ok, 0]) > np.degrees(np.arcsin(0.08))).any()  # past the locking branch point
        assert (d[s_ok, 0] < -1.0).any() and (d[:, 1] < 0.0).any()  # negative shear; warp in compression
        c = d[:, 3][np.isfinite(d[:, 3])]
        assert (c < -0.2).any() and (c > 0.0).any()  # compaction both ways (MIXED's table walked left and right)


def test_only_a_broadcast_row_takes_the_block_path():
    """Per-element parameter rows (not what a section compiles to) are left to the point path."""
    p = fh.pack(fc.FabricHyper(type="fabric_hyper", preset="3weave"))
    assert block_path_taken(fb, p, *points(5, 8, seed=1)) == (False, True)


def test_a_run_on_the_block_path_gives_the_bits_of_the_point_path(monkeypatch):
    """A whole run (an F-bar 3WEAVE strip sheared and compacted by its moving top face, 2 threads as the engine
    runs): every history column and the final positions identical with the block path on and off."""
    data = {
        "mesh": {"block": {"size": [20.0, 4.0, 2.5], "divisions": [10, 2, 3]}},
        "materials": {"fabric": {"type": "3weave"}},
        "sections": [{"material": "fabric", "formulation": "fbar"}],
        "boundary": [{"type": "fixed", "nodes": "zmin"},
                     {"type": "displacement", "nodes": "zmax", "dofs": ["x"], "value": 1.5},
                     {"type": "displacement", "nodes": "zmax", "dofs": ["z"], "value": -0.8}],
        "steps": [{"duration": 1e-3}],
        "output": {"history_points": 50},
    }

    taken, (fast_h, fast_x), (point_h, point_x) = runs_with_and_without(monkeypatch, fb, data)
    assert len(taken) > 100 and all(taken)  # every update of the run took the block path
    assert same_bits_where_not_nan(fast_h, point_h) and same_bits_where_not_nan(fast_x, point_x)
    # it did shear and compact: the top face moved 1.5 and -0.8 mm
    assert fast_x[:, 2].max() < 2.5 - 0.79 and fast_x[:, 0].max() > 20.0 + 1.49
