"""Physically absurd decks: the figures that make a schema-valid deck unrunnable, found before the run starts.

Two passes, each returning ``[(deck path tuple, message, severity)]`` with severity "error" (the deck is refused,
exit 2) or "warning":

* ``deck_figures(deck)``, before compiling (compiling a 10^11-element block would itself exhaust the memory):
  the element count of a built-in block or plate and the memory it needs, at ``BYTES_PER_ELEMENT``;
* ``problem_figures(problem)``, after compiling: per step the rest stable time step against a floor and the cycles
  it implies, and for every prescribed motion (boundary velocity/displacement on x, y, z, tool motion) the largest
  travel in one cycle in units of the smallest element edge.

The limits (``Limits``) are documented in their fields and can be overridden with environment variables:
``FDECK_MAX_CYCLES``, ``FDECK_DT_FLOOR`` [s], ``FDECK_MAX_MEMORY_GB`` [GiB].
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

# Element arrays measured by `fdeck info`: 4.9-5.4 KiB per hexahedron (block_compression, bias_extension fine),
# 2.2 KiB per shell (coupons/tension_sm); the engine's nodal arrays and the frames come on top.
BYTES_PER_ELEMENT = 6 * 1024


def _physical_memory() -> float:
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 64.0 * 2**30


def _env(name: str, default: float) -> float:
    try:
        value = float(os.environ.get(name, default))
    except ValueError:
        return default
    return value if value > 0 else default


@dataclass(frozen=True)
class Limits:
    """Where a deck stops being a run and becomes a mistake.

    max_cycles: total expected cycles above which a deck is refused (10^9 cycles of the smallest deck, 100
        elements at 0.3 us per element-cycle, are 8 hours; of a forming deck, months). ``FDECK_MAX_CYCLES``.
    warn_cycles: expected cycles above which a warning gives the figure.
    dt_floor: a rest stable step below this [s] is refused: no dry-fabric deck in mm-t-s or m-kg-s units has one
        (shipped decks: 6.7e-7 to 2.2e-5 s); it means a density or stiffness off by many orders. ``FDECK_DT_FLOOR``.
    max_memory: estimated memory [bytes] above which a deck is refused (default: this machine's physical memory).
        ``FDECK_MAX_MEMORY_GB``.
    max_travel / warn_travel: largest prescribed travel in one cycle, in smallest element edges, refused / warned:
        an element crossed in one cycle is crushed before any force can act.
    """

    max_cycles: float = 1e9
    warn_cycles: float = 1e8
    dt_floor: float = 1e-12
    max_memory: float = 0.0
    max_travel: float = 1.0
    warn_travel: float = 0.1

    @classmethod
    def from_env(cls) -> "Limits":
        return cls(max_cycles=_env("FDECK_MAX_CYCLES", cls.max_cycles),
                   dt_floor=_env("FDECK_DT_FLOOR", cls.dt_floor),
                   max_memory=_env("FDECK_MAX_MEMORY_GB", _physical_memory() / 2**30) * 2**30)


def estimated_elements(deck) -> float | None:
    """Element count of a built-in block or plate (a float: may be astronomically large), None for a mesh file."""
    for gen, dims in ((deck.mesh.block, 3), (deck.mesh.plate, 2)):
        if gen is None:
            continue
        if gen.divisions is not None:
            n = math.prod(float(d) for d in gen.divisions)
        else:
            n = math.prod(max(1.0, math.ceil(s / gen.element_size)) if s / gen.element_size < 1e300 else math.inf
                          for s in gen.size[:dims])
        return n * (2 if getattr(gen, "triangles", False) else 1)
    return None


def deck_figures(deck, limits: Limits | None = None) -> list[tuple[tuple, str, str]]:
    """Figures computable from the deck alone (mesh size and memory of built-in meshes)."""
    limits = limits or Limits.from_env()
    n = estimated_elements(deck)
    if n is None:
        return []
    memory = n * BYTES_PER_ELEMENT
    where = ("mesh", "block" if deck.mesh.block is not None else "plate")
    if memory > limits.max_memory:
        return [(where, f"the mesh has {n:.3g} elements, about {memory / 2**30:.3g} GiB of element arrays at "
                 f"{BYTES_PER_ELEMENT // 1024} KiB per element, above the limit {limits.max_memory / 2**30:.3g} GiB "
                 "(FDECK_MAX_MEMORY_GB)", "error")]
    return []


def _min_edge(problem) -> float:
    """Smallest non-zero element edge [length] over every group (hexahedra: 12 edges; shells: the node cycle)."""
    out = math.inf
    for g in problem.groups:
        conn = np.asarray(g.conn)
        k = conn.shape[1]
        if k == 8:
            pairs = [(i, (i + 1) % 4) for i in range(4)] + [(4 + i, 4 + (i + 1) % 4) for i in range(4)] \
                + [(i, i + 4) for i in range(4)]
        else:
            pairs = [(i, (i + 1) % k) for i in range(k)]
        for a, b in pairs:
            d = np.linalg.norm(problem.X[conn[:, a]] - problem.X[conn[:, b]], axis=1)
            d = d[d > 0]
            if len(d):
                out = min(out, float(d.min()))
    return out


def _speed(amplitude, value: float, kind: str, t0: float, t1: float) -> float:
    """Largest |velocity| [length/s] of a prescribed motion over [t0, t1]: |value a(t)| for a velocity, the largest
    finite-difference slope of value a(t) on 2000 intervals for a displacement."""
    t = np.linspace(t0, t1, 2001)
    a = np.array([amplitude(float(s)) for s in t]) * value
    if kind == "velocity":
        return float(np.max(np.abs(a)))
    return float(np.max(np.abs(np.diff(a)) / np.diff(t))) if t1 > t0 else 0.0


def _motions(problem):
    """(deck path, label, speed [length/s]) of every prescribed translation."""
    from fdeck.compile import amplitude

    deck = problem.deck
    amp = lambda name: amplitude.make(name, deck.amplitudes, deck.duration)  # noqa: E731
    for i, card in enumerate(deck.boundary):
        kind = getattr(card, "type", "")
        dofs = [d for d in getattr(card, "dofs", []) if d in ("x", "y", "z")]
        if kind in ("velocity", "displacement") and dofs:
            yield ("boundary", i, "value"), f"{kind} of node set '{card.nodes}'", \
                _speed(amp(card.amplitude), card.value, kind, 0.0, deck.duration)
    for name, tool in deck.tools.items():
        mo = tool.motion
        if mo is not None and mo.kind in ("velocity", "displacement"):
            yield ("tools", name, "motion", "value"), f"tool '{name}'", \
                _speed(amp(mo.amplitude_name), mo.value, mo.kind, 0.0, deck.duration)


def step_dts(problem) -> list[float]:
    """Rest stable step [s] of each step plan: dt_safety x the smallest element step (effects included)."""
    from fdeck.compile.problem import rest_dt

    out = []
    for plan in problem.steps:
        with np.errstate(all="ignore"):
            dts = [float(np.min(rest_dt(g, rho, problem.effects, plan.translational(i))))
                   for i, (g, rho) in enumerate(zip(problem.groups, plan.rho)) if len(g.conn)]
        out.append(plan.dt_safety * min(dts) if dts else math.inf)
    return out


def problem_figures(problem, limits: Limits | None = None) -> list[tuple[tuple, str, str]]:
    """Figures of a compiled deck: stable step floor, expected cycles, travel per cycle of prescribed motions."""
    limits = limits or Limits.from_env()
    found, total = [], 0.0
    dts = step_dts(problem)
    for i, (plan, dt) in enumerate(zip(problem.steps, dts)):
        if not (dt >= limits.dt_floor):  # also NaN
            found.append((("steps", i), f"step '{plan.name}': rest stable time step {dt:.3g} s is below the floor "
                          f"{limits.dt_floor:.3g} s (FDECK_DT_FLOOR): a density or stiffness is off by orders of "
                          "magnitude", "error"))
            total = math.inf
            continue
        cycles = plan.duration / dt
        if plan.max_cycles is not None:
            cycles = min(cycles, float(plan.max_cycles))
        total += cycles
    if total > limits.max_cycles and math.isfinite(total):
        found.append((("steps",), f"about {total:.3g} cycles expected (duration / rest stable step, max_cycles "
                      f"counted), above the limit {limits.max_cycles:.3g} (FDECK_MAX_CYCLES)", "error"))
    elif total > limits.warn_cycles and math.isfinite(total):
        found.append((("steps",), f"about {total:.3g} cycles expected: "
                      f"{total * problem.n_element:.3g} element-cycles", "warning"))
    dt = min(dts) if dts else math.inf
    h = _min_edge(problem)
    length = problem.deck.units.split("-")[0]  # mm or m
    if math.isfinite(dt) and dt > 0 and math.isfinite(h):
        for path, label, speed in _motions(problem):
            travel = speed * dt / h
            message = (f"{label} moves up to {speed:.3g} {length}/s, {travel:.3g} smallest element edges ({h:.3g} "
                       f"{length}) in one stable step of {dt:.3g} s")
            if travel > limits.max_travel:
                found.append((path, message + f", above the limit {limits.max_travel:g}", "error"))
            elif travel > limits.warn_travel:
                found.append((path, message, "warning"))
    return found
