"""YAML text -> plain Python data plus a source map (``Locations``) of every key and value.

Scalars follow YAML 1.2 where YAML 1.1 surprises engineers:

* only ``true``/``false`` (any case: True, TRUE) are booleans; ``yes``/``no``/``on``/``off`` stay strings;
* scientific notation is a float with or without a dot or an exponent sign: ``1e-9``, ``2E5``, ``-3.5e+2``;
* dates are not converted (``2024-01-01`` stays a string).

YAML 1.1 integers are unchanged (``012`` is octal, ``1:30`` is sexagesimal). Duplicate keys are errors; merge keys
(``<<: *anchor``) work and explicit keys override merged ones. The pure-Python ``SafeLoader`` is used on purpose:
its marks and messages are the same on every platform.
"""

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from fdeck.deck.errors import DeckError, Problem, format_path

Pos = tuple[int, int]  # (line, col), 1-based

_BOOL, _FLOAT, _TIMESTAMP = "tag:yaml.org,2002:bool", "tag:yaml.org,2002:float", "tag:yaml.org,2002:timestamp"


class _Loader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 booleans, dot-less scientific floats and no timestamps."""

    def __init__(self, stream):
        super().__init__(stream)
        self.own_keys = {}  # id(mapping node) -> ids of its explicit key nodes, noted before '<<' merging


_Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_BOOL, _TIMESTAMP)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(_BOOL, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))
_Loader.add_implicit_resolver(
    _FLOAT, re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"), list("-+.0123456789")
)


@dataclass
class Locations:
    """Where each value and each key of a loaded document sits; paths are tuples like
    ``("sections", 0, "material")``."""

    values: dict[tuple, Pos] = field(default_factory=dict)
    keys: dict[tuple, Pos] = field(default_factory=dict)
    data: Any = None  # the loaded document, so errors can be mapped back onto it

    def lookup(self, path) -> Pos | None:
        """Position of the value at ``path``, else of its deepest existing ancestor (e.g. the parent mapping)."""
        path = tuple(path)
        for n in range(len(path), -1, -1):
            if path[:n] in self.values:
                return self.values[path[:n]]
        return None

    def key(self, path) -> Pos | None:
        """Position of the key that names ``path`` (None for list items and the root)."""
        return self.keys.get(tuple(path))


def _pos(mark) -> Pos:
    return mark.line + 1, mark.column + 1


MAX_DECK_BYTES = 16 * 2**20  # a deck is text of some kilobytes; a bigger file is a mistake (a mesh named as deck)
MAX_VALUES = 1_000_000  # values after expanding aliases: stops a "billion laughs" document (aliases of aliases)


class _TooBig(Exception):
    def __init__(self, pos):
        self.pos = pos


def _expanded_size(node, memo) -> int:
    """Number of values ``node`` becomes once every alias is expanded, counted on the node graph (each distinct
    node once: cheap even when the expansion is astronomical); a recursive alias counts 1 (``_build`` reports it)."""
    key = id(node)
    if key in memo:
        return memo[key]
    memo[key] = 1
    if isinstance(node, yaml.SequenceNode):
        memo[key] = 1 + sum(_expanded_size(n, memo) for n in node.value)
    elif isinstance(node, yaml.MappingNode):
        memo[key] = 1 + sum(_expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value)
    return memo[key]


def _build(loader, node, path, locs, problems, filename, stack=frozenset()):
    if len(locs.values) >= MAX_VALUES:
        raise _TooBig(_pos(node.start_mark))
    locs.values[path] = _pos(node.start_mark)
    if isinstance(node, yaml.ScalarNode):
        return loader.construct_object(node)
    if id(node) in stack:
        problems.append(Problem(filename, *_pos(node.start_mark), format_path(path), "recursive alias is not allowed"))
        return None
    stack = stack | {id(node)}
    if isinstance(node, yaml.SequenceNode):
        return [_build(loader, item, path + (i,), locs, problems, filename, stack) for i, item in enumerate(node.value)]
    own = loader.own_keys.setdefault(id(node), {id(k) for k, _ in node.value})
    loader.flatten_mapping(node)  # resolves '<<' merge keys; merged entries come first
    out, explicit = {}, {}
    for knode, vnode in node.value:
        kpos = _pos(knode.start_mark)
        if not isinstance(knode, yaml.ScalarNode):
            problems.append(Problem(filename, *kpos, format_path(path), "mapping keys must be plain scalars"))
            continue
        key = loader.construct_object(knode)
        if key in explicit and id(knode) in own:
            first = explicit[key][0]
            message = f"duplicate key '{key}' (first defined at line {first})"
            problems.append(Problem(filename, *kpos, format_path(path + (key,)), message))
            continue
        if id(knode) in own:
            explicit[key] = kpos
        locs.keys[path + (key,)] = kpos
        out[key] = _build(loader, vnode, path + (key,), locs, problems, filename, stack)
    return out


def load_yaml(text: str, filename: str) -> tuple[Any, Locations]:
    """Parse one YAML document into plain data and its ``Locations``; raise ``DeckError`` on any YAML problem."""
    locs, problems = Locations(values={(): (1, 1)}), []
    loader = None
    try:
        loader = _Loader(text)
        node = loader.get_single_node()
        if node is not None and _expanded_size(node, {}) > MAX_VALUES:
            raise _TooBig(_pos(node.start_mark))
        locs.data = None if node is None else _build(loader, node, (), locs, problems, filename)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        syntax = isinstance(exc, (yaml.scanner.ScannerError, yaml.parser.ParserError))
        message = f"YAML {'syntax error' if syntax else 'error'}: {exc.problem or exc.context}"
        if exc.context and exc.problem and exc.context_mark:
            message += f" ({exc.context} at line {exc.context_mark.line + 1})"
        line, col = _pos(mark) if mark else (1, 1)
        raise DeckError([Problem(filename, line, col, "", message)]) from None
    except yaml.reader.ReaderError as exc:  # a character YAML does not allow (control characters, NUL)
        line, col = _offset_pos(text, exc.position)
        raise DeckError([Problem(filename, line, col, "", f"YAML error: character {exc.character!r} is not "
                                 "allowed in YAML text")]) from None
    except yaml.YAMLError as exc:
        raise DeckError([Problem(filename, 1, 1, "", f"YAML error: {exc}")]) from None
    except _TooBig as exc:
        raise DeckError([Problem(filename, *exc.pos, "", f"the document expands to more than {MAX_VALUES} "
                                 "values (aliases of aliases?)")]) from None
    except RecursionError:
        raise DeckError([Problem(filename, 1, 1, "", "the document is nested too deeply")]) from None
    finally:
        if loader is not None:
            loader.dispose()
    if problems:
        raise DeckError(problems)
    return locs.data, locs


def _offset_pos(text, offset: int) -> Pos:
    """(line, col), 1-based, of character (or byte) ``offset`` of ``text`` (a str or bytes)."""
    nl = "\n" if isinstance(text, str) else b"\n"
    offset = max(0, min(int(offset), len(text)))
    return text.count(nl, 0, offset) + 1, offset - (text.rfind(nl, 0, offset) + 1) + 1


def load_file(path) -> tuple[Any, Locations]:
    """Read ``path`` (UTF-8) and ``load_yaml`` it. An unreadable file is a ``DeckError`` without a location (there
    is no text to point into), bytes that are not UTF-8 one at their line and column, a file over
    ``MAX_DECK_BYTES`` one at 1:1."""
    name = str(path)
    try:
        size = Path(path).stat().st_size
        if size > MAX_DECK_BYTES:
            raise DeckError([Problem(name, 1, 1, "", f"deck file is {size / 2**20:.1f} MiB, above the "
                                     f"{MAX_DECK_BYTES // 2**20} MiB a deck may have (is it a mesh file?)")])
        data = Path(path).read_bytes()
    except OSError as exc:
        raise DeckError([Problem(name, None, None, "", f"cannot read deck: {exc.strerror or exc}")]) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _offset_pos(data, exc.start)
        raise DeckError([Problem(name, line, col, "", f"deck is not UTF-8 text: byte {data[exc.start]:#04x} "
                                 f"({exc.reason})")]) from None
    return load_yaml(text, name)
