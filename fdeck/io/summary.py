"""Atomic file replacement and the run-summary JSON writer.

``atomic_write_bytes`` is the one place that implements "write a temporary file beside the target, then
``os.replace``": a reader (ParaView, a monitoring script, the next run) sees either the old complete file or the new
complete file, never a half-written one, even if the writing process is killed with SIGKILL. The frame writers use
it for ``.pvd``/``.xdmf`` indexes and VTU frames.

Scope of the guarantee: atomic against the *process* dying. Against power loss the data must also reach the disk;
pass ``fsync=True`` for files where that matters (the summary does, it is written rarely).
"""

from __future__ import annotations

import json
import math
import os
import secrets
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["atomic_write_bytes", "atomic_write_text", "to_jsonable", "write_json_atomic"]


def atomic_write_bytes(path: str | os.PathLike, data: bytes, *, fsync: bool = False) -> None:
    """Replace ``path`` by a file holding ``data``, atomically.

    The temporary file is created in the target's folder (``os.replace`` is only atomic within one file system) with
    a hidden, unique name ``.<name>.<pid>.<random>.tmp``; it is removed if writing fails. A process killed between
    creating and renaming it can leave such a ``.tmp`` file behind; it is never read by anything.
    """
    path = Path(path)
    # O_EXCL + a random suffix: two writers never share a temporary file. Mode 0o666 lets the umask decide the
    # permissions, as a plain open() would (mkstemp would force 0o600).
    tmp = path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            if fsync:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def atomic_write_text(path: str | os.PathLike, text: str, *, fsync: bool = False) -> None:
    """``atomic_write_bytes`` of ``text`` encoded as UTF-8."""
    atomic_write_bytes(path, text.encode("utf-8"), fsync=fsync)


def to_jsonable(obj: Any) -> Any:
    """Convert ``obj`` recursively into plain JSON types.

    numpy scalars -> int/float/bool, numpy arrays -> nested lists, tuples/sets -> lists (sets sorted), Paths -> str,
    mapping keys -> str. Non-finite floats (NaN, +-inf) become ``None``: strict JSON has no spelling for them and a
    summary must load in any JSON reader; the run status says why a value is missing.
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, np.generic):
        return to_jsonable(obj.item())
    if isinstance(obj, int):
        return int(obj)  # also turns IntEnum / bool subclasses into plain ints
    if isinstance(obj, float):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, (set, frozenset)):
        return [to_jsonable(v) for v in sorted(obj)]
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"cannot write {type(obj).__name__} to JSON: {obj!r}")


def write_json_atomic(path: str | os.PathLike, obj: Any, *, fsync: bool = True) -> None:
    """Write ``obj`` as JSON (indent 2, trailing newline) to ``path`` atomically (temporary file + ``os.replace``).

    ``obj`` may hold numpy scalars and arrays (converted by ``to_jsonable``). Keys keep their insertion order.
    """
    text = json.dumps(to_jsonable(obj), indent=2, allow_nan=False, ensure_ascii=False) + "\n"
    atomic_write_text(path, text, fsync=fsync)
