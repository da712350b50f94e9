"""Card of the hyperelastic fabric law for hexahedra (`fabric_hyper`): modes, energy forms, presets.

Kernels and the packed layout in `fdeck.physics.materials.fabric_hyper`; this module imports neither numpy nor numba.
"""

from __future__ import annotations

from importlib import resources
from typing import Annotated, ClassVar, Literal, Union

from pydantic import Field, FiniteFloat, model_validator

from fdeck.cards import presets
from fdeck.cards.fibre_bending import FibreBending, FibreBendingLaws
from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


MODES = ("warp", "weft", "compaction", "in_plane_shear", "transverse_shear_warp", "transverse_shear_weft")


MAX_TABLE = 16
"""Largest number of (x, dpsi/dx) points of a tabulated form (fixes the parameter block size)."""


PRESET_DIR = resources.files(__package__).joinpath("presets", "fabric_hyper")
"""Folder of the preset YAML files (a module attribute so tests can point it at a temporary folder)."""


Coefficients = Annotated[list[FiniteFloat], Field(min_length=1, max_length=5)]


class _Form(Card):
    form_id: ClassVar[int]

    def packed(self) -> list[float]:
        """Form parameters as stored after form_id in the mode's block."""
        return []


class NoEnergy(_Form):
    """psi = 0: the mode carries no stiffness."""

    form: Literal["none"]
    form_id: ClassVar[int] = 0


class Polynomial(_Form):
    """psi(x) = sum_k a_k x^k, k = 1..5."""

    form: Literal["polynomial"]
    form_id: ClassVar[int] = 1
    coefficients: Coefficients = Field(
        description="[a1, ..., a5] [MPa], psi = a1 x + a2 x^2 + ... + a5 x^5; missing trailing terms are zero.")

    def packed(self):
        return _pad5(self.coefficients)


class TwoBranchPolynomial(_Form):
    """psi = poly_below(x) if x <= x0 else poly_above(x) (the weft form of [P]; its branches need not join)."""

    form: Literal["two_branch_polynomial"]
    form_id: ClassVar[int] = 2
    x0: FiniteFloat = Field(description="Split value of the invariant [-] (I_T of [P]).")
    below: Coefficients = Field(description="[a1, ..., a5] [MPa] of the polynomial used for x <= x0.")
    above: Coefficients = Field(description="[a1, ..., a5] [MPa] of the polynomial used for x > x0.")

    def packed(self):
        return [self.x0] + _pad5(self.below) + _pad5(self.above)


class LockingShear(_Form):
    """In-plane shear form of [P] (MODELS section 2): cubic up to I0, then K21 (1 - x)^-p22 + psi20 (locks at x = 1).

    psi, psi', psi'' are continuous at I0; psi''(0) = K_ps0 and psi''(I0) = K_ps1.
    """

    form: Literal["locking_shear"]
    form_id: ClassVar[int] = 3
    K_ps0: float = Field(gt=0.0, description="Initial tangent psi''(0) [MPa].")
    K_ps1: float = Field(gt=0.0, description="Tangent psi''(I0) at the branch point [MPa].")
    I0: float = Field(gt=0.0, lt=1.0, description="Branch point (sine of the shear angle) [-].")

    @model_validator(mode="after")
    def _locking_exponent_positive(self):
        if self.derived()[2] <= 0.0:
            raise ValueError("locking_shear needs K_ps1 (2 - 3 I0) > K_ps0 I0 (positive locking exponent p22)")
        return self

    def derived(self) -> tuple[float, float, float, float, float]:
        """(K12, K13 [MPa], p22 [-], K21, psi20 [MPa]) by the continuity conditions of MODELS section 2."""
        k0, k1, i0 = self.K_ps0, self.K_ps1, self.I0
        k12 = k0 / 2.0
        k13 = (k1 - k0) / (6.0 * i0)
        p22 = (k1 * (2.0 - 3.0 * i0) - k0 * i0) / (i0 * (k0 + k1))
        k21 = (k0 + k1) / (2.0 * p22) * i0 * (1.0 - i0) ** (1.0 + p22)
        psi20 = k12 * i0**2 + k13 * i0**3 - k21 * (1.0 - i0) ** (-p22)
        return k12, k13, p22, k21, psi20

    def packed(self):
        return [self.I0, *self.derived()]


class Compaction(_Form):
    """psi = K [(1 - x/I0)^-p - p x/I0 - 1] ([P] transverse compaction; psi -> inf as x -> I0 < 0)."""

    form: Literal["compaction"]
    form_id: ClassVar[int] = 4
    K_comp: float = Field(gt=0.0, description="Stiffness factor K_comp [MPa].")
    I0: float = Field(lt=0.0, description="Locking value of the invariant (log of the smallest thickness ratio) [-].")
    p: float = Field(gt=0.0, description="Exponent [-].")

    def packed(self):
        k, r, p = self.K_comp, 1.0 / self.I0, self.p
        return [k, r, p, k * p * r, k * p * (p + 1.0) * r * r]


class Quadratic(_Form):
    """psi = K x^2."""

    form: Literal["quadratic"]
    form_id: ClassVar[int] = 5
    K: float = Field(ge=0.0, description="Coefficient K [MPa] (psi'' = 2 K).")

    def packed(self):
        return [self.K]


class Tabulated(_Form):
    """psi(x) = integral from 0 to x of a piecewise-linear dpsi/dx through the table, extrapolated linearly."""

    form: Literal["tabulated"]
    form_id: ClassVar[int] = 6
    table: list[tuple[FiniteFloat, FiniteFloat]] = Field(
        min_length=2, max_length=MAX_TABLE,
        description=f"Points (x [-], dpsi/dx [MPa]), x strictly increasing, at most {MAX_TABLE}, including (0, 0).")

    @model_validator(mode="after")
    def _check_table(self):
        x = [pt[0] for pt in self.table]
        if any(b <= a for a, b in zip(x, x[1:])):
            raise ValueError("tabulated: x must be strictly increasing")
        if 0.0 not in x or self.table[x.index(0.0)][1] != 0.0:
            raise ValueError("tabulated: the table must contain the point x = 0 with dpsi/dx = 0 (stress-free rest)")
        return self

    def packed(self):
        n = len(self.table)
        xs = [pt[0] for pt in self.table] + [0.0] * (MAX_TABLE - n)
        ds = [pt[1] for pt in self.table] + [0.0] * (MAX_TABLE - n)
        return [float(n), float(xs.index(0.0))] + xs + ds


EnergyForm = Annotated[
    Union[NoEnergy, Polynomial, TwoBranchPolynomial, LockingShear, Compaction, Quadratic, Tabulated],
    Field(discriminator="form"),
]


def _pad5(a: list[float]) -> list[float]:
    return list(a) + [0.0] * (5 - len(a))


def available_presets() -> list[str]:
    """Names (file stems) of the YAML files in PRESET_DIR."""
    return presets.names(PRESET_DIR)


def load_preset(name: str) -> dict:
    """Card fields of preset ``name`` (a fresh dict). Unknown name or unknown key -> ValueError."""
    return presets.load(PRESET_DIR, name, {"density", "compression_ratio", "fibre_bending", *MODES}, "fabric_hyper")


def _mode_field(what: str):
    return Field(None, description=f"Energy form of the {what} mode; overrides the preset's.")


class FabricHyper(presets.PresetMaterial):
    """Hyperelastic fabric for hexahedra: six invariants (MODELS section 1), one energy form per mode.

    ``preset: 3weave`` gives every published number of [P] (Tables 2 and 4). ``preset: interlock`` gives
    REPRESENTATIVE (not published) values for a thick carbon layer-to-layer angle interlock: fibre tension stiffness
    three to four orders above transverse shear and compaction stiffness. Any mode, the density and the
    compression ratio given in the deck replace the preset's. Without a preset every mode must be given (``{form:
    none}`` for a mode without energy). Requires an orthonormal fibre frame for the stable-step modulus.
    """

    type: Literal["fabric_hyper"]
    preset_loader: ClassVar = staticmethod(lambda name: load_preset(name))
    required: ClassVar = ("density", "compression_ratio", *MODES)
    hint: ClassVar = " (give them, choose a preset, or use {form: none} for a mode without energy)"
    density: Annotated[float, Field(gt=0.0)] | None = Field(
        None, description="Mass density [t/mm^3]; taken from the preset when omitted.")
    preset: str | None = Field(None, description="Name of a parameter set in fdeck/cards/presets/fabric_hyper.")
    warp: EnergyForm | None = _mode_field("warp stretch (e1, Hencky strain along warp)")
    weft: EnergyForm | None = _mode_field("weft stretch (e2, Hencky strain along weft)")
    compaction: EnergyForm | None = _mode_field("transverse compaction (c, log thickness stretch)")
    in_plane_shear: EnergyForm | None = _mode_field("in-plane shear (s, sine of the shear angle; even)")
    transverse_shear_warp: EnergyForm | None = _mode_field("warp transverse shear (t1, sine; even)")
    transverse_shear_weft: EnergyForm | None = _mode_field("weft transverse shear (t2, sine; even)")
    compression_ratio: float | None = Field(
        None, ge=0.0, description="Fibre compressive / tensile quadratic stiffness [-] ([P]: 0.01); from the preset "
        "when omitted.")
    fibre_bending: FibreBendingLaws | None = Field(
        None, description="The fabric's own fibre bending laws ([B] cure 2; the body of a `fibre_bending` section "
        "effect without `type`): built on every hexahedral section of this material as if its `effects` listed them "
        "(a section listing its own as well is an error). Given in the deck, it replaces the preset's whole entry.")


    def section_effects(self) -> list:
        if self.fibre_bending is None:
            return []
        return [("fibre_bending", FibreBending(type="fibre_bending", **dict(self.fibre_bending)))]


register_card(CardEntry("fabric_hyper", FabricHyper, "material"))
