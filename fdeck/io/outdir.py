"""Who owns a result folder, and when a run may write into it.

Design: a run marks its output folder with ``.fdeck-run``, a small JSON file holding the resolved path of the deck
that writes there, the SHA-256 of the deck file, the fdeck version, and (rewritten at the end of the run) the names
of the files the run wrote. Before a run, ``claim`` decides:

* folder missing or empty: the run owns it;
* folder marked by the SAME deck (same resolved path; the digest may differ, editing a deck and re-running it is the
  usual work): the run may write; the earlier run's files are kept until the new run has written its first frame
  (a deck that fails to compile leaves the old results intact), then those of them the new run did not rewrite
  are removed (``Claim.first_frame``), so the folder never mixes two runs;
* ``--restart``: the checkpoint's own checks decide (see ``claim``);
* folder marked by ANOTHER deck, or holding files that no fdeck run marked (results written before this marker
  existed are recognised by their ``summary.json``'s ``deck``, a relative path taken from the working folder):
  refused, naming the other deck, unless ``overwrite``; with ``overwrite`` the other run's listed files are removed
  after the first frame, and files fdeck did not write are never removed.

Nothing outside the folder is ever written or removed: every removal is of a plain file, by a name listed in the
marker, that resolves to a path directly inside the folder.
"""

from __future__ import annotations

import hashlib
import json
import os
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from fdeck.io.summary import atomic_write_text

MARKER = ".fdeck-run"
LOCK = ".fdeck-lock"


class OutdirError(Exception):
    """The run may not write into this folder; ``str(exc)`` says why and what to do."""


@contextmanager
def writing(out: Path):
    """Hold ``out``'s write lock while a run writes there: an exclusive ``flock`` on ``out/.fdeck-lock`` (holding the
    writer's pid), released when the run ends or its process dies (the kernel drops it). A second run into a folder
    another one is writing is refused with an OutdirError naming the writer, instead of two processes writing one
    history file: a study re-run beside a worker left over from its killed predecessor wrote NUL-filled rows so."""
    import fcntl

    out.mkdir(parents=True, exist_ok=True)
    f = open(out / LOCK, "a+", encoding="utf-8")
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        f.seek(0)
        holder = f.read().strip() or "a process"
        f.close()
        raise OutdirError(f"another fdeck run ({holder}) is writing into {out}: wait for it to end, stop it, or "
                          "choose another result folder") from None
    f.seek(0)
    f.truncate()
    f.write(f"pid {os.getpid()}")
    f.flush()
    try:
        yield
    finally:
        f.close()  # closing the file releases the lock


def deck_digest(deck_path: Path) -> str:
    """SHA-256 (hex) of the deck file's bytes."""
    return hashlib.sha256(Path(deck_path).read_bytes()).hexdigest()


def _snapshot(out: Path) -> dict[str, tuple[int, int]]:
    """{name: (inode, mtime_ns)} of the plain files directly in ``out`` (the marker excluded)."""
    if not out.is_dir():
        return {}
    return {e.name: (e.stat().st_ino, e.stat().st_mtime_ns) for e in os.scandir(out)
            if e.is_file(follow_symlinks=False) and e.name not in (MARKER, LOCK)}


def _owner(out: Path) -> tuple[str | None, list[str]]:
    """(deck path of the run that wrote ``out`` or None when unknown, names of the files it wrote)."""
    marker = out / MARKER
    if marker.is_file():
        try:
            data = json.loads(marker.read_text(encoding="utf-8"))
            return str(data.get("deck")), [str(n) for n in data.get("files", [])]
        except (OSError, ValueError, AttributeError):
            return None, []
    summary = out / "summary.json"
    if summary.is_file():  # results written before the marker existed
        try:
            data = json.loads(summary.read_text(encoding="utf-8"))
            deck, tables = data.get("deck"), [str(t) for t in data.get("tables", [])]
        except (OSError, ValueError, AttributeError):
            deck, tables = None, []
        if deck:
            return str(Path(deck).resolve()), _legacy_files(out, Path(deck).stem, tables)
    return None, []


def _legacy_files(out: Path, stem: str, tables: list[str]) -> list[str]:
    """Files of a run that wrote no marker, recognised by the names fdeck gives them: ``<stem>.pvd|xdmf|h5``,
    ``<stem>_*.vtu``, history.csv, summary.json and the tables its summary lists."""
    known = {f"{stem}.pvd", f"{stem}.xdmf", f"{stem}.h5", "history.csv", "summary.json", *tables}
    return [n for n in _snapshot(out) if n in known or (n.startswith(f"{stem}_") and n.endswith(".vtu"))]


@dataclass
class Claim:
    """Permission to write into ``out``: call ``first_frame()`` once the new run has written its first frame and
    ``finish()`` at its end."""

    out: Path
    deck: Path
    stale: list[str]  # files of the earlier run to remove once the first frame is written
    before: dict[str, tuple[int, int]] = field(default_factory=dict)
    cleaned: bool = False
    restart: bool = False  # continues the folder's run: its earlier files stay its own

    def _write_marker(self, files: list[str]) -> None:
        from fdeck import __version__

        self.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.out / MARKER, json.dumps(
            {"deck": str(self.deck), "digest": deck_digest(self.deck), "fdeck": __version__,
             "files": sorted(files)}, indent=1) + "\n")

    def first_frame(self) -> None:
        """Remove the earlier run's files that the new run has not rewritten (same inode and mtime as before)."""
        if self.cleaned:
            return
        self.cleaned = True
        now = _snapshot(self.out)
        root = self.out.resolve()
        for name in self.stale:
            path = self.out / name
            if (name in now and now[name] == self.before.get(name) and path.resolve().parent == root
                    and path.is_file() and not path.is_symlink()):
                path.unlink()
        self._write_marker(self._written())

    def _written(self) -> list[str]:
        """Names of the files created or rewritten since the claim."""
        return [n for n, st in _snapshot(self.out).items() if self.before.get(n) != st]

    def finish(self) -> None:
        """Clean up (if no frame was reported) and list every file the run wrote (or, after a restart, every file
        of the folder) in the marker."""
        self.first_frame()
        if self.restart:  # the files the interrupted run listed, and what the continuation wrote
            _, listed = _owner(self.out)
            self._write_marker(sorted(set(listed) & set(_snapshot(self.out)) | set(self._written())))
        else:
            self._write_marker(self._written())


def claim(out: Path, deck_path: Path, overwrite: bool = False, restart: bool = False) -> Claim:
    """Decide whether the run of ``deck_path`` may write into ``out`` (see the module docstring); raise
    ``OutdirError`` naming the other deck when it may not. Writes the marker when the folder is taken.

    ``restart``: the run continues the folder's own run from a checkpoint, whose checks (deck digest, appended
    steps) decide whose run may be continued: no ownership check, no file is stale, and the marker is rewritten
    only by ``finish`` (a refused restart leaves it as it was)."""
    out, deck = Path(out), Path(deck_path).resolve()
    if out.exists() and not out.is_dir():
        raise OutdirError(f"output folder {out} is a file, not a folder")
    before = _snapshot(out)
    if restart:
        return Claim(out, deck, stale=[], before=before, cleaned=True, restart=True)
    owner, files = _owner(out) if out.is_dir() else (None, [])
    others = os.listdir(out) if out.is_dir() else []
    if owner is None and others and not overwrite:
        raise OutdirError(f"output folder {out} holds {len(others)} entries that no fdeck run marked as its own "
                          f"(e.g. '{sorted(others)[0]}'); choose another folder with -o, or pass --overwrite "
                          "(files fdeck did not write are kept)")
    if owner is not None and owner != str(deck) and not overwrite:
        raise OutdirError(f"output folder {out} holds the results of another deck, {owner}; choose another folder "
                          "with -o, or pass --overwrite to replace them")
    c = Claim(out, deck, stale=files, before=before)
    c._write_marker([n for n in files if n in before])
    return c
