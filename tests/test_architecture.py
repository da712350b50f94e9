"""The stages import in one direction: deck -> compile -> engine -> io (ARCHITECTURE.md)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit
PKG = Path(__file__).resolve().parents[1] / "fdeck"


def imports(folder: str) -> set[tuple[str, str]]:
    out = set()
    for f in (PKG / folder).rglob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Import):
                out |= {(f.name, a.name) for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module:
                out |= {(f.name, node.module)}
    return out


def test_deck_imports_neither_numpy_nor_numba():
    bad = [(f, m) for f, m in imports("deck") if m.split(".")[0] in ("numpy", "numba")]
    assert not bad, bad


def test_engine_imports_no_pydantic_yaml_or_io():
    bad = [(f, m) for f, m in imports("engine") if m.split(".")[0] in ("pydantic", "yaml")
           or m.startswith(("fdeck.io", "fdeck.deck"))]
    assert not bad, bad


def test_io_imports_no_engine_compile_or_deck():
    bad = [(f, m) for f, m in imports("io") if m.startswith(("fdeck.engine", "fdeck.compile", "fdeck.deck"))]
    assert not bad, bad


def test_no_code_branches_on_card_type_outside_plugins():
    """Nowhere outside the registry's plug-ins does code compare a card's `type` to a literal."""
    offenders = []
    for f in PKG.rglob("*.py"):
        if "physics" in f.parts:
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Compare) and isinstance(node.left, ast.Attribute) and node.left.attr == "type":
                if any(isinstance(c, ast.Constant) and isinstance(c.value, str) for c in node.comparators):
                    offenders.append(f"{f.name}:{node.lineno}")
    assert not offenders, offenders
