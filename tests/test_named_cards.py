"""Named material cards (issue 12): `interlock`, `3weave`, `sm`, `ts` are their general card with a preset, with the
same packed parameters and bitwise the same runs; messages for unknown types and contradicting sections."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck import registry
from fdeck.deck.errors import DeckError
from fdeck.deck.read import read_deck

from helpers import DECKS, deck_data, run_data

pytestmark = pytest.mark.unit


@pytest.mark.parametrize("named, general, preset", [("interlock", "fabric_hyper", "interlock"),
                                                    ("3weave", "fabric_hyper", "3weave"),
                                                    ("sm", "fabric_membrane", "t300_3k"),
                                                    ("ts", "fabric_membrane", "t300_3k_ts")])
def test_a_named_card_packs_exactly_as_its_general_card_with_the_preset(named, general, preset):
    """Requirement: same kernel kind, same packed parameters (bitwise), and a key given in the deck overrides the
    preset in both spellings alike."""
    cards = registry.cards("material")
    assert cards[named].runs_on == general
    kind = registry.MATERIALS[general]
    short = cards[named].card(type=named)
    long = cards[general].card(type=general, preset=preset)
    assert np.array_equal(kind.pack(short), kind.pack(long))
    assert short.density == long.density
    light = cards[named].card(type=named, density=1e-10)
    assert light.density == 1e-10 and np.array_equal(kind.pack(light), kind.pack(long))


def digest(data, base):
    problem, result, h = run_data(data, base)
    assert result.status == "completed", result.message
    return hashlib.sha256(result.final_positions.tobytes() + np.array(result.history).tobytes()).hexdigest()


def test_short_and_long_hexahedral_cards_run_bitwise_alike():
    """Requirement: the 3 mm interlock three-point bending regression deck (written with `type: interlock`) gives
    bitwise the same positions and history as with `{type: fabric_hyper, preset: interlock}` (150 cycles)."""
    data = deck_data("regression/three_point_bending_3mm/deck.yaml")
    data["steps"][0]["max_cycles"] = 150
    (name,) = data["materials"]
    assert data["materials"][name]["type"] == "interlock"
    long = {**data, "materials": {name: {"type": "fabric_hyper", "preset": "interlock"}}}
    base = DECKS / "regression" / "three_point_bending_3mm"
    assert digest(data, base) == digest(long, base)


def test_short_and_long_shell_cards_run_bitwise_alike():
    """Requirement: `{type: sm}` with a section that names only its material runs bitwise like the long form
    (`fabric_membrane` + preset t300_3k, section `formulation: sm, preset: t300_3k`) on the coarse sm bending
    regression deck (150 cycles)."""
    data = deck_data("regression/shell_bending_sm_4mm/deck.yaml")
    data["steps"][0]["max_cycles"] = 150
    (name,) = data["materials"]
    (sec,) = data["sections"]
    assert data["materials"][name] == {"type": "fabric_membrane", "preset": "t300_3k"}
    assert sec["formulation"] == "sm" and sec["preset"] == "t300_3k"
    short_sec = {k: v for k, v in sec.items() if k not in ("formulation", "preset")}
    short = {**data, "materials": {name: {"type": "sm"}}, "sections": [short_sec]}
    base = DECKS / "regression" / "shell_bending_sm_4mm"
    assert digest(short, base) == digest(data, base)


DECK = """mesh:
  plate: {{size: [20, 20], element_size: 4.0}}
materials:
  cloth: {{type: {type}}}
sections:
  - {{material: cloth{section}}}
steps:
  - {{duration: 0.01}}
"""


def problems_of(text, tmp_path):
    path = tmp_path / "d.yaml"
    path.write_text(text)
    with pytest.raises(DeckError) as info:
        read_deck(path)
    return info.value.problems


@pytest.mark.parametrize("spelling, card", [("3WEAVE", "3weave"), ("three_weave", "3weave"), ("S-M", "sm"),
                                            ("shell_membrane", "sm"), ("thick_shell", "ts"), ("TS", "ts"),
                                            ("Interlock", "interlock")])
def test_common_spellings_are_mapped_to_the_named_card(spelling, card, tmp_path):
    """Requirement: an unknown type names the intended card, then lists the named cards (with a line each) before
    the general ones, located at the `type` key."""
    problems = problems_of(DECK.format(type=spelling, section=""), tmp_path)
    (p,) = problems
    assert (p.line, p.col) == (4, 17) and p.path == "materials.cloth.type"
    assert f"unknown type '{spelling}' (did you mean '{card}'?)" in p.message
    named = p.message.index("named cards: interlock (")
    assert named < p.message.index("general cards: linear_elastic")
    for name in ("3weave (", "sm (", "ts ("):
        assert p.message.index(name) > named


def test_a_section_contradicting_its_named_material_is_a_located_error(tmp_path):
    """Requirement: a section that says `formulation: ts` for an `sm` material is an error naming both places."""
    problems = problems_of(DECK.format(type="sm", section=", formulation: ts, preset: t300_3k"), tmp_path)
    (p,) = problems
    assert p.path == "sections[0].formulation" and p.line == 6
    assert "materials.cloth.type 'sm' implies formulation 'sm'" in p.message and "'ts'" in p.message
