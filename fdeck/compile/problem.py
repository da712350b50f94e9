"""Deck -> Problem: arrays, element groups (one per section), the effects the deck names, and the step plan."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fdeck import registry
from fdeck.cards.mass_scaling import CG_MAX_ITERATIONS, CG_TOLERANCE
from fdeck.compile import amplitude
from fdeck.compile.errors import CompileError
from fdeck.compile.mesh import MeshArrays, add_box_sets, block, diagonal_block, plate, read_file
from fdeck.compile.orientation import element_orientation
from fdeck.deck.errors import unknown_name
from fdeck.deck.model import Deck
from fdeck.engine import subcycle

registry.load_plugins()  # the kernel side of every plug-in (the deck loaded only their cards)


@dataclass
class StepPlan:
    """One step: its duration [s], dt safety, the density of every group's elements [t/mm^3] and the lumped nodal
    mass [t] (and rotational inertia [t mm^2] when there are rotations) that follow from them."""

    name: str
    duration: float
    dt_safety: float
    rho: list[np.ndarray]  # per group (n_el,)
    mass: np.ndarray  # (n_node,)
    inertia: np.ndarray | None  # (n_node,) or None
    max_cycles: int | None
    added_mass: float  # fraction of the physical mass added by mass scaling
    start: float = 0.0  # nominal start time of the step [s] (the sum of the earlier steps' durations)
    # selective mass scaling (``engine.selective_mass``): per group (n_el,) factors beta_e of the added mass
    # beta_e (m_e / n)(I - P_e) (P_e: the element's rigid modes), None for a step without; ``rho`` then holds
    # rho_base (1 + beta) (the density the element steps see: every deformation mode of the element carries 1 + beta
    # times its mass) while ``mass`` is the lumped mass of rho_base (physical, or uniformly scaled under
    # ``selective_target_dt``; m_e above is rho_base's); ``added_mass`` is (tr(M) + tr(dM)) / tr(M_physical) - 1
    selective: list[np.ndarray] | None = None
    cg: tuple[float, int] = (CG_TOLERANCE, CG_MAX_ITERATIONS)  # (relative tolerance, iteration cap) of the solve

    def translational(self, i: int) -> np.ndarray | None:
        """(n_el,) densities of group i's translational (lumped) mass under selective scaling, rho / (1 + beta);
        None for a step without (the densities are then ``rho[i]`` throughout)."""
        return None if self.selective is None else self.rho[i] / (1.0 + self.selective[i])


@dataclass
class RotationalNodes:
    """Nodes with rotational dofs: d0 (n_node, 3) reference unit directors (zero elsewhere), nodes (k,) indices."""

    d0: np.ndarray
    nodes: np.ndarray


@dataclass
class Problem:
    deck: Deck
    X: np.ndarray  # (n_node, 3) reference coordinates [mm]
    cells: dict[str, np.ndarray]  # cell type -> conn, for output
    groups: list  # element groups (``engine.group.ElementGroup``)
    effects: list  # engine.effect.Effect instances, only those the deck names
    node_sets: dict[str, np.ndarray]
    physical_mass: np.ndarray  # (n_node,) lumped mass without mass scaling [t]
    steps: list[StepPlan]
    reactions: dict[str, np.ndarray] = field(default_factory=dict)
    measures: list = field(default_factory=list)  # objects with columns and evaluate(x, v)
    rotations: RotationalNodes | None = None  # only when a group carries directors (shells)

    @property
    def n_node(self) -> int:
        return len(self.X)

    @property
    def n_element(self) -> int:
        return sum(len(g.conn) for g in self.groups)

    @property
    def duration(self) -> float:
        return sum(s.duration for s in self.steps)


class Context:
    """What an effect's or measure's ``build`` may ask for, complete before any of them is built: the deck, the
    mesh and its sets, the element groups, the nodal rotations, the physical nodal mass and the exterior surface.
    Failures are CompileErrors at ``self.path``; ``group`` is the group a section add-on is built for."""

    def __init__(self, deck: Deck, mesh: MeshArrays, groups: list, rotations, physical_mass: np.ndarray):
        self.deck, self.mesh, self.X, self.physical_mass = deck, mesh, mesh.X, physical_mass
        self.groups, self.rotations = groups, rotations
        self.path: tuple = ()
        self.group = None
        self._surface = None
        self.base = Path(".")  # folder of the deck file (files a deck names are relative to it)
        self.tools: dict = {}  # rigid tools built so far, by name (``effects.tool``)
        self.effects: list = []  # effects built so far (compile_deck's list)

    def node_set(self, name: str) -> np.ndarray:
        if name not in self.mesh.node_sets:
            raise CompileError([(self.path + ("nodes",), unknown_name("node set", name, self.mesh.node_sets))])
        return self.mesh.node_sets[name]

    def amplitude(self, name: str):
        return amplitude.make(name, self.deck.amplitudes, self.deck.duration)

    @property
    def surface(self) -> dict[str, np.ndarray]:
        """The mesh's exterior: {"faces": (n_face, 4) node indices of hexahedron faces that belong to one element
        only, outward by the right-hand rule, and shell elements (both sides are exterior; triangles repeat their
        third node)}; computed on first use."""
        if self._surface is None:
            self._surface = {"faces": exterior_faces(self.groups)}
        return self._surface


def load_mesh(deck: Deck, base: Path) -> MeshArrays:
    m = deck.mesh
    if m.block is not None:
        make = diagonal_block if m.block.lattice == "diagonal" else block
        mesh = make(m.block.origin, m.block.size, m.block.divisions, m.block.element_size)
    elif m.plate is not None:
        p = m.plate
        mesh = plate(p.origin, p.size, p.divisions, p.element_size, p.triangles)
    else:
        path = (base / m.file) if not Path(m.file).is_absolute() else Path(m.file)
        if not path.exists():
            raise CompileError([(("mesh", "file"), f"mesh file '{path}' does not exist")])
        mesh = read_file(path)
    add_box_sets(mesh, m.node_sets, m.element_sets)
    return mesh


def build_groups(deck: Deck, mesh: MeshArrays) -> list:
    """One element group per section; every element must belong to exactly one section."""
    problems, groups, recipes = [], [], []
    owner = {t: np.full(len(c), -1) for t, c in mesh.cells.items()}
    top = max((s.subcycling.levels - 1 for s in deck.steps if s.subcycling is not None), default=0)
    block = min((s.subcycling.block_elements for s in deck.steps if s.subcycling is not None), default=0)
    for i, sec in enumerate(deck.sections):
        path = ("sections", i)
        if sec.elements not in mesh.element_sets:
            problems.append((path + ("elements",), unknown_name("element set", sec.elements, mesh.element_sets)))
            continue
        kind = registry.MATERIALS[registry.CARDS["material"][deck.materials[sec.material].type].runs_on]
        card = deck.materials[sec.material]
        form = registry.CARDS["formulation"][sec.formulation]
        build = registry.FORMULATIONS[sec.formulation].build
        if sec.orientation.field is not None and sec.orientation.field not in mesh.cell_data:
            message = unknown_name("cell field", sec.orientation.field, mesh.cell_data)
            if not deck.mesh.file:
                message += "; built-in meshes have none, fields come from a mesh file"
            problems.append((path + ("orientation", "field"), message))
            continue
        if form.plane_stress and not kind.plane_stress:
            known = sorted(k for k, v in registry.MATERIALS.items() if v.plane_stress)
            problems.append((path + ("material",), f"formulation '{sec.formulation}' needs a plane-stress law; "
                             f"'{sec.material}' is {kind.name} (plane-stress laws: {', '.join(known)})"))
            continue
        for ctype, idx in mesh.element_sets[sec.elements].items():
            if ctype not in form.cell_types:
                problems.append((path + ("elements",), f"formulation '{sec.formulation}' takes "
                                 f"{' or '.join(form.cell_types)} elements; set '{sec.elements}' holds {len(idx)} "
                                 f"{ctype} elements, ids {mesh.ids[ctype][idx[:10]].tolist()}"))
                continue
            twice = idx[owner[ctype][idx] >= 0]
            if len(twice):
                problems.append((path + ("elements",), f"elements already in section "
                                 f"{int(owner[ctype][twice[0]])}: ids {mesh.ids[ctype][twice[:10]].tolist()}"))
                continue
            owner[ctype][idx] = i
            conn, ids = mesh.cells[ctype][idx], mesh.ids[ctype][idx]
            params = np.broadcast_to(kind.pack(card), (len(idx), len(kind.pack(card))))
            try:
                field = mesh.cell_data[sec.orientation.field][ctype][idx] if sec.orientation.field else None
                orient = element_orientation(sec.orientation, len(idx), field)
            except ValueError as exc:
                problems.append((path + ("orientation",), str(exc)))
                continue
            rho = np.full(len(idx), card.density)
            try:
                g = build(f"section{i}:{sec.elements}", sec, mesh.X, conn, ids, kind, params, orient, rho, ctype)
            except CompileError as exc:  # the element reports its own problems relative to the section
                problems += [(path + tuple(p), m) for p, m in exc.problems]
                continue
            bad = g.detJ_min <= 0
            if bad.any():
                problems.append((path + ("elements",), f"{int(bad.sum())} inverted or degenerate elements, "
                                 f"ids {ids[bad][:10].tolist()}"))
            g.element_index, g.section_index = idx, i
            groups.append(g)
            if top:  # subcycling: the section is rebuilt below as one group per update level
                recipes.append(subcycle.subset_recipe(build, f"section{i}:{sec.elements}", sec, mesh.X, conn, ids,
                                                      kind, params, orient, rho, ctype, idx, i))
    for ctype, own in owner.items():
        if (own < 0).any():
            problems.append((("sections",), f"{int((own < 0).sum())} {ctype} elements have no section, ids "
                             f"{mesh.ids[ctype][own < 0][:10].tolist()}"))
    if problems:
        raise CompileError(problems)
    if top:
        groups = subcycle.split_groups(groups, recipes, mesh.X, top, block)
    return groups


def setup_rotations(deck: Deck, groups: list, n_node: int) -> RotationalNodes | None:
    """Reference directors of the nodes of groups that carry rotations (``group.rotational``), or None.

    Each such group adds area-weighted unit normals at its nodes (``add_normals``); a node's director is their
    normalised sum. Neighbouring elements whose normals disagree in sign (inconsistent node order) are an error.
    Then every such group derives its reference arrays from the directors (``set_directors``).
    """
    rot = [g for g in groups if g.rotational]
    if not rot:
        return None
    acc, mag = np.zeros((n_node, 3)), np.zeros(n_node)
    for g in rot:
        g.add_normals(acc, mag)
    norm = np.linalg.norm(acc, axis=1)
    nodes = np.nonzero(mag > 0)[0]
    d0 = np.zeros((n_node, 3))
    d0[nodes] = acc[nodes] / np.where(norm[nodes] > 0, norm[nodes], 1.0)[:, None]
    problems = []
    for g in rot:
        bad = g.flipped_elements(d0)
        if len(bad):
            problems.append((("sections", g.section_index, "elements"), f"{len(bad)} shell elements have a normal "
                             f"opposite to their neighbours' (node order reversed), ids {bad[:10].tolist()}"))
    if problems:
        raise CompileError(problems)
    for g in rot:
        g.set_directors(d0)
    return RotationalNodes(d0, nodes)


def exterior_faces(groups: list) -> np.ndarray:
    """(n_face, 4) exterior faces of the solid groups (faces owned by one hexahedron, node order outward) and the
    shell elements of the other groups."""
    from fdeck.physics.elements.hex8 import FACES

    faces = []
    solid = [g.conn[:, FACES].reshape(-1, 4) for g in groups if g.solid]
    if solid:
        f = np.concatenate(solid)
        key = np.sort(f, axis=1)
        _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        faces.append(f[counts[inverse.ravel()] == 1])
    faces += [g.conn for g in groups if not g.solid]
    return np.concatenate(faces) if faces else np.zeros((0, 4), np.int64)


def lumped(groups: list, n_node: int, rho: list[np.ndarray], per_element) -> np.ndarray:
    """(n_node,) sum over the groups of per_element(g, rho_g) (n_el, nodes per element); groups for which
    per_element returns None are skipped."""
    out = np.zeros(n_node)
    for g, r in zip(groups, rho):
        values = per_element(g, r)
        if values is not None:
            np.add.at(out, g.conn.ravel(), values.ravel())
    return out


def nodal_inertia(groups: list, n_node: int, rho: list[np.ndarray]) -> np.ndarray:
    """Lumped rotational inertia (n_node,) [t mm^2] of the groups that carry rotations (0 elsewhere)."""
    return lumped(groups, n_node, rho, lambda g, r: g.inertia(r) if g.rotational else None)


def nodal_mass(groups: list, n_node: int, rho: list[np.ndarray]) -> np.ndarray:
    """Lumped nodal mass (n_node,) [t] of the groups with densities rho (one (n_el,) array per group)."""
    return lumped(groups, n_node, rho, lambda g, r: g.mass(r))


def rest_dt(group, rho: np.ndarray, effects=(), translational: np.ndarray | None = None) -> np.ndarray:
    """(n_el,) rest stable steps [s] of a group's elements with densities rho, lowered by every effect acting on that
    group with a stiffness of its own (an effect whose ``group`` is this one and whose ``rest_dt`` gives steps,
    e.g. fibre bending). ``translational``: under selective mass scaling, the densities (n_el,) of the translational
    (lumped) mass, rho / (1 + beta); an effect whose stiffness acts on element rotations (``own_omega2``) then
    counts against that mass only, as selective mass leaves rotations as they are."""
    dt = continuum = group.rest_dt(rho)
    for e in effects:
        if e.group is group:
            if hasattr(e, "own_omega2"):  # squared frequencies add (the effect's own rest_dt, with rho for both)
                own = 2.0 / np.sqrt(e.own_omega2(rho if translational is None else translational)
                                    + (2.0 / continuum) ** 2)
            else:
                own = e.rest_dt(rho)
        elif any(p is group for p in getattr(e.group, "parts", ())):  # over the subcycling blocks of a section
            own = e.rest_dt(e.group.with_part_rho(group, rho))
            own = None if own is None else own[e.group.slice(group)]
        else:
            continue
        if own is not None:
            dt = np.minimum(dt, own)
    return dt


def selective_density(group, base: np.ndarray, target: float, safety: float, effects=()) -> np.ndarray:
    """(n_el,) densities rho_base (1 + beta_e) whose element steps reach ``target`` [s] (the stable step, so
    target / safety per element) by selective mass on top of the translational densities base (n_el,).

    The element's continuum frequency omega_g^2 = (2 / dt_g)^2 divides by 1 + beta (the added mass sits on its
    deformation modes, ``engine.selective_mass``); an effect's own stiffness on element rotations (fibre bending's
    hinges, ``own_omega2``) does not, so the element step 2 / sqrt(omega_g^2 / (1 + beta) + omega_b^2) reaches the
    target where omega_b is below the target's frequency omega_t, with 1 + beta = omega_g^2 / (omega_t^2 - omega_b^2).
    Raises ``Unreachable`` (the largest reachable target) where some element's own omega_b alone is at or above
    omega_t. Without such effects: (target / (safety dt_g))^2, conventional mass scaling's factor."""
    own = [e for e in effects if e.group is group and hasattr(e, "own_omega2")]
    if not own:
        return base * np.maximum(1.0, (target / (safety * group.rest_dt(base))) ** 2)
    wg2 = (2.0 / group.rest_dt(base)) ** 2
    wb2 = sum((e.own_omega2(base) for e in own), np.zeros_like(wg2))
    wt2 = (2.0 * safety / target) ** 2
    room = wt2 - wb2
    if not np.all(room > 0.0):
        raise Unreachable(safety * 2.0 / math.sqrt(float(wb2.max())), [e.name for e in own])
    return base * np.maximum(1.0, wg2 / room)


class Unreachable(ValueError):
    """A selective target at or above the step an effect's stiffness on rotations allows with any added mass."""

    def __init__(self, limit: float, by: list[str]):
        super().__init__(limit, by)
        self.limit, self.by = limit, by


def plan_steps(deck: Deck, groups: list, physical_mass: np.ndarray, effects=()) -> list[StepPlan]:
    total = physical_mass.sum()
    n_node = len(physical_mass)
    rotational = any(g.rotational for g in groups)
    plans = []
    for s in deck.steps:
        rho = [g.rho.copy() for g in groups]
        ms = s.mass_scaling
        if ms is not None and ms.factor is not None:
            rho = [r * ms.factor for r in rho]
        elif ms is not None and not ms.selective:  # a selective target_dt is met below, by selective_density
            for i, g in enumerate(groups):
                dt0 = rest_dt(g, g.rho, effects)  # rest stable step per element
                rho[i] = g.rho * np.maximum(1.0, (ms.target_dt / (s.dt_safety * dt0)) ** 2)
        selective = None
        if ms is not None and ms.is_selective:
            stiff = sorted({e.name for e in effects if e.group is not None and not hasattr(e, "own_omega2")
                            and e.rest_dt(e.group.rho) is not None})
            key = "selective" if ms.selective else "selective_target_dt"
            if stiff:  # a stiffness that turns whole elements in a way the planner cannot bound
                raise CompileError([(("steps", len(plans), "mass_scaling", key), "selective mass scaling "
                                     "adds no mass to element rotations, which section effects with a stiffness "
                                     f"of their own act on ({', '.join(stiff)}): their step would not grow; use "
                                     "mass scaling without `selective`")])
            # the translational (lumped) mass: physical for `selective`, the uniformly scaled one for
            # `selective_target_dt`; rho then reaches the target element steps by mass on the deformation modes only
            # (closed form: the element's deformation eigenvalues divide by 1 + beta, see engine.selective_mass)
            base = [g.rho for g in groups] if ms.selective else rho
            target = ms.selective_target
            if target is not None:
                try:
                    rho = [selective_density(g, b, target, s.dt_safety, effects) for g, b in zip(groups, base)]
                except Unreachable as exc:
                    raise CompileError([(("steps", len(plans), "mass_scaling",
                                          "target_dt" if ms.selective else key),
                                         f"selective target {target:.4g} s is out of reach: the stiffness of "
                                         f"{', '.join(exc.by)} on element rotations, which selective mass leaves "
                                         f"as they are, allows at most {exc.limit:.4g} s with any added mass; ask "
                                         "for less (the added mass grows without bound as the target nears that)")]
                                       ) from None
            selective = [r / b - 1.0 for r, b in zip(rho, base)]
            mass = nodal_mass(groups, n_node, base)
            inertia = nodal_inertia(groups, n_node, base) if rotational else None
            added = (mass.sum() - total + sum(float((be * g.mass(b).sum(axis=1)).sum()) * (1.0 - 2.0 / g.conn.shape[1])
                                              for be, g, b in zip(selective, groups, base))) / total
        else:
            mass = nodal_mass(groups, n_node, rho)
            inertia = nodal_inertia(groups, n_node, rho) if rotational else None
            added = (mass.sum() - total) / total
        start = sum(p.duration for p in plans)
        cg = (ms.cg_tolerance, ms.cg_max_iterations) if ms is not None else (CG_TOLERANCE, CG_MAX_ITERATIONS)
        plans.append(StepPlan(s.name, s.duration, s.dt_safety, rho, mass, inertia, s.max_cycles, float(added),
                              start, selective, cg))
    return plans


def _build(kind, card, ctx, problems: list, effects: list) -> None:
    """Build one effect (skipping None: a step effect no step needs), collecting CompileErrors."""
    try:
        effect = kind.build(card, ctx)
    except CompileError as exc:
        problems += exc.problems
        return
    if effect is not None:
        effect.path = ctx.path
        effects.append(effect)


def _material_effects(deck: Deck, i: int, own: list, problems: list) -> list:
    """(path, card) of the section add-ons section i's material carries (``MaterialCard.section_effects``, e.g. a
    fabric's own fibre bending from an identified preset), located at the material's field; one the section lists
    itself as well is a problem, not a guess of which one to keep."""
    name = deck.sections[i].material
    out = []
    for field, card in deck.materials[name].section_effects():
        clash = [path for path, c in own if c.type == card.type]
        if clash:
            problems.append((clash[0], f"'{card.type}' is given twice: here and by material '{name}' "
                             f"(materials.{name}.{field}, its card or preset); keep one"))
        else:
            out.append((("materials", name, field), card))
    return out


def compile_deck(deck: Deck, base: Path = Path(".")) -> Problem:
    """Build every array the engine needs. Raises CompileError listing every geometric or set problem."""
    mesh = load_mesh(deck, base)
    groups = build_groups(deck, mesh)
    rotations = setup_rotations(deck, groups, len(mesh.X))
    mass = nodal_mass(groups, len(mesh.X), [g.rho for g in groups])
    ctx = Context(deck, mesh, groups, rotations, mass)
    ctx.base = base
    effects, problems = [], []
    ctx.effects = effects  # built so far: step settings (built last) may read the section add-ons
    for i, sec in enumerate(deck.sections):  # section add-ons act on that section's groups
        cards = [(("sections", i, "effects", j), card) for j, card in enumerate(getattr(sec, "effects", []))]
        cards += _material_effects(deck, i, cards, problems)
        for path, card in cards:
            ctx.path = path
            for unit in subcycle.section_units(groups, i):  # a group, or the view of its subcycling blocks
                ctx.group = unit
                _build(registry.EFFECTS[card.type], card, ctx, problems, effects)
    ctx.group = None
    for section in ("boundary", "loads"):
        for i, card in enumerate(getattr(deck, section)):
            ctx.path = (section, i)
            _build(registry.EFFECTS[card.type], card, ctx, problems, effects)
    for name in dict.fromkeys(c.tool for c in deck.contact if c.tool in deck.tools):  # tools some contact uses
        ctx.path = ("tools", name)
        try:
            ctx.tools[name] = registry.EFFECTS["tool"].build(name, deck.tools[name], ctx)
            effects.append(ctx.tools[name])  # before the contact pairs: it clears their summed load each cycle
        except CompileError as exc:
            problems += exc.problems
    for i, card in enumerate(deck.contact):  # blank against tools, built only for decks with contact
        ctx.path = ("contact", i)
        if card.tool in ctx.tools:
            _build(registry.EFFECTS["contact"], card, ctx, problems, effects)
    for name in registry.cards("effect", "step"):  # step settings (damping, bulk viscosity), built when a step asks
        ctx.path = ("steps",)
        _build(registry.EFFECTS[name], [getattr(s, name) for s in deck.steps], ctx, problems, effects)
    reactions = {}
    for i, name in enumerate(deck.output.reactions):
        ctx.path = ("output", "reactions", i)
        try:
            reactions[name] = ctx.node_set(name)
        except CompileError as exc:
            problems += [(("output", "reactions", i), m) for _, m in exc.problems]
    measures = []
    for i, card in enumerate(deck.output.measures):
        ctx.path = ("output", "measures", i)
        try:
            measures.append(registry.MEASURES[card.type].build(card, ctx))
        except CompileError as exc:
            problems += exc.problems
    sub = next((e for e in effects if getattr(e, "subcycles", False)), None)
    if sub is not None:
        problems += sub.refuse(effects)
    if problems:
        raise CompileError(problems)
    steps = plan_steps(deck, groups, mass, effects)
    problems = [(getattr(e, "path", ()), m) for e in effects for m in e.check_plan(steps)]
    if problems:
        raise CompileError(problems)
    return Problem(deck, mesh.X, mesh.cells, groups, effects, mesh.node_sets, mass, steps, reactions, measures,
                   rotations)
