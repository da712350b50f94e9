"""The stages import in one direction: deck -> compile -> engine -> io (ARCHITECTURE.md), checked on real imports:
each check runs a fresh interpreter that blocks or watches modules, so a lazy or indirect import counts too."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit
ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "fdeck"

BLOCK = """
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in {blocked!r}:
            raise ImportError("blocked by the architecture test: " + name)
sys.meta_path.insert(0, Block())
"""


def run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)


def test_the_deck_stage_reads_and_validates_decks_without_numpy_or_numba():
    """Requirement: with numpy and numba unimportable, the deck model imports and every card family (hexahedral
    fabric, shells with presets, boundary, loads, measures, section add-ons) validates from a shipped deck file."""
    decks = ["decks/coupons/bending_sm_0.yaml", "decks/regression/bias_extension_3weave/deck.yaml",
             "decks/three_point_bending/fbar_bending_3mm.yaml", "decks/cantilever.yaml"]
    code = BLOCK.format(blocked=("numpy", "numba")) + f"""
import fdeck.deck.model
from fdeck.deck.read import read_deck
for path in {decks!r}:
    read_deck(path)
print(sorted(m for m in sys.modules if m.split(".")[0] in ("numpy", "numba")))
"""
    r = run(code)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_the_engine_and_io_load_neither_pydantic_nor_yaml():
    """Requirement: importing every engine and io module pulls in no pydantic, yaml or deck module."""
    modules = [f"fdeck.engine.{p.stem}" for p in (PKG / "engine").glob("*.py") if p.stem != "__init__"]
    modules += [f"fdeck.io.{p.stem}" for p in (PKG / "io").glob("*.py") if p.stem != "__init__"]
    code = BLOCK.format(blocked=("pydantic", "yaml")) + f"""
import importlib
for m in {modules!r}:
    importlib.import_module(m)
print(sorted(m for m in sys.modules if m.startswith(("fdeck.deck", "fdeck.cards", "fdeck.compile"))))
"""
    r = run(code)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_io_loads_no_engine_or_compile():
    """Requirement: the writers are sinks: importing fdeck.io loads nothing of the engine, compile or deck stages."""
    modules = [f"fdeck.io.{p.stem}" for p in (PKG / "io").glob("*.py") if p.stem != "__init__"]
    code = f"""
import importlib, sys
for m in {modules!r}:
    importlib.import_module(m)
print(sorted(m for m in sys.modules if m.startswith(("fdeck.engine", "fdeck.compile", "fdeck.deck", "fdeck.physics"))))
"""
    r = run(code)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_every_card_has_its_kernel_side_and_every_kernel_its_card():
    """Requirement: the card tables (deck side) and the kind tables (kernel side) name the same plug-ins (a named
    material card, e.g. `3weave`, runs on the kind of its general card)."""
    import fdeck.physics  # noqa: F401
    from fdeck import registry

    cards = registry.cards("material")
    assert {e.runs_on for e in cards.values()} == set(registry.MATERIALS)  # named cards run on a general kind
    assert all(e.kind in ("", *registry.MATERIALS) for e in cards.values())
    assert set(registry.CARDS["effect"]) == set(registry.EFFECTS)
    assert set(registry.CARDS["measure"]) == set(registry.MEASURES)
    assert set(registry.CARDS["formulation"]) == set(registry.FORMULATIONS)


def test_no_code_branches_on_card_type_outside_plugins():
    """Nowhere outside the plug-ins does code compare a card's `type` to a literal."""
    offenders = []
    for f in PKG.rglob("*.py"):
        if "physics" in f.parts or "cards" in f.parts:
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Compare) and isinstance(node.left, ast.Attribute) and node.left.attr == "type":
                if any(isinstance(c, ast.Constant) and isinstance(c.value, str) for c in node.comparators):
                    offenders.append(f"{f.name}:{node.lineno}")
    assert not offenders, offenders


def test_no_empty_packages():
    """Requirement: every package folder holds a module besides its __init__ (no placeholder packages)."""
    empty = [str(d.relative_to(ROOT)) for d in PKG.rglob("__init__.py")
             if not [p for p in d.parent.glob("*.py") if p.name != "__init__.py"]
             and not [p for p in d.parent.iterdir() if p.is_dir() and (p / "__init__.py").exists()]]
    assert not empty, empty
