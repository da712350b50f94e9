"""In-plane fabric law for shells and membranes, LS-DYNA MAT 249 style but hyperelastic (MODELS.md section 5).

Two fibre families (warp m1, weft m2: unit vectors of the reference fibre frame, rows 0 and 1 of ``frame``) follow
the deformation: a_i = F m_i. The energy per reference volume [MPa = mJ/mm^3] is

    psi = psi_1(E_1) + psi_2(E_2) + Phi(gamma)

* E_i = (a_i . a_i - 1) / 2, the Green-Lagrange strain along fibre i; psi_i(E) = integral_0^E f_i, with f_i the
  fibre's stress-strain load curve: a piecewise-linear table for E >= 0 (``tension``) and another for E <= 0
  (``compression``), so compression can be made as asymmetric as the thick-shell model of [J] needs. Beyond its last
  point a table continues with its last slope. f_i is the second Piola-Kirchhoff stress along the fibre, so
  S = f_1 m1 x m1 + f_2 m2 x m2 and sigma = (1/J) f F (m x m) F^T, MODELS 5's fibre term.
  Kinks are rounded so that f is C1: each interior kink over +-5 % of its shorter segment (the stress equals the
  table outside; see ``_curve``) and the tension/compression junction over |E| < JUNCTION = 1e-10 (both curves
  are then shifted by -3/16 (k_t - k_c) JUNCTION, 1e-7 MPa for the presets, so that f(0) = 0; a wider band
  would shift the soft compressive curve of t300_3k_ts enough to change its bending). Central differences on a
  spring whose stiffness switches abruptly have instability tongues well below the critical step (a 100:1
  tension/compression switch grows from any start at 0.9 of it, tests/test_fabric_membrane.py; three-point
  bending coupons of the presets blew up within 0.1 s); with rounded kinks the round-off noise meets a smooth
  spring and stays small. Only noise below JUNCTION, though: an undamped oscillation that crosses E = 0 with a
  larger amplitude sees a sharp 100:1 switch, whose tongues reach down to ~0.3 of the critical step (a scan in
  steps of 0.0025; 0.41 and 0.465 grow, 0.25 and below do not), and a free t300_3k strip spinning at 100 rad/s,
  whose rigid motion alone stirs fibre strains of (Omega dt)^2 / 2 ~ 3e-9 per cycle, blows up at dt_safety 0.9
  although the step estimate is below the exact critical step in every state it passes
  (tests/test_fabric_membrane_step.py). A wider band cannot cure it: its stress shift would change the bending of
  t300_3k_ts, and an oscillation larger than the band again sees the switch.
* gamma = asin(s) - asin(m1 . m2), s = a_1 . a_2 / (|a_1| |a_2|): the in-plane shear angle between the current
  fibres [rad] (positive when they close). Phi'(gamma) = tau(gamma), the shear stress-shear angle curve of the card
  (table in degrees, odd in gamma) up to the locking angle, then tau(gamma_lock) + G_lock (|gamma| - gamma_lock):
  the second, stiff modulus beyond locking.

Stress: S = 2 dpsi/dC = sum_ij W_ij m_i x m_j and P = F S = sum_ij W_ij a_i x m_j with
W_11 = f_1 - tau s / (I_1 c), W_22 = f_2 - tau s / (I_2 c), W_12 = W_21 = tau / (c sqrt(I_1 I_2)), where
c = sqrt(1 - s^2) = cos(gamma + gamma_0) and I_i = a_i . a_i. S has no component along the frame's third row (the
sheet normal): the law is plane stress and carries no through-thickness energy, so a shell may give F any third
column (fdeck's shells give the unit normal).

Where this differs from LS-DYNA's *MAT_REINFORCED_THERMOPLASTIC (MAT 249; LS-DYNA Keyword User's Manual, Vol. II),
to our reading of that manual:
  1. Hyperelastic: stresses are derivatives of one stored energy, so fdeck's energy ledger closes on it; the LS-DYNA
     law's fibre and fibre-interaction stresses are evaluated from the current state as written in MODELS 5, without a
     guarantee that a stored energy exists. The shear term here therefore carries, besides the symmetric
     m1 x m2 + m2 x m1 part that MODELS 5 writes with g(gamma), fibre-direction parts (-tau s/(I_i c) m_i x m_i) that
     make it the exact derivative of Phi; they vanish at gamma = 0.
  2. Measures: the curves are read as second Piola-Kirchhoff fibre stress against Green-Lagrange fibre strain, and as
     tau = dPhi/dgamma per reference volume against the angle between the current fibres. A curve measured as
     engineering stress against engineering strain converts exactly (S = P / lambda, E = ((1 + e)^2 - 1) / 2);
     tau relates to the bias-extension shear stress of MODELS 6.1 by sigma_12 = tau / cos(gamma).
  3. No matrix, no plasticity, no rate or temperature dependence: MAT 249 was written for thermoplastic prepregs
     with a matrix law beside the fibres; a dry fabric has none.
  4. Two families at any initial angle (the frame's warp and weft rows); MAT 249 takes up to eight.

Stable-step moduli: along fibre i, max(k_i I_i + |f_i| + shear terms, f_i'(0+)), with k_i the slope of the
segment holding E_i or, within 10 % of the segment's length from one of its ends, the larger of it and the
neighbour's slope there, so that a fibre straddling a kink (the end of the toe, where the tangent grows 5x in the
presets) is integrated with its stiffer side's step (a precaution: the rounding above is what cured the measured
blow-up); and never below the tensile tangent at rest, because a fabric entirely in compression (a buckled sheet)
would otherwise get a step sized for its soft compressive curve and become unstable the cycle its fibres go back
into tension. The shear slope likewise includes the locking modulus within 10 % of the locking angle. The third
modulus (along the normal) holds only the second-variation terms that act in every direction.

Presets (``presets/fabric_membrane/*.yaml``, selected by ``preset:``; deck values override them key by key):
    t300_3k     plain-weave carbon T300-3K, 0.23 mm, curves for the shell-membrane hybrid (``sm``) of [J]
    t300_3k_ts  the same fabric for the thick shell (``ts``): compressive curve made asymmetric to fit bending
Both hold REPRESENTATIVE curves, not published numbers ([J] publishes curves, not values); each file says where its
numbers come from.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from fdeck.jit import FLAGS, njit, njit_parallel, prange
from fdeck.physics.layout import layout
from fdeck.physics.tensor import push
from fdeck.registry import MaterialKind, register_material
from fdeck.cards.fabric_membrane import MAX_POINTS, FabricMembrane


CURVE = 1 + 5 * MAX_POINTS
"""A packed curve: [n, x_0..x_15, y_0..y_15, energy at x_0..x_15, rounding half-width at x_0..x_15, energy shift
of the rounding accumulated up to and including x_0..x_15] (see ``_curve``)."""

PARAMS = layout(warp_tension=CURVE, warp_compression=CURVE, weft_tension=CURVE, weft_compression=CURVE, shear=CURVE,
                locking=4, floor=2)
"""The packed parameters: four fibre curves, the tau(gamma) shear curve in radians, the locking data (gamma_lock,
tau_lock, Phi_lock, G_lock) and, at ``floor + i``, the tensile tangent at rest of family i (the stable-step floor)."""

_inline = numba.njit(inline="always", **FLAGS)

JUNCTION = 1e-10
"""Half-width [-] of the strain band over which the tension and compression tangents are blended at E = 0."""

ROUND = 0.05
"""Half-width of the rounding of a curve's interior kinks, as a fraction of the shorter adjacent segment."""

NEAR = 0.1
"""Fraction of a curve segment, at each end, within which the stable step also takes the neighbouring slope."""




# ----------------------------------------------------------------------------------------------------------------
# Packing
# ----------------------------------------------------------------------------------------------------------------

def _pack_curve(p: np.ndarray, o: int, pts, rounded: bool = True) -> None:
    """Curve at p[o:o+CURVE]: n, abscissae, ordinates, the energy integral_0^x_k f of the piecewise-linear curve at
    every point, and (``rounded``) the half-width d_k = ROUND min(adjacent lengths) of the rounding of each interior
    kink with the energy shift it leaves beyond it, 0.1 (s_k - s_(k-1)) d_k^2, accumulated from the first kink."""
    x = np.array([q[0] for q in pts], float)
    y = np.array([q[1] for q in pts], float)
    n = len(x)
    energy = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(x))])
    width, shift = np.zeros(n), np.zeros(n)
    if rounded and n > 2:
        length = np.abs(np.diff(x))
        slope = np.diff(y) / np.diff(x)
        width[1:-1] = ROUND * np.minimum(length[:-1], length[1:])
        shift[1:-1] = 0.1 * (slope[1:] - slope[:-1]) * width[1:-1] ** 2
    p[o] = n
    for i, arr in enumerate((x, y, energy, width, np.cumsum(shift))):
        p[o + 1 + i * MAX_POINTS:o + 1 + i * MAX_POINTS + n] = arr


def pack(card: FabricMembrane) -> np.ndarray:
    """-> (PARAMS.size,): four fibre curves, the shear curve in radians with its locking data, the step floors."""
    p = np.zeros(PARAMS.size)
    _pack_curve(p, PARAMS.warp_tension, card.warp.tension)
    _pack_curve(p, PARAMS.warp_compression, card.warp.compression)
    _pack_curve(p, PARAMS.weft_tension, card.weft.tension)
    _pack_curve(p, PARAMS.weft_compression, card.weft.compression)
    sh = card.shear
    _pack_curve(p, PARAMS.shear, [(math.radians(g), t) for g, t in sh.curve], rounded=False)
    g_lock = math.radians(sh.locking_angle)
    tau, phi, _, _ = _curve(p, PARAMS.shear, g_lock)
    p[PARAMS.locking:PARAMS.locking + 4] = [g_lock, tau, phi, sh.locking_modulus]
    for i, c in enumerate((card.warp.tension, card.weft.tension)):
        p[PARAMS.floor + i] = c[1][1] / c[1][0]
    return p


# ----------------------------------------------------------------------------------------------------------------
# Kernels
# ----------------------------------------------------------------------------------------------------------------

@_inline
def _slope(p, xs, ys, k):
    return (p[ys + k + 1] - p[ys + k]) / (p[xs + k + 1] - p[xs + k])


@_inline
def _curve(p, o, x):
    """(f(x), integral_0^x f, f'(x), step slope) of the curve packed at p[o]; x on the curve's side of 0.

    The curve is the piecewise-linear table with every interior kink x_k rounded over |x - x_k| < d_k: there the
    tangent goes from the left slope a to the right slope b as a + (b - a) S(u), S(u) = 3u^2 - 2u^3,
    u = (x - x_k + d_k) / (2 d_k), so f is C1 and equals the table outside the bands (the symmetric S integrates
    to the table's chord); the energy beyond a band is the table's plus 0.1 (b - a) d_k^2. Why: an explicit step
    near its limit turns a spring whose stiffness switches abruptly into a growing oscillation (central
    differences on a bilinear spring have instability tongues from about 0.55 of the critical step; measured in
    tests/test_fabric_membrane.py), while noise about a rounded kink sees a smooth, linear-looking spring.

    The step slope is the largest |slope| of the segment holding x and, within NEAR of a segment's length from one
    of its ends, of the neighbour beyond that end, so that a fibre straddling a kink is integrated with the step
    of its stiffer side.
    """
    n = int(p[o])
    xs, ys, es = o + 1, o + 1 + MAX_POINTS, o + 1 + 2 * MAX_POINTS
    ds, cs = o + 1 + 3 * MAX_POINTS, o + 1 + 4 * MAX_POINTS
    k = 0
    if p[xs + 1] > 0.0:  # increasing abscissae (tension, shear)
        while k + 2 < n and x > p[xs + k + 1]:
            k += 1
    else:  # decreasing abscissae (compression)
        while k + 2 < n and x < p[xs + k + 1]:
            k += 1
    slope = _slope(p, xs, ys, k)
    step = abs(slope)
    h = x - p[xs + k]
    length = p[xs + k + 1] - p[xs + k]
    u = h / length  # position in the segment, 0..1 (beyond 1 on the extrapolated last segment)
    if k > 0 and u < NEAR:
        step = max(step, abs(_slope(p, xs, ys, k - 1)))
    if k + 2 < n and u > 1.0 - NEAR:
        step = max(step, abs(_slope(p, xs, ys, k + 1)))
    # the kink nearest to x: node k (start of the segment) or node k + 1 (its end)
    j = k if abs(h) <= abs(x - p[xs + k + 1]) else k + 1
    d = p[ds + j] if 0 < j < n - 1 else 0.0
    s = x - p[xs + j]
    if d > 0.0 and abs(s) < d:
        # a, b: slopes left and right of the kink in increasing x (for a compression curve, walked towards
        # decreasing x, the segment beyond the kink lies on the left)
        increasing = p[xs + 1] > 0.0
        a, b = _slope(p, xs, ys, j - 1), _slope(p, xs, ys, j)
        if not increasing:
            a, b = b, a
        v = 0.5 * (s + d) / d
        s1 = v * v * v * (1.0 - 0.5 * v)
        s2 = v * v * v * v * (0.25 - 0.1 * v)
        y = p[ys + j]
        f = y + a * s + 2.0 * d * (b - a) * s1
        psi = p[es + j] + p[cs + j - 1] + y * s + 0.5 * a * s * s + 4.0 * d * d * (b - a) * s2
        if not increasing:
            psi -= 0.1 * (b - a) * d * d
        return f, psi, a + (b - a) * v * v * (3.0 - 2.0 * v), step
    return p[ys + k] + slope * h, p[es + k] + p[cs + k] + p[ys + k] * h + 0.5 * slope * h * h, slope, step


@_inline
def _fibre(p, tension, compression, e):
    """(f, psi, f', step slope) of one family at Green-Lagrange strain e (see ``_curve``), with the junction of
    the tension and compression curves rounded over |e| < JUNCTION (see the module docstring)."""
    d = JUNCTION
    kt = p[tension + 2 + MAX_POINTS] / p[tension + 2]  # first slopes: y_1 / x_1 of each curve
    kc = p[compression + 2 + MAX_POINTS] / p[compression + 2]
    dk = kt - kc
    off = 0.1875 * dk * d  # both curves are shifted down by this beyond the band (f(0) = 0)
    if e >= d:
        f, psi, k, step = _curve(p, tension, e)
        return f - off, psi - off * e + 0.05 * dk * d * d, k, step
    if e <= -d:
        f, psi, k, step = _curve(p, compression, e)
        return f - off, psi - off * e - 0.05 * dk * d * d, k, step
    u = 0.5 * (e + d) / d
    s1 = u * u * u * (1.0 - 0.5 * u)
    s2 = u * u * u * u * (0.25 - 0.1 * u)
    # f(0) = 0 and psi(0) = 0 exactly: 2 s1(1/2) = 0.1875 and s2(1/2) = 0.0125
    return (kc * e + dk * d * (2.0 * s1 - 0.1875), 0.5 * kc * e * e + dk * d * (4.0 * d * (s2 - 0.0125) - 0.1875 * e),
            kc + dk * u * u * (3.0 - 2.0 * u), max(kt, kc))


@_inline
def _shear(p, g):
    """(tau, Phi, dtau/dgamma, step slope) at shear angle g [rad]: the curve up to the locking angle, then the
    locking modulus; odd tau, even Phi. The step slope includes the locking modulus within NEAR of the locking
    angle (the lock is the stiffest kink a shear wave meets)."""
    a = abs(g)
    o = PARAMS.locking
    if a <= p[o]:
        tau, phi, k, step = _curve(p, PARAMS.shear, a)
        if a > (1.0 - NEAR) * p[o]:
            step = max(step, p[o + 3])
    else:
        k = p[o + 3]
        step = k
        h = a - p[o]
        tau, phi = p[o + 1] + k * h, p[o + 2] + p[o + 1] * h + 0.5 * k * h * h
    if g < 0.0:
        tau = -tau
    return tau, phi, k, step


@_inline
def _kinematics(F, frame):
    """-> a1, a2 (3-tuples), I1, I2, I12, s, c = sqrt(1 - s^2), gamma [rad]."""
    a1, a2 = push(F, frame, 0), push(F, frame, 1)
    i1 = a1[0] * a1[0] + a1[1] * a1[1] + a1[2] * a1[2]
    i2 = a2[0] * a2[0] + a2[1] * a2[1] + a2[2] * a2[2]
    i12 = a1[0] * a2[0] + a1[1] * a2[1] + a1[2] * a2[2]
    s = i12 / math.sqrt(i1 * i2)
    s0 = frame[0, 0] * frame[1, 0] + frame[0, 1] * frame[1, 1] + frame[0, 2] * frame[1, 2]
    c = math.sqrt(max(1.0 - s * s, 0.0))
    return a1, a2, i1, i2, i12, s, c, math.asin(s) - math.asin(s0)


@njit
def point(F, frame, params, state, P):
    """First Piola-Kirchhoff stress into P (3, 3) [MPa]; returns (psi [MPa], m1, m2, m3): wave-modulus bounds [MPa]
    along warp, weft and the normal (see the module docstring). F (3, 3), frame (3, 3) rows warp, weft, normal.

    For a plane wave dF = m x N (unit m, N; beta_i = m_i . N) the second variation is at most
    sum_i (f_i' I_i + |f_i|) beta_i^2 + tau' (dgamma)^2 + |tau| |d2gamma|, with (dgamma)^2 <= (1 + |s|)(beta_1^2/I_1 +
    beta_2^2/I_2) and |d2gamma| <= ((2/sqrt 3) max(1/I_i) + 1/sqrt(I_1 I_2)) / c + |s| (1 + |s|) max(1/I_i) / c^2.
    """
    a1, a2, i1, i2, i12, s, c, g = _kinematics(F, frame)
    f1, p1, _, k1 = _fibre(params, PARAMS.warp_tension, PARAMS.warp_compression, 0.5 * (i1 - 1.0))
    f2, p2, _, k2 = _fibre(params, PARAMS.weft_tension, PARAMS.weft_compression, 0.5 * (i2 - 1.0))
    tau, phi, _, kt = _shear(params, g)
    r = 1.0 / math.sqrt(i1 * i2)
    t = tau / c  # dPhi/ds
    w11 = f1 - t * s / i1
    w22 = f2 - t * s / i2
    w12 = t * r
    for row in range(3):
        b1 = w11 * a1[row] + w12 * a2[row]
        b2 = w12 * a1[row] + w22 * a2[row]
        for col in range(3):
            P[row, col] = b1 * frame[0, col] + b2 * frame[1, col]
    m1, m2, second = _moduli(i1, i2, s, c, r, f1, k1, f2, k2, tau, kt, params[PARAMS.floor],
                             params[PARAMS.floor + 1])
    return p1 + p2 + phi, m1, m2, second


@_inline
def _moduli(i1, i2, s, c, r, f1, k1, f2, k2, tau, kt, floor1, floor2):
    """The stable-step moduli (m1, m2, second) of ``point`` (its docstring), with the step slopes k1, k2, kt (largest
    of the neighbouring segments, see ``_curve``) and the families' floors; r = 1/sqrt(I1 I2)."""
    inv_max = max(1.0 / i1, 1.0 / i2)
    kk = max(kt, 0.0) * (1.0 + abs(s))
    second = abs(tau) * ((1.1547005383792517 * inv_max + r) / c + abs(s) * (1.0 + abs(s)) * inv_max / (c * c))
    m1 = max(max(k1, 0.0) * i1 + abs(f1) + kk / i1 + second, floor1)
    m2 = max(max(k2, 0.0) * i2 + abs(f2) + kk / i2 + second, floor2)
    return m1, m2, second


@njit_parallel
def evaluate_points(F, frame, params, state, P, psi, modulus):
    """Array kernel, one point at a time; shapes in ``fdeck.registry.MaterialKind``."""
    for e in prange(F.shape[0]):
        for q in range(F.shape[1]):
            psi[e, q], modulus[e, q, 0], modulus[e, q, 1], modulus[e, q, 2] = point(
                F[e, q], frame[e], params[e], state[e, q], P[e, q])


def evaluate(F, frame, params, state, P, psi, modulus) -> None:
    """Array kernel; shapes in ``fdeck.registry.MaterialKind``. A section's parameters (one broadcast row) take
    the block path of ``fabric_membrane_blocks`` (the same bits, packed arithmetic), anything else
    ``evaluate_points``."""
    if not fabric_membrane_blocks.evaluate(F, frame, params, state, P, psi, modulus):
        evaluate_points(F, frame, params, state, P, psi, modulus)


DIAGNOSTICS = ("shear_angle", "warp_strain", "weft_strain", "warp_x", "warp_y", "warp_z", "weft_x", "weft_y",
               "weft_z", "psi_warp", "psi_weft", "psi_in_plane_shear", "warp_stress", "weft_stress", "shear_stress")


@njit
def diagnose(F, frame, params):
    """-> (15,) in DIAGNOSTICS order: shear angle [deg], Green-Lagrange fibre strains [-], current unit fibre
    directions, energies [MPa], fibre stresses f_i [MPa] and tau [MPa]."""
    a1, a2, i1, i2, i12, s, c, g = _kinematics(F, frame)
    f1, p1, _, _ = _fibre(params, PARAMS.warp_tension, PARAMS.warp_compression, 0.5 * (i1 - 1.0))
    f2, p2, _, _ = _fibre(params, PARAMS.weft_tension, PARAMS.weft_compression, 0.5 * (i2 - 1.0))
    tau, phi, _, _ = _shear(params, g)
    out = np.empty(len(DIAGNOSTICS))
    out[0], out[1], out[2] = math.degrees(g), 0.5 * (i1 - 1.0), 0.5 * (i2 - 1.0)
    q1, q2 = 1.0 / math.sqrt(i1), 1.0 / math.sqrt(i2)
    for i in range(3):
        out[3 + i] = a1[i] * q1
        out[6 + i] = a2[i] * q2
    out[9], out[10], out[11], out[12], out[13], out[14] = p1, p2, phi, f1, f2, tau
    return out


# the block path reads this module's helpers, so it is imported once they exist
from fdeck.physics.materials import fabric_membrane_blocks  # noqa: E402

register_material(MaterialKind("fabric_membrane", pack, evaluate, point, 0, DIAGNOSTICS, diagnose,
                               plane_stress=True))
