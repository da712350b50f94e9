"""Cost of keeping the selective mass's target during a step (``track_target``), per call (not part of the suite).

    python benchmarks/tracking.py                      # 0/90 double dome at 3 mm (40 000 hexahedra), one thread
    python benchmarks/tracking.py --divisions 60 60 4  # at 5 mm

Compiles decks/forming/fbar/double_dome_090_5mm_fbar.yaml (F-bar, as measured in the README) with the selective
mass kept (the variants of decks/studies/double_dome_090_tracking.yaml) on the given mesh, runs 300 cycles, then
times the stable-step update of a cycle on which tracking raises every 5 000th element (their continuum steps set to
2e-5 s, below the target): the group's element steps, then ``SelectiveMassEffect.track``. Best of three rounds of
20 calls, in ms per call; and the same without a raise, for the step alone. Late in a forming stroke a few elements
fall below the target on most cycles, so this is paid on most cycles there.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def best_ms(fn) -> float:
    """Best of three rounds of 20 calls of fn(), per call [ms] (kernel_parts' timing)."""
    from kernel_parts import best_us_per_element

    return 1e-3 * best_us_per_element(fn, 1, calls=20, repeats=3)


def main():
    import numba
    import numpy as np

    from fdeck.compile.problem import compile_deck
    from fdeck.deck.loader import load_file
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--divisions", type=int, nargs=3, default=[100, 100, 4])
    ap.add_argument("--threads", type=int, default=1)
    a = ap.parse_args()
    numba.set_num_threads(a.threads)
    path = ROOT / "decks/forming/fbar/double_dome_090_5mm_fbar.yaml"
    data, _ = load_file(path)
    data["mesh"]["block"]["divisions"] = a.divisions
    data["steps"][0]["mass_scaling"] = {"factor": 30, "selective_target_dt": 3e-5, "track_target": 3e-5}
    data["steps"][0]["max_cycles"] = 300
    data["output"].pop("checkpoint", None)
    problem = compile_deck(Deck.model_validate(data), path.parent)
    solver.run(problem, solver.Sink())
    g = problem.groups[0]
    sms = next(e for e in problem.effects if getattr(e, "solves_mass", False))
    v = np.random.default_rng(0).standard_normal(problem.X.shape)
    raised = np.arange(0, len(g.conn), 5000)  # the same elements each call: their density grows ~3x per call
    # (finite over the ~80 calls; the timing is of the work per raised element, which does not depend on it)

    def with_raise():
        g.stable_dt()
        g.dt_e[raised] = 2e-5
        sms.track([float(g.dt_e.min())], sms.track_dt, problem.steps[0].dt_safety, v, v, None)

    step = best_ms(g.stable_dt)
    both = best_ms(with_raise)
    print(f"{len(g.conn)} hexahedra, {len(raised)} raised per call, {a.threads} thread(s): "
          f"element steps {step:.3f} ms, "
          f"with the raise {both:.3f} ms (the raise itself {both - step:.3f} ms)")


if __name__ == "__main__":
    main()
