"""Cost of contact per blank node and cycle, against the cost of the shell elements (issue 8, deliverable 3).

A square `sm` plate of about 10^4 and 10^5 nodes (0.23 mm T300, 1 mm elements) rests under gravity on a floor and
is indented by a sphere of radius a quarter of the plate's side; floor and sphere are analytic in one case and
triangulated in the other (a floor of about as many triangles as the plate has nodes; a sphere of 20 000 triangles),
so the cost of a query shows whether it depends on the tool's facet count. Every blank node is a contact node of
both pairs. The engine's own timers give the seconds spent in each contact pair and in the elements; a warm-up on
the same problem comes first (compilation, first touch).

    python benchmarks/contact.py            # 10^4 and 10^5 nodes, 1 and 2 threads (about 3 minutes)
    python benchmarks/contact.py --report   # markdown table of benchmarks/contact.json (what the README shows)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # the fdeck beside this file, not an installed one


def uv_sphere(radius: float, n: int):
    """(points, triangles) of a sphere about the origin, n meridians and n/2 + 1 rings, outward."""
    import numpy as np

    th = np.linspace(0.0, np.pi, n // 2 + 1)[1:-1]
    ph = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    P = [[0.0, 0.0, radius]] + [[radius * np.sin(t) * np.cos(p), radius * np.sin(t) * np.sin(p), radius * np.cos(t)]
                                 for t in th for p in ph] + [[0.0, 0.0, -radius]]
    T, m = [], len(th)
    for j in range(n):
        T.append([0, 1 + j, 1 + (j + 1) % n])
        T.append([len(P) - 1, 1 + (m - 1) * n + (j + 1) % n, 1 + (m - 1) * n + j])
    for r in range(m - 1):
        for j in range(n):
            a, b = 1 + r * n + j, 1 + r * n + (j + 1) % n
            T += [[a, a + n, b + n], [a, b + n, b]]
    return np.array(P), np.array(T)


def grid(side: float, m: int, z: float):
    """(points, triangles) of an m x m grid of squares (2 m^2 triangles) covering [-side/2, 3 side/2]^2, normal +z."""
    import numpy as np

    s = np.linspace(-0.5 * side, 1.5 * side, m + 1)
    X, Y = np.meshgrid(s, s, indexing="ij")
    P = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, z)])
    T = []
    for i in range(m):
        for j in range(m):
            a, b, c, d = i * (m + 1) + j, (i + 1) * (m + 1) + j, (i + 1) * (m + 1) + j + 1, i * (m + 1) + j + 1
            T += [[a, b, c], [a, c, d]]
    return P, np.array(T)


def deck(n: int, triangulated: bool, folder: Path, cycles: int) -> dict:
    import numpy as np

    from fdeck.physics.tools.generators import write_surface

    side = float(n)
    r = 0.25 * side
    centre = [0.5 * side, 0.5 * side, r + 0.115]  # touching the plate at its centre
    if triangulated:
        P, T = uv_sphere(r, 200)
        write_surface(folder / "sphere.stl", P + np.array(centre), T)
        m = int(round(n / 2 ** 0.5))
        write_surface(folder / "floor.stl", *grid(side, m, -0.115))
        floor, punch = {"shape": "mesh", "file": str(folder / "floor.stl")}, \
            {"shape": "mesh", "file": str(folder / "sphere.stl")}
    else:
        floor = {"shape": "plane", "point": [0, 0, -0.115]}
        punch = {"shape": "sphere", "centre": centre, "radius": r}
    law = {"law": "linear", "stiffness": 10.0}
    return {
        "mesh": {"plate": {"size": [side, side], "divisions": [n, n]}},
        "materials": {"fab": {"type": "sm"}},
        "sections": [{"material": "fab"}],
        "tools": {"floor": {"surface": floor},
                  "punch": {"surface": punch, "motion": {"kind": "velocity", "value": 20.0}}},
        "contact": [{"tool": "floor", "normal": law, "friction": {"static": 0.2}},
                    {"tool": "punch", "normal": law, "friction": {"static": 0.2}}],
        "loads": [{"type": "gravity", "acceleration": [0, 0, -9810.0]}],
        "steps": [{"duration": 1.0, "max_cycles": cycles}],
        "output": {"frames": 1, "history_points": 2},
    }


def measure(n: int, triangulated: bool, cycles: int, threads: int) -> dict:
    import numba

    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    numba.set_num_threads(threads)
    with tempfile.TemporaryDirectory() as tmp:
        problem = compile_deck(Deck.model_validate(deck(n, triangulated, Path(tmp), cycles)))
    problem.steps[0].max_cycles = 3
    solver.run(problem, solver.Sink())
    problem.steps[0].max_cycles = cycles
    res = solver.run(problem, solver.Sink())
    pairs = [e for e in problem.effects if e.name.startswith("contact:")]
    nodes = sum(len(e.nodes) for e in pairs)
    contact = sum(res.timings[e.name] for e in pairs)
    elements = sum(v for k, v in res.timings.items() if k.startswith("section"))
    touching = int(sum((e.status > 0).sum() for e in pairs))
    return {"nodes": problem.n_node, "elements": problem.n_element, "triangulated": triangulated, "threads": threads,
            "cycles": res.cycles, "triangles": sum(len(e.grid.T) for e in pairs if e.grid is not None),
            "contact_nodes": nodes, "touching_at_end": touching,
            "us_per_contact_node_cycle": 1e6 * contact / (res.cycles * nodes),
            "us_per_element_cycle_elements": 1e6 * elements / (res.cycles * problem.n_element),
            "contact_share": contact / res.wall, "status": res.status}


def report(result: dict) -> str:
    lines = ["| tools | blank nodes | triangles | threads | us per contact node-cycle (2 pairs) | "
             "us per element-cycle, elements | contact share of the cycle |", "|---|---|---|---|---|---|---|"]
    for r in result["runs"]:
        lines.append(f"| {'triangulated' if r['triangulated'] else 'analytic'} | {r['nodes']:,} | {r['triangles']:,} "
                     f"| {r['threads']} | {r['us_per_contact_node_cycle']:.3f} | "
                     f"{r['us_per_element_cycle_elements']:.3f} | {100 * r['contact_share']:.0f} % |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--one", nargs=4, help=argparse.SUPPRESS)  # n triangulated cycles threads
    a = ap.parse_args()
    if a.report:
        print(report(json.loads((HERE / "contact.json").read_text())))
        return
    if a.one:
        n, tri, cycles, threads = a.one
        print(json.dumps(measure(int(n), tri == "1", int(cycles), int(threads))))
        return
    rows = []
    for n, cycles in ((99, 300), (315, 60)):  # 10 000 and 99 856 nodes
        for tri in (False, True):
            for threads in (1, 2):
                r = subprocess.run([sys.executable, __file__, "--one", str(n), "1" if tri else "0", str(cycles),
                                    str(threads)], capture_output=True, text=True, env=dict(os.environ))
                if r.returncode:
                    print(r.stderr, file=sys.stderr)
                    continue
                row = json.loads(r.stdout.strip().splitlines()[-1])
                rows.append(row)
                print(row, flush=True)
    (HERE / "contact.json").write_text(json.dumps({"runs": rows}, indent=1) + "\n")
    print(report({"runs": rows}))


if __name__ == "__main__":
    main()
