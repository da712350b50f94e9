"""Cards of rigid tools (`tools:`) and of their contact with the blank (`contact:`); the effects are
`fdeck.physics.effects.tool` (the tool's motion) and `fdeck.physics.effects.contact`, the geometry
`fdeck.physics.tools.analytic` and `fdeck.physics.tools.triangulated`.

A tool is a rigid surface (analytic, or triangles read from a file) that translates: by a prescribed displacement
or velocity, or driven by a force on a mass of its own (a blank holder). Contact is node-to-surface penalty
(MODELS 7): a blank node whose gap to the tool surface is below zero (or below the clearance of the exponential law)
is pushed out with the pressure of the normal law times its tributary area, and Coulomb friction with an elastic
stick spring acts in the tangent plane.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, Union

from pydantic import Field, model_validator

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card

Vector = tuple[float, float, float]


class _Shape(Card):
    @model_validator(mode="after")
    def _unit_vectors(self):
        for name in ("normal", "axis"):
            v = getattr(self, name, None)
            if v is not None and math.sqrt(sum(c * c for c in v)) == 0.0:
                raise ValueError(f"`{name}` must not be the zero vector")
        return self


class Plane(_Shape):
    """Infinite plane through `point` with outward normal `normal` (the blank lies on the normal's side)."""

    shape: Literal["plane"]
    point: Vector = Field((0.0, 0.0, 0.0), description="A point of the plane [mm].")
    normal: Vector = Field((0.0, 0.0, 1.0), description="Outward normal (normalised).")


class Sphere(_Shape):
    """Sphere of `radius` about `centre`; the blank lies outside (a hemispherical punch)."""

    shape: Literal["sphere"]
    centre: Vector = Field(description="Centre [mm].")
    radius: float = Field(gt=0.0, description="Radius [mm].")


class Cylinder(_Shape):
    """Infinite circular cylinder of `radius` about the line through `point` along `axis`; the blank lies outside (a
    roller, a rounded die edge, the capstan)."""

    shape: Literal["cylinder"]
    point: Vector = Field(description="A point of the axis [mm].")
    axis: Vector = Field(description="Axis direction (normalised).")
    radius: float = Field(gt=0.0, description="Radius [mm].")


class RoundedBox(_Shape):
    """Box of half-sizes `half_size` about `centre` (axis-aligned) with every edge and corner rounded by `radius`
    (the rounding lies inside the half-sizes); the blank lies outside (a punch, a die block)."""

    shape: Literal["rounded_box"]
    centre: Vector = Field(description="Centre [mm].")
    half_size: Vector = Field(description="Half-sizes along x, y, z, rounding included [mm].")
    radius: float = Field(0.0, ge=0.0, description="Edge and corner radius [mm] (0: sharp box).")

    @model_validator(mode="after")
    def _radius_fits(self):
        if min(self.half_size) <= self.radius:
            raise ValueError(f"radius {self.radius} must be below every half-size {list(self.half_size)}")
        return self


class Mesh(_Shape):
    """Triangulated surface read from a file (STL, OBJ, an Abaqus .inp with R3D3/R3D4 elements, or any surface mesh
    meshio reads; quadrilaterals are split in two). Triangle normals (p1 - p0) x (p2 - p0) must point out of the tool,
    toward the blank (`flip: true` reverses a file written the other way round). Open sheets are allowed."""

    shape: Literal["mesh"]
    file: str = Field(description="Surface file, relative to the deck's folder.")
    part: str | None = Field(None, description="Cell set of the file to use (an Abaqus element set); default all.")
    flip: bool = Field(False, description="Reverse every triangle's orientation.")
    scale: float = Field(1.0, gt=0.0, description="Factor on the file's coordinates (1 for a file in mm).")
    offset: Vector = Field((0.0, 0.0, 0.0), description="Translation added to the file's coordinates [mm].")


class Profile(_Shape):
    """Extruded rounded profile: a polyline in the plane of `u_axis` and `v_axis` (through `origin`), every interior
    corner rounded by a fillet of its radius, extruded without end along u x v (a die or punch section: a channel,
    a rounded step). The blank lies on the left of the polyline walked from its first point to its last (a profile
    walked along +u with v up has the blank above it); the first and last segments continue as straight lines
    beyond the end points, so the surface has no rim."""

    shape: Literal["profile"]
    points: list[tuple[float, float]] = Field(min_length=2, description="Corners (u, v) of the polyline [mm].")
    radii: float | list[float] = Field([], description="Fillet radius at each interior corner [mm], > 0 (one value "
                                                       "for all, or one per interior point; none for two points).")
    origin: Vector = Field((0.0, 0.0, 0.0), description="Where (u, v) = (0, 0) lies [mm].")
    u_axis: Vector = Field((1.0, 0.0, 0.0), description="Direction of the profile's first coordinate.")
    v_axis: Vector = Field((0.0, 0.0, 1.0), description="Direction of its second coordinate (made normal to u).")

    @model_validator(mode="after")
    def _profile(self):
        n_corner = len(self.points) - 2
        radii = [self.radii] * n_corner if isinstance(self.radii, float) else self.radii
        if len(radii) != n_corner:
            raise ValueError(f"`radii` lists {len(radii)} values for {n_corner} interior points")
        if any(r <= 0.0 for r in radii):
            raise ValueError("every fillet radius must be > 0 (a sharp corner has no unique normal)")
        u, v = self.u_axis, self.v_axis
        cross = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        if math.sqrt(sum(c * c for c in cross)) <= 1e-9 * math.sqrt(sum(c * c for c in u) * sum(c * c for c in v)):
            raise ValueError("`u_axis` and `v_axis` must not be parallel (or zero)")
        return self


Shape = Annotated[Union[Plane, Sphere, Cylinder, RoundedBox, Profile, Mesh], Field(discriminator="shape")]


class Motion(Card):
    """How the tool translates along `direction`: `displacement` u(t) = value * amplitude(t); `velocity`
    v(t) = value * amplitude(t); `force`: a force value * amplitude(t) [N] pushes the tool of mass `mass` along
    `direction` against the blank's contact reaction (a blank holder), integrated by central differences like the
    blank."""

    kind: Literal["displacement", "velocity", "force"] = Field("displacement", description="What `value` "
                                                               "prescribes: displacement, velocity or force.")
    direction: Vector = Field((0.0, 0.0, -1.0), description="Direction of travel (normalised).")
    value: float = Field(0.0, description="Travel [mm], velocity [mm/s] or force [N] at amplitude 1.")
    amplitude: str | None = Field(None, description="Amplitude name (see boundary `displacement`); default `smooth` "
                                  "for a displacement, `constant` for a velocity or a force.")
    mass: float | None = Field(None, gt=0.0, description="Mass of a force-driven tool [t]; required with kind force.")

    @model_validator(mode="after")
    def _force_has_mass(self):
        if self.kind == "force" and self.mass is None:
            raise ValueError("a force-driven tool needs its `mass` [t]")
        if self.kind != "force" and self.mass is not None:
            raise ValueError(f"`mass` is for force-driven tools only (this motion is a {self.kind})")
        if math.sqrt(sum(c * c for c in self.direction)) == 0.0:
            raise ValueError("`direction` must not be the zero vector")
        return self

    @property
    def amplitude_name(self) -> str:
        return self.amplitude or ("smooth" if self.kind == "displacement" else "constant")


class Tool(Card):
    """A rigid tool: its surface and its motion (fixed when `motion` is absent)."""

    surface: Shape = Field(description="Analytic surface (plane, sphere, cylinder, rounded_box) or a triangulated "
                           "`mesh` file.")  # type: ignore[valid-type]
    motion: Motion | None = Field(None, description="Prescribed translation or driving force; none = fixed tool.")


class Linear(Card):
    """p = stiffness * h for overclosure h > 0 (penetration), 0 otherwise."""

    law: Literal["linear"]
    stiffness: float = Field(gt=0.0, description="Pressure per penetration [MPa/mm]; the nodal force is p times the "
                             "node's tributary area, so a node of area A is a spring of stiffness A * stiffness.")


class Exponential(Card):
    """Abaqus-style exponential pressure-overclosure (MODELS 7): p = 0 for h <= -c0, p0 / (e - 1) (h/c0 + 1)
    (exp(h/c0 + 1) - 1) above, continued linearly once its slope reaches `max_stiffness` (so that the law cannot
    ruin the stable step)."""

    law: Literal["exponential"]
    p0: float = Field(gt=0.0, description="Pressure at zero clearance [MPa].")
    c0: float = Field(gt=0.0, description="Clearance at which the pressure starts [mm].")
    max_stiffness: float = Field(gt=0.0, description="Largest slope dp/dh [MPa/mm]; linear beyond it.")


NormalLaw = Annotated[Union[Linear, Exponential], Field(discriminator="law")]


class Friction(Card):
    """Coulomb friction with an elastic stick spring: the tangential force grows with the relative tangential
    displacement at `stick_stiffness` times the node's normal stiffness until it reaches `static` times the normal
    force; it then slides at `dynamic` times the normal force until it sticks again."""

    static: float = Field(ge=0.0, description="Static friction coefficient mu_s [-].")
    dynamic: float | None = Field(None, ge=0.0, description="Dynamic coefficient mu_d [-] (<= static); default "
                                  "static.")
    stick_stiffness: float = Field(1.0, gt=0.0, description="Tangential stick stiffness as a multiple of the normal "
                                   "penalty stiffness of each node [-].")

    @model_validator(mode="after")
    def _order(self):
        if self.dynamic is not None and self.dynamic > self.static:
            raise ValueError(f"dynamic {self.dynamic} is above static {self.static}")
        return self


class Contact(Card):
    """Penalty contact of blank nodes against one tool."""

    tool: str = Field(description="Name of a tool in `tools`.")
    nodes: str | None = Field(None, description="Node set of the blank; default: every node of the blank's exterior "
                              "(faces of one hexahedron only, and every shell node, both faces).")
    normal: NormalLaw = Field(description="Normal law: linear or exponential.")  # type: ignore[valid-type]
    friction: Friction | None = Field(None, description="Coulomb friction; none = frictionless.")
    search_distance: float | None = Field(None, gt=0.0, description="Triangulated tools: how far from the surface "
                                          "a node is looked for [mm]; default the largest shell offset plus the "
                                          "exponential law's clearance plus a quarter of the blank's largest surface "
                                          "edge (the step bound keeps a tool from travelling half of it in one "
                                          "cycle, and a penalty that lets a node sink deeper is refused).")
    springs: Literal["explicit", "implicit"] = Field("explicit", description="How the penalty and stick springs "
                                                     "of the nodes in contact are integrated. explicit: with the "
                                                     "forces, so each node's spring bounds the stable step by "
                                                     "sqrt(m / k). implicit: the spring's stiffness at the start of "
                                                     "the cycle enters the node's own velocity update (a linearly "
                                                     "implicit step; a 3 x 3 solve per node, or the selective "
                                                     "mass's solve), so the normal springs no longer bound the "
                                                     "step and the stick springs only at 2 sqrt(m / k_t) (a "
                                                     "sliding node's return to sticking stays explicit); the "
                                                     "energy this step removes is booked as "
                                                     "`contact_implicit_dissipation`. Needs the exponential "
                                                     "law; not with subcycling.")

    @model_validator(mode="after")
    def _smooth_onset(self):
        # a node is taken implicitly only while in contact at the start of a cycle: the exponential law's slope
        # starts from 0 at -c0, the linear law's jumps to k at 0, and a node resting there crosses that kink every
        # cycle once the step exceeds the spring's own (a 10 mm block on a plane: balance error 2 % at 1.5x that
        # step, 9 % at 8x; with the exponential law 2e-4 at 8x)
        if self.springs == "implicit" and self.normal.law == "linear":
            raise ValueError("springs: implicit needs the exponential normal law (its stiffness rises from zero; "
                             "a node resting at the linear law's kink would cross it every cycle)")
        return self


register_card(CardEntry("tool", Tool, "effect", "tools"))
register_card(CardEntry("contact", Contact, "effect", "contact"))
