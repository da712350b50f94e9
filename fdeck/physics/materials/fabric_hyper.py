"""Hyperelastic fabric law for hexahedra (dry textile reinforcements): one energy per deformation mode.

psi = sum_k psi_k(I_k) over six invariants of C = F^T F built on the reference fibre frame (f1 warp, f2 weft,
f3 thickness), as in MODELS.md section 1 (after [P] Pazmino et al., Composites A 72 (2015), and Charmetant et al.
2012 for the interlock family):

    k  mode                   invariant                                    dI/dC
    0  warp stretch           e1 = 1/2 ln I41                              M11 / (2 I41)
    1  weft stretch           e2 = 1/2 ln I42                              M22 / (2 I42)
    2  transverse compaction  c  = 1/2 ln(I3 / D), D = I41 I42 - I412^2    C^-1/2 - (I42 M11 + I41 M22 - 2 I412 M12)/2D
    3  in-plane shear         s  = I412 / sqrt(I41 I42)                    M12/sqrt(I41 I42) - s/2 (M11/I41 + M22/I42)
    4  transverse shear warp  t1 = I413 / sqrt(I41 I43)                    same pattern on (1, 3)
    5  transverse shear weft  t2 = I423 / sqrt(I42 I43)                    same pattern on (2, 3)

with I4ij = f_i.C.f_j and M_ij = sym(f_i x f_j). The compaction derivative is the exact one (with the I412 term
that [P] drops); an inverted element (J <= 0) gives c = nan for the engine's monitor. Each mode takes an energy form
from a small library (``EnergyForm``); the stretch modes switch to psi = compression_ratio * K1 * e^2 for e < 0
(K1 = psi''(0)/2 of the tensile form, [P] uses 1 %), the shear modes are even (psi(|s|)). Singular states (in-plane
shear s >= 1, compaction c <= I0) give inf/nan without raising.

Kernel arithmetic is done in the fibre frame: with a_i = F f_i (current fibre vectors) and G_ij = a_i.a_j = I4ij,
S = 2 sum psi_k' dI_k/dC = sum_ij W_ij f_i x f_j + psi_c' C^-1, hence P = F S = sum_ij W_ij a_i x f_j + psi_c' F^-T.

Presets (``presets/*.yaml``, selected by ``preset:``; deck values override them mode by mode):
    3weave     every published number of [P] (Tables 2 and 4), E-glass non-crimp 3D orthogonal weave.
    interlock  REPRESENTATIVE values for a thick carbon layer-to-layer angle interlock, NOT published data (the
               Charmetant 2012 parameters are not available): fibre tension stiffness three to four orders above the
               transverse shear and compaction stiffnesses, which is the ratio that matters for the spurious
               hexahedral modes of [B].
A new preset is a new YAML file in ``presets/`` with card fields only; nothing else to change.
"""

import math

import numba
import numpy as np

from fdeck.jit import FLAGS, njit, njit_parallel, prange
from fdeck.physics.layout import layout
from fdeck.physics.tensor import push
from fdeck.registry import MaterialKind, register_material
from fdeck.cards.fabric_hyper import MAX_TABLE, MODES, FabricHyper

BLOCK = 3 + 2 * MAX_TABLE
"""Parameters per mode: [form_id, then up to 2 + 2 * MAX_TABLE form parameters] (the tabulated form is the largest)."""

PARAMS = layout(**{mode: BLOCK for mode in MODES}, compression_ratio=1, compressive_k=2)
"""The packed parameters: one block per mode (in MODES order, so mode k starts at k * BLOCK), the compression ratio,
and the compressive quadratic coefficient of the two stretch modes [MPa]."""
assert PARAMS[:len(MODES)] == tuple(k * BLOCK for k in range(len(MODES)))

_inline = numba.njit(inline="always", **FLAGS)
"""fdeck's flags plus numba-level inlining for the small helpers of ``point``: LLVM alone does not inline the
energy-form dispatch, whose six calls cost about a sixth of a point (measured: ~195 -> ~160 ns)."""


# ----------------------------------------------------------------------------------------------------------------
# Packing
# ----------------------------------------------------------------------------------------------------------------

def pack(card: FabricHyper) -> np.ndarray:
    """-> (PARAMS.size,) = 6 mode blocks [form_id, form parameters...], compression_ratio, K_comp(warp), K_comp(weft).

    The compressive coefficients are compression_ratio * psi''(0)/2 of each stretch mode's tensile form [MPa].
    """
    p = np.zeros(PARAMS.size)
    for k, name in enumerate(MODES):
        form = getattr(card, name)
        vals = form.packed()
        p[k * BLOCK] = form.form_id
        p[k * BLOCK + 1:k * BLOCK + 1 + len(vals)] = vals
    p[PARAMS.compression_ratio] = card.compression_ratio
    for k in (0, 1):
        p[PARAMS.compressive_k + k] = card.compression_ratio * 0.5 * _form(p, k * BLOCK, 0.0)[2]
    return p


# ----------------------------------------------------------------------------------------------------------------
# Kernels: energy forms (psi, psi', psi'') of one scalar
# ----------------------------------------------------------------------------------------------------------------

@_inline
def _poly(p, o, x):
    """sum_k a_k x^k (k = 1..5) with a = p[o:o+5], and its two derivatives (Horner)."""
    a1, a2, a3, a4, a5 = p[o], p[o + 1], p[o + 2], p[o + 3], p[o + 4]
    psi = x * (a1 + x * (a2 + x * (a3 + x * (a4 + x * a5))))
    d1 = a1 + x * (2.0 * a2 + x * (3.0 * a3 + x * (4.0 * a4 + x * 5.0 * a5)))
    d2 = 2.0 * a2 + x * (6.0 * a3 + x * (12.0 * a4 + x * 20.0 * a5))
    return psi, d1, d2


@_inline
def _locking(p, o, x):
    """[P] in-plane shear form; params [I0, K12, K13, p22, K21, psi20]. x >= 1 gives inf/nan (locked)."""
    if x <= p[o]:
        k12, k13 = p[o + 1], p[o + 2]
        return x * x * (k12 + k13 * x), x * (2.0 * k12 + 3.0 * k13 * x), 2.0 * k12 + 6.0 * k13 * x
    p22, k21 = p[o + 3], p[o + 4]
    u = 1.0 - x
    up = u ** (-p22)
    d1 = k21 * p22 * up / u
    return k21 * up + p[o + 5], d1, d1 * (p22 + 1.0) / u


@_inline
def _compaction(p, o, x):
    """[P] compaction form; params [K, 1/I0, p, K p/I0, K p (p+1)/I0^2]. x <= I0 gives inf/nan (locked)."""
    k, r, e = p[o], p[o + 1], p[o + 2]
    u = 1.0 - x * r
    up = u ** (-e)
    return k * (up - e * x * r - 1.0), p[o + 3] * (up / u - 1.0), p[o + 4] * up / (u * u)


@njit
def _tabulated(p, o, x):
    """Integral from 0 of the piecewise-linear table; params [n, i0, x[16], d[16]], x[i0] = 0."""
    n, b = int(p[o]), int(p[o + 1])
    xs, ds = o + 2, o + 2 + MAX_TABLE
    psib = 0.0
    if x >= 0.0:  # walk right from the zero node; base = left node of the segment holding x
        while b + 1 < n and x > p[xs + b + 1]:
            psib += 0.5 * (p[ds + b] + p[ds + b + 1]) * (p[xs + b + 1] - p[xs + b])
            b += 1
        j = b if b + 1 < n else n - 2
    else:  # walk left; base = right node of the segment holding x
        while b - 1 >= 0 and x < p[xs + b - 1]:
            psib -= 0.5 * (p[ds + b - 1] + p[ds + b]) * (p[xs + b] - p[xs + b - 1])
            b -= 1
        j = b - 1 if b >= 1 else 0
    k = (p[ds + j + 1] - p[ds + j]) / (p[xs + j + 1] - p[xs + j])  # slope of dpsi/dx, also used to extrapolate
    h = x - p[xs + b]
    return psib + p[ds + b] * h + 0.5 * k * h * h, p[ds + b] + k * h, k


@_inline
def _form(p, o, x):
    """(psi [MPa], dpsi/dx, d2psi/dx2) of the form packed at p[o:o+BLOCK]."""
    fid = int(p[o])
    if fid == 1:
        return _poly(p, o + 1, x)
    if fid == 2:
        return _poly(p, o + 2, x) if x <= p[o + 1] else _poly(p, o + 7, x)
    if fid == 3:
        return _locking(p, o + 1, x)
    if fid == 4:
        return _compaction(p, o + 1, x)
    if fid == 5:
        k = p[o + 1]
        return k * x * x, 2.0 * k * x, 2.0 * k
    if fid == 6:
        return _tabulated(p, o + 1, x)
    return 0.0, 0.0, 0.0


@_inline
def _stretch(p, k, x):
    """Stretch mode k (0 warp, 1 weft): tensile form for x >= 0, compression_ratio * K1 * x^2 below."""
    if x < 0.0:
        kc = p[PARAMS.compressive_k + k]
        return kc * x * x, 2.0 * kc * x, 2.0 * kc
    return _form(p, k * BLOCK, x)


@_inline
def _even(p, k, x):
    """Shear mode k: psi(|x|), derivative with sign(x)."""
    psi, d1, d2 = _form(p, k * BLOCK, abs(x))
    if x < 0.0:
        d1 = -d1
    elif x == 0.0:
        d1 = 0.0
    return psi, d1, d2


# ----------------------------------------------------------------------------------------------------------------
# Kernels: kinematics
# ----------------------------------------------------------------------------------------------------------------

@_inline
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_inline
def _det(F):
    return (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]) - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
            + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))


@_inline
def _kinematics(F, frame):
    """Fibre kinematics at a point, divisions done once.

    -> a1, a2, a3 (3-tuples a_i = F f_i), (g11, g22, g33, g12, g13, g23) with g_ij = I4ij,
       (q1, q2, q3) with q_i = 1/|a_i|, J = det F, iD = 1/D with D = I41 I42 - I412^2.
    """
    a1, a2, a3 = push(F, frame, 0), push(F, frame, 1), push(F, frame, 2)
    g11, g22, g33 = _dot(a1, a1), _dot(a2, a2), _dot(a3, a3)
    g12, g13, g23 = _dot(a1, a2), _dot(a1, a3), _dot(a2, a3)
    q1, q2, q3 = 1.0 / math.sqrt(g11), 1.0 / math.sqrt(g22), 1.0 / math.sqrt(g33)
    return a1, a2, a3, (g11, g22, g33, g12, g13, g23), (q1, q2, q3), _det(F), 1.0 / (g11 * g22 - g12 * g12)


@_inline
def _invariants(g, q, J, iD):
    """(e1, e2, c, s, t1, t2) from the outputs of _kinematics; J <= 0 (inverted element) gives c = nan."""
    # c = 1/2 ln(I3 / D) with I3 = J^2; the sign test keeps inversion visible to the engine's monitor
    c = 0.5 * math.log(J * J * iD) if J > 0.0 else math.nan
    return (0.5 * math.log(g[0]), 0.5 * math.log(g[1]), c, g[3] * q[0] * q[1], g[4] * q[0] * q[2], g[5] * q[1] * q[2])


# ----------------------------------------------------------------------------------------------------------------
# Kernels: stress, energy, modulus
# ----------------------------------------------------------------------------------------------------------------

_K2A = 2.0 / math.sqrt(3.0)  # max |second variation of a unit vector a/|a||, in units beta^2/|a|^2


@_inline
def _row(P, r, b1, b2, b3, frame):
    """P[r, :] = b1 f1 + b2 f2 + b3 f3 (row r of sum_j B_j x f_j)."""
    for col in range(3):
        P[r, col] = b1 * frame[0, col] + b2 * frame[1, col] + b3 * frame[2, col]


@njit
def point(F, frame, params, state, P):
    """First Piola-Kirchhoff stress into P (3, 3) [MPa]; returns (psi [MPa], m1, m2, m3) with m_i the wave-modulus
    bound [MPa] along the reference fibre direction f_i (see ``_modulus``).

    F (3, 3) deformation gradient, frame (3, 3) rows f1, f2, f3 (reference unit vectors), params (PARAMS.size,).
    Scalars only: no allocation per point. Not inlined at numba level: inlined into ``_element`` it saved a further
    5 % per cycle (fbar 3WEAVE, 10 k elements, 1 thread: 2.68 against 2.82 us per element-cycle) but doubled the
    cold compile of a 3WEAVE deck (81 against 41 s), which every new install and every CI run pays.
    """
    a1, a2, a3, g, q, J, iD = _kinematics(F, frame)
    e1, e2, c, s, t1, t2 = _invariants(g, q, J, iD)
    g11, g22, g12 = g[0], g[1], g[3]
    i11, i22, i33 = q[0] * q[0], q[1] * q[1], q[2] * q[2]  # 1/I4i

    pw, dw, hw = _stretch(params, 0, e1)
    pf, df, hf = _stretch(params, 1, e2)
    pc, dc, hc = _form(params, PARAMS.compaction, c)
    ps, ds, hs = _even(params, 3, s)
    p1, d1, h1 = _even(params, 4, t1)
    p2, d2, h2 = _even(params, 5, t2)

    # S = sum_ij W_ij f_i x f_j + dc C^-1 (2 psi' dI/dC of the table above, written in the fibre frame)
    w11 = dw * i11 - dc * g22 * iD - (ds * s + d1 * t1) * i11
    w22 = df * i22 - dc * g11 * iD - (ds * s + d2 * t2) * i22
    w33 = -(d1 * t1 + d2 * t2) * i33
    w12 = dc * g12 * iD + ds * q[0] * q[1]
    w13 = d1 * q[0] * q[2]
    w23 = d2 * q[1] * q[2]
    # P = sum_j B_j x f_j + dc cof(F) / J, with B_j = sum_i W_ij a_i
    _row(P, 0, w11 * a1[0] + w12 * a2[0] + w13 * a3[0], w12 * a1[0] + w22 * a2[0] + w23 * a3[0],
         w13 * a1[0] + w23 * a2[0] + w33 * a3[0], frame)
    _row(P, 1, w11 * a1[1] + w12 * a2[1] + w13 * a3[1], w12 * a1[1] + w22 * a2[1] + w23 * a3[1],
         w13 * a1[1] + w23 * a2[1] + w33 * a3[1], frame)
    _row(P, 2, w11 * a1[2] + w12 * a2[2] + w13 * a3[2], w12 * a1[2] + w22 * a2[2] + w23 * a3[2],
         w13 * a1[2] + w23 * a2[2] + w33 * a3[2], frame)
    gc = dc / J
    P[0, 0] += gc * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
    P[0, 1] += gc * (F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2])
    P[0, 2] += gc * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
    P[1, 0] += gc * (F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2])
    P[1, 1] += gc * (F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0])
    P[1, 2] += gc * (F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1])
    P[2, 0] += gc * (F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1])
    P[2, 1] += gc * (F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2])
    P[2, 2] += gc * (F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0])

    m1, m2, m3 = _modulus(g, q, J, iD, s, t1, t2, (hw, hf, hc, hs, h1, h2), (dw, df, dc, ds, d1, d2))
    return pw + pf + pc + ps + p1 + p2, m1, m2, m3


@_inline
def _modulus(g, q, J, iD, s, t1, t2, h, d):
    """Directional wave-modulus bounds (m1, m2, m3) [MPa] along the reference fibre directions f1, f2, f3.

    g, q, J, iD from _kinematics; h, d = (psi_k'', psi_k') of the six modes. For a plane wave dF = m x N (unit m,
    N; beta_i = f_i . N) they bound the reference acoustic tensor: m.Q(N).m <= sum_i m_i beta_i^2, so that an
    element can pair each direction's stiffness with its own length along f_i (``hex8.element_dt``).
    d2psi = sum_k psi_k'' (dI_k)^2 + psi_k' d2I_k with dI_k = m . v_k(N). First part: at most
    sum_k max(psi_k'', 0) |v_k|^2 = beta.H.beta with H the fibre-frame 3x3 matrix below (exact per mode), and
    beta.H.beta <= sum_i beta_i^2 (H_ii + sum_j |H_ij|) (Gershgorin rows, from 2|beta_i beta_j| <= beta_i^2 +
    beta_j^2). Second part: sum_k |psi_k'| max|d2I_k|, added to every direction. The largest of the three bounds
    the acoustic tensor over all directions; exact at rest for a single mode, and ~1 % above the true value under
    fibre tension (psi'' >> psi'). Assumes an orthonormal frame (|beta| = 1).
    """
    g11, g22, g33, g12, g13, g23 = g
    i11, i22, i33 = q[0] * q[0], q[1] * q[1], q[2] * q[2]
    q12, q13, q23 = q[0] * q[1], q[0] * q[2], q[1] * q[2]
    # stretch: de_i = a_i . y_i / I4i, |w|^2 = 1 / I4i
    H11 = max(h[0], 0.0) * i11
    H22 = max(h[1], 0.0) * i22
    # shear s = a1^.a2^: |v|^2 = (1 - s^2)(beta1^2/I41 + beta2^2/I42 - 2 s beta1 beta2/sqrt(I41 I42)); same for t1, t2
    ks, k1, k2 = max(h[3], 0.0) * (1.0 - s * s), max(h[4], 0.0) * (1.0 - t1 * t1), max(h[5], 0.0) * (1.0 - t2 * t2)
    H11 += (ks + k1) * i11
    H22 += (ks + k2) * i22
    H33 = (k1 + k2) * i33
    H12 = ks * abs(s) * q12
    H13 = k1 * abs(t1) * q13
    H23 = k2 * abs(t2) * q23
    # compaction c = ln h (h thickness stretch normal to the fibre plane): v = n (beta3 - x1 beta1 - x2 beta2) / h,
    # where a3 = h n + x1 a1 + x2 a2, and 1/h^2 = D / J^2
    x1 = (g22 * g13 - g12 * g23) * iD
    x2 = (g11 * g23 - g12 * g13) * iD
    iJ2 = 1.0 / (J * J)
    D = g11 * g22 - g12 * g12
    kc = max(h[2], 0.0) * iJ2 * D
    H11 += kc * x1 * x1
    H22 += kc * x2 * x2
    H33 += kc
    H12 += kc * abs(x1 * x2)
    H13 += kc * abs(x1)
    H23 += kc * abs(x2)
    # second variations: |d2e_i| <= 1/I4i; |d2 sin(a_i, a_j)| <= K2A max(1/I4i, 1/I4j) + 1/sqrt(I4i I4j);
    # |d2c| <= tr(C^-1) + (I41 + I42)/D (from ln J and ln D); tr(C^-1) = tr(cof G)/det G, det G = J^2
    trcinv = (g22 * g33 - g23 * g23 + g11 * g33 - g13 * g13 + D) * iJ2
    second = (abs(d[0]) * i11 + abs(d[1]) * i22 + abs(d[2]) * (trcinv + (g11 + g22) * iD)
              + abs(d[3]) * (_K2A * max(i11, i22) + q12)
              + abs(d[4]) * (_K2A * max(i11, i33) + q13)
              + abs(d[5]) * (_K2A * max(i22, i33) + q23))
    return H11 + H12 + H13 + second, H22 + H12 + H23 + second, H33 + H13 + H23 + second


@njit
def _element(F, frame, params, state, P, psi, modulus, e):
    """The points of element e (arrays as in ``evaluate``). A serial function of its own: inlined
    straight into the ``prange`` body of ``evaluate_points``, ``point`` trips numba's parfor array analysis (numba 0.68:
    "Dimension mismatch" on its tuple unpacking). Keeps the ``prange`` body free of per-point array views; the
    calls to ``point`` pay their reference counting here, on one thread's own element."""
    for q in range(F.shape[1]):
        psi[e, q], modulus[e, q, 0], modulus[e, q, 1], modulus[e, q, 2] = point(
            F[e, q], frame[e], params[e], state[e, q], P[e, q])


@njit_parallel
def evaluate_points(F, frame, params, state, P, psi, modulus):
    """Array kernel, one point at a time; shapes in ``fdeck.registry.MaterialKind``."""
    for e in prange(F.shape[0]):
        _element(F, frame, params, state, P, psi, modulus, e)


def evaluate(F, frame, params, state, P, psi, modulus) -> None:
    """Array kernel; shapes in ``fdeck.registry.MaterialKind``. A section's parameters (one broadcast row) take
    the block path of ``fabric_hyper_blocks`` (the same bits, packed arithmetic), anything else ``evaluate_points``."""
    if not fabric_hyper_blocks.evaluate(F, frame, params, state, P, psi, modulus):
        evaluate_points(F, frame, params, state, P, psi, modulus)


# ----------------------------------------------------------------------------------------------------------------
# Diagnostics (output frames only)
# ----------------------------------------------------------------------------------------------------------------

DIAGNOSTICS = ("shear_angle", "warp_strain", "weft_strain", "compaction_strain", "transverse_shear_warp",
               "transverse_shear_weft", "warp_x", "warp_y", "warp_z", "weft_x", "weft_y", "weft_z",
               "psi_warp", "psi_weft", "psi_compaction", "psi_in_plane_shear", "psi_transverse_shear_warp",
               "psi_transverse_shear_weft")


@njit
def diagnose(F, frame, params):
    """-> (18,) in DIAGNOSTICS order: angles [deg], strains [-], current unit warp/weft directions, energies [MPa]."""
    a1, a2, _, g, q, J, iD = _kinematics(F, frame)
    e1, e2, c, s, t1, t2 = _invariants(g, q, J, iD)
    out = np.empty(len(DIAGNOSTICS))
    out[0], out[1], out[2], out[3] = math.degrees(math.asin(s)), e1, e2, c
    out[4], out[5] = math.degrees(math.asin(t1)), math.degrees(math.asin(t2))
    for i in range(3):
        out[6 + i] = a1[i] * q[0]
        out[9 + i] = a2[i] * q[1]
    out[12] = _stretch(params, 0, e1)[0]
    out[13] = _stretch(params, 1, e2)[0]
    out[14] = _form(params, PARAMS.compaction, c)[0]
    out[15] = _even(params, 3, s)[0]
    out[16] = _even(params, 4, t1)[0]
    out[17] = _even(params, 5, t2)[0]
    return out


def smallest_acoustic(F: np.ndarray, frame: np.ndarray, params: np.ndarray, directions: np.ndarray,
                      components=(0, 1, 2), h: float = 1e-7) -> np.ndarray:
    """(n,) smallest eigenvalue [MPa] of the reference acoustic tensor Q_ik(N) = dP_iJ/dF_kL N_J N_L over the unit
    directions N (m, 3) at each of the deformation gradients F (n, 3, 3); negative where the law has lost strong
    ellipticity (a plane wave of that direction has no stiffness: bands that the mesh alone resolves).

    dP/dF by central differences of ``point`` (step h; exact to O(h^2) away from the fibres' kink at zero strain).
    ``components`` keeps the polarisations i, k of a constrained model: (0, 2) for a plane-strain slice in x-z,
    whose directions N then lie in that plane. A diagnostic (post-processing, studies), not an engine kernel."""
    state, P, A = np.zeros(0), np.zeros((3, 3)), np.zeros((3, 3, 3, 3))
    keep = np.asarray(components)
    out = np.empty(len(F))
    for e, Fe in enumerate(np.asarray(F, float)):
        for k in range(3):
            for L in range(3):
                dF = np.zeros((3, 3))
                dF[k, L] = h
                point(Fe + dF, frame, params, state, P)
                plus = P.copy()
                point(Fe - dF, frame, params, state, P)
                A[:, :, k, L] = (plus - P) / (2.0 * h)
        Q = np.einsum("iJkL,nJ,nL->nik", A, directions, directions)[:, keep][:, :, keep]
        out[e] = np.linalg.eigvalsh(0.5 * (Q + Q.transpose(0, 2, 1))).min()
    return out


# the block path reads this module's helpers, so it is imported once they exist
from fdeck.physics.materials import fabric_hyper_blocks  # noqa: E402

register_material(MaterialKind("fabric_hyper", pack, evaluate, point, 0, DIAGNOSTICS, diagnose))
