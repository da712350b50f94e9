"""numba's on-disk cache of fdeck's kernels is keyed on the whole source tree (``fdeck.jit``)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fdeck import jit

pytestmark = pytest.mark.unit
PKG = Path(jit.__file__).resolve().parent


def test_any_source_change_moves_the_cache_folder(tmp_path):
    """Requirement: a change to ANY fdeck source file, not only to the file that defines a kernel, gives another
    cache folder. numba alone invalidates per defining file, so a kernel that calls a changed function of another
    file ran its stale compiled code (a forming deck measured 0.049 on such a cache, 0.096 compiled afresh).
    Reference: the digest of a copy of the tree equals the package's; after a one-character change to a callee
    module (physics/tensor.py, called by the material kernels) it differs; the copy restored gives it back."""
    copy = tmp_path / "fdeck"
    shutil.copytree(PKG, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert jit._source_digest(copy) == jit._source_digest(PKG)
    callee = copy / "physics" / "tensor.py"
    text = callee.read_text()
    callee.write_text(text + "#")
    assert jit._source_digest(copy) != jit._source_digest(PKG)
    callee.write_text(text)
    assert jit._source_digest(copy) == jit._source_digest(PKG)


def test_user_cache_dir_wins(tmp_path):
    """Requirement: NUMBA_CACHE_DIR set by the user is where the kernels go (benchmarks use it for cold starts);
    without it, the folder ends with the source digest."""
    code = "import fdeck.jit, numba; print(numba.config.CACHE_DIR)"
    env = {"NUMBA_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == str(tmp_path)
    env.pop("NUMBA_CACHE_DIR")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert Path(out.stdout.strip()).name == jit._source_digest() and str(tmp_path) in out.stdout
