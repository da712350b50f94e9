"""The eight-point hexahedra (``full``, ``fbar``) fused and vectorised over blocks of 64 elements with the law in
the block (issue 10's SIMD route for them; a probe, not part of the engine or the tests: it was slower).

    python benchmarks/fused8_probe.py      # full elastic, F-bar elastic, F-bar 3WEAVE; 1 thread, 3 rounds
    python benchmarks/fused8_probe.py fbar fabric_hyper_3weave --rounds 5 --threads 2

Item 10 of docs/kernels.md packed the kinematics and forces of ``hex8`` alone and found the transposes between the
engine's point-major F, P and the SIMD lanes costing what the packed sums saved; it said the fused form (positions
in, element forces out, the law in the block) was what was left. This is that form: per block of 64 elements (one
per lane) the positions are gathered once, the eight points' F and J (F-bar: Jbar, the ratios), the law (the elastic
law per lane; the 3WEAVE law through ``fabric_hyper_blocks.law_stages`` on 64 elements' point q at a time, called
as a function of its own: inlined, the kernel took 150 s to compile) and the forces (F-bar's effective stress) stay
in one work array; the engine's arrays (F, J, P, psi, moduli, F-bar's Fbar, Jbar, ratios and pressures, the
element forces) are written at the end of the block. The points are written out one call per point (q a constant
in each), so that every row offset is a constant and LLVM tells the rows apart (with q a loop variable it packed
a seventh as much). Every value is formed by the same operations in the same order as ``hex8``'s passes and the laws'
point code: the probe checks the same bits on every output before timing.

What it measured (docs/kernels.md, item 12), per element and update, 10 000 elements, 1 thread, against the three
passes in the same process: slower for each of the three, in every round; without the stores of F, P and Fbar
(not a valid update: the frames read them; measured on the first form, with those stores deleted from the source)
still slower for ``full`` elastic. The gather and the stores of a block, transposed between lanes and the engine's
layout, cost what the packed arithmetic saves, and the kernels compiled in 79 s (elastic) and 91 s (3WEAVE).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from fdeck.jit import njit, njit_inline, njit_parallel, prange
from fdeck.physics.materials import elastic, fabric_hyper, fabric_hyper_blocks as fhb

LANES = fhb.LANES
ELASTIC, FABRIC = 0, 1  # the law in the block

W_ROW = 192  # reference rows: dN (192), then the eight point volumes
REF_ROWS = 200

# rows of the work array: x[a, i] (24); per point q: F_q (9 rows at F_ROW + 9 q), J_q, ratio_q, P_q (9),
# psi_q, modulus_q (3), p_q; Jbar; T (9: the law's argument; later F-bar's mean pressure in its first row)
X_ROW, F_ROW, J_ROW, R_ROW, P_ROW, PSI_ROW, M_ROW, PP_ROW = 0, 24, 96, 104, 112, 184, 192, 216
JB_ROW, T_ROW = 224, 225
EFF_ROW = T_ROW + 1  # F-bar's effective stress (9 rows), beside the mean pressure that stays in row T
WORK_ROWS = 235


def eligible(formulation: str, material, params: np.ndarray) -> int | None:
    """The law id of this path for a non-empty ``full`` or ``fbar`` group, or None: ``linear_elastic`` with one
    pair of Lame constants for the group; ``fabric_hyper`` with the section's broadcast parameter row (the row its
    own block path takes) and without SVML (whose vector maths would change the last bits of its logs and powers)."""
    if formulation not in ("full", "fbar") or len(params) == 0:
        return None
    kernel = getattr(material, "evaluate", None)
    if kernel is elastic.evaluate and bool(np.all(params == params[:1])):
        return ELASTIC
    if kernel is fabric_hyper.evaluate and params.strides[0] == 0 and not numba.config.USING_SVML:
        return FABRIC
    return None


_NO_F, _NO_JBAR, _NO_PTS = np.empty((0, 8, 3, 3)), np.empty(0), np.empty((0, 8))


def _to_blocks(a: np.ndarray, n_block: int) -> np.ndarray:
    """(n_el, ...) -> (n_block, prod(...), LANES), the last block padded by repeating the last element."""
    pad = n_block * LANES - len(a)
    a = np.concatenate([a, np.repeat(a[-1:], pad, axis=0)]) if pad else a
    return np.ascontiguousarray(a.reshape(n_block, LANES, -1).transpose(0, 2, 1))


class Blocks:
    """The block layout of one group: conn_t (n_block, 8, LANES) int64, ref_t (n_block, REF_ROWS, LANES), frame_t
    (n_block, 9, LANES) (the fibre frame, for ``fabric_hyper``), the law id and its parameter row."""

    def __init__(self, formulation, law, conn, dN, w, frame, params):
        n = len(conn)
        self.n_el, self.fbar, self.law = n, formulation == "fbar", law
        n_block = -(-n // LANES)
        self.conn_t = _to_blocks(np.asarray(conn, np.int64), n_block)
        self.ref_t = _to_blocks(np.concatenate([dN.reshape(n, 192), w.reshape(n, 8)], axis=1), n_block)
        self.frame_t = _to_blocks(np.asarray(frame, float).reshape(n, 9), n_block)
        self.prm = np.ascontiguousarray(params[0], float)  # elastic: (lam, mu); fabric_hyper: its packed row
        for a in (self.conn_t, self.ref_t, self.frame_t, self.prm):  # constants: a checkpoint skips read-only arrays
            a.setflags(write=False)

    def update(self, x, g) -> None:
        """The outputs of ``hex8``'s three passes for group g (a ``Hex8Group``), in its arrays."""
        out = ((g.F, g.J, g.P, g.psi, g.modulus, g.fe, g.Fbar, g.Jbar, g.ratio, g.p) if self.fbar else
               (g.F, g.J, g.P, g.psi, g.modulus, g.fe, _NO_F, _NO_JBAR, _NO_PTS, _NO_PTS))  # (F-bar's unused)
        if self.law == ELASTIC:
            update_elastic(x, self.conn_t, self.ref_t, self.prm, self.fbar, self.n_el, 8, *out)
        else:
            update_fabric(x, self.conn_t, self.ref_t, self.frame_t, self.prm, self.fbar, self.n_el, 8, *out)


# Two kernels, one per law, so that a deck compiles only the law it uses (both share every other stage). The fabric
# law is called out of line (``law_block``): inlined into this ``prange`` body, the kernel took about 150 s to
# compile.

@njit_parallel
def update_elastic(x, conn_t, ref_t, prm, fbar, n_el, n_qp, F, J, P, psi, modulus, fe, Fbar, Jbar, ratio, p):
    """One pass per block with ``linear_elastic`` (arrays in the module docstring; for ``full`` the F-bar outputs
    are not written)."""
    lam, mu = prm[elastic.PARAMS.lam], prm[elastic.PARAMS.mu]
    for blk in prange(conn_t.shape[0]):
        w = np.empty((WORK_ROWS, LANES))
        r = ref_t[blk]
        _begin(w, r, x, conn_t, blk, fbar)
        _elastic(w, 0, fbar, lam, mu)
        _elastic(w, 1, fbar, lam, mu)
        _elastic(w, 2, fbar, lam, mu)
        _elastic(w, 3, fbar, lam, mu)
        _elastic(w, 4, fbar, lam, mu)
        _elastic(w, 5, fbar, lam, mu)
        _elastic(w, 6, fbar, lam, mu)
        _elastic(w, 7, fbar, lam, mu)
        _finish(w, r, blk, fbar, n_el, F, J, P, psi, modulus, fe, Fbar, Jbar, ratio, p)


@njit_parallel
def update_fabric(x, conn_t, ref_t, frame_t, prm, fbar, n_el, n_qp, F, J, P, psi, modulus, fe, Fbar, Jbar, ratio, p):
    """One pass per block with ``fabric_hyper`` (``law_block``, which runs ``fabric_hyper_blocks.law_stages``, once
    per point; the block's frame rows set once)."""
    for blk in prange(conn_t.shape[0]):
        w = np.empty((WORK_ROWS, LANES))
        r = ref_t[blk]
        fin = np.empty((18, LANES))  # the law's argument: F (9 rows), then the block's frame (9 rows)
        out = np.empty((13, LANES))
        for k in range(9):
            for l in range(LANES):
                fin[9 + k, l] = frame_t[blk, k, l]
        _begin(w, r, x, conn_t, blk, fbar)
        for q in range(n_qp):
            _argument(w, q, fbar)
            _fabric(w, fin, out, q, prm)
        _finish(w, r, blk, fbar, n_el, F, J, P, psi, modulus, fe, Fbar, Jbar, ratio, p)


@njit_inline
def _begin(w, r, x, conn_t, blk, fbar):
    """Gather the block's positions (scalar loads), the eight points' F and J, and F-bar's ratio."""
    for a in range(8):
        for l in range(LANES):
            n = conn_t[blk, a, l]
            w[X_ROW + 3 * a, l] = x[n, 0]
            w[X_ROW + 3 * a + 1, l] = x[n, 1]
            w[X_ROW + 3 * a + 2, l] = x[n, 2]
    _kinematics(w, r, 0)
    _kinematics(w, r, 1)
    _kinematics(w, r, 2)
    _kinematics(w, r, 3)
    _kinematics(w, r, 4)
    _kinematics(w, r, 5)
    _kinematics(w, r, 6)
    _kinematics(w, r, 7)
    if fbar:
        _fbar_ratio(w, r)


@njit_inline
def _argument(w, q, fbar):
    """The law's argument at point q into rows T: F_q, or Fbar_q = ratio_q F_q."""
    for k in range(9):
        src, dst = w[F_ROW + 9 * q + k], w[T_ROW + k]
        if fbar:
            a = w[R_ROW + q]
            for l in range(LANES):
                dst[l] = a[l] * src[l]
        else:
            for l in range(LANES):
                dst[l] = src[l]


@njit_inline
def _finish(w, r, blk, fbar, n_el, F, J, P, psi, modulus, fe, Fbar, Jbar, ratio, p):
    """The element forces from the points' stresses (F-bar's effective stress), then everything to the engine."""
    f = np.zeros((24, LANES))
    if fbar:
        _mean_pressure(w, r)
    _point_forces(w, r, f, 0, fbar)
    _point_forces(w, r, f, 1, fbar)
    _point_forces(w, r, f, 2, fbar)
    _point_forces(w, r, f, 3, fbar)
    _point_forces(w, r, f, 4, fbar)
    _point_forces(w, r, f, 5, fbar)
    _point_forces(w, r, f, 6, fbar)
    _point_forces(w, r, f, 7, fbar)
    _store(w, f, blk, fbar, n_el, F, J, P, psi, modulus, fe, Fbar, Jbar, ratio, p)


@njit_inline
def _point_forces(w, r, f, q, fbar):
    """Point q's share of the element forces: its stress (F-bar's effective stress) against its gradients."""
    if fbar:
        _effective_stress(w, q)
        _add_forces(w, r, f, q, EFF_ROW)
    else:
        _add_forces(w, r, f, q, P_ROW + 9 * q)


@njit_inline
def _kinematics(w, r, q):
    """F_q = sum_a x_a (x) dN_qa and J_q = det F_q (``hex8._deformation_gradients``), lanes innermost."""
    o = 24 * q
    for l in range(LANES):
        f00 = 0.0
        f01 = 0.0
        f02 = 0.0
        f10 = 0.0
        f11 = 0.0
        f12 = 0.0
        f20 = 0.0
        f21 = 0.0
        f22 = 0.0
        for a in range(8):
            x0, x1, x2 = w[X_ROW + 3 * a, l], w[X_ROW + 3 * a + 1, l], w[X_ROW + 3 * a + 2, l]
            d0, d1, d2 = r[o + 3 * a, l], r[o + 3 * a + 1, l], r[o + 3 * a + 2, l]
            f00 += x0 * d0
            f01 += x0 * d1
            f02 += x0 * d2
            f10 += x1 * d0
            f11 += x1 * d1
            f12 += x1 * d2
            f20 += x2 * d0
            f21 += x2 * d1
            f22 += x2 * d2
        s = F_ROW + 9 * q
        w[s, l], w[s + 1, l], w[s + 2, l] = f00, f01, f02
        w[s + 3, l], w[s + 4, l], w[s + 5, l] = f10, f11, f12
        w[s + 6, l], w[s + 7, l], w[s + 8, l] = f20, f21, f22
        w[J_ROW + q, l] = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
                           + f02 * (f10 * f21 - f11 * f20))


@njit_inline
def _fbar_ratio(w, r):
    """Jbar = sum_q w_q J_q / sum_q w_q and ratio_q = (Jbar / J_q)^(1/3) (``hex8.kinematics_fbar``); the cube
    roots in a scalar loop of their own (``pow``, which LLVM does not pack without a vector maths library)."""
    for l in range(LANES):
        vol = 0.0
        jw = 0.0
        for q in range(8):
            vol += r[W_ROW + q, l]
            jw += r[W_ROW + q, l] * w[J_ROW + q, l]
        w[JB_ROW, l] = jw / vol
    for q in range(8):
        for l in range(LANES):
            jq = w[J_ROW + q, l]
            w[R_ROW + q, l] = (w[JB_ROW, l] / jq) ** (1.0 / 3.0) if jq > 0.0 else np.nan


@njit_inline
def _elastic(w, q, fbar, lam, mu):
    """``elastic.stress`` at point q's F (F-bar: ratio_q F_q), into its P, psi and modulus rows."""
    s, o = F_ROW + 9 * q, P_ROW + 9 * q
    for l in range(LANES):
        a = w[R_ROW + q, l] if fbar else 1.0
        f00, f01, f02 = w[s, l], w[s + 1, l], w[s + 2, l]
        f10, f11, f12 = w[s + 3, l], w[s + 4, l], w[s + 5, l]
        f20, f21, f22 = w[s + 6, l], w[s + 7, l], w[s + 8, l]
        if fbar:
            f00, f01, f02, f10, f11, f12, f20, f21, f22 = (a * f00, a * f01, a * f02, a * f10, a * f11, a * f12,
                                                           a * f20, a * f21, a * f22)
        p00, p01, p02, p10, p11, p12, p20, p21, p22, psi, m = elastic.stress(
            f00, f01, f02, f10, f11, f12, f20, f21, f22, lam, mu)
        w[o, l], w[o + 1, l], w[o + 2, l] = p00, p01, p02
        w[o + 3, l], w[o + 4, l], w[o + 5, l] = p10, p11, p12
        w[o + 6, l], w[o + 7, l], w[o + 8, l] = p20, p21, p22
        w[PSI_ROW + q, l] = psi
        w[M_ROW + 3 * q, l] = m
        w[M_ROW + 3 * q + 1, l] = m
        w[M_ROW + 3 * q + 2, l] = m


@njit_inline
def _fabric(w, fin, out, q, prm):
    """``law_block`` at the argument rows T (fin's frame rows are the block's), into point
    q's P, psi and modulus rows."""
    for k in range(9):
        for l in range(LANES):
            fin[k, l] = w[T_ROW + k, l]
    law_block(fin, prm, out)
    for k in range(9):
        for l in range(LANES):
            w[P_ROW + 9 * q + k, l] = out[k, l]
    for l in range(LANES):
        w[PSI_ROW + q, l] = out[9, l]
    for k in range(3):
        for l in range(LANES):
            w[M_ROW + 3 * q + k, l] = out[10 + k, l]


@njit_inline
def _mean_pressure(w, r):
    """p_q = ratio_q (P_q : F_q) / 3 into rows PP, and their volume mean into row T (``hex8.mean_pressure``)."""
    for l in range(LANES):
        vol = 0.0
        pw = 0.0
        for q in range(8):
            pf = 0.0
            for k in range(9):
                pf += w[P_ROW + 9 * q + k, l] * w[F_ROW + 9 * q + k, l]
            pq = w[R_ROW + q, l] * pf / 3.0
            w[PP_ROW + q, l] = pq
            pw += r[W_ROW + q, l] * pq
            vol += r[W_ROW + q, l]
        w[T_ROW, l] = pw / vol


@njit_inline
def _effective_stress(w, q):
    """F-bar's effective stress of point q into rows EFF_ROW (``hex8.forces_fbar``: a Pbar + c cof(F),
    c = (pavg J / Jbar - p) / J, the mean pressure pavg in row T)."""
    s, o = F_ROW + 9 * q, P_ROW + 9 * q
    for l in range(LANES):
        pavg = w[T_ROW, l]
        a = w[R_ROW + q, l]
        jq = w[J_ROW + q, l]
        c = (pavg / w[JB_ROW, l] * jq - w[PP_ROW + q, l]) / jq
        f00, f01, f02 = w[s, l], w[s + 1, l], w[s + 2, l]
        f10, f11, f12 = w[s + 3, l], w[s + 4, l], w[s + 5, l]
        f20, f21, f22 = w[s + 6, l], w[s + 7, l], w[s + 8, l]
        e0 = a * w[o, l] + c * (f11 * f22 - f12 * f21)
        e1 = a * w[o + 1, l] + c * (f12 * f20 - f10 * f22)
        e2 = a * w[o + 2, l] + c * (f10 * f21 - f11 * f20)
        e3 = a * w[o + 3, l] + c * (f21 * f02 - f22 * f01)
        e4 = a * w[o + 4, l] + c * (f22 * f00 - f20 * f02)
        e5 = a * w[o + 5, l] + c * (f20 * f01 - f21 * f00)
        e6 = a * w[o + 6, l] + c * (f01 * f12 - f02 * f11)
        e7 = a * w[o + 7, l] + c * (f02 * f10 - f00 * f12)
        e8 = a * w[o + 8, l] + c * (f00 * f11 - f01 * f10)
        w[EFF_ROW, l], w[EFF_ROW + 1, l], w[EFF_ROW + 2, l] = e0, e1, e2
        w[EFF_ROW + 3, l], w[EFF_ROW + 4, l], w[EFF_ROW + 5, l] = e3, e4, e5
        w[EFF_ROW + 6, l], w[EFF_ROW + 7, l], w[EFF_ROW + 8, l] = e6, e7, e8


@njit_inline
def _add_forces(w, r, f, q, src):
    """f[3 a + i] += P_i . (w_q dN_qa) with P_q's rows at ``src`` (``hex8._add_point_forces``), lanes
    innermost over 1-D rows."""
    wq = r[W_ROW + q]
    o = 24 * q
    for a in range(8):
        b0, b1, b2 = r[o + 3 * a], r[o + 3 * a + 1], r[o + 3 * a + 2]
        for i in range(3):
            p0, p1, p2, out = w[src + 3 * i], w[src + 3 * i + 1], w[src + 3 * i + 2], f[3 * a + i]
            for l in range(LANES):
                out[l] += p0[l] * (wq[l] * b0[l]) + p1[l] * (wq[l] * b1[l]) + p2[l] * (wq[l] * b2[l])


@njit_inline
def _store(w, f, blk, fbar, n_el, F, J, P, psi, modulus, fe, Fbar, Jbar, ratio, p):
    """The block's results to the engine's arrays (its real elements only), point by point so that the rows read
    stay in L1 (lane by lane over all rows, each lane read a line of every row: 120 KB, beyond L1)."""
    n = min(LANES, n_el - blk * LANES)
    e0 = blk * LANES
    for l in range(n):
        for k in range(24):
            fe[e0 + l, k // 3, k % 3] = f[k, l]
    for q in range(8):
        for l in range(n):
            e = e0 + l
            for k in range(9):
                F[e, q, k // 3, k % 3] = w[F_ROW + 9 * q + k, l]
        for l in range(n):
            e = e0 + l
            for k in range(9):
                P[e, q, k // 3, k % 3] = w[P_ROW + 9 * q + k, l]
            J[e, q] = w[J_ROW + q, l]
            psi[e, q] = w[PSI_ROW + q, l]
            modulus[e, q, 0] = w[M_ROW + 3 * q, l]
            modulus[e, q, 1] = w[M_ROW + 3 * q + 1, l]
            modulus[e, q, 2] = w[M_ROW + 3 * q + 2, l]
        if fbar:
            for l in range(n):
                e = e0 + l
                a = w[R_ROW + q, l]
                ratio[e, q] = a
                p[e, q] = w[PP_ROW + q, l]
                for k in range(9):
                    Fbar[e, q, k // 3, k % 3] = a * w[F_ROW + 9 * q + k, l]
    if fbar:
        for l in range(n):
            Jbar[e0 + l] = w[JB_ROW, l]


@njit
def law_block(fin, prm, out):
    """``fabric_hyper_blocks.law_stages`` on one block of points: fin (18, LANES) F then the frame, out (13, LANES)
    P, psi and the three moduli (work rows allocated here)."""
    w = np.empty((fhb.ROWS, LANES))
    for k in range(18):
        for l in range(LANES):
            w[fhb.F_ROW + k, l] = fin[k, l]  # (F_ROW, FR_ROW) = (0, 9)
    fhb.law_stages(w, prm)
    for k in range(9):
        for l in range(LANES):
            out[k, l] = w[fhb.P_ROW + k, l]
    for k in range(4):
        for l in range(LANES):
            out[9 + k, l] = w[fhb.OUT_ROW + k, l]


OUTPUTS = ("fe", "F", "J", "P", "psi", "modulus", "Fbar", "Jbar", "ratio", "p")


def probe(form: str, mat: str, rounds: int) -> None:
    """Same-bits check, then per round the three passes and the fused kernel, 100 updates each, per element."""
    import bench
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from tests.helpers import same_bits_where_not_nan

    problem = compile_deck(Deck.model_validate(bench.deck(form, mat, [50, 50, 4], 200)))
    g = problem.groups[0]
    law = eligible(form, g.material, g.params)
    if law is None:
        raise SystemExit(f"{form} {mat}: not a pairing of this probe (or SVML is present)")
    blocks = Blocks(form, law, g.conn, g.dN, g.w, g.frame, g.params)
    x = problem.X + 0.01 * np.random.default_rng(0).standard_normal(problem.X.shape)  # 1 % of the 1 mm elements
    v = np.zeros_like(x)
    g.update(x, v)  # hex8's passes
    ref = {k: getattr(g, k).copy() for k in OUTPUTS if hasattr(g, k)}
    for k in ref:
        getattr(g, k)[...] = np.nan
    t0 = time.perf_counter()
    blocks.update(x, g)
    compile_s = time.perf_counter() - t0
    same = all(same_bits_where_not_nan(ref[k], getattr(g, k)) for k in ref)
    n = len(g.conn)
    print(f"{form} {mat}: same bits {same}, first call {compile_s:.1f} s (compilation unless cached)")
    for r in range(rounds):
        out = []
        for fn in (lambda: g.update(x, v), lambda: blocks.update(x, g)):
            fn()
            t0 = time.perf_counter()
            for _ in range(100):
                fn()
            out.append(1e6 * (time.perf_counter() - t0) / 100 / n)
        print(f"  round {r}: hex8 passes {out[0]:.4f}, fused {out[1]:.4f} us per element")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pairs", nargs="*", default=["full", "linear_elastic", "fbar", "linear_elastic", "fbar",
                                                 "fabric_hyper_3weave"], help="formulation material ...")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1)
    a = ap.parse_args()
    numba.set_num_threads(a.threads)
    for form, mat in zip(a.pairs[::2], a.pairs[1::2]):
        probe(form, mat, a.rounds)


if __name__ == "__main__":
    main()
