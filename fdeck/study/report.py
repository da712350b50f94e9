"""A study's table as study.csv and study.json, its error-against-wall-time plot (study.png, Pareto front marked)
and the text printed at the end of ``fdeck study``."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from fdeck.io.summary import write_json_atomic


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)  # full precision: a table read back compares bitwise
    if isinstance(v, (list, dict)):
        return json.dumps(v, separators=(",", ":"))
    return v


def columns(table: dict) -> tuple[list[str], list[list]]:
    """Header and rows of study.csv: name, one column per deck path whose value differs between variants, status, answer and error per quantity,
    largest error, within tolerance, wall time [s], cycles, elements, us per element-cycle, added mass [%],
    reused, run folder, message."""
    paths: list[str] = []
    for r in table["rows"]:
        paths += [p for p in r["settings"] if p not in paths]
    # a path every variant sets alike (the study's common `set`) says nothing about the rows: it stays in study.json
    paths = [p for p in paths if len({json.dumps(r["settings"].get(p), sort_keys=True) for r in table["rows"]}) > 1]
    qs = table["quantities"]
    head = (["variant"] + paths + ["status"] + [f"{q}" for q in qs] + [f"error_{q}" for q in qs]
            + ["max_error", "within_tolerance", "wall_time_s", "cycles", "elements", "us_per_element_cycle",
               "added_mass_percent", "reused", "run_dir", "message"])
    body = []
    for r in table["rows"]:
        body.append([r["name"]] + [_cell(r["settings"].get(p)) for p in paths] + [r["status"]]
                    + [_cell(r["answers"][q]) for q in qs] + [_cell(r["errors"][q]) for q in qs]
                    + [_cell(r[k]) for k in ("max_error", "within_tolerance", "wall_time", "cycles", "elements",
                                             "us_per_element_cycle", "added_mass_percent", "reused", "run_dir",
                                             "message")])
    return head, body


def write(table: dict, out_dir: Path) -> list[Path]:
    """Write study.csv, study.json and (with matplotlib) study.png into out_dir; returns the files written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    head, body = columns(table)
    with open(out_dir / "study.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(head)
        w.writerows(body)
    write_json_atomic(out_dir / "study.json", table)
    files = [out_dir / "study.csv", out_dir / "study.json"]
    if plot(table, out_dir / "study.png"):
        files.append(out_dir / "study.png")
    return files


def plot(table: dict, png: Path) -> bool:
    """Largest relative error against wall time, log-log, one labelled point per variant with an answer, the
    Pareto front as a line and the tolerance as a dashed level. False when matplotlib is missing or nothing has
    an error."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    pts = [r for r in table["rows"] if r["max_error"] is not None and r["wall_time"]]
    if not pts:
        return False
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    floor = min((r["max_error"] for r in pts if r["max_error"] > 0), default=1e-16) / 10
    for r in pts:
        y = max(r["max_error"], floor)
        ax.plot(r["wall_time"], y, "o", color="C0" if r["within_tolerance"] else "C1")
        ax.annotate(r["name"], (r["wall_time"], y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    front = [r for name in table["pareto"] for r in pts if r["name"] == name]
    ax.plot([r["wall_time"] for r in front], [max(r["max_error"], floor) for r in front], "-", color="C2",
            label="Pareto front")
    ax.axhline(table["tolerance"], ls="--", color="grey", label=f"tolerance {table['tolerance']:g}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time [s]")
    ax.set_ylabel(f"largest relative error vs {table['reference']['type']}")
    ax.set_title(table.get("title") or Path(table["study"]).stem, fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return True


def _num(v, fmt="{:.6g}") -> str:
    return "-" if v is None else fmt.format(v)


def text(table: dict) -> str:
    """The printed summary: reference, one line per variant, the cheapest within the tolerance."""
    ref = table["reference"]
    qs = table["quantities"]
    lines = [f"reference ({ref['type']}" + (f" of {', '.join(ref['variants'])}" if ref["variants"] else "")
             + (f"; {ref['source']}" if ref["source"] else "") + "): "
             + ", ".join(f"{q} = {_num(ref['values'].get(q))}"
                         + (f" (observed order {_num(ref['order'].get(q), '{:.3g}')})" if ref["order"] else "")
                         for q in qs)]
    if ref["message"]:
        lines.append(f"  no reference: {ref['message']}")
    lines.append(f"  {'variant':<32s} {'status':<13s} " + " ".join(f"{q[:14]:>14s}" for q in qs)
                 + f" {'max error':>10s} {'wall s':>8s} {'cycles':>8s} {'us/el-cyc':>9s}")
    for r in table["rows"]:
        lines.append(f"  {r['name'][:32]:<32s} {r['status']:<13s} "
                     + " ".join(f"{_num(r['answers'][q]):>14s}" for q in qs)
                     + f" {_num(r['max_error'], '{:.3e}'):>10s} {_num(r['wall_time'], '{:.2f}'):>8s}"
                     f" {_num(r['cycles'], '{:d}'):>8s} {_num(r['us_per_element_cycle'], '{:.3f}'):>9s}"
                     + (" (reused)" if r["reused"] else "") + (f"  {r['message']}" if r["message"] else ""))
    tol = table["tolerance"]
    lines.append(f"cheapest within {tol:g}: {table['cheapest']}" if table["cheapest"]
                 else f"no variant is within {tol:g} of the reference")
    return "\n".join(lines)
