"""The deterministic gather of per-element nodal vectors (``engine.gather``), which every element group, the
fibre-bending hinges and the selective-mass solve use to assemble nodal forces."""

import numpy as np
import pytest

from fdeck.engine.gather import gather_add, node_slots


@pytest.mark.parametrize("k", [4, 8])
def test_gather_sums_each_node_slots_in_slot_order(k):
    """Requirement: f[n] += the sum of fe[e, a] over the slots (e, a) with conn[e, a] = n, in increasing slot
    order e * k + a, whatever k (quadrilaterals 4, hexahedra 8) and however irregular the connectivity (nodes used
    by 0 to many elements).

    Reference: the same sums written out in Python in slot order, so the comparison is exact (bitwise: the gather
    promises the same operations in the same order on any thread count); and numpy's unordered ``add.at``, within
    1e-13 of the largest sum (rounding of at most ~20 terms of order 1)."""
    rng = np.random.default_rng(7)
    n_node, n_el = 40, 60
    conn = rng.integers(0, n_node - 3, size=(n_el, k))  # the last three nodes belong to no element
    fe = rng.standard_normal((n_el, k, 3))
    ptr, slots = node_slots(conn, n_node)
    f = np.full((n_node, 3), 0.5)
    gather_add(fe, ptr, slots, f)
    expect = np.full((n_node, 3), 0.5)
    for n in range(n_node):
        s = np.zeros(3)
        for slot in range(n_el * k):
            e, a = divmod(slot, k)
            if conn[e, a] == n:
                s = s + fe[e, a]
        expect[n] += s
    assert np.array_equal(f, expect)
    loose = np.full((n_node, 3), 0.5)
    np.add.at(loose, conn.ravel(), fe.reshape(-1, 3))
    assert np.abs(f - loose).max() <= 1e-13 * np.abs(loose).max()
    assert np.all(f[-3:] == 0.5)  # untouched nodes keep their value
