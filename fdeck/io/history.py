"""History CSV: one header line of column names, then one line of numbers per history sample.

Numbers are written with ``repr(float(v))``, Python's shortest string that reads back to the *same* float64, so a
history read back is bit-identical to what the engine held (``'%.10g'`` would lose the last 6 digits and make gold
comparisons depend on formatting). NaN and infinities are written ``nan``, ``inf``, ``-inf``.

Crash safety: each row is encoded completely and handed to the OS in a single unbuffered ``write()``, newline last,
so a process killed at any moment leaves every row it finished complete on disk (the OS page cache survives the
process). A line without its final newline can only be the last one, cut by a kill or a full disk;
``read_history`` drops it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = ["HistoryWriter", "read_history"]


class HistoryWriter:
    """Write a history CSV row by row.

    Parameters
    ----------
    path
        Output file; created or truncated. Its folder must exist.
    columns
        Column names, e.g. ``["time", "kinetic_energy", "internal_energy"]``; unique, non-empty, without commas,
        quotes or line breaks (the file is plain CSV with no quoting). Values are in the model's units (fdeck:
        mm, N, MPa, s).
    """

    def __init__(self, path: str | os.PathLike, columns: Sequence[str]):
        columns = [str(c) for c in columns]
        if not columns:
            raise ValueError("history needs at least one column")
        for c in columns:
            if not c.strip() or any(ch in c for ch in ',"\r\n'):
                raise ValueError(f"history column name {c!r} must be non-empty without commas, quotes or newlines")
        if len(set(columns)) != len(columns):
            dup = sorted({c for c in columns if columns.count(c) > 1})
            raise ValueError(f"duplicate history columns: {dup}")
        self.path = Path(path)
        self.columns: list[str] = columns
        # buffering=0: every write() goes straight to the OS, one system call per row, nothing held in Python.
        self._file = open(self.path, "wb", buffering=0)
        self._write_line(",".join(columns))

    def _write_line(self, line: str) -> None:
        data = (line + "\n").encode("ascii")
        n = self._file.write(data)
        # A raw file may accept fewer bytes than offered (disk full, signal); finish the line rather than leave a gap.
        while n is not None and n < len(data):
            data = data[n:]
            n = self._file.write(data)

    def write_row(self, values: Sequence[float]) -> None:
        """Append one row: ``values`` (len(columns),) of real numbers, written exactly (``repr`` of float64)."""
        if self._file.closed:
            raise RuntimeError(f"history {self.path} is closed")
        values = list(values)
        if len(values) != len(self.columns):
            raise ValueError(f"history row has {len(values)} values for {len(self.columns)} columns")
        self._write_line(",".join(repr(float(v)) for v in values))

    def close(self) -> None:
        """Close the file (idempotent)."""
        self._file.close()

    def __enter__(self) -> HistoryWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_history(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read a history CSV into ``{column: (n_row,) float64}``, in file column order.

    Only complete lines count: a last line without its newline (the run was killed while writing it) is dropped,
    as is a trailing line with the wrong number of fields. A malformed line anywhere else is an error, since
    the writer never produces one.
    """
    raw = Path(path).read_bytes().decode("ascii")
    lines = raw.split("\n")
    # After the last "\n" comes either "" (file ends cleanly) or a fragment of an unfinished line: drop it.
    complete = lines[:-1]
    if not complete:
        raise ValueError(f"{path}: no complete header line")
    columns = complete[0].split(",")
    rows = []
    for i, line in enumerate(complete[1:], start=2):
        fields = line.split(",")
        if len(fields) != len(columns):
            if i == len(complete):  # defensive: a damaged last complete line is treated like a truncated one
                break
            raise ValueError(f"{path}:{i}: {len(fields)} fields, expected {len(columns)}")
        rows.append([float(x) for x in fields])
    data = np.array(rows, dtype=np.float64).reshape(len(rows), len(columns))
    return {c: np.ascontiguousarray(data[:, j]) for j, c in enumerate(columns)}

