"""Run one hexahedral and one shell deck, cut to a few cycles, with the installed `fdeck` (CI's wheel check).

Usage: python wheel_smoke.py DECKS_FOLDER. Copies each deck beside its mesh references, sets max_cycles, runs
`fdeck validate` and `fdeck run` from the installed console script and fails on any exit code but 0 or 3 (a check
of a cut run may fail; a traceback or a bad input may not), or if fdeck was imported from the source tree.
"""

import shutil
import subprocess
import sys
from pathlib import Path

import yaml

decks = Path(sys.argv[1])
exe = Path(sys.executable).parent / "fdeck"
import fdeck  # noqa: E402

assert decks.parent not in Path(fdeck.__file__).parents, f"fdeck imported from the source tree: {fdeck.__file__}"
for name in ("block_compression.yaml", "coupons/bending_sm_0.yaml"):
    src = decks / name
    data = yaml.safe_load(src.read_text())
    for step in data["steps"]:
        step["max_cycles"] = 50
    deck = src.parent / f"_wheel_smoke_{src.name}"
    deck.write_text(yaml.safe_dump(data))
    try:
        for cmd in (["validate", str(deck)], ["run", str(deck), "--out", str(Path.cwd() / src.stem)]):
            r = subprocess.run([str(exe), *cmd], capture_output=True, text=True)
            print(f"fdeck {cmd[0]} {name}: exit {r.returncode}")
            if r.returncode not in (0, 3) or "Traceback" in r.stderr:
                sys.exit(f"{r.stdout}\n{r.stderr}")
    finally:
        deck.unlink()
shutil.rmtree(Path.cwd() / "block_compression", ignore_errors=True)
