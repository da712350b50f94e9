"""Generic snapshot of the mutable state an engine object holds (element groups, effects, measures, rotations).

Element kernels and effects keep their history variables (material state, friction springs, a tool's position,
bending curvatures...) as numpy arrays and plain scalars in their attributes. Rather than ask every module for a
state protocol, ``capture`` walks an object's attributes and records:

* every WRITEABLE numpy array (a copy; read-only arrays are constants by construction and skipped),
* every plain scalar (bool, int, float, str, None, numpy scalar) and tuples/lists made only of such scalars,
* recursively, lists, tuples and dicts holding arrays or objects, and objects of fdeck's own classes (an effect's
  tool, a group's material), each object once (the first path that reaches it, as walks are deterministic).

Skipped: pydantic models (the deck's cards), frozen dataclasses (ledger terms), functions, numba dispatchers,
modules, classes and objects of other packages, and the attributes a class names in ``deck_settings``: what it is
given at set-up, not what it evolves: values it reads from the deck per step (an effect's damping coefficient of
each step), rebuilt from the deck a restart runs, which may have added steps (restored, such a list would be the
checkpoint's shorter one), and links the engine binds (damping's selective mass, saved with its own effect). An object may refine this
with ``state()`` / ``load_state(state)``;
``capture`` calls them when present. ``restore`` writes arrays back IN PLACE when shape and dtype match, so views
and references other objects hold (a group bound to the engine's rotations) see the restored values; otherwise it
rebinds the attribute. Constants restored to their own values are harmless, which is what makes the walk safe
without an opt-in list; the price is size (a tool's writeable broad-phase grid is saved with every checkpoint).
"""

from __future__ import annotations

import numpy as np

_SCALARS = (bool, int, float, complex, str, type(None), np.generic)
_ARRAY, _LEAF, _OBJ, _SEQ, _MAP = "a", "s", "o", "l", "d"


def _plain(v) -> bool:
    """A scalar or a (nested) tuple/list of scalars: stored as one value."""
    if isinstance(v, _SCALARS):
        return True
    return isinstance(v, (tuple, list)) and all(_plain(e) for e in v)


def _own_object(v) -> bool:
    cls = type(v)
    return (hasattr(v, "__dict__") and not isinstance(v, type) and cls.__module__.startswith("fdeck.")
            and not hasattr(cls, "model_fields") and not callable(getattr(v, "py_func", None))
            and not getattr(getattr(cls, "__dataclass_params__", None), "frozen", False))


def capture(obj, _seen=None):
    """Nested snapshot of ``obj`` (an fdeck object, list, tuple or dict); None where nothing is mutable."""
    seen = set() if _seen is None else _seen
    if isinstance(obj, np.ndarray):
        return (_ARRAY, obj.copy()) if obj.flags.writeable else None
    if _plain(obj):
        return (_LEAF, obj)
    if isinstance(obj, (list, tuple)):
        items = {i: capture(v, seen) for i, v in enumerate(obj)}
        return (_SEQ, {i: s for i, s in items.items() if s is not None})
    if isinstance(obj, dict):
        items = {k: capture(v, seen) for k, v in obj.items() if _plain(k)}
        return (_MAP, {k: s for k, s in items.items() if s is not None})
    if _own_object(obj):
        if id(obj) in seen:
            return None
        seen.add(id(obj))
        if callable(getattr(obj, "state", None)) and callable(getattr(obj, "load_state", None)):
            return (_OBJ, {"__state__": obj.state()})
        skip = getattr(type(obj), "deck_settings", ())
        attrs = {k: capture(v, seen) for k, v in vars(obj).items() if k not in skip}
        return (_OBJ, {k: s for k, s in attrs.items() if s is not None})
    return None


def _restored_value(live, snap):
    """The value to bind where ``live`` is (None: it was updated in place)."""
    kind, data = snap
    if kind == _ARRAY:
        if isinstance(live, np.ndarray) and live.shape == data.shape and live.dtype == data.dtype \
                and live.flags.writeable:
            live[...] = data
            return None
        return data.copy()
    if kind == _LEAF:
        return data
    restore(live, snap)
    return None


def _same_leaf(live, saved) -> bool:
    """Whether a saved scalar (or tuple of scalars) equals the live one, NaN equal to NaN."""
    if type(live) is not type(saved):
        return False
    if isinstance(live, (tuple, list)):
        return len(live) == len(saved) and all(_same_leaf(a, b) for a, b in zip(live, saved))
    return bool(live == saved) or (live != live and saved != saved)


def restore(obj, snap, _seen=None) -> None:
    """Write the snapshot ``snap`` (from ``capture``) back into the live object ``obj`` of the same structure."""
    if snap is None:
        return
    kind, data = snap
    if kind == _OBJ:
        if "__state__" in data:
            obj.load_state(data["__state__"])
            return
        for name, s in data.items():
            new = _restored_value(getattr(obj, name, None), s)
            if new is not None:
                setattr(obj, name, new)
    elif kind in (_SEQ, _MAP):
        for key, s in data.items():
            live = obj[key] if (kind == _MAP and key in obj) or (kind == _SEQ and key < len(obj)) else None
            new = _restored_value(live, s)
            if new is not None:
                if isinstance(obj, tuple):
                    if s[0] == _LEAF and _same_leaf(live, new):
                        continue  # a constant in a tuple, such as a region's name beside its node indices
                    raise ValueError(f"cannot restore item {key} of a tuple with another value ({new!r:.60})")
                obj[key] = new
    elif kind == _ARRAY:
        obj[...] = data
