"""Checkpoint files: the whole state of a run, written atomically, verified on reading.

A checkpoint is ``checkpoint_<cycles:010d>.fdck`` in the output folder::

    b"FDECKCP1"  (8 bytes, format tag)
    SHA-256 of the payload (32 bytes)
    payload: a pickle (protocol 5) of a dict of plain Python values and numpy arrays

The payload holds what ``fdeck.run`` puts in it: the engine state (``engine.solver.run``'s ``resume``), the state of
the output writers (frames written, the series' indexes, history rows) and the digests that tie it to a deck, a
mesh and an fdeck version. The file is written to a temporary name, flushed to the disk (fsync) and renamed
(``io.summary.atomic_write_bytes``), so a run killed at any moment leaves the previous checkpoints intact and never
a partial one under a checkpoint's name; the hash catches a file damaged afterwards (a full disk, a copy cut short).

Checkpoints are pickles: load only checkpoints of your own runs (as any pickle, a crafted file can run code).
"""

from __future__ import annotations

import hashlib
import os
import pickle
import re
from pathlib import Path

from fdeck.io.summary import atomic_write_bytes

__all__ = ["CheckpointError", "checkpoint_files", "latest_valid", "read_checkpoint", "write_checkpoint"]

MAGIC = b"FDECKCP1"
_NAME = re.compile(r"^checkpoint_(\d{10})\.fdck$")


class CheckpointError(Exception):
    """A checkpoint file that cannot be used (damaged, truncated, not a checkpoint)."""


def checkpoint_files(out_dir: str | os.PathLike) -> list[Path]:
    """Checkpoints in ``out_dir``, oldest first (by the cycle count in their names)."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return []
    return sorted(p for p in out_dir.iterdir() if _NAME.match(p.name))


def write_checkpoint(out_dir: str | os.PathLike, cycles: int, payload: dict, keep: int) -> Path:
    """Write ``payload`` as the checkpoint of cycle ``cycles`` and remove all but the newest ``keep`` (>= 1)."""
    data = pickle.dumps(payload, protocol=5)
    path = Path(out_dir) / f"checkpoint_{cycles:010d}.fdck"
    atomic_write_bytes(path, MAGIC + hashlib.sha256(data).digest() + data, fsync=True)
    for old in checkpoint_files(out_dir)[:-keep]:
        old.unlink(missing_ok=True)
    return path


def read_checkpoint(path: str | os.PathLike) -> dict:
    """The payload of the checkpoint ``path``; CheckpointError when the file is not a complete, intact one."""
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise CheckpointError(f"{path}: cannot be read ({exc.strerror})") from None
    if raw[:len(MAGIC)] != MAGIC:
        raise CheckpointError(f"{path}: not an fdeck checkpoint")
    digest, data = raw[len(MAGIC):len(MAGIC) + 32], raw[len(MAGIC) + 32:]
    if hashlib.sha256(data).digest() != digest:
        raise CheckpointError(f"{path}: damaged or truncated (its SHA-256 does not match its content)")
    try:
        payload = pickle.loads(data)
    except Exception as exc:  # an intact hash over a payload we cannot read: another format version
        raise CheckpointError(f"{path}: unreadable payload ({type(exc).__name__}: {exc})") from None
    if not isinstance(payload, dict):
        raise CheckpointError(f"{path}: not an fdeck checkpoint payload")
    return payload


def latest_valid(out_dir: str | os.PathLike, report=lambda msg: None) -> tuple[Path, dict] | None:
    """(path, payload) of the newest intact checkpoint in ``out_dir``, or None; each damaged newer one is skipped
    and ``report``ed with the reason."""
    for path in reversed(checkpoint_files(out_dir)):
        try:
            return path, read_checkpoint(path)
        except CheckpointError as exc:
            report(f"skipping {exc}")
    return None
