"""Kernels against the memory/flop floor of this machine (not part of the test suite).

The floor of a kernel is max(bytes / bandwidth, flops / flop rate) per element-cycle, with

* bandwidth: a STREAM-like triad a = b + s c (McCalpin, "Memory bandwidth and machine balance in current high
  performance computers", IEEE TCCA newsletter 1995) on arrays far larger than the last-level cache, compiled by
  numba like the kernels, best of several repeats, 1 and 2 threads; bytes counted the STREAM way (24 per index:
  two reads, one write; the write-allocate read of ``a`` is not counted, and the kernels' writes are counted the
  same way);
* flop rate: independent chains of multiply-add held in registers, compiled with fdeck's own flags (no fastmath, so
  LLVM does not fuse them into FMA instructions), 1 and 2 threads; the assembly is searched for packed ``ymm``/``zmm``
  arithmetic to say whether LLVM vectorised it; sixteen chains in scalar registers (which LLVM leaves scalar, also
  checked in the assembly) give the scalar rate beside it, since most element passes are scalar code;
* bytes per element-cycle: the compulsory traffic of the algorithm as stored today (``compulsory_bytes``): the
  per-element reference data each cycle must read, the element's state read and written, and per node (shared by
  the elements around it, so counted once per node and spread over the elements) the positions, velocities and
  forces the cycle must read and write. Intermediates (F, P, per-element force buffers, moduli) are not
  compulsory: a fused kernel keeps them in registers. Today's resident element arrays are shown beside it;
* flops per element-cycle: counted by running the real kernels once, under ``NUMBA_DISABLE_JIT=1``, on object
  arrays of a float subclass that counts every + - * / sqrt and transcendental call (``Counted``), on a generically
  deformed element, so the count follows the code (branches included) rather than a hand reading of it.

The measured cost is bench.py's ``measure()`` (whole explicit cycle per element-cycle, after warm-up), on the same
block decks, in a fresh process per row; floor, bandwidth and kernels are measured back to back in rounds, and the
best of the rounds is kept (the host is shared: the spread and the load are written beside the numbers).

    python benchmarks/floor.py            # 102 400 elements (DRAM-resident), 3 rounds
    python benchmarks/floor.py --quick    # 10 000 elements, 1 round (the block partly fits the 32 MB L3)
    python benchmarks/floor.py --report   # the markdown table of benchmarks/floor.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT))  # the fdeck beside this file, not an installed one

KERNELS = [("reduced", "linear_elastic"), ("full", "linear_elastic"), ("fbar", "linear_elastic"),
           ("reduced", "fabric_hyper_3weave"), ("full", "fabric_hyper_3weave"), ("fbar", "fabric_hyper_3weave"),
           ("sm", "fabric_membrane_t300")]


# ----------------------------------------------------------------------------------------------------------------
# Flop counting (run in a subprocess with NUMBA_DISABLE_JIT=1)
# ----------------------------------------------------------------------------------------------------------------

COUNTS = {"add": 0, "mul": 0, "div": 0, "sqrt": 0, "transcendental": 0}
"""Operations counted since the last reset: add (+ and -), mul, div, sqrt, transcendental (pow, log, exp, trig)."""


def _op(kind, value):
    COUNTS[kind] += 1
    return Counted(value)


class Counted(float):
    """A float whose arithmetic counts itself into COUNTS (each operation once; an FMA would be two).

    Comparisons, abs, negation, min/max and conversions are not counted: they are not floating-point arithmetic.
    """

    def __add__(self, o): return _op("add", float(self) + float(o))
    def __radd__(self, o): return _op("add", float(o) + float(self))
    def __sub__(self, o): return _op("add", float(self) - float(o))
    def __rsub__(self, o): return _op("add", float(o) - float(self))
    def __mul__(self, o): return _op("mul", float(self) * float(o))
    def __rmul__(self, o): return _op("mul", float(o) * float(self))

    def __truediv__(self, o):
        return _op("div", float(self) / float(o) if float(o) != 0.0 else math.copysign(math.inf, float(self)))

    def __rtruediv__(self, o): return _op("div", float(o) / float(self))
    def __pow__(self, o): return _op("transcendental", float(self) ** float(o))
    def __rpow__(self, o): return _op("transcendental", float(o) ** float(self))
    def __neg__(self): return Counted(-float(self))
    def __abs__(self): return Counted(abs(float(self)))


def _patch_math():
    """Count math.sqrt and the transcendental functions the kernels call (they look them up at call time)."""
    for name, kind in (("sqrt", "sqrt"), ("log", "transcendental"), ("exp", "transcendental"),
                       ("cos", "transcendental"), ("acos", "transcendental"), ("sin", "transcendental"),
                       ("asin", "transcendental"), ("atan2", "transcendental"), ("cbrt", "transcendental")):
        if hasattr(math, name):
            f = getattr(math, name)
            setattr(math, name, lambda *a, _f=f, _k=kind: _op(_k, _f(*map(float, a))))


def _counted(a):
    """Object-array copy of a float array whose entries are Counted (other arrays and scalars unchanged)."""
    import numpy as np

    if isinstance(a, np.ndarray) and a.dtype == np.float64:
        out = np.empty(a.shape, dtype=object)
        out.flat[:] = [Counted(v) for v in a.ravel()]
        return out
    return a


def _count(fn):
    for k in COUNTS:
        COUNTS[k] = 0
    fn()
    return dict(COUNTS)


def count_flops(form: str, mat: str) -> dict:
    """Operations per element-cycle of the element update, the gather and the stable step (one element, 1 x 1 x 1
    block or 1 x 1 plate, nodes moved by a fixed pseudo-random 3 % of the element size so every branch is a
    deformed one), and per node-cycle of the integrator's two node kernels. Needs NUMBA_DISABLE_JIT=1."""
    import numba
    import numpy as np

    assert numba.config.DISABLE_JIT, "count_flops needs NUMBA_DISABLE_JIT=1"
    _patch_math()
    import bench
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import integrate

    problem = compile_deck(Deck.model_validate(bench.deck(form, mat, (1, 1, 1), 1)))
    (g,) = problem.groups
    # the block path of reduced + linear_elastic (hex8_blocks) forms every value by the general path's operations in
    # the same order (tests/test_hex8_blocks.py), but in float work arrays the counter cannot see: count the general
    if getattr(g, "blocks", None) is not None:
        g.blocks = None
    X = problem.X if hasattr(problem, "X") else problem.x0
    rng = np.random.default_rng(1)
    x = _counted(X + 0.03 * rng.uniform(-1.0, 1.0, X.shape))
    v = _counted(rng.uniform(-1.0, 1.0, X.shape))
    for name, a in list(vars(g).items()):
        if isinstance(a, np.ndarray) and a.dtype == np.float64:
            setattr(g, name, _counted(np.array(a)))
    rot = None
    if getattr(g, "has_dir", False):  # shells with directors: bind the engine's rotational state, tilted a little
        from fdeck.engine.rotation import Rotations

        rot = Rotations(problem.rotations.d0, problem.rotations.nodes)
        rot.d = rot.d + 0.03 * rng.uniform(-1.0, 1.0, rot.d.shape)
        rot.d /= np.linalg.norm(rot.d, axis=1)[:, None]
        g.bind(rot)
    if rot is not None:
        for name, a in list(vars(rot).items()):
            if isinstance(a, np.ndarray) and a.dtype == np.float64:
                setattr(rot, name, _counted(np.array(a)))
    f_int = _counted(np.zeros_like(X))
    n_el = len(g.conn)
    out = {"update": _count(lambda: g.update(x, v)),
           "gather": _count(lambda: g.add_forces(f_int)),
           "stable_dt": _count(lambda: g.stable_dt())}
    out = {k: {op: c / n_el for op, c in d.items()} for k, d in out.items()}
    # node kernels, one node
    one = lambda: _counted(rng.uniform(0.5, 1.0, (1, 3)))  # noqa: E731
    args = [one() for _ in range(11)]
    inv_m = _counted(np.ones(1))
    out["kick"] = _count(lambda: integrate.kick(args[0], args[1], inv_m, args[2], args[3], args[4], Counted(1e-6)))
    out["drift"] = _count(lambda: integrate.drift(args[0], args[1], args[2], inv_m, *args[3:10], Counted(1e-6),
                                                  Counted(1e-6), False))
    return out


def flops_total(c: dict) -> float:
    return float(sum(c.values()))


# ----------------------------------------------------------------------------------------------------------------
# Compulsory bytes
# ----------------------------------------------------------------------------------------------------------------

def compulsory_bytes(form: str, mat: str, divisions) -> dict:
    """Bytes per element-cycle that any implementation of today's algorithm and storage must move, by item.

    Per element: connectivity (int64), the reference gradients and point volumes the kernel reads (dN, w; the
    one-point element's uniform gradient), hourglass vectors and coefficients (reduced), the fibre frame (laws that
    read it), the stable-step inputs (L0, 1/L_i^2, rho, hourglass step term), the state read and written.
    Material parameters are one row per section (a broadcast view): they stay in cache and count zero.
    Per node, spread over n_node / n_el: positions and velocities read and written, internal force written and read,
    inverse mass read (shells add the directors and angular velocities, written and read, and their inertia).
    """
    import bench
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck

    problem = compile_deck(Deck.model_validate(bench.deck(form, mat, divisions, 1)))
    (g,) = problem.groups
    n_el, n_node = len(g.conn), problem.n_node
    d = 8  # bytes per double
    items = {"connectivity": g.conn.itemsize * g.conn.shape[1]}
    if form in bench.SHELLS:
        n_z = len(g.z)
        # per point: T, tau (level maps) and e1, e2, nrm (local bases), T0, tau0, w; per element: aw, k0, bend, ks, gam0
        items["reference"] = d * (4 * n_z * (9 + 3) + 4 * 9 + 4 * (4 + 2) + 4 * n_z + 4 + 12 + 3 + 1 + 4)
        items["frame"] = d * g.frame[0].size if g.frame.strides[0] else 0
        items["stable step"] = d * 4
        per_node = 2 * 2 * 3 * d + 2 * 3 * d + d + (2 * 2 * 3 * d + 2 * 3 * d + d)  # x, v, f; d, omega, m; masses
    else:
        n_qp = g.dN.shape[1]
        items["reference"] = d * (n_qp * 8 * 3 + n_qp)
        if g.has_hourglass:
            items["hourglass"] = d * (4 * 8 + 1)
        items["frame"] = 9 * d if mat.startswith("fabric") else 0
        items["stable step"] = d * (1 + 3 + 1 + 1)
        per_node = 2 * 3 * d + 2 * 3 * d + 2 * 3 * d + d
    items["state"] = 2 * g.state[0].size * d
    items["nodes"] = per_node * n_node / n_el
    return {"items": items, "total": float(sum(items.values())), "n_el": n_el, "n_node": n_node}


# ----------------------------------------------------------------------------------------------------------------
# Floor: triad and flop loop
# ----------------------------------------------------------------------------------------------------------------

LANES = 64
"""Independent multiply-add chains of the vector flop loop: 16 AVX2 vectors in flight, more than the add and
multiply latency needs."""


def _floor_kernels():
    import numba
    import numpy as np

    from fdeck.jit import FLAGS

    flags = dict(FLAGS, cache=False)

    @numba.njit(parallel=True, **flags)
    def triad(a, b, c, s):
        for i in numba.prange(a.shape[0]):
            a[i] = b[i] + s * c[i]

    @numba.njit(**flags)
    def chains(n, m, c, seed, width):
        """`width` independent chains acc_k = acc_k m + c, four times per lane and pass, n passes: 8 n width flops.
        The width is a run-time value so LLVM keeps the lane loop and vectorises it (instead of unrolling it into
        scalar registers); four updates per load and store keep the loop on the arithmetic units."""
        acc = np.empty(width)
        for k in range(width):
            acc[k] = seed + k
        for _ in range(n):
            for k in range(width):
                a = acc[k]
                a = a * m + c
                a = a * m + c
                a = a * m + c
                a = a * m + c
                acc[k] = a
        s = 0.0
        for k in range(width):
            s += acc[k]
        return s

    @numba.njit(**flags)
    def scalar_chains(n, m, c, seed):
        """16 independent chains in scalar registers, n times: 32 n flops (LLVM leaves them scalar)."""
        a0, a1, a2, a3, a4, a5, a6, a7 = seed, seed + 1, seed + 2, seed + 3, seed + 4, seed + 5, seed + 6, seed + 7
        b0, b1, b2, b3, b4, b5, b6, b7 = seed, seed - 1, seed - 2, seed - 3, seed - 4, seed - 5, seed - 6, seed - 7
        for _ in range(n):
            a0, a1, a2, a3 = a0 * m + c, a1 * m + c, a2 * m + c, a3 * m + c
            a4, a5, a6, a7 = a4 * m + c, a5 * m + c, a6 * m + c, a7 * m + c
            b0, b1, b2, b3 = b0 * m + c, b1 * m + c, b2 * m + c, b3 * m + c
            b4, b5, b6, b7 = b4 * m + c, b5 * m + c, b6 * m + c, b7 * m + c
        return a0 + a1 + a2 + a3 + a4 + a5 + a6 + a7 + b0 + b1 + b2 + b3 + b4 + b5 + b6 + b7

    @numba.njit(parallel=True, **flags)
    def flops(n, m, c, out):
        for t in numba.prange(out.shape[0]):
            out[t] = chains(n, m, c, float(t), LANES)

    @numba.njit(parallel=True, **flags)
    def scalar_flops(n, m, c, out):
        for t in numba.prange(out.shape[0]):
            out[t] = scalar_chains(n, m, c, float(t))

    return triad, chains, flops, scalar_chains, scalar_flops


def measure_floor(threads: int, n_triad: int, repeats: int) -> dict:
    """Best-of-`repeats` triad bandwidth [B/s] (24 B per index) and flop rate [flop/s] on `threads` threads."""
    import numba
    import numpy as np

    numba.set_num_threads(threads)
    triad, chains, flops, scalar_chains, scalar_flops = _floor_kernels()
    a, b, c = np.zeros(n_triad), np.ones(n_triad), np.full(n_triad, 2.0)
    triad(a, b, c, 3.0)  # compile and first touch
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        triad(a, b, c, 3.0)
        times.append(time.perf_counter() - t0)
    assert a[0] == 7.0 and a[-1] == 7.0
    out = np.zeros(threads)
    rates = {}
    for name, fn, per_pass, n in (("vector", flops, 8.0 * LANES, 250_000), ("scalar", scalar_flops, 32.0, 4_000_000)):
        fn(100, 0.999999, 1e-7, out)
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn(n, 0.999999, 1e-7, out)
            ts.append(time.perf_counter() - t0)
        rates[name] = (per_pass * n * threads / min(ts), max(ts) / min(ts))
    packed = {}
    for name, fn in (("vector", chains), ("scalar", scalar_chains)):
        asm = "\n".join(fn.inspect_asm().values()).splitlines()
        packed[name] = sorted({op for op in ("vmulpd", "vaddpd", "vfmadd") for ln in asm
                               if op in ln and ("ymm" in ln or "zmm" in ln)})
    return {"threads": threads, "triad_bytes": 24 * n_triad, "bandwidth": 24 * n_triad / min(times),
            "bandwidth_spread": max(times) / min(times), "flop_rate": rates["vector"][0],
            "flop_spread": rates["vector"][1], "vectorised": bool(packed["vector"]), "packed_ops": packed["vector"],
            "scalar_flop_rate": rates["scalar"][0], "scalar_packed_ops": packed["scalar"]}


# ----------------------------------------------------------------------------------------------------------------
# Driver
# ----------------------------------------------------------------------------------------------------------------

def _run(args, env=None, script=__file__) -> dict:
    r = subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True, cwd=ROOT,
                       env=dict(os.environ, **(env or {})))
    if r.returncode:
        raise RuntimeError(r.stderr[-3000:])
    return json.loads(r.stdout.strip().splitlines()[-1])


def _load() -> str:
    return open("/proc/loadavg").read().split()[0] if os.path.exists("/proc/loadavg") else "?"


def table(result: dict) -> str:
    fl = {f["threads"]: f for f in result["floor"]}
    lines = ["| kernel | material | elements | flops/el-cycle | compulsory B/el-cycle | resident B/el today | "
             "floor 1 thr [us] | measured 1 thr [us] | ratio 1 thr | floor 2 thr [us] | measured 2 thr [us] | "
             "ratio 2 thr |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for k in result["kernels"]:
        cells = []
        for t in (1, 2):
            m = k["measured"].get(str(t))
            fl_us = k["floor_us"][str(t)]
            cells += [f"{fl_us:.3f}", f"{m:.3f}" if m else "-", f"{m / fl_us:.1f}" if m else "-"]
        lines.append(f"| {k['formulation']} | {k['material']} | {k['elements']} | {k['flops']:.0f} | "
                     f"{k['bytes']:.0f} | {k['resident_bytes']:.0f} | " + " | ".join(cells) + " |")
    f1, f2 = fl[1], fl[2]
    lines.append("")
    lines.append(f"Floor measured by the benchmark (numba, fdeck's flags): triad {f1['bandwidth'] / 1e9:.1f} GB/s on "
                 f"1 thread, {f2['bandwidth'] / 1e9:.1f} GB/s on 2; multiply-add chains "
                 f"{f1['flop_rate'] / 1e9:.1f} Gflop/s on 1 thread, {f2['flop_rate'] / 1e9:.1f} on 2 "
                 f"({'vectorised: ' + ', '.join(f1['packed_ops']) if f1['vectorised'] else 'scalar'}); scalar build "
                 f"{f1['scalar_flop_rate'] / 1e9:.1f} Gflop/s on 1 thread. Load average "
                 f"{', '.join(result['load'])} during the rounds; best of {result['rounds']} rounds.")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--count", nargs=2, help=argparse.SUPPRESS)  # form mat (subprocess, NUMBA_DISABLE_JIT=1)
    ap.add_argument("--floor", nargs=3, type=int, help=argparse.SUPPRESS)  # threads n_triad repeats (subprocess)
    ap.add_argument("--bytes", nargs=3, help=argparse.SUPPRESS)  # form mat divisions
    args = ap.parse_args(argv)
    if args.count:
        print(json.dumps(count_flops(*args.count)))
        return
    if args.floor:
        print(json.dumps(measure_floor(*args.floor)))
        return
    if args.bytes:
        print(json.dumps(compulsory_bytes(args.bytes[0], args.bytes[1], tuple(map(int, args.bytes[2].split(","))))))
        return
    path = HERE / "floor.json"
    if args.report:
        print(table(json.loads(path.read_text())))
        return
    div, cycles = ((50, 50, 4), 200) if args.quick else ((160, 160, 4), 40)
    rounds = args.rounds or (1 if args.quick else 3)
    n_triad = 1 << 24  # 3 arrays of 128 MiB: 12x the 32 MiB L3
    counts, nbytes = {}, {}
    for form, mat in KERNELS:
        c = _run(["--count", form, mat], env={"NUMBA_DISABLE_JIT": "1"})
        counts[(form, mat)] = c
        nbytes[(form, mat)] = _run(["--bytes", form, mat, ",".join(map(str, div))])
        print(f"{form:8s} {mat:22s} flops/el-cycle {flops_total(c['update']) + flops_total(c['gather']):.0f}  "
              f"compulsory {nbytes[(form, mat)]['total']:.0f} B/el-cycle", flush=True)
    floors = {1: [], 2: []}
    runs = {}
    loads = []
    for r in range(rounds):
        loads.append(_load())
        for t in (1, 2):
            floors[t].append(_run(["--floor", str(t), str(n_triad), "5"]))
            print(f"round {r}: {t} thr triad {floors[t][-1]['bandwidth'] / 1e9:.2f} GB/s, flops "
                  f"{floors[t][-1]['flop_rate'] / 1e9:.2f} Gflop/s", flush=True)
        for form, mat in KERNELS:
            for t in (1, 2):
                row = _run(["--one", form, mat, ",".join(map(str, div)), str(cycles), str(t)],
                           script=HERE / "bench.py")
                runs.setdefault((form, mat, t), []).append(row)
                print(f"round {r}: {form:8s} {mat:22s} {t} thr {row['us_per_element_cycle']:.3f} us/el-cycle",
                      flush=True)
    loads.append(_load())
    best_floor = []
    for t in (1, 2):
        fs = floors[t]
        bw = max(f["bandwidth"] for f in fs)
        fr = max(f["flop_rate"] for f in fs)
        best_floor.append(dict(fs[0], bandwidth=bw, flop_rate=fr,
                               scalar_flop_rate=max(f["scalar_flop_rate"] for f in fs),
                               bandwidth_rounds=[f["bandwidth"] for f in fs], flop_rounds=[f["flop_rate"] for f in fs]))
    kernels = []
    for form, mat in KERNELS:
        c, b = counts[(form, mat)], nbytes[(form, mat)]
        n_el, n_node = b["n_el"], b["n_node"]
        fl = (flops_total(c["update"]) + flops_total(c["gather"]) + flops_total(c["stable_dt"])
              + (flops_total(c["kick"]) + flops_total(c["drift"])) * n_node / n_el)
        floor_us, measured, spread = {}, {}, {}
        for f in best_floor:
            t = f["threads"]
            floor_us[str(t)] = 1e6 * max(b["total"] / f["bandwidth"], fl / f["flop_rate"])
            rs = [r["us_per_element_cycle"] for r in runs.get((form, mat, t), [])]
            if rs:
                measured[str(t)], spread[str(t)] = min(rs), max(rs) / min(rs)
        first = runs[(form, mat, 1)][0]
        kernels.append({"formulation": form, "material": mat, "elements": n_el, "nodes": n_node,
                        "flops": fl, "flop_counts": c, "bytes": b["total"], "byte_items": b["items"],
                        "resident_bytes": first["bytes_per_element"], "floor_us": floor_us, "measured": measured,
                        "measured_spread": spread,
                        "measured_rounds": {str(t): [r["us_per_element_cycle"] for r in runs[(form, mat, t)]]
                                            for t in (1, 2)},
                        "elements_only": {str(t): min(r["us_per_element_cycle_elements_only"]
                                                      for r in runs[(form, mat, t)]) for t in (1, 2)}})
    result = {"machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                          "python": platform.python_version(), "numba_threads_env": os.environ.get(
                              "NUMBA_NUM_THREADS", "unset")},
              "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "rounds": rounds, "load": loads,
              "floor": best_floor,
              "kernels": kernels, "divisions": list(div), "cycles": cycles}
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(table(result))


if __name__ == "__main__":
    main()
