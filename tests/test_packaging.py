"""Package data: every data file the package reads at run time is declared, so a wheel (non-editable) install
carries it (issue 13: shell presets were missing from the wheel). CI also installs the built wheel and runs decks."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit
ROOT = Path(__file__).resolve().parents[1]


def test_every_yaml_file_under_the_package_is_package_data():
    """Requirement: each .yaml under fdeck/ matches a [tool.setuptools.package-data] pattern of its package."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    missing = []
    for f in sorted((ROOT / "fdeck").rglob("*.yaml")):
        rel = f.relative_to(ROOT)
        ok = False
        for package, patterns in data.items():
            base = ROOT / package.replace(".", "/")
            if base in f.parents and any(f.relative_to(base).match(p) for p in patterns):
                ok = True
        if not ok:
            missing.append(str(rel))
    assert not missing, f"not in package-data: {missing}"
    assert len(list((ROOT / "fdeck").rglob("*.yaml"))) >= 6  # the test sees the presets (3weave ... ts)
