"""Pass/fail checks a deck can require, evaluated on the run's history (rows at the history points)."""

from __future__ import annotations

import numpy as np


def evaluate(checks, history: np.ndarray, columns: list[str], duration: float) -> list[dict]:
    """-> [{name, value, limit, passed, what}] for every check the deck names. history (n_rows, n_cols)."""
    col = {c: history[:, i] for i, c in enumerate(columns)} if len(history) else {}
    out = []
    if not len(history):
        return out
    ke, ie = col["kinetic_energy"], col["internal_energy"]
    if checks.quasi_static is not None:
        c = checks.quasi_static
        late = col["time"] >= c.after * duration
        ratio = np.where(ie[late] > 0, ke[late] / np.maximum(ie[late], 1e-300), np.inf)
        value = float(ratio.max()) if late.any() else 0.0
        out.append(dict(name="quasi_static", value=value, limit=c.max_ratio, passed=bool(value <= c.max_ratio),
                        what=f"max kinetic/internal energy after {c.after:g} of the run"))
    if checks.energy_balance is not None:
        c = checks.energy_balance
        scale = max(np.abs(ke).max(), np.abs(ie).max(), np.abs(col["external_work"]).max(),
                    np.abs(col["damping_energy"]).max(), 1e-300)
        value = float(np.abs(col["energy_balance_error"]).max() / scale)
        out.append(dict(name="energy_balance", value=value, limit=c.max_error, passed=bool(value <= c.max_error),
                        what="max |energy balance error| / largest energy"))
    if checks.hourglass is not None:
        c = checks.hourglass
        hg = col["hourglass_energy"][-1] + (col["hourglass_dissipation"][-1] if "hourglass_dissipation" in col else 0)
        value = float(hg / max(ie[-1], 1e-300))
        out.append(dict(name="hourglass", value=value, limit=c.max_ratio, passed=bool(value <= c.max_ratio),
                        what="hourglass (stored and viscous) / internal energy at the end"))
    for lim in checks.limits:
        rows = col["time"] >= lim.after * duration
        vals = col[lim.measure][rows]
        lo, hi = (float(vals.min()), float(vals.max())) if len(vals) else (np.nan, np.nan)
        for bound, value, ok in (("min", lo, lim.min is None or lo >= lim.min),
                                 ("max", hi, lim.max is None or hi <= lim.max)):
            limit = getattr(lim, bound)
            if limit is not None:
                out.append(dict(name=f"{lim.measure}_{bound}", value=value, limit=limit, passed=bool(ok),
                                what=f"{'smallest' if bound == 'min' else 'largest'} {lim.measure} after "
                                     f"{lim.after:g} of the run"))
    return out
