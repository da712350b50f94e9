"""Deck loading: YAML -> data with line numbers, and pydantic errors -> located, engineer-readable problems."""

from textwrap import dedent
from typing import Annotated, Literal, Union

import pytest
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from fdeck.deck.errors import DeckError, Problem, format_problems, problems_from_validation_error
from fdeck.deck.loader import load_file, load_yaml

pytestmark = pytest.mark.unit


# Small stand-ins for the real Deck: nested models, a dict of tagged-union cards, a list of models.
class _Card(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Elastic(_Card):
    type: Literal["linear_elastic"]
    density: float = Field(gt=0)
    young: float = Field(gt=0)


class NeoHookean(_Card):
    type: Literal["neo_hookean"]
    density: float = Field(gt=0)
    shear: float = Field(gt=0)


class Section(_Card):
    material: str
    thickness: float = Field(gt=0)


class Control(_Card):
    end_time: float = Field(gt=0)
    output_every: int = 1


class Deck(_Card):
    control: Control
    materials: dict[str, Annotated[Union[Elastic, NeoHookean], Field(discriminator="type")]]
    sections: list[Section] = []


GOOD = """\
control:
  end_time: 0.01
materials:
  steel:
    type: linear_elastic
    density: 7.85e-9
    young: 210000
sections:
  - material: steel
    thickness: 1.5
"""


def problems(text: str) -> list[str]:
    """Load ``text``, validate it against ``Deck`` and return the formatted problems."""
    data, locs = load_yaml(dedent(text), "deck.yaml")
    with pytest.raises(ValidationError) as info:
        Deck.model_validate(data)
    return [str(p) for p in problems_from_validation_error(info.value, locs, "deck.yaml", Deck)]


def yaml_error(text: str) -> list[str]:
    with pytest.raises(DeckError) as info:
        load_yaml(dedent(text), "deck.yaml")
    return [str(p) for p in info.value.problems]


# --- loader --------------------------------------------------------------------------------------------------------


def test_good_deck_validates():
    """A correct deck loads and validates without problems."""
    data, _ = load_yaml(GOOD, "deck.yaml")
    assert Deck.model_validate(data).materials["steel"].density == 7.85e-9


def test_scientific_notation_is_float():
    """1e-9, 2E5, -3.5e+2 and 1.0e5 are floats (PyYAML's YAML 1.1 resolver would leave them strings)."""
    data, _ = load_yaml("a: 1e-9\nb: 2E5\nc: -3.5e+2\nd: 1.0e5\ne: .5e3\nf: 12\ng: e5\nh: 1e\n", "d.yaml")
    assert data == {"a": 1e-9, "b": 2e5, "c": -350.0, "d": 1e5, "e": 500.0, "f": 12, "g": "e5", "h": "1e"}
    assert all(isinstance(data[k], float) for k in "abcde") and isinstance(data["f"], int)


def test_only_true_false_are_booleans():
    """YAML 1.2 booleans: yes/no/on/off stay strings, true/false (any case) are bools; dates stay strings."""
    data, _ = load_yaml("a: yes\nb: off\nc: true\nd: FALSE\ne: 2024-01-01\nf: ~\n", "d.yaml")
    assert data == {"a": "yes", "b": "off", "c": True, "d": False, "e": "2024-01-01", "f": None}


def test_locations_of_keys_and_values():
    """Values and keys are located 1-based; lookup falls back to the deepest existing ancestor."""
    _, locs = load_yaml(GOOD, "deck.yaml")
    assert locs.lookup(("materials", "steel", "density")) == (6, 14)
    assert locs.key(("materials", "steel", "density")) == (6, 5)
    assert locs.lookup(("sections", 0, "material")) == (9, 15)
    assert locs.lookup(("sections", 0)) == (9, 5)
    assert locs.lookup(("materials", "steel", "shear")) == (5, 5)  # missing key -> the steel mapping
    assert locs.lookup(("nowhere",)) == (1, 1)


def test_merge_keys_can_be_overridden():
    """A '<<' merge is not a duplicate: explicit keys override merged ones, also when the mapping is aliased again."""
    text = "base: &b {density: 1.0, young: 2.0}\nsteel: &s\n  <<: *b\n  young: 3.0\ncopper: *s\n"
    data, _ = load_yaml(text, "d.yaml")
    assert data["steel"] == data["copper"] == {"density": 1.0, "young": 3.0}


def test_duplicate_key_names_both_lines():
    """A key given twice in one mapping is an error at the second, naming the line of the first."""
    text = """\
    materials:
      steel:
        density: 7.85e-9
        young: 1
        density: 7.9e-9
    """
    assert yaml_error(text) == [
        "deck.yaml:5:5: materials.steel.density: duplicate key 'density' (first defined at line 3)"
    ]


def test_yaml_syntax_error_is_located():
    """A YAML syntax error is a located DeckError, not a traceback."""
    text = """\
    control:
      end_time: 0.01
     materials: {}
    """
    (message,) = yaml_error(text)
    assert message.startswith("deck.yaml:3:")
    assert "YAML syntax error" in message


def test_unclosed_flow_mapping_is_located():
    """An unclosed bracket is reported with the line where the parser gave up and where the bracket opened."""
    (message,) = yaml_error("a: 1\nb: {c: 2\n")
    assert message.startswith("deck.yaml:3:1: YAML syntax error:")
    assert "at line 2" in message


def test_missing_file():
    """A missing file is a DeckError without line or column."""
    with pytest.raises(DeckError) as info:
        load_file("/nonexistent/deck.yaml")
    assert str(info.value).startswith("/nonexistent/deck.yaml: cannot read deck:")


def test_load_file_reads_and_locates(tmp_path):
    """load_file reports problems under the file's path."""
    path = tmp_path / "deck.yaml"
    path.write_text("a: 1\na: 2\n")
    with pytest.raises(DeckError) as info:
        load_file(path)
    assert str(info.value) == f"{path}:2:1: a: duplicate key 'a' (first defined at line 1)"


# --- validation errors ------------------------------------------------------------------------------------------------


def test_unknown_key_did_you_mean_points_at_key():
    """An unknown key inside a tagged-union card gets a did-you-mean and the key's own line:col."""
    assert problems(GOOD.replace("density:", "densty:")) == [
        "deck.yaml:5:5: materials.steel: missing required key 'density'",
        "deck.yaml:6:5: materials.steel.densty: unknown key 'densty' (did you mean 'density'?)",
    ]


def test_unknown_key_lists_allowed_keys():
    """With no close match, the allowed keys are listed."""
    assert problems(GOOD.replace("  end_time: 0.01", "  end_time: 0.01\n  colour: red")) == [
        "deck.yaml:3:3: control.colour: unknown key 'colour' (allowed: end_time, output_every)"
    ]


def test_bad_value_type():
    """A value of the wrong type names the expected type and what was given."""
    assert problems(GOOD.replace("thickness: 1.5", "thickness: thick")) == [
        "deck.yaml:10:16: sections[0].thickness: Input should be a valid number, "
        "unable to parse string as a number, got 'thick'"
    ]


def test_constraint_violation_shows_value():
    """A bound (gt=0) violation states the bound and the received value, at the value's position."""
    assert problems(GOOD.replace("young: 210000", "young: -1.0")) == [
        "deck.yaml:7:12: materials.steel.young: must be > 0, got -1.0"
    ]


def test_missing_required_key_points_at_parent():
    """A missing key is reported on the parent mapping."""
    assert problems(GOOD.replace("  end_time: 0.01", "  output_every: 5")) == [
        "deck.yaml:2:3: control: missing required key 'end_time'"
    ]


def test_unknown_union_tag_did_you_mean():
    """An unknown card type points at the 'type' value and suggests the closest registered type."""
    assert problems(GOOD.replace("linear_elastic", "linear_elastc")) == [
        "deck.yaml:5:11: materials.steel.type: unknown type 'linear_elastc' (did you mean 'linear_elastic'?)"
    ]


def test_missing_union_tag_lists_types():
    """A card without 'type' lists the allowed types."""
    assert problems(GOOD.replace("    type: linear_elastic\n", "")) == [
        "deck.yaml:5:5: materials.steel: missing key 'type' (one of: linear_elastic, neo_hookean)"
    ]


def test_three_mistakes_three_problems():
    """Three seeded mistakes in one deck (bound, typo'd key, wrong type) give three problems on three lines."""
    text = (
        GOOD.replace("end_time: 0.01", "end_time: 0\n  output_evry: 10")
        .replace("thickness: 1.5", "thickness: [1.5]")
    )
    assert problems(text) == [
        "deck.yaml:2:13: control.end_time: must be > 0, got 0",
        "deck.yaml:3:3: control.output_evry: unknown key 'output_evry' (did you mean 'output_every'?)",
        "deck.yaml:11:16: sections[0].thickness: Input should be a valid number, got a list",
    ]


def test_unknown_key_in_card_lists_that_cards_keys():
    """Allowed keys come from the card type named in the data (neo_hookean here), not from another union member."""
    text = GOOD.replace("linear_elastic", "neo_hookean").replace("young: 210000", "shear: 80000\n    nu: 0.3")
    assert problems(text) == ["deck.yaml:8:5: materials.steel.nu: unknown key 'nu' (allowed: type, density, shear)"]


# --- formatting -------------------------------------------------------------------------------------------------------


def test_problem_formatting_and_sorting():
    """Unknown positions are omitted, warnings are marked, and problems sort by file then line."""
    found = [
        Problem("b.yaml", 3, 1, "x", "late"),
        Problem("a.yaml", 9, 2, "sections[1].material", "unknown material 'stel'"),
        Problem("a.yaml", None, None, "", "cannot read deck"),
        Problem("a.yaml", 2, 7, "control", "deprecated", severity="warning"),
    ]
    assert format_problems(found).splitlines() == [
        "a.yaml: cannot read deck",
        "a.yaml:2:7: control: warning: deprecated",
        "a.yaml:9:2: sections[1].material: unknown material 'stel'",
        "b.yaml:3:1: x: late",
    ]
