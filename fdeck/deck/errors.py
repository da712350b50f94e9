"""Located deck problems (``file:line:col: path.to.key: message``) and their translation from pydantic errors."""

import ast
import collections.abc as cabc
import difflib
import re
import types
from dataclasses import dataclass
from typing import Annotated, Literal, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from fdeck import registry


@dataclass(frozen=True)
class Problem:
    """One located problem; ``line``/``col`` are 1-based or None when unknown, ``path`` is dotted (``a[0].b``)."""

    file: str
    line: int | None
    col: int | None
    path: str
    message: str
    severity: Literal["error", "warning"] = "error"

    def __str__(self) -> str:
        where = self.file if self.line is None else f"{self.file}:{self.line}:{self.col or 1}"
        text = ("warning: " if self.severity == "warning" else "") + _printable(self.message)
        return f"{where}: {_printable(self.path)}: {text}" if self.path else f"{where}: {text}"


def _printable(text: str) -> str:
    """``text`` with control and other non-printable characters escaped (``\\x1e``, ``\\n``): a key or value
    quoted from the deck must not break the one-line-per-problem format."""
    return text if text.isprintable() else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def format_problems(problems) -> str:
    """One problem per line, sorted by file then position."""
    return "\n".join(str(p) for p in sorted(problems, key=lambda p: (p.file, p.line or 0, p.col or 0)))


class DeckError(Exception):
    """The deck cannot be used; ``problems`` lists every located reason."""

    def __init__(self, problems):
        self.problems = list(problems)
        super().__init__(format_problems(self.problems))


def format_path(path) -> str:
    """``("sections", 0, "material")`` -> ``sections[0].material``."""
    out = ""
    for el in path:
        out += f"[{el}]" if isinstance(el, int) and not isinstance(el, bool) else ("." if out else "") + str(el)
    return out


# --- walking the input data and the pydantic model side by side -----------------------------------------------------


def _clean(loc, data) -> tuple:
    """Keep only loc elements that are keys/indices in the data (drops union tags, validator names, '[key]')."""
    path, node = [], data
    for el in loc:
        if (isinstance(node, dict) and el in node) or (
            isinstance(node, list) and isinstance(el, int) and 0 <= el < len(node)
        ):
            path.append(el)
            node = node[el]
    return tuple(path)


def _is_model(tp) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def _members(tp) -> list:
    """Flatten Annotated/Optional/Union into the list of member types (None dropped)."""
    if get_origin(tp) is Annotated:
        return _members(get_args(tp)[0])
    if get_origin(tp) in (Union, types.UnionType):
        return [m for arg in get_args(tp) for m in _members(arg)]
    return [] if tp is type(None) else [tp]


def _key(name, info) -> str:
    return info.alias or name


def _literal_values(model, key) -> tuple:
    for name, info in model.model_fields.items():
        if _key(name, info) == key and get_origin(info.annotation) is Literal:
            return get_args(info.annotation)
    return ()


def _pick(tp, node):
    """The member of a (tagged) union that ``node`` is meant to be: the model whose Literal field matches the data."""
    members = _members(tp)
    models = [m for m in members if _is_model(m)]
    if isinstance(node, dict):
        for m in models:
            if any(isinstance(k, str) and node[k] in _literal_values(m, k) for k in node):
                return m
    if models and isinstance(node, dict):
        return models[0]
    return members[0] if members else None


def _child(tp, el, node):
    tp = _pick(tp, node)
    if _is_model(tp):
        return next((i.annotation for n, i in tp.model_fields.items() if el in (n, i.alias)), None)
    origin, args = get_origin(tp), get_args(tp)
    if origin in (dict, cabc.Mapping) and len(args) == 2:
        return args[1]
    if origin is tuple and args:
        return args[0] if args[-1] is Ellipsis else (args[el] if isinstance(el, int) and el < len(args) else None)
    if origin in (list, set, frozenset, cabc.Sequence) and args:
        return args[0]
    return None


def _type_at(model_cls, path, data):
    """Annotation expected at ``path`` (a cleaned path) and the data found there."""
    tp, node = model_cls, data
    for el in path:
        tp, node = _child(tp, el, node), node[el]
        if tp is None:
            return None, node
    return tp, node


# --- messages ---------------------------------------------------------------------------------------------------------


def _show(value) -> str:
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _num(x) -> str:
    text = repr(x)
    return text[:-2] if isinstance(x, float) and text.endswith(".0") else text


def unknown_name(what: str, name: str, known) -> str:
    """Message for a name that refers to nothing: "unknown <what> '<name>'" with the closest known name, or the
    list of known names (or 'none')."""
    close = difflib.get_close_matches(name, [str(k) for k in known], n=1)
    hint = f" (did you mean '{close[0]}'?)" if close else f" (known: {', '.join(sorted(map(str, known))) or 'none'})"
    return f"unknown {what} '{name}'{hint}"


def _normal(word: str) -> str:
    return re.sub(r"[\s_\-]", "", str(word)).lower()


def unknown_material(name: str) -> str:
    """Message for an unknown material `type`: a did-you-mean (common spellings and aliases of the named cards
    included), then the named cards with a line each, then the general cards."""
    cards = registry.cards("material")
    spellings = {_normal(n): n for n in cards}
    spellings.update({_normal(a): n for n, e in cards.items() for a in e.aliases})
    guess = spellings.get(_normal(name))
    if guess is None:
        close = difflib.get_close_matches(_normal(name), list(spellings), n=1)
        guess = spellings[close[0]] if close else None
    named = [f"{n} ({e.description.splitlines()[0].rstrip('.')})" for n, e in cards.items() if e.kind]
    general = [n for n, e in cards.items() if not e.kind]
    return (f"unknown type '{name}'" + (f" (did you mean '{guess}'?)" if guess else "")
            + f"; named cards: {'; '.join(named)}; general cards: {', '.join(general)}")


def _suggest(word, choices) -> str:
    choices = [str(c) for c in choices]
    close = difflib.get_close_matches(str(word), choices, n=1)
    if close:
        return f" (did you mean '{close[0]}'?)"
    return f" (allowed: {', '.join(choices)})" if choices else ""


_COMPARE = {"greater_than": (">", "gt"), "greater_than_equal": (">=", "ge"),
            "less_than": ("<", "lt"), "less_than_equal": ("<=", "le")}
_PREFIXES = ("Value error, ", "Assertion failed, ")


def _problem(err, locations, filename, model_cls) -> Problem:
    data, kind, ctx = locations.data, err["type"], err.get("ctx") or {}
    path = _clean(err["loc"], data)
    pos = locations.lookup(path)
    if kind == "extra_forbidden":
        tp, node = _type_at(model_cls, path[:-1], data)
        model = _pick(tp, node) if tp is not None else None
        allowed = [_key(n, i) for n, i in model.model_fields.items()] if _is_model(model) else []
        message = f"unknown key '{path[-1]}'" + _suggest(path[-1], allowed)
        pos = locations.key(path) or pos
    elif kind == "missing":
        message = f"missing required key '{err['loc'][-1]}'"
    elif kind in ("union_tag_invalid", "union_tag_not_found"):
        raw = ctx.get("discriminator", "'type'")  # a quoted field name, or "name()" for a callable discriminator
        disc = raw[:-2] if raw.endswith("()") else ast.literal_eval(raw)
        if kind == "union_tag_invalid":
            tags = ast.literal_eval(ctx["expected_tags"])
            tags = tags if isinstance(tags, tuple) else (tags,)
            message = f"unknown {disc} '{ctx['tag']}'" + _suggest(ctx["tag"], tags)
            if disc == "type" and set(tags) == set(registry.cards("material")):
                message = unknown_material(ctx["tag"])
            if isinstance(node := _type_at(model_cls, path, data)[1], dict) and disc in node:
                path, pos = path + (disc,), locations.lookup(path + (disc,))
        else:
            union, _ = _type_at(model_cls, path, data)
            tags = [v for m in _members(union) if _is_model(m) for v in _literal_values(m, disc)]
            message = f"missing key '{disc}'" + (f" (one of: {', '.join(map(str, tags))})" if tags else "")
    elif kind in _COMPARE:
        op, bound = _COMPARE[kind]
        message = f"must be {op} {_num(ctx[bound])}, got {_show(err['input'])}"
    elif kind == "literal_error":
        expected = re.findall(r"'([^']*)'", str(ctx.get("expected", "")))
        message = f"{err['msg']}, got {_show(err['input'])}" + (_suggest(err["input"], expected)
                                                                  if isinstance(err["input"], str) else "")
    elif err["msg"].startswith(_PREFIXES):
        message = next(err["msg"][len(p):] for p in _PREFIXES if err["msg"].startswith(p))
    else:
        message = f"{err['msg']}, got {_show(err['input'])}"
    line, col = pos if pos else (None, None)
    return Problem(filename, line, col, format_path(path), message)


def problems_from_validation_error(exc: ValidationError, locations, filename: str, model_cls) -> list[Problem]:
    """Translate every pydantic error into a located ``Problem`` (duplicates from smart unions are dropped)."""
    problems: list[Problem] = []
    for err in exc.errors(include_url=False):
        problem = _problem(err, locations, filename, model_cls)
        if problem not in problems:
            problems.append(problem)
    return problems
