"""Named parameter sets (presets) shipped as YAML files beside the cards that read them.

A preset is a file ``<folder>/<name>.yaml`` holding some of a card's fields; the deck names it with ``preset:``
and may override any of its keys. Adding a preset is adding a file: no code.
"""

from __future__ import annotations

from typing import Callable, ClassVar

import yaml
from pydantic import model_validator

from fdeck.deck.base import MaterialCard


def names(folder) -> list[str]:
    """Preset names (file stems) in ``folder`` (an importlib.resources Traversable or a Path)."""
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def load(folder, name: str, allowed, what: str) -> dict:
    """Fields of preset ``name`` (a fresh dict). Unknown name, or a key outside ``allowed`` -> ValueError naming
    ``what`` (the card the preset belongs to)."""
    known = names(folder)
    if name not in known:
        raise ValueError(f"unknown preset {name!r} ({what}); available presets: {', '.join(known)}")
    data = yaml.safe_load(folder.joinpath(f"{name}.yaml").read_text()) or {}
    bad = sorted(set(data) - set(allowed))
    if bad:
        raise ValueError(f"preset {name!r} has keys {bad} that are not {what} fields {sorted(allowed)}")
    return data


def merged(data, load_preset):
    """Card data laid over the preset it names (deck keys win; keys given as null fall back to the preset), or the
    data unchanged when it names none. For a pydantic ``model_validator(mode="before")``."""
    if not isinstance(data, dict) or data.get("preset") is None:
        return data
    out = load_preset(data["preset"])
    out.update({k: v for k, v in data.items() if v is not None})
    return out


class PresetMaterial(MaterialCard):
    """A material card whose fields a named preset may give: deck keys are laid over the preset (``merged``), then
    every field of ``required`` must be known. ``default_preset`` is the preset a named card (``3weave``, ``sm``)
    uses when the deck names none; ``hint`` ends the message for missing fields."""

    preset_loader: ClassVar[Callable[[str], dict]]
    required: ClassVar[tuple[str, ...]]
    default_preset: ClassVar[str | None] = None
    hint: ClassVar[str] = ""

    @model_validator(mode="before")
    @classmethod
    def _merge_preset(cls, data):
        if isinstance(data, dict) and cls.default_preset and data.get("preset") is None:
            data = {**data, "preset": cls.default_preset}
        return merged(data, cls.preset_loader)

    @model_validator(mode="after")
    def _complete(self):
        missing = [k for k in self.required if getattr(self, k) is None]
        if missing:
            raise ValueError(f"{self.type}: {', '.join(missing)} not defined by the deck or a preset{self.hint}")
        return self
