"""The study and identification files (STUDY.yaml, IDENT.yaml) as frozen pydantic cards.

They are read like decks (``load``): YAML 1.2 scalars, duplicate keys refused, every problem located as
``file:line:col: path: message`` through the deck loader's machinery (``fdeck.deck.errors``). Deck paths inside them
(``sections.0.formulation``) are checked against the base deck by ``variants.check_paths``.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import Field, ValidationError, model_validator

from fdeck.deck.base import Card

Settings = dict[str, Any]
_SETTINGS = "Values by deck path, e.g. {sections.0.formulation: reduced, mesh.block.divisions: [40, 1, 4]}."
_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.=,\[\]+-]*$"


class Variant(Card):
    """One named variant: the deck paths it sets (over the study's common `set`)."""

    name: str = Field(pattern=_NAME, description="Variant name (letters, digits and _ . = , [ ] + -).")
    set: Settings = Field(default_factory=dict, description=_SETTINGS)


class Finest(Card):
    """Reference = the answer of one variant (by default the last one listed, taken as the finest)."""

    type: Literal["finest"]
    variant: str | None = Field(None, description="Name of the reference variant (default: the last variant).")


class Richardson(Card):
    """Reference = Richardson extrapolation of three systematically refined variants (coarse, medium, fine), each
    refined by the same `ratio` h_coarse / h_medium = h_medium / h_fine; the observed order is reported."""

    type: Literal["richardson"]
    variants: list[str] | None = Field(None, min_length=3, max_length=3, description="Coarse, medium, fine (default: "
                                       "the last three grid points of a one-path grid, as listed).")
    ratio: float = Field(2.0, gt=1.0, description="Refinement ratio between consecutive variants (element length).")


class Given(Card):
    """Reference = a given value per quantity: a closed form or a measurement (say which in `source`)."""

    type: Literal["closed_form", "measured"]
    values: dict[str, float] = Field(min_length=1, description="Reference value per quantity (quantity's units).")
    source: str = Field("", description="Where the values come from (formula, paper, test).")


Reference = Annotated[Union[Finest, Richardson, Given], Field(discriminator="type")]


class Continuation(Card):
    """Static solves along one deck parameter: each run is solved first at these values (each from the previous
    equilibrium), then at the run's own value (a value that fails is halved geometrically, see
    ``fdeck.engine.static.continuation``)."""

    path: str = Field(description="Deck path of the parameter, e.g. materials.3weave.compression_ratio.")
    values: list[float] = Field(min_length=1, description="Values before the run's own, in order (those on the "
                                "run's side of its own value are skipped).")


class StaticSolve(Card):
    """How `solver: static` solves each run (``fdeck.engine.static``: load-stepped Newton, finite-difference
    tangent; hexahedra, loads that do not follow the body, no tools)."""

    continuation: Continuation | None = None
    max_iterations: int = Field(20, ge=1, description="Newton iterations per load increment before it is halved.")
    follow_stable: bool = Field(False, description="Check every converged load increment's stability and, where "
                                "the branch followed has lost it (negative eigenvalues of the tangent), switch to a "
                                "stable branch along a direction of negative curvature (fdeck.engine.static, "
                                "`stable`); the summary counts the switches (`branch_switches`).")
    stability: bool = Field(False, description="Also count the negative eigenvalues of the tangent stiffness at "
                            "the answer (summary `negative_eigenvalues`: 0 at a stable equilibrium; one sparse "
                            "factorisation more), or at the last equilibrium of a solve that stops short of full "
                            "load (`negative_eigenvalues_at_stop`, `load_factor_reached`, stop_positions.npy).")


class Solver(Card):
    """Dynamic runs (the deck as `fdeck run` runs it) or static equilibria under the loads at the end of the last
    step (seconds instead of minutes for a strip settling under its own weight; measures at the equilibrium)."""

    solver: Literal["dynamic", "static"] = Field("dynamic", description="dynamic: `fdeck run`; static: equilibrium "
                                                  "by Newton (fdeck.engine.static), measures at the answer.")
    static: StaticSolve = Field(default_factory=StaticSolve, description="Options of `solver: static`.")

    def solver_options(self) -> dict | None:
        """None for dynamic runs, else the static options as plain data (part of every run's cache key)."""
        return None if self.solver == "dynamic" else self.static.model_dump(mode="json")


class StudySpec(Solver):
    """A study: a base deck, its variants, the quantities compared, the reference and the tolerance."""

    title: str = ""
    base: str = Field(description="Base deck, relative to the study file.")
    set: Settings = Field(default_factory=dict, description="Applied to every variant first. " + _SETTINGS)
    grid: dict[str, list[Any]] = Field(default_factory=dict, description="Values per deck path; every combination "
                                       "(first path slowest) is a variant named after its values.")
    variants: list[Variant] = Field(default_factory=list, description="Named variants, after the grid points.")
    quantities: list[str] = Field(min_length=1, description="Summary measures, check values or final history "
                                  "columns compared (by name).")
    reference: Reference
    tolerance: float = Field(gt=0, description="Largest relative error |answer - reference| / |reference| of every "
                             "quantity for a variant to count as accurate enough.")

    @model_validator(mode="after")
    def _consistent(self):
        if not self.grid and not self.variants:
            raise ValueError("give a `grid`, `variants` or both")
        if any(len(v) == 0 for v in self.grid.values()):
            raise ValueError("every grid path needs at least one value")
        if isinstance(self.reference, Given):
            missing = [q for q in self.quantities if q not in self.reference.values]
            if missing:
                raise ValueError(f"reference.values gives no value for {missing}")
        if isinstance(self.reference, Richardson) and self.reference.variants is None:
            if len(self.grid) != 1 or len(next(iter(self.grid.values()))) < 3:
                raise ValueError("reference.variants: name the coarse, medium and fine variants (only a one-path "
                                 "grid of three or more values implies them)")
        return self


class Parameter(Card):
    """A deck parameter to fit, by path, with its start value and bounds."""

    path: str = Field(description="Deck path of a number, e.g. materials.bar.youngs_modulus.")
    initial: float | None = Field(None, description="Start value (default: the base deck's value).")
    lower: float = Field(-math.inf, description="Lower bound.")
    upper: float = Field(math.inf, description="Upper bound.")

    @model_validator(mode="after")
    def _bounds(self):
        if not self.lower < self.upper:
            raise ValueError(f"lower {self.lower} must be below upper {self.upper}")
        if self.initial is not None and not self.lower <= self.initial <= self.upper:
            raise ValueError(f"initial {self.initial} lies outside [{self.lower}, {self.upper}]")
        if self.initial == 0.0:
            raise ValueError("initial must not be 0: the finite-difference steps are relative to it")
        return self


class DataPoint(Card):
    """One measured value: the deck (base or its own) with its settings, and the value measured on it."""

    name: str | None = Field(None, pattern=_NAME, description="Label in the report (default p0, p1, ...).")
    deck: str | None = Field(None, description="Deck of this point, relative to the file (default: `base`).")
    set: Settings = Field(default_factory=dict, description=_SETTINGS)
    value: float = Field(description="Measured value of the quantity.")
    sigma: float | None = Field(None, gt=0, description="Its uncertainty; residuals are divided by it (default: "
                                "|value| for relative residuals, 1 for absolute ones).")


class Table(Card):
    """Measured values against one deck path: rows of [value set at `path`, measured quantity]."""

    path: str = Field(description="Deck path varied, e.g. mesh.block.size.0.")
    rows: list[tuple[Any, float]] = Field(min_length=1)


class PresetOut(Card):
    """Where the fitted values go: a preset file of the fitted material."""

    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_-]*$", description="Preset name: <out>/<name>.yaml.")
    material: str | None = Field(None, description="Material whose preset it is (default: the material of the "
                                 "first parameter's path, materials.<name>...).")


class IdentSpec(Solver):
    """A fit of deck parameters to measured values of one quantity (scipy least_squares)."""

    title: str = ""
    base: str = Field(description="Base deck, relative to the file.")
    set: Settings = Field(default_factory=dict, description="Applied to every run first. " + _SETTINGS)
    parameters: list[Parameter] = Field(min_length=1)
    quantity: str = Field(description="Summary measure, check value or final history column compared (by name).")
    points: list[DataPoint] = Field(default_factory=list)
    table: Table | None = None
    residual: Literal["relative", "absolute"] = Field("relative", description="(model - measured) / |measured| or "
                                                      "model - measured, each divided by the point's sigma if given.")
    rel_step: float = Field(1e-3, gt=0, lt=0.5, description="Finite-difference step relative to each parameter.")
    max_evaluations: int = Field(20, ge=1, description="Largest number of residual evaluations of least_squares.")
    tolerance: float = Field(1e-8, gt=0, description="ftol = xtol = gtol of least_squares.")
    preset: PresetOut | None = None

    @model_validator(mode="after")
    def _data(self):
        if not self.points and self.table is None:
            raise ValueError("give measured `points`, a `table` or both")
        if self.n_data < len(self.parameters):
            raise ValueError(f"{self.n_data} data points cannot determine {len(self.parameters)} parameters")
        paths = [p.path for p in self.parameters]
        if len(set(paths)) != len(paths):
            raise ValueError(f"a parameter path is repeated: {paths}")
        return self

    @property
    def n_data(self) -> int:
        return len(self.points) + (len(self.table.rows) if self.table else 0)

    def data_points(self) -> list[DataPoint]:
        """Points then table rows, all as DataPoints with names."""
        pts = [p if p.name else p.model_copy(update={"name": f"p{i}"}) for i, p in enumerate(self.points)]
        if self.table:
            keys = self.table.path.split(".")
            tail = ".".join(keys[-2:]) if keys[-1].isdigit() and len(keys) > 1 else keys[-1]
            last = re.sub(r"[^A-Za-z0-9_.]", "_", tail)  # mesh.block.size.0 -> size.0
            for x, y in self.table.rows:
                pts.append(DataPoint(name=f"{last}={x}".replace(" ", ""), set={self.table.path: x}, value=y))
        return pts


def load(path: str | Path, model_cls):
    """-> (spec, Locations). Raises DeckError with every located problem."""
    from fdeck.deck.errors import DeckError, problems_from_validation_error
    from fdeck.deck.loader import load_file

    data, locs = load_file(path)
    try:
        return model_cls.model_validate(data), locs
    except ValidationError as exc:
        raise DeckError(problems_from_validation_error(exc, locs, str(path), model_cls)) from None


def json_schemas() -> dict[str, dict]:
    """JSON schemas of the study and identification files, by file name (``fdeck schema`` writes them beside the
    deck's, for editors: a file's first line ``# yaml-language-server: $schema=.../study.schema.json``)."""
    out = {}
    for name, cls, title in (("study.schema.json", StudySpec, "fdeck study"),
                             ("ident.schema.json", IdentSpec, "fdeck identify")):
        s = cls.model_json_schema()
        s["$schema"] = "https://json-schema.org/draft/2020-12/schema"
        s["title"] = title
        out[name] = s
    return out
