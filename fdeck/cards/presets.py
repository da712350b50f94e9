"""Named parameter sets (presets) shipped as YAML files beside the cards that read them.

A preset is a file ``<folder>/<name>.yaml`` holding some of a card's fields; the deck names it with ``preset:``
and may override any of its keys. Adding a preset is adding a file: no code.
"""

from __future__ import annotations

import yaml


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
