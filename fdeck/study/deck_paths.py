"""Read and set a value in a deck's plain data by its path: ``sections.0.formulation``, ``mesh.block.divisions``.

A path is dot-separated; a part made of digits indexes a list, any other part is a mapping key. Setting may create
the last key of a mapping (``steps.0.mass_scaling: {factor: 4}``), nothing above it (a misspelt key on the way is
an error, not a new mapping) and never list items. Whether the value makes sense is left to the deck's validation.
"""

from __future__ import annotations

import copy
from typing import Any


class PathError(ValueError):
    """A deck path that does not lead anywhere in the deck; the message says where it stops."""


def parts(path: str) -> tuple:
    """``"sections.0.formulation"`` -> ``("sections", 0, "formulation")``."""
    if not path or any(p == "" for p in path.split(".")):
        raise PathError(f"deck path '{path}' has an empty part")
    return tuple(int(p) if p.isdigit() else p for p in path.split("."))


def _step(node: Any, part, path: str, done: tuple):
    where = ".".join(map(str, done)) or "the deck"
    if isinstance(part, int):
        if not isinstance(node, list):
            raise PathError(f"deck path '{path}': {where} is not a list, so '{part}' cannot index it")
        if not 0 <= part < len(node):
            raise PathError(f"deck path '{path}': {where} has {len(node)} items, no item {part}")
        return node[part]
    if not isinstance(node, dict):
        raise PathError(f"deck path '{path}': {where} is not a mapping, so it has no key '{part}'")
    if part not in node:
        raise PathError(f"deck path '{path}': {where} has no key '{part}' (keys: {', '.join(map(str, node))})")
    return node[part]


def get(data: Any, path: str) -> Any:
    """The value at ``path``; PathError when the path leaves the data."""
    node, done = data, ()
    for part in parts(path):
        node = _step(node, part, path, done)
        done += (part,)
    return node


def check_settable(data: Any, path: str) -> None:
    """Raise PathError unless ``set_value`` can set ``path`` in ``data`` (everything above the last key must
    exist)."""
    set_value(copy.deepcopy(data), path, None)


def set_value(data: Any, path: str, value: Any) -> None:
    """Set ``path`` to (a deep copy of) ``value`` in place."""
    keys = parts(path)
    node, done = data, ()
    for part in keys[:-1]:
        node = _step(node, part, path, done)
        done += (part,)
    last = keys[-1]
    if isinstance(last, int):
        _step(node, last, path, done)
    elif not isinstance(node, dict):
        _step(node, last, path, done)  # raises: not a mapping
    node[last] = copy.deepcopy(value)
