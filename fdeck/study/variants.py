"""A study's variants: names, the values each sets, its resolved deck data and that deck's digest.

The digest (SHA-256 of the resolved deck as canonical JSON, plus the bytes of a mesh file it reads) keys the run
cache: a re-run study reuses every variant whose resolved deck it has already run, whatever the variant is called.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import re
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any

from fdeck.study import deck_paths


@dataclass
class Planned:
    """One run to make: a name, the settings applied (path -> value, in order), the resolved deck data, the folder
    of the deck it came from (mesh files are relative to it) and its digest."""

    name: str
    settings: dict[str, Any]
    deck: dict
    base_dir: Path
    digest: str = field(default="")
    solver: dict | None = None  # None: run dynamically; else the static options (``models.Solver``)
    seed: str | None = None  # static: folder of a neighbouring run whose equilibrium starts this one (not in the key)


def _short(value: Any) -> str:
    text = json.dumps(value, separators=(",", ":"))
    return text.strip('"').replace('"', "")


def grid_name(settings: dict[str, Any]) -> str:
    """``{mesh.block.divisions: [40, 1, 4]}`` -> ``divisions=[40,1,4]`` (the last key part of each path that is not
    an index, joined by ','). A file path stands as its stem (``mesh.file: meshes/bias_w100_n6.inp`` ->
    ``file=bias_w100_n6``), and any character outside letters, digits and ``_.=,[]+-`` becomes '_' (braces,
    colons, spaces of a mapping value): the name also names the run's frame series, a file name."""
    out = []
    for path, value in settings.items():
        keys = [p for p in deck_paths.parts(path) if not isinstance(p, int)]
        is_path = isinstance(value, str) and re.search(r"[/\\]", value)
        text = PurePath(re.split(r"[/\\]", value)[-1]).stem if is_path else _short(value)
        out.append(f"{keys[-1] if keys else path}={text}")
    return re.sub(r"[^A-Za-z0-9_.=,\[\]+-]", "_", ",".join(out))


def expand(spec) -> list[tuple[str, dict[str, Any]]]:
    """(name, settings) of every variant: the grid's combinations (first path slowest), then the listed
    variants. Each variant's settings start with the study's common `set`."""
    out = []
    if spec.grid:
        paths = list(spec.grid)
        for combo in itertools.product(*(spec.grid[p] for p in paths)):
            own = dict(zip(paths, combo))
            out.append((grid_name(own), {**spec.set, **own}))
    out += [(v.name, {**spec.set, **v.set}) for v in spec.variants]
    return out


def resolve(base: dict, settings: dict[str, Any]) -> dict:
    """A deep copy of deck data with every setting applied in order."""
    data = copy.deepcopy(base)
    for path, value in settings.items():
        deck_paths.set_value(data, path, value)
    return data


def digest(deck: dict, base_dir: Path) -> str:
    """SHA-256 (hex) of the resolved deck and, when it reads a mesh file, of that file's bytes."""
    h = hashlib.sha256(json.dumps(deck, sort_keys=True, separators=(",", ":"), default=repr).encode())
    mesh_file = (deck.get("mesh") or {}).get("file") if isinstance(deck.get("mesh"), dict) else None
    if isinstance(mesh_file, str) and (base_dir / mesh_file).is_file():
        h.update((base_dir / mesh_file).read_bytes())
    return h.hexdigest()


def plan(name: str, settings: dict[str, Any], base_data: dict, base_dir: Path, solver: dict | None = None) -> Planned:
    """The run of ``settings`` over ``base_data``; a static solve (``solver``: its options) has its own digest."""
    deck = resolve(base_data, settings)
    key = digest(deck, base_dir)
    if solver is not None:
        key = hashlib.sha256((key + json.dumps(solver, sort_keys=True)).encode()).hexdigest()
    return Planned(name, settings, deck, base_dir, key, solver)


def path_problems(filename: str, locs, base_data: dict, where: list[tuple[tuple, dict]]):
    """Located problems for every deck path that does not lead into the base deck, or whose last key is new to it
    and not a key the deck allows there (a misspelt field: did-you-mean from the deck's schema). ``where`` lists
    (location of the settings mapping in the file, settings)."""
    from fdeck.deck.read import located

    problems = []
    for loc, settings in where:
        for path in settings:
            try:
                deck_paths.check_settable(base_data, path)
            except deck_paths.PathError as exc:
                problems.append(located(filename, locs, loc + (path,), str(exc)))
                continue
            try:
                deck_paths.get(base_data, path)
            except deck_paths.PathError:  # a new key: is it one the deck knows?
                message = unknown_key(base_data, path)
                if message:
                    problems.append(located(filename, locs, loc + (path,), f"deck path '{path}': {message}"))
    return problems


def unknown_key(base_data: dict, path: str) -> str | None:
    """The deck schema's message when setting the new last key of ``path`` makes it an unknown key, else None."""
    from pydantic import ValidationError

    from fdeck.deck.errors import problems_from_validation_error
    from fdeck.deck.loader import Locations
    from fdeck.deck.model import Deck

    data = resolve(base_data, {path: 0})
    try:
        Deck.model_validate(data)
    except ValidationError as exc:
        here = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in deck_paths.parts(path)).lstrip(".")
        for prob in problems_from_validation_error(exc, Locations(data=data), "deck", Deck):
            if prob.path == here and prob.message.startswith("unknown key"):
                return prob.message
    return None


def duplicate_names(names: list[str]) -> list[str]:
    return sorted({n for n in names if names.count(n) > 1})
