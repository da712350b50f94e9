"""The deck: every section of a YAML input as a frozen pydantic model.

Material, boundary, load, measure and section cards come from the card tables of the registry (``fdeck.registry``,
filled by ``fdeck.cards``, which imports neither numpy nor numba), so a new card is a new module, not an edit here.
Values are canonical after validation (SI-consistent numbers in the declared unit system, defaults filled in); cross
references by name are checked in ``Deck``'s validator, mesh set names in the compiler.
"""

from __future__ import annotations

import bisect
from typing import Annotated, Literal, Union

from pydantic import Discriminator, Field, Tag, model_validator

from fdeck import registry
from fdeck.deck.base import Card
from fdeck.deck.errors import unknown_name
from fdeck.cards.contact import Contact, Tool
from fdeck.cards.checkpoint import Checkpoint
from fdeck.cards.steps import BulkViscosity, Damping, DeformationDamping
from fdeck.cards.mass_scaling import MassScaling
from fdeck.cards.subcycling import Subcycling
from fdeck.deck.section import SectionBase

Vector = tuple[float, float, float]
PositiveInt = Annotated[int, Field(ge=1)]


def _union(table: str, section: str | None = None):
    cards = tuple(k.card for k in registry.cards(table, section).values())
    if len(cards) == 1:
        return cards[0]
    return Annotated[Union[cards], Field(discriminator="type")]


FORMULATIONS = registry.cards("formulation")
MaterialCardU = _union("material")
BoundaryCard = _union("effect", "boundary")
LoadCard = _union("effect", "loads")
SectionEffectCard = _union("effect", "section") if registry.cards("effect", "section") else None
MeasureCard = _union("measure")
SOLID_FORMULATIONS = tuple(k for k, v in FORMULATIONS.items() if v.card is None)
Formulation = Literal[SOLID_FORMULATIONS]  # type: ignore[valid-type]


# -- mesh -------------------------------------------------------------------------------------------
class _Structured(Card):
    """What the built-in generators share: `divisions` or `element_size`, and positive edge lengths `size`."""

    @model_validator(mode="after")
    def _one_of(self):
        if (self.divisions is None) == (self.element_size is None):
            raise ValueError("give exactly one of `divisions` or `element_size`")
        if min(self.size) <= 0:
            raise ValueError(f"every edge length must be > 0, got {list(self.size)}")
        return self


class Block(_Structured):
    """Structured block of hexahedra. Node sets xmin, xmax, ymin, ymax, zmin, zmax (faces) and `all` are made."""

    origin: Vector = Field((0.0, 0.0, 0.0), description="Corner with the smallest coordinates [mm].")
    size: Vector = Field(description="Edge lengths along x, y, z [mm].")
    divisions: tuple[PositiveInt, PositiveInt, PositiveInt] | None = Field(
        None, description="Elements along x, y, z. Give this or `element_size`.")
    element_size: float | None = Field(None, gt=0, description="Target edge length [mm]; divisions = ceil(size/h) "
                                       "(diagonal lattice: see `lattice`).")
    lattice: Literal["grid", "diagonal"] = Field(
        "grid", description="`grid`: edges along x, y, z. `diagonal`: edges in x-y at +-45 deg (diamonds, the halves "
        "cut by the sides one element each), for fibres at +-45 deg; divisions x, y then count half-diagonals "
        "(even) and size x / divisions x must equal size y / divisions y; element_size is then the diamonds' "
        "edge.")


class BoxSet(Card):
    """Entities inside an axis-aligned box (nodes by position, elements by centroid), bounds inclusive [mm]."""

    box: tuple[Vector, Vector] = Field(description="[[xmin, ymin, zmin], [xmax, ymax, zmax]] [mm].")
    tolerance: float = Field(1e-6, ge=0, description="Added to every side of the box [mm].")


class Plate(_Structured):
    """Structured plate of quadrilaterals (or triangles) in the plane z = origin z, normal +z, for shells and
    membranes. Node sets xmin, xmax, ymin, ymax (edges) and `all` are made."""

    origin: Vector = Field((0.0, 0.0, 0.0), description="Corner with the smallest coordinates [mm].")
    size: tuple[float, float] = Field(description="Edge lengths along x and y [mm].")
    divisions: tuple[PositiveInt, PositiveInt] | None = Field(
        None, description="Elements along x and y. Give this or `element_size`.")
    element_size: float | None = Field(None, gt=0, description="Target edge length [mm]; divisions = ceil(size/h).")
    triangles: bool = Field(False, description="Split every quadrilateral into two triangles.")


class Mesh(Card):
    """A built-in block (hexahedra), a built-in plate (shells) or a mesh file read by meshio (Abaqus .inp, Gmsh
    .msh, ...; hexahedra, quadrilaterals and triangles, in any mix), plus extra sets."""

    block: Block | None = None
    plate: Plate | None = None
    file: str | None = Field(None, description="Mesh file, relative to the deck's folder; its sets are kept.")
    node_sets: dict[str, BoxSet] = Field(default_factory=dict, description="Extra node sets by box.")
    element_sets: dict[str, BoxSet] = Field(default_factory=dict, description="Extra element sets by box.")

    @model_validator(mode="after")
    def _one_of(self):
        if sum(x is not None for x in (self.block, self.plate, self.file)) != 1:
            raise ValueError("give exactly one of `block`, `plate` or `file`")
        return self


# -- sections -----------------------------------------------------------------------------------------
class Hourglass(Card):
    """Flanagan-Belytschko hourglass control of `reduced` hexahedra."""

    type: Literal["stiffness", "viscous"] = "stiffness"
    coefficient: float = Field(0.05, gt=0, le=1.0, description="Dimensionless coefficient (stiffness: k = c M V "
                               "sum|b|^2/8 with M the rest wave modulus; viscous: c rho c0 V^(2/3)/4).")


class Section(SectionBase):
    """A solid section: assigns a material and a hexahedral formulation to an element set."""

    formulation: Formulation = Field("fbar", description="Element formulation: "  # type: ignore[valid-type]
                                     + "; ".join(f"{k}: {v.description}" for k, v in FORMULATIONS.items()
                                                 if v.card is None))
    hourglass: Hourglass | None = Field(None, description="Hourglass control (reduced only; default stiffness 0.05).")
    if SectionEffectCard is not None:
        effects: list[SectionEffectCard] = Field(  # type: ignore[valid-type]
            default_factory=list, description="Add-ons computed on this section's elements (e.g. fibre_bending).")

    @model_validator(mode="after")
    def _hourglass_only_reduced(self):
        if self.hourglass is not None and self.formulation != "reduced":
            raise ValueError("`hourglass` applies to formulation `reduced` only")
        return self

    @model_validator(mode="after")
    def _each_effect_once(self):
        # two entries of one effect would each bound the stable step by their own stiffness only, while the
        # elements feel both (fibre_bending: give warp, weft and in_plane in one entry)
        types = [e.type for e in getattr(self, "effects", [])]
        twice = sorted({t for t in types if types.count(t) > 1})
        if twice:
            raise ValueError(f"`effects` lists {', '.join(twice)} more than once: give each effect one entry (for "
                             "fibre_bending, warp, weft and in_plane together), as each entry's stable step counts "
                             "its own stiffness only")
        return self


def formulation(value) -> str | None:
    """Discriminator of section cards: their `formulation`, `fbar` when omitted."""
    if isinstance(value, dict):
        return value.get("formulation", "fbar")
    return getattr(value, "formulation", None)


SectionCard = Annotated[
    Union[tuple(Annotated[k.card or Section, Tag(name)] for name, k in FORMULATIONS.items())],
    Discriminator(formulation)]


# -- amplitudes ------------------------------------------------------------------------------------------
class Tabular(Card):
    """Piecewise-linear amplitude through (time [s], value) points, constant beyond the ends."""

    type: Literal["tabular"]
    points: list[tuple[float, float]] = Field(min_length=2)

    @model_validator(mode="after")
    def _increasing(self):
        ts = [p[0] for p in self.points]
        if any(b <= a for a, b in zip(ts, ts[1:])):
            raise ValueError("times in `points` must increase strictly")
        return self

    def curve(self):
        """a(t): linear interpolation, constant beyond the ends."""
        ts, vs = [p[0] for p in self.points], [p[1] for p in self.points]

        def a(t: float) -> float:
            if t <= ts[0]:
                return vs[0]
            if t >= ts[-1]:
                return vs[-1]
            i = bisect.bisect_right(ts, t)
            return vs[i - 1] + (vs[i] - vs[i - 1]) * (t - ts[i - 1]) / (ts[i] - ts[i - 1])

        return a


class SmoothStep(Card):
    """Quintic smooth step from a0 at t0 to a1 at t1 (zero velocity and acceleration at both ends)."""

    type: Literal["smooth_step"]
    t0: float = Field(0.0, ge=0)
    t1: float = Field(gt=0)
    a0: float = 0.0
    a1: float = 1.0

    @model_validator(mode="after")
    def _order(self):
        if self.t1 <= self.t0:
            raise ValueError("t1 must be greater than t0")
        return self

    def curve(self):
        t0, t1, a0, a1 = self.t0, self.t1, self.a0, self.a1
        return lambda t: a0 + (a1 - a0) * smoothstep((t - t0) / (t1 - t0))


def smoothstep(tau: float) -> float:
    """Quintic 0 -> 1 on [0, 1] with zero first and second derivatives at both ends."""
    s = min(1.0, max(0.0, tau))
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


Amplitude = Annotated[Union[Tabular, SmoothStep], Field(discriminator="type")]
BUILTIN_AMPLITUDES = ("constant", "ramp", "smooth")


# -- steps, output, checks ----------------------------------------------------------------------------------
class Step(Card):
    name: str = "step"
    duration: float = Field(gt=0, description="Step duration [s].")
    dt_safety: float = Field(0.9, gt=0, le=1.0, description="Time step = dt_safety x smallest element step.")
    mass_scaling: MassScaling | None = None
    damping: Damping | None = None
    deformation_damping: DeformationDamping | None = Field(None, description="Damping of each element's motion "
                                                           "relative to its rigid-body motion; none when absent.")
    bulk_viscosity: BulkViscosity | None = Field(None, description="Bulk viscosity in this step ({} for the "
                                                 "defaults b1 = 0.06, b2 = 1.2); none when absent.")
    subcycling: Subcycling | None = Field(None, description="Node steps in powers of two of the smallest in this "
                                          "step ({} for 4 step sizes); none when absent.")
    max_cycles: int | None = Field(None, ge=1, description="End this step after this many cycles (a guard); the "
                                   "next step starts there with its own duration; summary.json names such steps.")
    min_dt_ratio: float = Field(1e-3, gt=0, lt=1, description="Stop the run (exit 4, naming the element or effect "
                                "that sets it) when the stable step falls below this fraction of the step's first "
                                "one: a collapsing step means a crushed element or a runaway contact.")


class PathStack(Card):
    """Through-thickness averaging of a path: each path sample becomes ``samples`` points evenly spread over
    ``span`` along ``axis`` (midpoints of equal sub-intervals, reference coordinates), and the sample's shear angle
    is the mean over the elements holding them. Why: on a layered blank the mid-plane is a layer interface (which
    element a point on it falls into is a tie), and meshes with different layer counts are compared on the same
    quantity when every layer is weighted by its thickness (choose ``samples`` a multiple of each mesh's layers)."""

    axis: Vector = Field([0.0, 0.0, 1.0], description="Thickness direction (reference), normalised by fdeck.")
    span: tuple[float, float] = Field(description="Coordinates along axis of the blank's two faces [mm] (reference).")
    samples: int = Field(8, ge=1, description="Points through the thickness per path sample.")

    @model_validator(mode="after")
    def _proper(self):
        if sum(a * a for a in self.axis) == 0.0:
            raise ValueError("axis must not be the zero vector")
        if self.span[0] == self.span[1]:
            raise ValueError("span needs two different coordinates (the blank's faces)")
        return self


class OutputPath(Card):
    """A polyline in the reference configuration along which the shear angle is tabulated at the end of the run
    (``path_<name>.csv``, and ``path_<name>.png`` when matplotlib is installed)."""

    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$",
                      description="File name part: path_<name>.csv (letters, digits, '_', '.', '-').")
    points: list[Vector] = Field(min_length=2, description="Corners of the polyline, reference coordinates [mm].")
    samples: int = Field(100, ge=2, description="Points sampled evenly along the polyline's arc length.")
    through_thickness: PathStack | None = Field(
        None, description="Average the shear angle through the blank's thickness at every sample (columns "
        "shear_angle = mean, shear_angle_min, shear_angle_max over the stack); absent: the element at the point.")
    window: float | None = Field(
        None, gt=0.0, description="Side [mm] of a square window centred on every sample, aligned with the path, in "
        "the plane normal to the thickness axis (through_thickness.axis, else z), over which the shear angle is "
        "averaged (8 x 8 points): a filter of the element-wise field, so that two meshes are compared on the same "
        "quantity where the shear changes sharply (set it to the coarser mesh's element size); absent: no window.")

    @model_validator(mode="after")
    def _has_length(self):
        zero = [i for i in range(1, len(self.points)) if self.points[i] == self.points[i - 1]]
        if zero:
            raise ValueError(f"points {zero[0] - 1} and {zero[0]} coincide: every segment needs a length")
        if self.window is not None:
            a = self.through_thickness.axis if self.through_thickness is not None else [0.0, 0.0, 1.0]
            na = sum(c * c for c in a) ** 0.5
            for i in range(1, len(self.points)):
                d = [q - p for p, q in zip(self.points[i - 1], self.points[i])]
                along = sum(x * y for x, y in zip(d, a)) / na
                if sum(x * x for x in d) - along * along <= 1e-12 * sum(x * x for x in d):
                    raise ValueError(f"segment {i - 1}-{i} runs along the thickness axis: its window has no "
                                     "in-plane direction")
        return self


class Output(Card):
    frames: int = Field(20, ge=1, description="Frames written, evenly spaced over the run (plus the initial one).")
    formats: list[Literal["vtu", "xdmf"]] = Field(["vtu"], min_length=1)
    history_points: int = Field(1000, ge=2, description="History rows, evenly spaced over the run.")
    reactions: list[str] = Field(default_factory=list, description="Node sets whose reaction forces are recorded.")
    measures: list[MeasureCard] = Field(  # type: ignore[valid-type]
        default_factory=list, description="Quantities recorded as history columns and reported in summary.json.")
    paths: list[OutputPath] = Field(
        default_factory=list, description="Polylines (reference configuration) along which the final shear angle "
        "[deg] is written, with arc length [mm], reference and current points [mm], to path_<name>.csv (+ .png).")
    fibre_table: bool = Field(
        False, description="Write fibres.csv at the end: per element (1-based, mesh order) the current centroid "
        "[mm], the current unit warp and weft directions and the shear angle [deg], for mapping onto a structural "
        "model.")
    checkpoint: Checkpoint | None = Field(
        None, description="Save the whole state every so often for `fdeck run --restart` (none by default; a run "
        "stopped by a signal or --max-wall saves one anyway).")

    @model_validator(mode="after")
    def _unique_paths(self):
        names = [p.name for p in self.paths]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"path names repeated: {dup}")
        return self


class QuasiStatic(Card):
    max_ratio: float = Field(0.05, gt=0, description="Limit of kinetic / internal energy.")
    after: float = Field(0.1, ge=0, lt=1, description="Checked after this fraction of the run.")


class EnergyBalance(Card):
    max_error: float = Field(0.01, gt=0, description="Limit of |balance error| / largest energy.")
    stop_above: float | None = Field(None, gt=0, description="Stop the run (exit 4) as soon as energy is created "
                                     "beyond this fraction of the largest energy so far (balance error > 0) at two "
                                     "history rows in a row, growing: an instability caught before it blows up, with "
                                     "a last good frame. Off when absent.")


class HourglassCheck(Card):
    max_ratio: float = Field(0.05, gt=0, description="Limit of hourglass / internal energy at the end.")


class Limit(Card):
    """Bounds on a recorded measure (a column of `output.measures`), e.g. the largest shear angle below locking."""

    measure: str = Field(description="Name of a measure in `output.measures`.")
    min: float | None = Field(None, description="Smallest allowed value (in the measure's unit).")
    max: float | None = Field(None, description="Largest allowed value (in the measure's unit).")
    after: float = Field(0.0, ge=0, lt=1, description="Checked after this fraction of the run.")

    @model_validator(mode="after")
    def _a_bound(self):
        if self.min is None and self.max is None:
            raise ValueError("give `min`, `max` or both")
        if self.min is not None and self.max is not None and self.min > self.max:
            raise ValueError(f"min {self.min} is above max {self.max}")
        return self


class Checks(Card):
    quasi_static: QuasiStatic | None = None
    energy_balance: EnergyBalance | None = None
    hourglass: HourglassCheck | None = None
    limits: list[Limit] = Field(default_factory=list, description="Bounds on measures; a run outside fails (exit 3).")


# -- the deck -----------------------------------------------------------------------------------------------
class Deck(Card):
    """A complete fdeck input."""

    title: str = ""
    units: Literal["mm-t-s-N-MPa", "m-kg-s-N-Pa"] = Field(
        "mm-t-s-N-MPa", description="Consistent unit system of every number in the deck (no conversion is done).")
    mesh: Mesh
    materials: dict[str, MaterialCardU] = Field(min_length=1)  # type: ignore[valid-type]
    sections: list[SectionCard] = Field(min_length=1)  # type: ignore[valid-type]
    amplitudes: dict[str, Amplitude] = Field(default_factory=dict)
    boundary: list[BoundaryCard] = Field(default_factory=list)  # type: ignore[valid-type]
    loads: list[LoadCard] = Field(default_factory=list)  # type: ignore[valid-type]
    tools: dict[str, Tool] = Field(default_factory=dict, description="Rigid tools by name (punch, die, holder).")
    contact: list[Contact] = Field(default_factory=list, description="Penalty contact of the blank with the tools.")
    steps: list[Step] = Field(min_length=1)
    output: Output = Field(default_factory=Output)
    checks: Checks = Field(default_factory=Checks)

    @property
    def duration(self) -> float:
        return sum(s.duration for s in self.steps)

    @model_validator(mode="before")
    @classmethod
    def _implied_formulations(cls, data):
        """A section of a named shell material (`sm`, `ts`) that names no formulation gets the card's, and the
        card's section preset when it gives neither a preset nor a thickness (``CardEntry.formulation``)."""
        if not isinstance(data, dict) or not isinstance(data.get("sections"), list) \
                or not isinstance(data.get("materials"), dict):
            return data
        cards = registry.cards("material")
        sections = []
        for sec in data["sections"]:
            name = sec.get("material") if isinstance(sec, dict) else None
            mat = data["materials"].get(name) if isinstance(name, str) else None
            kind = mat.get("type") if isinstance(mat, dict) else None
            entry = cards.get(kind) if isinstance(kind, str) else None
            if entry is not None and entry.formulation and "formulation" not in sec:
                sec = {**sec, "formulation": entry.formulation}
                if "preset" not in sec and "thickness" not in sec:
                    sec["preset"] = entry.section_preset
            sections.append(sec)
        return {**data, "sections": sections}


def cross_reference_problems(deck: Deck) -> list[tuple[tuple, str, str]]:
    """Name references the schema cannot see: [(path, message, severity)]."""
    out = []
    for i, s in enumerate(deck.sections):
        if s.material not in deck.materials:
            out.append((("sections", i, "material"), unknown_name("material", s.material, deck.materials), "error"))
            continue
        kind = deck.materials[s.material].type
        implied = registry.cards("material")[kind].formulation
        if implied and s.formulation != implied:
            out.append((("sections", i, "formulation"), f"formulation '{s.formulation}' contradicts the material: "
                        f"materials.{s.material}.type '{kind}' implies formulation '{implied}'", "error"))
    for name in deck.amplitudes:
        if name in BUILTIN_AMPLITUDES:  # the built-in would win silently where the name is used
            out.append((("amplitudes", name), f"'{name}' is a built-in amplitude ({', '.join(BUILTIN_AMPLITUDES)}); "
                        "give this one another name", "error"))
    names = set(BUILTIN_AMPLITUDES) | set(deck.amplitudes)
    for group in ("boundary", "loads"):
        for i, c in enumerate(getattr(deck, group)):
            amp = getattr(c, "amplitude", None)
            if amp is not None and amp not in names:
                out.append(((group, i, "amplitude"), unknown_name("amplitude", amp, names), "error"))
    for i, c in enumerate(deck.contact):
        if c.tool not in deck.tools:
            out.append((("contact", i, "tool"), unknown_name("tool", c.tool, deck.tools), "error"))
    for name, tool in deck.tools.items():
        if tool.motion is not None and tool.motion.amplitude_name not in names:
            out.append((("tools", name, "motion", "amplitude"), unknown_name("amplitude", tool.motion.amplitude_name,
                                                                             names), "error"))
    used = {c.tool for c in deck.contact}
    for name in deck.tools:
        if name not in used:
            out.append((("tools", name), f"tool '{name}' is in no `contact` pair, so nothing touches it", "warning"))
    measures = [m.name for m in deck.output.measures]
    for i, lim in enumerate(deck.checks.limits):
        if lim.measure not in measures:
            out.append((("checks", "limits", i, "measure"), unknown_name("measure", lim.measure, measures), "error"))
    used = {s.material for s in deck.sections}
    for name in deck.materials:
        if name not in used:
            out.append((("materials", name), f"material '{name}' is not used by any section", "warning"))
    solids = any("hexahedron" in FORMULATIONS[s.formulation].cell_types for s in deck.sections
                 if s.formulation in FORMULATIONS)
    for i, st in enumerate(deck.steps):
        if st.bulk_viscosity is not None and not solids:
            out.append((("steps", i, "bulk_viscosity"), "bulk viscosity acts on hexahedra only and no section has "
                        "them: it will have no effect", "warning"))
    return out
