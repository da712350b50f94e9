"""Measures recorded in history and summary: each against a closed form."""

from __future__ import annotations

import numpy as np
import pytest

import fdeck.physics  # noqa: F401
from fdeck.compile.mesh import block
from fdeck.cards.measures import SurfaceWaviness
from fdeck.physics.measures import surface_waviness

pytestmark = pytest.mark.unit


def _measure(X, nodes):
    card = SurfaceWaviness(type="surface_waviness", name="w", nodes="top")
    win, s = surface_waviness.windows(X, nodes, 0, 2)
    return surface_waviness.Measure(card, win, s)


def test_surface_waviness_is_zero_on_a_smooth_bend_and_48_35_A_on_a_zigzag():
    """Requirement: the spurious-mode indicator ignores smooth bending and reads a zig-zag's amplitude."""
    m = block((0, 0, 0), (60, 6, 3), (20, 2, 1))
    top = m.node_sets["zmax"]
    meas = _measure(m.X, top)
    R = 40.0  # bend the block onto a cylinder of radius R about the y axis
    x = m.X.copy()
    x[:, 0] = (R - m.X[:, 2]) * np.sin(m.X[:, 0] / R)
    x[:, 2] = R - (R - m.X[:, 2]) * np.cos(m.X[:, 0] / R)
    smooth = meas.evaluate(x, None)[0]
    # local quadratic fit error of a circle ~ h^4 / R^3 = 81 / 64000 ~ 1e-3 mm, against a 40 mm deflection
    assert smooth < 2e-3
    A = 0.05
    zig = x.copy()
    ix = np.round(m.X[:, 0] / 3.0).astype(int)
    zig[:, 2] += A * (-1.0) ** ix
    # exact for a uniform line: 48/35 A from the smoothing weights, plus the tiny smooth-bend residual
    assert meas.evaluate(zig, None)[0] == pytest.approx(48 / 35 * A, abs=2e-3)
