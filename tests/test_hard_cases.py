"""Hard cases of the fabric law stay numerically stable: in-plane shear driven into locking.

Each run must complete without NaN, keep its energy-balance error below 1 % of the largest energy, and keep the
invariants inside their admissible range (s < 1, c > I0_comp).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import ROOT, run_data

pytestmark = [pytest.mark.verification, pytest.mark.slow]


def balance_ratio(h) -> float:
    scale = max(np.abs(h[k]).max() for k in ("kinetic_energy", "internal_energy", "external_work"))
    return float(np.abs(h["energy_balance_error"]).max() / scale)


def test_bias_extension_pulled_past_the_pin_jointed_lock_stays_stable():
    """Requirement: a 3WEAVE bias sample pulled 10 % past the travel at which the pin-jointed net locks (shear angle
    90 deg at d = (sqrt 2 - 1)(H - W)) runs to completion, balanced, with s < 1 everywhere."""
    W, H = 50.0, 100.0
    d_lock = (math.sqrt(2) - 1) * (H - W)
    data = {
        "mesh": {"file": str(ROOT / "tests" / "data" / "bias_w50_n4.inp")},
        "materials": {"f": {"type": "fabric_hyper", "preset": "3weave"}},
        "sections": [{"elements": "ALL", "material": "f", "formulation": "fbar",
                      "orientation": {"warp_angle": 45}}],
        "boundary": [{"type": "fixed", "nodes": "GRIP_LOW"},
                     {"type": "fixed", "nodes": "GRIP_HIGH", "dofs": ["x", "z"]},
                     {"type": "displacement", "nodes": "GRIP_HIGH", "dofs": ["y"], "value": 1.1 * d_lock,
                      "amplitude": "smooth"}],
        "steps": [{"duration": 0.1}],
        "output": {"history_points": 100, "measures": [
            {"type": "element_average", "name": "max_shear", "elements": "ALL", "field": "shear_angle",
             "reduce": "max"}]},
    }
    problem, result, h = run_data(data)
    assert result.status == "completed", result.message
    assert all(np.isfinite(h[c]).all() for c in h)
    # 1 %: the issue's stability requirement
    assert balance_ratio(h) < 0.01
    # admissible range: |s| < 1 means a shear angle below 90 deg in every element, at every history row
    assert h["max_shear"].max() < 90.0
    # the sample did go far into the locking branch (s > I0 = 0.076 means > 4.4 deg; here well beyond 45 deg)
    assert h["max_shear"].max() > 45.0
