"""Static cantilever of hexahedra against Timoshenko's beam, for the locking tests (``test_bending_locking``).

The beam is solved statically (Newton on the element forces, tangent by central differences of the forces of an
"exploded" copy of the mesh, one element per node set, so one force call gives one column of every element
stiffness). The section is a fabric with quadratic energies (small strain: fibre modulus E along x and y, compaction
modulus E, shear moduli G, no Poisson coupling), fibres bimodular when ``ratio`` < 1 (compression modulus ratio E).

Boundary conditions are those under which Timoshenko's beam with the energy-consistent shear coefficient is the exact
plane elasticity solution (Lekhnitskii, Anisotropic plates, 1968, cantilever with end shear; the bimodular section
by the same construction with the shifted neutral axis): at the tip the shear traction tau(z) of the section's
equilibrium, at the root w = 0 on every node and the weighted rotation int E(z) (z - z_n) u dA = 0 (a Lagrange
multiplier: the section can warp) with u = 0 at one node. Then for every E/G the tip deflection is
P L^3 / (3 EI) + P L int tau^2 dA / (G P^2) with no end zone, which an over-constrained root (u = 0 on the whole
face) would add over a decay length ~ h sqrt(E/G) / pi, longer than the beam itself for E/G = 1e5.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.compile.mesh import block
from fdeck.registry import CARDS, FORMULATIONS, MATERIALS

GL_X, GL_W = np.polynomial.legendre.leggauss(5)  # exact for polynomials up to degree 9


def fabric(E: float, G: float, ratio: float):
    """(material kind, packed parameters) of fabric_hyper with quadratic modes: psi = E/2 e^2 per stretch mode and
    compaction, G/2 s^2 per shear mode; fibre compression modulus ratio E."""
    q = lambda K: {"form": "quadratic", "K": K}  # noqa: E731
    card = CARDS["material"]["fabric_hyper"].card(
        type="fabric_hyper", density=1e-9, compression_ratio=ratio, warp=q(E / 2), weft=q(E / 2),
        compaction=q(E / 2), in_plane_shear=q(G / 2), transverse_shear_warp=q(G / 2), transverse_shear_weft=q(G / 2))
    kind = MATERIALS["fabric_hyper"]
    return kind, kind.pack(card)


def make_group(form, X, conn, kind, p):
    """The group the registry builds for formulation ``form``, with material (kind, p) and the global frame."""
    n = len(conn)
    section = SimpleNamespace(formulation=form, hourglass=SimpleNamespace(type="stiffness", coefficient=0.05))
    orientation = SimpleNamespace(frames=lambda: np.broadcast_to(np.eye(3), (n, 3, 3)).copy())
    return FORMULATIONS[form].build("g", section, X, conn, np.arange(1, n + 1), kind, np.broadcast_to(p, (n, len(p))),
                                    orientation, np.full(n, 1e-9), "hexahedron")


class Section:
    """Bimodular rectangular section 0 <= z <= h, width b: neutral axis, EI, shear flow, shear compliance."""

    def __init__(self, E, ratio, G, h, b):
        self.E, self.Ec, self.G, self.h, self.b = E, ratio * E, G, h, b
        # tension below the axis for a downward tip load (hogging moment: top in tension); the compressive side is
        # the bottom: Et (h - zn)^2 = Ec zn^2 balances the axial force
        r = np.sqrt(self.Ec / E)
        self.zn = h / (1.0 + r)
        self.EI = b / 3.0 * (E * (h - self.zn) ** 3 + self.Ec * self.zn ** 3)

    def modulus(self, z):
        return np.where(z > self.zn, self.E, self.Ec)

    def moment_weight(self, z):
        """E(z) (z - z_n) [MPa mm]: the bending stress per unit curvature."""
        return self.modulus(z) * (z - self.zn)

    def first_moment(self, z):
        """F(z) = int_z^h E(z') (z' - z_n) dz' [MPa mm^2], exact; F(0) = F(h) = 0 by the choice of z_n."""
        E, Ec, zn, h = self.E, self.Ec, self.zn, self.h
        above = 0.5 * E * ((h - zn) ** 2 - (z - zn) ** 2)
        below = 0.5 * E * (h - zn) ** 2 - 0.5 * Ec * (zn - z) ** 2
        return np.where(z >= zn, above, below)

    def tau(self, z, V):
        """Shear stress [MPa] of a shear force V [N] (equilibrium of the bending stress): V F(z) / (EI / b)."""
        return V * self.first_moment(z) * self.b / self.EI

    def integrate(self, f, a, c):
        """int_a^c f dz, exact for piecewise polynomials of degree <= 9 with a kink at z_n."""
        pieces = [(a, c)] if not (a < self.zn < c) else [(a, self.zn), (self.zn, c)]
        total = 0.0
        for lo, hi in pieces:
            z = 0.5 * (lo + hi) + 0.5 * (hi - lo) * GL_X
            total += 0.5 * (hi - lo) * np.dot(GL_W, f(z))
        return total

    def shear_compliance(self, V=1.0):
        """1 / (k G A) = int tau^2 dA / (G V^2) [1/N]."""
        return self.b * self.integrate(lambda z: self.tau(z, V) ** 2, 0.0, self.h) / (self.G * V * V)

    def timoshenko(self, P, L):
        """Tip deflection [mm] of a cantilever of length L under a tip shear P."""
        return P * L ** 3 / (3.0 * self.EI) + P * L * self.shear_compliance()

    def consistent(self, f, zs):
        """Nodal values int f(z) N_n(z) dz (times b) of a traction f over the face, piecewise-linear N_n on the
        node heights zs (sorted)."""
        out = np.zeros(len(zs))
        for k in range(len(zs) - 1):
            lo, hi = zs[k], zs[k + 1]
            out[k] += self.integrate(lambda z: f(z) * (hi - z) / (hi - lo), lo, hi)
            out[k + 1] += self.integrate(lambda z: f(z) * (z - lo) / (hi - lo), lo, hi)
        return self.b * out


def cantilever(form, E, G, ratio, slender, h=1.0, nz=4, min_elements=5, strain=1e-5):
    """Static tip deflection of a cantilever of length L = slender h, height h (nz layers), width h (one element,
    y held), elements 2 h long (at least ``min_elements`` along the beam). Returns (w_fe, w_timoshenko) [mm].

    The load gives a largest fibre strain ~ ``strain`` (small: the fabric law's geometric terms are O(strain)).
    """
    L = slender * h
    nx = max(min_elements, int(round(slender / 2)))
    m = block((0, 0, 0), (L, h, h), (nx, 1, nz))
    X, conn = m.X, m.cells["hexahedron"]
    sec = Section(E, ratio, G, h, h)
    P = strain * sec.EI / (L * max(sec.zn, h - sec.zn))
    kind, p = fabric(E, G, ratio)
    n_el = len(conn)
    Xe = X[conn].reshape(-1, 3)
    g = make_group(form, Xe, np.arange(8 * n_el).reshape(-1, 8), kind, p)
    zero = np.zeros_like(Xe)

    def element_forces(xe):
        g.update(xe.reshape(-1, 3), zero)
        return g.fe.reshape(n_el, 24).copy()

    ndof = 3 * len(X)
    rows = (3 * conn[:, :, None] + np.arange(3)).reshape(n_el, 24)
    I, Jc = np.repeat(rows, 24, axis=1).ravel(), np.tile(rows, (1, 24)).ravel()

    def residual_and_tangent(x, step):
        xe = x[conn].reshape(n_el, 24)
        r = np.zeros(ndof)
        np.add.at(r, rows, element_forces(xe))
        Ke = np.empty((n_el, 24, 24))
        for k in range(24):
            xp, xm = xe.copy(), xe.copy()
            xp[:, k] += step
            xm[:, k] -= step
            Ke[:, :, k] = (element_forces(xp) - element_forces(xm)) / (2 * step)
        return r, sp.csr_matrix((Ke.ravel(), (I, Jc)), shape=(ndof, ndof))

    root = np.where(X[:, 0] < 1e-9)[0]
    tip = np.where(np.abs(X[:, 0] - L) < 1e-9)[0]
    fixed = np.zeros((len(X), 3), bool)
    fixed[:, 1] = True
    fixed[root, 2] = True
    fixed[root[np.argmin(np.abs(X[root, 2] - sec.zn))], 0] = True
    free = np.where(~fixed.ravel())[0]
    # root weighted-rotation constraint and tip load: consistent nodal values over the faces (the faces are one
    # element wide, two node columns in y, each carrying half)
    c = np.zeros(ndof)
    f_ext = np.zeros(ndof)
    for nodes, vec, fun, comp in ((root, c, sec.moment_weight, 0), (tip, f_ext, lambda z: -sec.tau(z, P), 2)):
        zs = np.unique(X[nodes, 2])
        vals = sec.consistent(fun, zs)
        for n in nodes:
            vec[3 * n + comp] += 0.5 * vals[np.searchsorted(zs, X[n, 2])]
    cf = c[free][:, None]
    x, lam = X.copy(), 0.0
    for _ in range(40):
        r, K = residual_and_tangent(x, 1e-6 * strain * h)
        res = r - f_ext + c * lam
        u = (x - X).ravel()
        A = sp.bmat([[K[free][:, free], sp.csr_matrix(cf)], [sp.csr_matrix(cf.T), None]]).tocsc()
        d = spl.spsolve(A, -np.concatenate([res[free], [c @ u]]))
        du = np.zeros(ndof)
        du[free] = d[:-1]
        x = x + du.reshape(-1, 3)
        lam += d[-1]
        if np.abs(du).max() < 1e-7 * np.abs(x - X).max():  # 1e-7 of the deflection: far below 3 %
            break
    zs = np.unique(X[tip, 2])
    weights = sec.consistent(lambda z: np.ones_like(z), zs) / (sec.b * h)  # area weights per height, sum 1
    w = -sum(0.5 * weights[np.searchsorted(zs, X[n, 2])] * (x[n, 2] - X[n, 2]) for n in tip)
    return w, sec.timoshenko(P, L)
