"""Write the rigid-tool surfaces of the forming decks into decks/forming/tools/ (binary STL; quarter models, half for the tetrahedron).

Tools are written in their INITIAL position: die flange at z = 0 with the blank on it, punch / upper tool raised by
its travel above its closed position (double dome and tetrahedron 65 mm, MODELS.md 6.4; square tube 20 mm, 6.5), so a deck moves
them by -travel along z. Run: python decks/forming/make_tools.py [OUT_DIR]
"""

from pathlib import Path

import numpy as np

import sys

from fdeck.physics.tools.generators import double_dome, flange_holder, square_tube, tetrahedron, write_surface

OUT = Path(__file__).resolve().parent / "tools"


def tetrahedron_holder(**kw):
    """The tetrahedron die's flat flange turned over (generators.flange_holder); decks lift it by an offset."""
    return flange_holder(*tetrahedron(part="die", **kw))


H = 4.0            # plan edge on curved parts [mm]: chord error <= 4^2 / (8 * 12.6) = 0.16 mm on the punch fillet
TOOLS = {
    "double_dome_punch.stl": (double_dome, dict(part="punch", h=H), 65.0),
    # the whole punch for the quarter decks: a quarter punch is closed by caps on the symmetry planes, which a blank
    # node on those planes would take for the nearest face (distance 0, normal across the plane)
    "double_dome_punch_whole.stl": (double_dome, dict(part="punch", h=H, quarter=False), 65.0),
    "double_dome_die.stl": (double_dome, dict(part="die", h=H), 0.0),
    "double_dome_holder.stl": (double_dome, dict(part="holder", h=H), 0.0),
    "tetrahedron_punch.stl": (tetrahedron, dict(part="punch", h=H), 65.0),
    # the whole punch for the half decks (the half one is capped on the symmetry plane, see above)
    "tetrahedron_punch_whole.stl": (tetrahedron, dict(part="punch", h=H, half=False), 65.0),
    "tetrahedron_die.stl": (tetrahedron, dict(part="die", h=H), 0.0),
    "tetrahedron_holder.stl": (tetrahedron_holder, dict(h=H), 0.0),
    # whole die and holder: the full-model check of the symmetry condition (decks/studies/tetrahedron_symmetry.yaml)
    "tetrahedron_die_whole.stl": (tetrahedron, dict(part="die", h=H, half=False), 0.0),
    "tetrahedron_holder_whole.stl": (tetrahedron_holder, dict(h=H, half=False), 0.0),
    "square_tube_lower.stl": (square_tube, dict(part="lower", h=2.0), 0.0),
    "square_tube_upper.stl": (square_tube, dict(part="upper", h=2.0), 20.0),
}


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else OUT  # another folder: compare with the shipped surfaces
    out.mkdir(exist_ok=True)
    for name, (gen, kw, lift) in TOOLS.items():
        p, t = gen(**kw)
        p = p + np.array([0.0, 0.0, lift])
        write_surface(out / name, p, t)
        print(f"{name}: {len(t)} triangles, {(out / name).stat().st_size / 1e6:.2f} MB, "
              f"bbox {p.min(axis=0).round(2)} .. {p.max(axis=0).round(2)}")


if __name__ == "__main__":
    main()
