"""Everything ``fdeck validate`` checks, in order, as one function the CLI and the tests share: the deck's schema
and names, the absurd-figure checks that need no mesh (``sanity.deck_figures``), compilation (sets, geometry,
files), then the figures of the compiled problem (``sanity.problem_figures``). Every error is a located
``Problem`` inside one ``DeckError``; nothing is run."""

from __future__ import annotations

from pathlib import Path

from fdeck.deck.errors import DeckError


def check_deck(path: Path):
    """-> (deck, locations, problem, warnings). Raises ``DeckError`` listing every located error (with the
    warnings found up to there)."""
    from fdeck.compile import sanity
    from fdeck.compile.errors import CompileError
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.read import located, read_deck

    path = Path(path)
    deck, locs, warnings = read_deck(path)
    limits = sanity.Limits.from_env()

    def split(found):
        problems = [located(str(path), locs, p, m, sev) for p, m, sev in found]
        warnings.extend(p for p in problems if p.severity == "warning")
        errors = [p for p in problems if p.severity == "error"]
        if errors:
            raise DeckError(errors + warnings)

    split(sanity.deck_figures(deck, limits))
    try:
        problem = compile_deck(deck, path.parent)
    except CompileError as exc:
        raise DeckError([located(str(path), locs, p, m) for p, m in exc.problems] + warnings) from None
    split(sanity.problem_figures(problem, limits))
    return deck, locs, problem, warnings


def _preset_dir(card_cls):
    """The PRESET_DIR of the first module along the card class's bases that has one, or None."""
    import sys

    for cls in card_cls.__mro__:
        folder = getattr(sys.modules.get(cls.__module__), "PRESET_DIR", None)
        if folder is not None:
            return folder
    return None


def read_paths(deck, base: Path) -> list[tuple[str, str]]:
    """[(what, resolved path)] of every file the deck makes fdeck read: the mesh file and tool surfaces (relative
    to the deck's folder ``base``, or absolute as written), and the presets its materials and sections name (from
    fdeck's own preset folders, by name only)."""
    def resolve(name: str) -> str:
        p = Path(name)
        return str((p if p.is_absolute() else Path(base) / p).resolve())

    out = []
    if deck.mesh.file is not None:
        out.append(("mesh file", resolve(deck.mesh.file)))
    for name, tool in deck.tools.items():
        if getattr(tool.surface, "file", None):
            out.append((f"tool {name} surface", resolve(tool.surface.file)))
    for name, card in deck.materials.items():
        folder = _preset_dir(type(card)) if getattr(card, "preset", None) else None
        if folder is not None:
            out.append((f"material {name} preset {card.preset}", str(folder.joinpath(f"{card.preset}.yaml"))))
    for i, sec in enumerate(deck.sections):
        folder = _preset_dir(type(sec)) if getattr(sec, "preset", None) else None
        if folder is not None:
            path = folder.joinpath(sec.formulation, f"{sec.preset}.yaml")
            out.append((f"sections[{i}] preset {sec.preset}", str(path)))
    return out
