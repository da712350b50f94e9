"""The byte and flop accounting of benchmarks/floor.py against closed forms (the floor table rests on it)."""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

COUNT = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
import numpy as np
import floor
from fdeck.physics.elements import hex8

rng = np.random.default_rng(0)
n_qp, n_el = 8, 1
x = floor._counted(rng.uniform(0.0, 1.0, (8, 3)))
conn = np.arange(8).reshape(1, 8)
dN = floor._counted(rng.uniform(-1.0, 1.0, (n_el, n_qp, 8, 3)))
F = floor._counted(np.zeros((n_el, n_qp, 3, 3)))
J = floor._counted(np.zeros((n_el, n_qp)))
kin = floor._count(lambda: hex8.kinematics(x, conn, dN, F, J))
b = floor.compulsory_bytes("full", "linear_elastic", (3, 2, 1))
print(json.dumps({"kinematics": kin, "bytes": b}))
"""


def test_flop_counter_and_compulsory_bytes_match_closed_forms():
    """Requirement: the flop counter of benchmarks/floor.py, run on the real hexahedron kinematics kernel, counts
    exactly the closed-form operations of F = sum_a x_a (x) dN_a at 8 points (8 x 8 x 9 multiply-adds) plus a 3x3
    determinant per point (9 multiplications, 5 additions), and the compulsory bytes of a 3 x 2 x 1 block of `full`
    hexahedra are the reference gradients and point volumes (8 x 8 x 3 + 8 doubles), the int64 connectivity
    (8 x 8 bytes), the stable-step inputs (6 doubles) and 152 bytes per node (x, v, f written and read, inverse mass)
    over 24 nodes / 6 elements. Counts are integers: tolerance zero."""
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    r = subprocess.run([sys.executable, "-c", COUNT, str(ROOT / "benchmarks")], capture_output=True, text=True,
                       env=env, cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    kin = out["kinematics"]
    assert kin["mul"] == 8 * 8 * 9 + 8 * 9
    assert kin["add"] == 8 * 8 * 9 + 8 * 5
    assert kin["div"] == kin["sqrt"] == kin["transcendental"] == 0
    items = out["bytes"]["items"]
    assert items["reference"] == 8 * (8 * 8 * 3 + 8)
    assert items["connectivity"] == 8 * 8
    assert items["stable step"] == 6 * 8
    assert items["frame"] == 0 and items["state"] == 0
    assert abs(items["nodes"] - 152 * 24 / 6) < 1e-12


PASSES = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
import kernel_parts
print(json.dumps(kernel_parts.count_passes("ans_tbar", "linear_elastic")))
"""


def test_pass_counter_sees_the_kernels_scratch_arrays():
    """Requirement: `kernel_parts.py --count` (the README's operation counts of `ans_tbar`) counts arithmetic done
    in a kernel's local scratch arrays. Closed form for the assumed-shear kinematics of one element: at each of the
    8 points two Cholesky factors of a 3 x 3 matrix (C and C~), each 3 square roots and 3 reciprocals of its
    diagonal, and one volume mean of the symmetric modification's upper triangle (6 divisions by the element
    volume): 48 square roots and 8 x 6 + 6 = 54 divisions, no transcendental. Without the scratch counting the
    volume mean's 6 divisions (of sums held in a scratch array by a counted volume) are missed. Counts are
    integers: tolerance zero."""
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    r = subprocess.run([sys.executable, "-c", PASSES, str(ROOT / "benchmarks")], capture_output=True, text=True,
                       env=env, cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    kin = json.loads(r.stdout.strip().splitlines()[-1])["kinematics_ans"]
    assert kin["sqrt"] == 8 * 2 * 3
    assert kin["div"] == 8 * 2 * 3 + 6
    assert kin["transcendental"] == 0
