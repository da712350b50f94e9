"""Eight-node hexahedron, total-Lagrangian, in three formulations.

* ``full``: 2x2x2 Gauss integration of the material law.
* ``fbar``: F-bar / mean dilatation (de Souza Neto et al. 1996): at every point F_bar = (J_bar/J)^(1/3) F with
  J_bar the volume average of det F; the internal force is the exact derivative of sum_q w_q psi(F_bar_q), see
  ``forces_fbar``. Passes the patch test; removes volumetric locking.
* ``reduced``: one point with the Flanagan-Belytschko (1981) uniform gradient b_a = (1/V0) int dN_a/dX dV, plus
  hourglass control on the four modes gamma_alpha = h_alpha - (h_alpha . X_j) b_j. In the total-Lagrangian form
  used here the hourglass "strain" q_alpha = sum_a x_a gamma_a,alpha vanishes for every affine motion (gamma is
  orthogonal to 1 and to X), so the stiffness energy 1/2 k |q|^2 is exactly objective and conservative.

Node order is VTK/Abaqus C3D8: 0-3 the bottom face counter-clockwise, 4-7 above them. All shape-function
gradients are taken once in the reference configuration (``prepare``); per cycle only F = x . grad0 N changes.
Units: x [mm], forces [N], stresses [MPa], volumes [mm^3].
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.ledger import DISSIPATED, STORED, Term
from fdeck.physics.elements import diagnostics, hex8_blocks
from fdeck.jit import njit_inline, njit_parallel, prange
from fdeck.registry import FormulationKind, register_formulation

_inline = njit_inline  # per-element helpers of the kernels below (see fdeck.jit.njit_inline)

# Reference node signs (xi, eta, zeta) in VTK order.
NODE_SIGNS = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float
)
GAUSS_2 = NODE_SIGNS / math.sqrt(3.0)  # 2x2x2 points, unit weights
# Hourglass base vectors h_alpha (4, 8): xi*eta, eta*zeta, zeta*xi, xi*eta*zeta at the nodes.
HOURGLASS_BASE = np.array([
    NODE_SIGNS[:, 0] * NODE_SIGNS[:, 1],
    NODE_SIGNS[:, 1] * NODE_SIGNS[:, 2],
    NODE_SIGNS[:, 2] * NODE_SIGNS[:, 0],
    NODE_SIGNS[:, 0] * NODE_SIGNS[:, 1] * NODE_SIGNS[:, 2],
])
FACES = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])


def shape_gradients_local(points: np.ndarray) -> np.ndarray:
    """dN_a/dxi at natural points (n_p, 3) -> (n_p, 8, 3)."""
    s = NODE_SIGNS
    out = np.empty((len(points), 8, 3))
    for p, (xi, eta, zeta) in enumerate(points):
        fx, fy, fz = 1 + s[:, 0] * xi, 1 + s[:, 1] * eta, 1 + s[:, 2] * zeta
        out[p, :, 0] = s[:, 0] * fy * fz / 8
        out[p, :, 1] = s[:, 1] * fx * fz / 8
        out[p, :, 2] = s[:, 2] * fx * fy / 8
    return out


def prisms(conn: np.ndarray) -> np.ndarray:
    """(n_el,) bool: hexahedra collapsed into a prism, six distinct nodes with corner k + 1 of the bottom face on
    corner k's node and the same on the top face (k + 4, k + 5) for one k (cyclic)."""
    bottom, top = conn[:, :4], conn[:, 4:]
    same_b = bottom == np.roll(bottom, -1, axis=1)
    same_t = top == np.roll(top, -1, axis=1)
    c = np.sort(conn, axis=1)
    distinct = 1 + (c[:, 1:] != c[:, :-1]).sum(axis=1)
    return (same_b.sum(axis=1) == 1) & (same_b == same_t).all(axis=1) & (distinct == 6)


def prepare(X: np.ndarray, conn: np.ndarray) -> dict:
    """Reference-state arrays of hexahedra.

    X (n_node, 3) reference coordinates; conn (n_el, 8). Returns dN (n_el, 8, 8, 3) gradients dN_a/dX at the
    2x2x2 points, w (n_el, 8) point volumes [mm^3], V0 (n_el,), b (n_el, 8, 3) uniform gradient, gamma
    (n_el, 4, 8) hourglass vectors, L0 (n_el,) characteristic length V0 / largest face area [mm], prism (n_el,)
    the collapsed ones (``prisms``), and
    detJ_min (n_el,) the smallest Jacobian at the 2x2x2 points and the nodes (<= 0 means inverted/degenerate; in
    an element with a repeated node, a node's Jacobian that is zero to round-off is left out).
    """
    xe = X[conn]  # (n_el, 8, 3)
    dxi = shape_gradients_local(GAUSS_2)  # (8, 8, 3)
    J = np.einsum("eai,qaj->eqij", xe, dxi)  # dX_i/dxi_j
    detJ = np.linalg.det(J)
    dxi_nodes = shape_gradients_local(NODE_SIGNS)
    detJ_nodes = np.linalg.det(np.einsum("eai,qaj->eqij", xe, dxi_nodes))
    # at the corners of a collapsed edge (the prisms of compile.mesh.diagonal_block's sides: one side edge of the
    # bottom face collapsed and the same one of the top face) the Jacobian is zero, where 2x2x2 and one-point
    # integration never sample: the integration points decide there; any other element with a zero corner
    # Jacobian (a straight angle, a pyramid, a tetrahedron) is still refused
    prism = prisms(conn)
    flat = prism[:, None] & (np.abs(detJ_nodes) <= 1e-9 * np.abs(detJ).mean(axis=1, keepdims=True))
    detJ_min = np.minimum(detJ.min(axis=1), np.where(flat, np.inf, detJ_nodes).min(axis=1))
    safe = np.where(np.abs(detJ) > 0, detJ, 1.0)
    Jinv = np.linalg.inv(np.where(np.abs(detJ)[..., None, None] > 0, J, np.eye(3)))
    dN = np.einsum("qaj,eqji->eqai", dxi, Jinv)
    w = safe * (detJ != 0)
    V0 = w.sum(axis=1)
    b = np.einsum("eq,eqai->eai", w, dN) / np.where(V0 > 0, V0, 1.0)[:, None, None]
    gamma = HOURGLASS_BASE[None, :, :] - np.einsum("ha,eaj,ebj->ehb", HOURGLASS_BASE, xe, b)
    # face areas from the diagonals' cross product (exact for planar quads)
    f = xe[:, FACES]  # (n_el, 6, 4, 3)
    area = 0.5 * np.linalg.norm(np.cross(f[:, :, 2] - f[:, :, 0], f[:, :, 3] - f[:, :, 1]), axis=-1)
    L0 = V0 / area.max(axis=1)
    return dict(dN=np.ascontiguousarray(dN), w=np.ascontiguousarray(w), V0=V0, b=np.ascontiguousarray(b),
                gamma=np.ascontiguousarray(gamma), L0=L0, detJ_min=detJ_min, prism=prism)


@_inline
def _gradient(x, conn, row, dN, e, q):
    """The nine components of F = sum_a x[conn[row, a]] (x) dN[e, q, a] at point q of element e (row 1-D slot rows of
    conn: e itself, or 0 with an identity row when x holds the element's own nodes), summed in registers over the
    nodes in order."""
    f00 = f01 = f02 = f10 = f11 = f12 = f20 = f21 = f22 = 0.0
    for a in range(8):
        n = conn[row, a]
        x0, x1, x2 = x[n, 0], x[n, 1], x[n, 2]
        d0, d1, d2 = dN[e, q, a, 0], dN[e, q, a, 1], dN[e, q, a, 2]
        f00 += x0 * d0
        f01 += x0 * d1
        f02 += x0 * d2
        f10 += x1 * d0
        f11 += x1 * d1
        f12 += x1 * d2
        f20 += x2 * d0
        f21 += x2 * d1
        f22 += x2 * d2
    return f00, f01, f02, f10, f11, f12, f20, f21, f22


@_inline
def _deformation_gradients(x, conn, dN, F, J, e):
    """F[e, q] = sum_a x_a (x) dN[e, q, a] and J[e, q] = det F for one element.

    Point by point, the nine sums in registers, stored once (x is read once per point, eight times per element):
    accumulated in F itself node by node, every update was a load and a store of F, which the compiler cannot keep
    in registers because F might alias x. The sums run over the nodes in the same order either way, so the bits
    are the same. Measured with benchmarks/kernel_parts.py (best of 5 x 100 calls, 10 000 elements, 1 thread):
    0.21 -> 0.12 us per element with 8 points, 0.042 -> 0.021 us with one.
    """
    for q in range(dN.shape[1]):
        f00, f01, f02, f10, f11, f12, f20, f21, f22 = _gradient(x, conn, e, dN, e, q)
        F[e, q, 0, 0] = f00
        F[e, q, 0, 1] = f01
        F[e, q, 0, 2] = f02
        F[e, q, 1, 0] = f10
        F[e, q, 1, 1] = f11
        F[e, q, 1, 2] = f12
        F[e, q, 2, 0] = f20
        F[e, q, 2, 1] = f21
        F[e, q, 2, 2] = f22
        J[e, q] = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
                   + f02 * (f10 * f21 - f11 * f20))


@_inline
def _det_at(F, e, q):
    """det F[e, q] (F (n_el, n_qp, 3, 3)), indexed in place: a view F[e, q] would be reference-counted."""
    return (F[e, q, 0, 0] * (F[e, q, 1, 1] * F[e, q, 2, 2] - F[e, q, 1, 2] * F[e, q, 2, 1])
            - F[e, q, 0, 1] * (F[e, q, 1, 0] * F[e, q, 2, 2] - F[e, q, 1, 2] * F[e, q, 2, 0])
            + F[e, q, 0, 2] * (F[e, q, 1, 0] * F[e, q, 2, 1] - F[e, q, 1, 1] * F[e, q, 2, 0]))


@_inline
def _nodal_forces(P, dN, w, fe, e):
    """fe[e, a] = sum_q w_q P_q . dN_qa for one element.

    With eight points: point by point, P_q read once into registers and each node's sum carried in fe (node by
    node, P was read eight times): 0.14 -> 0.12 us per element (full, linear elastic) and 0.13-0.17 -> 0.12 us
    (full, 3WEAVE), measured as in ``_deformation_gradients``. Each fe[e, a] sums its points in order from zero,
    each term formed as before: the same bits either way. With one point (reduced) the node-by-node sums in
    registers stay (the point-by-point form measured 0.014 -> 0.020 us there).
    """
    if dN.shape[1] == 1:  # 0.0 + (...) below: the old running sum from zero, so a -0.0 term still gives +0.0
        wq = w[e, 0]
        for a in range(8):
            d0, d1, d2 = wq * dN[e, 0, a, 0], wq * dN[e, 0, a, 1], wq * dN[e, 0, a, 2]
            fe[e, a, 0] = 0.0 + (P[e, 0, 0, 0] * d0 + P[e, 0, 0, 1] * d1 + P[e, 0, 0, 2] * d2)
            fe[e, a, 1] = 0.0 + (P[e, 0, 1, 0] * d0 + P[e, 0, 1, 1] * d1 + P[e, 0, 1, 2] * d2)
            fe[e, a, 2] = 0.0 + (P[e, 0, 2, 0] * d0 + P[e, 0, 2, 1] * d1 + P[e, 0, 2, 2] * d2)
        return
    _zero_forces(fe, e)
    for q in range(dN.shape[1]):
        _add_point_forces(fe, dN, e, q, w[e, q], P[e, q, 0, 0], P[e, q, 0, 1], P[e, q, 0, 2], P[e, q, 1, 0],
                          P[e, q, 1, 1], P[e, q, 1, 2], P[e, q, 2, 0], P[e, q, 2, 1], P[e, q, 2, 2])


@_inline
def _zero_forces(fe, e):
    for a in range(8):
        fe[e, a, 0] = 0.0
        fe[e, a, 1] = 0.0
        fe[e, a, 2] = 0.0


@_inline
def _add_point_forces(fe, dN, e, q, wq, p00, p01, p02, p10, p11, p12, p20, p21, p22):
    """fe[e, a] += w_q P_q . dN_qa for the eight nodes, P_q (row-major scalars) held in registers."""
    for a in range(8):
        d0, d1, d2 = wq * dN[e, q, a, 0], wq * dN[e, q, a, 1], wq * dN[e, q, a, 2]
        fe[e, a, 0] += p00 * d0 + p01 * d1 + p02 * d2
        fe[e, a, 1] += p10 * d0 + p11 * d1 + p12 * d2
        fe[e, a, 2] += p20 * d0 + p21 * d1 + p22 * d2


@njit_parallel
def kinematics(x, conn, dN, F, J):
    """F (n_el, n_qp, 3, 3) = sum_a x_a (x) dN_a; J (n_el, n_qp) = det F. dN (n_el, n_qp, 8, 3)."""
    for e in prange(conn.shape[0]):
        _deformation_gradients(x, conn, dN, F, J, e)


@njit_parallel
def kinematics_fbar(x, conn, dN, w, F, J, Fbar, Jbar, ratio):
    """As ``kinematics``, plus Fbar (n_el, n_qp, 3, 3), Jbar (n_el,) = sum_q w_q J_q / V0 and
    ratio (n_el, n_qp) = (Jbar / J)^(1/3), so that Fbar = ratio F."""
    for e in prange(conn.shape[0]):
        _deformation_gradients(x, conn, dN, F, J, e)
        vol = 0.0
        jw = 0.0
        for q in range(dN.shape[1]):
            vol += w[e, q]
            jw += w[e, q] * J[e, q]
        Jbar[e] = jw / vol
        for q in range(dN.shape[1]):
            r = (Jbar[e] / J[e, q]) ** (1.0 / 3.0) if J[e, q] > 0.0 else np.nan
            ratio[e, q] = r
            for i in range(3):
                for j in range(3):
                    Fbar[e, q, i, j] = r * F[e, q, i, j]


@njit_parallel
def forces(P, dN, w, fe):
    """fe (n_el, 8, 3) = sum_q w_q P_q . dN_qa: internal nodal forces [N] from P (n_el, n_qp, 3, 3)."""
    for e in prange(fe.shape[0]):
        _nodal_forces(P, dN, w, fe, e)


@_inline
def mean_pressure(P, F, ratio, w, p, e):
    """The F-bar pressures of element e, p[e, q] = ratio[e, q] (P_q : F_q) / 3 [MPa] (P, F (n_el, n_qp, 3, 3),
    ratio, w, p (n_el, n_qp)), and their volume mean, returned: the mean-dilatation part of every averaged
    formulation's forces (``forces_fbar``, ``ans_fbar``, ``ans_tbar``)."""
    vol = 0.0
    pw = 0.0
    for q in range(w.shape[1]):
        pf = 0.0
        for i in range(3):
            for j in range(3):
                pf += P[e, q, i, j] * F[e, q, i, j]
        p[e, q] = ratio[e, q] * pf / 3.0
        pw += w[e, q] * p[e, q]
        vol += w[e, q]
    return pw / vol


@njit_parallel
def forces_fbar(F, J, Jbar, ratio, Pbar, dN, w, p, fe):
    """Exact internal forces of W = sum_q w_q psi(Fbar_q); Pbar = dpsi/dFbar (n_el, n_qp, 3, 3).

    dW = sum_q w_q Peff_q : dF_q with Peff = a Pbar - p F^-T + (pbar_avg / Jbar) J F^-T, where
    a = (Jbar/J)^(1/3) (``ratio``), p = a (Pbar : F) / 3 and pbar_avg the volume average of p.
    p (n_el, n_qp) is scratch owned by the caller; F^-T = cof(F) / J. Peff is formed point by point in registers
    and added to the nodes at once; it used to go through a scratch array, with the same bits: 0.236 -> 0.222 us
    per element (3WEAVE, measured as in ``_deformation_gradients``).
    """
    for e in prange(fe.shape[0]):
        pavg = mean_pressure(Pbar, F, ratio, w, p, e)
        _zero_forces(fe, e)
        for q in range(dN.shape[1]):
            a = ratio[e, q]
            c = (pavg / Jbar[e] * J[e, q] - p[e, q]) / J[e, q]  # c F^-T = (pavg J / Jbar - p) cof(F) / J
            f00, f01, f02 = F[e, q, 0, 0], F[e, q, 0, 1], F[e, q, 0, 2]
            f10, f11, f12 = F[e, q, 1, 0], F[e, q, 1, 1], F[e, q, 1, 2]
            f20, f21, f22 = F[e, q, 2, 0], F[e, q, 2, 1], F[e, q, 2, 2]
            _add_point_forces(fe, dN, e, q, w[e, q],
                              a * Pbar[e, q, 0, 0] + c * (f11 * f22 - f12 * f21),
                              a * Pbar[e, q, 0, 1] + c * (f12 * f20 - f10 * f22),
                              a * Pbar[e, q, 0, 2] + c * (f10 * f21 - f11 * f20),
                              a * Pbar[e, q, 1, 0] + c * (f21 * f02 - f22 * f01),
                              a * Pbar[e, q, 1, 1] + c * (f22 * f00 - f20 * f02),
                              a * Pbar[e, q, 1, 2] + c * (f20 * f01 - f21 * f00),
                              a * Pbar[e, q, 2, 0] + c * (f01 * f12 - f02 * f11),
                              a * Pbar[e, q, 2, 1] + c * (f02 * f10 - f00 * f12),
                              a * Pbar[e, q, 2, 2] + c * (f00 * f11 - f01 * f10))


@njit_parallel
def hourglass(x, v, conn, gamma, k_hg, c_hg, fe, e_hg, p_hg):
    """Add Flanagan-Belytschko hourglass forces to fe (n_el, 8, 3).

    q_alpha = sum_a x_a gamma_alpha,a; stiffness force k q gamma, viscous force c qdot gamma.
    k_hg, c_hg (n_el,) [N/mm], [N s/mm]; outputs e_hg (n_el,) stored energy 1/2 k |q|^2 [mJ],
    p_hg (n_el,) viscous dissipation rate c |qdot|^2 [mW].

    One pass over the nodes for the four modes' sums (each node's position read once, not once per mode) and one
    for the forces (each fe[e, a] read and stored once, the four modes added in a register), only the sums the
    element's hourglass type needs (one of k, c is zero). Every sum and every fe update runs in the same order as
    mode by mode, so the bits are those of the mode-by-mode loops; a skipped sum that is non-finite (a NaN or
    infinite position or velocity) does not reach fe through its zero coefficient. Measured with
    ``benchmarks/kernel_parts.py reduced linear_elastic``: 0.060-0.071 -> 0.049 us per element on a machine loaded by
    two other runs (docs/kernels.md, item 5).
    """
    for e in prange(conn.shape[0]):
        hourglass_element(x, v, conn, gamma, k_hg, c_hg, fe, e_hg, p_hg, e)


@_inline
def hourglass_element(x, v, conn, gamma, k_hg, c_hg, fe, e_hg, p_hg, e):
    """``hourglass`` for element e (inlined into element loops: the kernel above and benchmarks/fusion_probe.py)."""
    k = k_hg[e]
    c = c_hg[e]
    s = _hourglass_sums(x, conn, gamma, e) if k != 0.0 else _NO_SUMS
    r = _hourglass_sums(v, conn, gamma, e) if c != 0.0 else _NO_SUMS
    e_hg[e] = _squares(0.5 * k, s)
    p_hg[e] = _squares(c, r)
    h00, h01, h02 = k * s[0] + c * r[0], k * s[1] + c * r[1], k * s[2] + c * r[2]
    h10, h11, h12 = k * s[3] + c * r[3], k * s[4] + c * r[4], k * s[5] + c * r[5]
    h20, h21, h22 = k * s[6] + c * r[6], k * s[7] + c * r[7], k * s[8] + c * r[8]
    h30, h31, h32 = k * s[9] + c * r[9], k * s[10] + c * r[10], k * s[11] + c * r[11]
    for a in range(8):
        g0, g1, g2, g3 = gamma[e, 0, a], gamma[e, 1, a], gamma[e, 2, a], gamma[e, 3, a]
        f0 = fe[e, a, 0]
        f1 = fe[e, a, 1]
        f2 = fe[e, a, 2]
        f0 += h00 * g0
        f1 += h01 * g0
        f2 += h02 * g0
        f0 += h10 * g1
        f1 += h11 * g1
        f2 += h12 * g1
        f0 += h20 * g2
        f1 += h21 * g2
        f2 += h22 * g2
        f0 += h30 * g3
        f1 += h31 * g3
        f2 += h32 * g3
        fe[e, a, 0] = f0
        fe[e, a, 1] = f1
        fe[e, a, 2] = f2


_NO_SUMS = (0.0,) * 12


@_inline
def _squares(scale, q):
    """sum_i scale q_i q_i over a 12-tuple, in order from zero (as the mode-by-mode loops summed it)."""
    t = 0.0
    t += scale * q[0] * q[0]
    t += scale * q[1] * q[1]
    t += scale * q[2] * q[2]
    t += scale * q[3] * q[3]
    t += scale * q[4] * q[4]
    t += scale * q[5] * q[5]
    t += scale * q[6] * q[6]
    t += scale * q[7] * q[7]
    t += scale * q[8] * q[8]
    t += scale * q[9] * q[9]
    t += scale * q[10] * q[10]
    t += scale * q[11] * q[11]
    return t


@_inline
def _hourglass_sums(y, conn, gamma, e):
    """The four modes' sums sum_a y_a gamma_alpha,a of nodal values y (n_node, 3) for element e, as a 12-tuple
    (mode-major: alpha 0 x, y, z, alpha 1 x, ...), each summed over the nodes in order from zero."""
    q00 = q01 = q02 = q10 = q11 = q12 = q20 = q21 = q22 = q30 = q31 = q32 = 0.0
    for a in range(8):
        n = conn[e, a]
        y0, y1, y2 = y[n, 0], y[n, 1], y[n, 2]
        g = gamma[e, 0, a]
        q00 += y0 * g
        q01 += y1 * g
        q02 += y2 * g
        g = gamma[e, 1, a]
        q10 += y0 * g
        q11 += y1 * g
        q12 += y2 * g
        g = gamma[e, 2, a]
        q20 += y0 * g
        q21 += y1 * g
        q22 += y2 * g
        g = gamma[e, 3, a]
        q30 += y0 * g
        q31 += y1 * g
        q32 += y2 * g
    return (q00, q01, q02, q10, q11, q12, q20, q21, q22, q30, q31, q32)


@njit_parallel
def element_dt(modulus, L0, inv_len2, extra, coupling, rho, dt_e):
    """dt_e (n_el,) [s]: the time a wave takes to cross the element, each stiffness over its own length.

    modulus (n_el, n_qp, 3) directional bounds m_i along the frame rows f_i [MPa] (see MaterialKind); L0 (n_el,)
    smallest height V0 / largest face [mm]; inv_len2 (n_el, 3) = 1 / L_i^2, the element's inverse squared length
    along f_i [1/mm^2]; extra (n_el,) stiffness of other origin (hourglass springs) in the same units as m / L^2
    [MPa/mm^2]; coupling: share of the directional excess that the formulation spreads to every direction (F-bar:
    1/9, because J-bar feeds a third of any point's volume change into the fibre stretch); rho (n_el,) [t/mm^3].

        rho (c / L)^2 = (m_min + coupling sum_i (m_i - m_min)) / L0^2 + max_i (m_i - m_min) / L_i^2 + extra

    with m_i the largest over the points and m_min = min_i m_i, the stiffness every direction has (for isotropic
    laws only the first term remains: L0 / c, the usual explicit estimate). A fibre stiffness therefore limits the
    step through the element's length along the fibre, not through its thickness: for a 5 x 5 x 0.635 mm 3WEAVE
    element at 1 % warp strain the step is 3x (F-bar) to 8x (full) longer than L0 over the fibre wave speed, and
    stays below the exact critical step of the assembled mesh (``tests/test_stable_step.py``).
    """
    for e in prange(L0.shape[0]):
        m0 = 0.0
        m1 = 0.0
        m2 = 0.0
        for q in range(modulus.shape[1]):
            m0 = max(m0, modulus[e, q, 0])
            m1 = max(m1, modulus[e, q, 1])
            m2 = max(m2, modulus[e, q, 2])
        lo = min(m0, m1, m2)
        x0, x1, x2 = m0 - lo, m1 - lo, m2 - lo
        s = ((lo + coupling * (x0 + x1 + x2)) / (L0[e] * L0[e])
             + max(x0 * inv_len2[e, 0], x1 * inv_len2[e, 1], x2 * inv_len2[e, 2]) + extra[e])
        dt_e[e] = math.sqrt(rho[e] / s) if s > 0.0 else np.inf


def directional_lengths(b: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """(n_el, 3) inverse squared lengths 1/L_i^2 = f_i . T . f_i with T = 2 sum_a b_a (x) b_a [1/mm^2].

    b (n_el, 8, 3) uniform gradients, frame (n_el, 3, 3) rows f_i. For a box of edges (a, b, c) aligned with the
    frame, L_i are the edges; the definition is invariant to how the element is meshed around f_i.
    """
    bf = np.einsum("eaj,eij->eai", b, frame)  # b_a . f_i
    return 2.0 * np.einsum("eai,eai->ei", bf, bf)


class Hex8Group:
    """One homogeneous group: hexahedra of one section (one formulation x one material), an
    ``engine.group.ElementGroup``.

    The engine calls ``update(x, v)`` once per cycle, then ``add_forces(f_int)``. All arrays are allocated once here.
    Ledger: the strain energy, and with hourglass control its stored spring energy and viscous dissipation.
    """

    nodes_per_element = 8
    cell_type = "hexahedron"
    solid = True
    rotational = False

    def __init__(self, name, formulation, X, conn, ids, material, params, frame, rho, hourglass=None):
        from fdeck.engine.gather import node_slots

        self.name, self.formulation, self.material = name, formulation, material
        self.conn, self.ids = np.ascontiguousarray(conn, np.int64), ids
        geo = prepare(X, self.conn)
        self.dN, self.w, self.V0, self.b = geo["dN"], geo["w"], geo["V0"], geo["b"]
        self.gamma, self.L0, self.detJ_min = geo["gamma"], geo["L0"], geo["detJ_min"]
        n_el = len(conn)
        reduced = formulation == "reduced"
        n_qp = 1 if reduced else 8
        # the one-point element lumps collapsed hexahedra (the prisms of a diagonal lattice's sides) by the 2x2x2
        # row sums, as full integration does: V0 / 8 per corner would give the repeated node twice its share
        self.collapsed = np.nonzero(geo["prism"])[0]
        self.w_collapsed = geo["w"][self.collapsed] if reduced else None
        if reduced:  # one point with the uniform gradient and the whole volume
            self.dN, self.w = self.b[:, None], self.V0[:, None].copy()
        self.params, self.frame = params, np.ascontiguousarray(frame)
        self.rho = np.ascontiguousarray(rho, float)  # (n_el,) density incl. mass scaling [t/mm^3]
        self.state = np.zeros((n_el, n_qp, material.n_state))
        self.F = np.zeros((n_el, n_qp, 3, 3))
        self.F[:] = np.eye(3)
        self.J = np.ones((n_el, n_qp))
        self.P = np.zeros((n_el, n_qp, 3, 3))
        self.psi = np.zeros((n_el, n_qp))
        self.modulus = np.zeros((n_el, n_qp, 3))
        self.fe = np.zeros((n_el, 8, 3))
        self.dt_e = np.zeros(n_el)
        self.e_hg = np.zeros(n_el)
        self.p_hg = np.zeros(n_el)
        if formulation == "fbar":
            self.Fbar, self.Jbar = self.F.copy(), np.ones(n_el)
            self.ratio, self.p = np.ones((n_el, n_qp)), np.zeros((n_el, n_qp))
        self.ptr, self.slots = node_slots(self.conn, len(X))
        # rest-state wave modulus (per element) scales the hourglass stiffness so it stays conservative
        material.evaluate(self.F, self.frame, self.params, self.state, self.P, self.psi, self.modulus)
        self.modulus_rest = self.modulus.max(axis=1, keepdims=True)  # (n_el, 1, 3)
        self.modulus0 = self.modulus.max(axis=(1, 2))  # largest rest modulus (hourglass scale, info)
        self.inv_len2 = directional_lengths(self.b, self.frame)
        self.dt_coupling = 1.0 / 9.0 if formulation == "fbar" else 0.0
        self.k_hg = np.zeros(n_el)
        self.c_hg = np.zeros(n_el)
        if reduced and hourglass is not None:
            coeff = hourglass.coefficient
            if hourglass.type == "stiffness":
                self.k_hg = coeff * self.modulus0 * self.V0 * np.einsum("eai,eai->e", self.b, self.b) / 8.0
            else:
                c0 = np.sqrt(self.modulus0 / self.rho)
                self.c_hg = coeff * self.rho * c0 * self.V0 ** (2.0 / 3.0) / 4.0
        self.has_hourglass = bool(reduced and hourglass is not None)
        # reduced + linear_elastic: the same update fused and vectorised over blocks of elements (same bits)
        self.blocks = (hex8_blocks.Blocks(self.conn, self.b, self.V0, self.gamma, self.k_hg, self.c_hg, params)
                       if hex8_blocks.eligible(formulation, material, params) else None)
        # hourglass springs in the stable step: a mode u_a = gamma_a has omega^2 = k |gamma|^2 / m_a with
        # m_a = rho V0 / 8, i.e. rho (c/L)^2 = rho omega^2 / 4 = 2 k max|gamma|^2 / V0
        self.dt_extra = 2.0 * self.k_hg * np.einsum("ema,ema->em", self.gamma, self.gamma).max(axis=1) / self.V0
        self.terms = (Term("strain_energy", STORED),)
        if self.has_hourglass:
            self.terms += (Term("hourglass_energy", STORED),)
            if hourglass.type == "viscous":
                self.terms += (Term("hourglass_dissipation", DISSIPATED, rate=True),)

    # -- per cycle ---------------------------------------------------------------------------------
    def update(self, x, v):
        """Kinematics, material, element forces at positions x (n_node, 3), velocities v (n_node, 3)."""
        m = self.material
        if self.blocks is not None:
            self.blocks.update(x, v, self.F, self.P, self.fe, self.psi, self.J, self.modulus, self.e_hg, self.p_hg)
            return
        if self.formulation == "fbar":
            kinematics_fbar(x, self.conn, self.dN, self.w, self.F, self.J, self.Fbar, self.Jbar, self.ratio)
            m.evaluate(self.Fbar, self.frame, self.params, self.state, self.P, self.psi, self.modulus)
            forces_fbar(self.F, self.J, self.Jbar, self.ratio, self.P, self.dN, self.w, self.p, self.fe)
        else:
            kinematics(x, self.conn, self.dN, self.F, self.J)
            m.evaluate(self.F, self.frame, self.params, self.state, self.P, self.psi, self.modulus)
            forces(self.P, self.dN, self.w, self.fe)
        if self.has_hourglass:
            hourglass(x, v, self.conn, self.gamma, self.k_hg, self.c_hg, self.fe, self.e_hg, self.p_hg)

    def add_forces(self, f_int):
        from fdeck.engine.gather import gather_add

        gather_add(self.fe, self.ptr, self.slots, f_int)

    def term_values(self) -> tuple[float, ...]:
        """Stored hyperelastic energy sum_q w_q psi_q [mJ]; hourglass stored energy [mJ] and viscous hourglass
        dissipation rate [mW] when the group has hourglass control (see ``terms``)."""
        values = (float(np.einsum("eq,eq->", self.w, self.psi)), float(self.e_hg.sum()), float(self.p_hg.sum()))
        return values[:len(self.terms)]

    def set_density(self, rho: np.ndarray) -> None:
        """Densities (n_el,) [t/mm^3] of the step, copied: the group's own array (mass tracking raises it during a
        step), never an alias of the step plan's (which a checkpoint saves and restores separately)."""
        self.rho = np.array(rho, float)

    def stable_dt(self) -> float:
        """Smallest element step [s] at the current moduli and densities (see ``element_dt``)."""
        element_dt(self.modulus, self.L0, self.inv_len2, self.dt_extra, self.dt_coupling, self.rho, self.dt_e)
        return float(self.dt_e.min())

    def rest_dt(self, rho: np.ndarray) -> np.ndarray:
        """(n_el,) element steps [s] at rest with densities rho (n_el,), for mass scaling and ``fdeck info``."""
        out = np.empty(len(self.conn))
        element_dt(self.modulus_rest, self.L0, self.inv_len2, self.dt_extra, self.dt_coupling,
                   np.ascontiguousarray(rho, float), out)
        return out

    def worst_jacobian(self) -> tuple[float, int]:
        """(smallest det F over the group's points, its element id)."""
        flat = int(np.argmin(self.J))
        return float(self.J.flat[flat]), int(self.ids[flat // self.J.shape[1]])

    def mass(self, rho: np.ndarray) -> np.ndarray:
        """Lumped element masses per node (n_el, 8) [t] with densities rho (n_el,) [t/mm^3]: row sums of the
        consistent mass, int rho N_a dV (V0 / 8 per node for the one-point element, except collapsed ones)."""
        rho = np.asarray(rho, float)
        N = np.prod(1 + NODE_SIGNS[None, :, :] * GAUSS_2[:, None, :], axis=2) / 8.0  # (8 qp, 8 nodes)
        if self.w.shape[1] == 8:
            return rho[:, None] * self.w @ N
        m = rho[:, None] * np.repeat(self.V0[:, None] / 8.0, 8, axis=1)
        m[self.collapsed] = rho[self.collapsed, None] * self.w_collapsed @ N
        return m

    # -- output ------------------------------------------------------------------------------------
    def cell_fields(self, idx=None, names=None) -> dict[str, np.ndarray]:
        """Per-element output averaged over points, for all elements or the local indices ``idx``:
        Cauchy stress (n, 6) XX YY ZZ XY YZ XZ [MPa], strain-energy density [MPa], J, the formulation's
        diagnostics (J_bar, hourglass energy density) and the material's (see its ``diagnostics``), all taken at the
        deformation gradient the material sees (``F_material`` of a subclass, F-bar's Fbar, else F). ``names``
        (a collection of field names): compute only those where that saves work (the stress, the material's
        diagnostics); the history's measures ask for one field every row, and the stress was 3/5 of their time
        (`max_shear_angle` on the 24 000-hexahedron tetrahedron, 0.113 -> 0.044 s per row)."""
        idx = np.arange(len(self.conn)) if idx is None else np.asarray(idx)
        F = getattr(self, "F_material", self.Fbar if self.formulation == "fbar" else self.F)[idx]
        w = self.w[idx]
        wn = w / w.sum(axis=1, keepdims=True)
        out = {}
        if names is None or "stress" in names:
            sigma = np.einsum("eqij,eqkj->eqik", self.P[idx], F) / np.linalg.det(F)[..., None, None]
            s = np.einsum("eq,eqij->eij", wn, sigma)
            out["stress"] = np.stack([s[:, 0, 0], s[:, 1, 1], s[:, 2, 2], s[:, 0, 1], s[:, 1, 2], s[:, 0, 2]], axis=1)
        out["strain_energy_density"] = np.einsum("eq,eq->e", wn, self.psi[idx])
        out["J"] = np.einsum("eq,eq->e", wn, self.J[idx])
        if self.formulation == "fbar":
            out["J_bar"] = self.Jbar[idx]
        if self.has_hourglass:
            out["hourglass_energy_density"] = self.e_hg[idx] / self.V0[idx]
        if names is None or not set(names).isdisjoint(self.material.diagnostics):
            src = np.broadcast_to(idx[:, None], wn.shape)  # every point reads its element's frame and law
            out.update(diagnostics.averaged(self.material, F, self.frame, self.params, src, wn))
        return out


def build(name, section, X, conn, ids, material, params, orientation, rho, cell_type):
    """Registry hook: a Hex8Group for one section card (``reduced`` gets default hourglass control if none given)."""
    hourglass = section.hourglass
    if section.formulation == "reduced" and hourglass is None:
        from fdeck.deck.model import Hourglass

        hourglass = Hourglass()
    try:
        frames = orientation.frames()
    except ValueError as exc:
        raise CompileError([(("orientation",), str(exc))]) from None
    return Hex8Group(name, section.formulation, X, conn, ids, material, params, frames, rho, hourglass)


for _name in ("full", "fbar", "reduced"):
    register_formulation(FormulationKind(_name, build, 8))
