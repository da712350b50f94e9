"""Plain CSV tables and their optional plots (end-of-run outputs: ``path_<name>.csv``, ``fibres.csv``).

A table is ``{column: (n,) array}``; it is written as CSV with a header line, integers as integers, floats with
``repr`` (exact round trip), NaN as ``nan``, atomically (``atomic_write_text``). Plots need matplotlib, an optional
dependency: ``plot_xy`` returns False without writing anything when it is not installed.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from fdeck.io.summary import atomic_write_text

__all__ = ["plot_xy", "read_table", "write_table"]


def write_table(path: str | os.PathLike, columns: Mapping[str, np.ndarray]) -> Path:
    """Write ``columns`` (equal lengths) as CSV to ``path``; return the path."""
    names = list(columns)
    arrays = [np.asarray(columns[c]) for c in names]
    n = {len(a) for a in arrays}
    if len(n) != 1:
        raise ValueError(f"table columns differ in length: {sorted(n)}")
    fmt = [(lambda v: str(int(v))) if a.dtype.kind in "iub" else (lambda v: repr(float(v))) for a in arrays]
    lines = [",".join(names)]
    lines += [",".join(f(a[i]) for f, a in zip(fmt, arrays)) for i in range(n.pop())]
    atomic_write_text(path, "\n".join(lines) + "\n")
    return Path(path)


def read_table(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read a table written by ``write_table``: {column: (n,) float64}."""
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=float, ndmin=1)
    return {c: np.atleast_1d(data[c]).astype(float) for c in data.dtype.names}


def plot_xy(path: str | os.PathLike, x: np.ndarray, y: np.ndarray, xlabel: str, ylabel: str, title: str) -> bool:
    """One curve y(x) to a PNG at ``path``; False (nothing written) when matplotlib is not installed."""
    try:
        from matplotlib.figure import Figure  # no pyplot: no global state, no display backend
    except ImportError:
        return False
    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    ax.plot(x, y, "-o", ms=2)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return True
