"""Runs are bitwise identical whatever the number of threads (fixed-order gather, no atomics)."""

from __future__ import annotations

import pytest

from helpers import digests_on_one_and_two_threads

pytestmark = pytest.mark.unit

SCRIPT = """
import hashlib, sys, numba
from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import solver
solver.SERIAL_BELOW = 0  # use every thread even on this small model
d = Deck.model_validate({
    "mesh": {"block": {"size": [20, 20, 4], "divisions": [20, 20, 4]}},
    "materials": {"m": {"type": "neo_hookean", "density": 1e-9, "youngs_modulus": 100.0, "poisson_ratio": 0.4}},
    "sections": [{"material": "m", "formulation": sys.argv[1]}],
    "boundary": [{"type": "fixed", "nodes": "zmin"},
                 {"type": "velocity", "nodes": "zmax", "dofs": ["x", "z"], "value": -500.0}],
    "steps": [{"duration": 1.0, "max_cycles": 60}], "output": {"history_points": 2}})
p = compile_deck(d)
r = solver.run(p, solver.Sink())
print(numba.get_num_threads(), hashlib.sha256(r.final_positions.tobytes()).hexdigest())
"""


@pytest.mark.parametrize("form", ["fbar", "reduced", "ans", "ans_tbar", "ans_fbar"])
def test_results_identical_on_one_and_two_threads(form):
    """Requirement: final positions are bitwise equal with NUMBA_NUM_THREADS=1 and 2."""
    assert len(digests_on_one_and_two_threads(SCRIPT, form)) == 1
