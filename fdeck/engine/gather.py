"""Deterministic scatter of per-element nodal vectors into nodes (no atomics, any thread count)."""

import numpy as np

from fdeck.jit import njit_inline, njit_parallel, prange


def node_slots(conn: np.ndarray, n_node: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR map node -> flat slots e * k + a of conn (n_el, k), in increasing slot order.

    Returns ptr (n_node + 1,) and slots (n_el * k,) int64.
    """
    flat = conn.ravel()
    order = np.argsort(flat, kind="stable")
    counts = np.bincount(flat, minlength=n_node)
    ptr = np.zeros(n_node + 1, np.int64)
    np.cumsum(counts, out=ptr[1:])
    return ptr, order.astype(np.int64)


@njit_inline
def slot_rows(fe):
    """fe (n_el, k, 3), C-contiguous, seen as (n_el * k, 3): row e * k + a is fe[e, a], so a slot indexes it
    directly. Splitting the slot into (e, a) cost an integer division per slot (k is not known when compiling):
    0.026 -> 0.010 us per element and gather (benchmarks/kernel_parts.py, 10 000 hexahedra, one thread), the same
    bits."""
    return fe.reshape((fe.shape[0] * fe.shape[1], fe.shape[2]))


@njit_inline
def node_sum(rows, ptr, slots, n):
    """(s0, s1, s2): the sum of rows (n_el * k, 3) (``slot_rows``) over the slots of node n, in slot order
    (inlined into the loops that call it, so no array reference counting per node)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in range(ptr[n], ptr[n + 1]):
        r = slots[i]
        s0 += rows[r, 0]
        s1 += rows[r, 1]
        s2 += rows[r, 2]
    return s0, s1, s2


@njit_parallel
def gather_add(fe, ptr, slots, f):
    """f (n_node, 3) += sum of fe (n_el, k, 3) over the slots of each node, in a fixed order."""
    rows = slot_rows(fe)
    for n in prange(f.shape[0]):
        s0, s1, s2 = node_sum(rows, ptr, slots, n)
        f[n, 0] += s0
        f[n, 1] += s1
        f[n, 2] += s2
