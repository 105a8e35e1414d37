"""Scenes: named selections of a model's effects, values and outputs.

A scene switches effects on (``effects:``) or off (``without:``). Since
``fbar = C^T f`` is a sum over the effects (8'), (F), a scene's equations are
the model's with the switched-off effects left out *before* projection: no
term, symbol or parameter of them reaches the derived equations or the
generated code. A scene also gives parameter and initial values, the time span
and step, the method, and the outputs it wants; outputs not asked for are not
computed.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Mapping

import sympy

from ..core.known_system import KnownSystem
from ..core.subspace import effect_labels
from ..core.symbols import symbol
from ..errors import ModelError, Problem, close_matches, given, option
from .derive import derive_model
from .initial import read_initial
from .requirements import parameters_in, unmet
from .schema import scene_methods
from .reader import ModelReader
from .source import Node

KEYS = ("description", "effects", "without", "parameters", "initial", "t_end", "dt", "method", "outputs")
OUTPUT_KINDS = ("coordinates", "velocities", "energies", "points")


@dataclass(frozen=True)
class Outputs:
    """What a run reports: ``points`` None means every named point (on request)."""

    coordinates: bool = True
    velocities: bool = True
    energies: bool = True
    points: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Scene:
    """A named scene of a model; ``effects`` are the labels switched on, in model order."""

    name: str
    effects: tuple[str, ...]
    description: str = ""
    parameters: Mapping[str, sympy.Expr] = field(default_factory=dict)
    initial: Mapping[sympy.Symbol, sympy.Expr] = field(default_factory=dict)
    t_end: float | None = None
    dt: float | None = None
    method: str | None = None
    outputs: Outputs = Outputs(points=())


# ------------------------------------------------------------------------------------ reading
def build_scenes(reader: ModelReader, node: Node | None, declared_effects, primitive, coords,
                 speeds=()) -> tuple[Scene, ...]:
    """Read ``scenes:``; problems go to the reader. ``declared_effects`` are the names under
    ``effects:``; a known system's own effects are named ``part.effect``."""
    labels = [label for label in effect_labels(primitive, ()) if "." in label] + list(declared_effects)
    points = primitive.points()  # listed (every part's points built) only for a scene's `outputs:`
    scenes = []
    for sname, spec in reader.mapping(node, "scenes", "write `scenes: {free: {effects: [gravity]}}`").items():
        if not reader.identifier(sname, node.key_locations[sname], "scene"):
            continue
        if spec.value is None:
            spec = Node({}, None, spec.location)
        if not spec.is_mapping:
            reader.error(spec, f"scene '{sname}' must be a mapping", "e.g. `free: {effects: [gravity]}`")
            continue
        spec = reader.check_keys(spec, KEYS, f"scene '{sname}'")
        scene = _scene(reader, sname, spec, labels, points, coords, speeds)
        if scene is not None:
            scenes.append(scene)
    if node is not None and node.is_mapping:
        reader.locations["scenes"] = node.location
    return tuple(scenes)


def _scene(reader: ModelReader, sname: str, spec: Node, labels, points, coords, speeds=()) -> Scene | None:
    on, off = spec.get("effects"), spec.get("without")
    if on is not None and off is not None:
        reader.error(spec.key_locations["without"], f"scene '{sname}' has both `effects:` and `without:`",
                     "list the effects it switches on, or those it switches off, not both")
        return None
    chosen = set(labels)
    for what, listed in (("effects", on), ("without", off)):
        if listed is None:
            continue
        names = _names(reader, listed, labels, f"`{what}:` of scene '{sname}'", "effect")
        if names is None:
            return None
        chosen = set(names) if what == "effects" else chosen - set(names)
    parameters = {}
    allowed = reader.parameter_names()
    pnode = spec.get("parameters")
    for pname, vnode in reader.mapping(pnode, f"{sname}.parameters", "write `parameters: {F: 2}`").items():
        if pname not in allowed:
            reader.error(pnode.key_locations[pname], f"scene '{sname}' sets '{pname}', which is not a parameter",
                         close_matches(pname, allowed))
            continue
        value = reader.expr(vnode, {}, what=f"value of parameter '{pname}' in scene '{sname}'")
        if value is not None:
            parameters[pname] = value
    _check_values(reader, pnode, parameters)
    initial = read_initial(reader, spec.get("initial"), coords, speeds)
    t_end = _positive(reader, spec.get("t_end"), f"`t_end:` of scene '{sname}'")
    dt = _positive(reader, spec.get("dt"), f"`dt:` of scene '{sname}'")
    method = _method(reader, spec.get("method"), sname)
    outputs = _outputs(reader, spec.get("outputs"), points, sname)
    return Scene(
        name=sname,
        effects=tuple(label for label in labels if label in chosen),
        description=reader.string(spec.get("description"), ""),
        parameters=parameters,
        initial=initial,
        t_end=t_end,
        dt=dt,
        method=method,
        outputs=outputs,
    )


def _check_values(reader: ModelReader, pnode: Node | None, parameters: dict) -> None:
    """The components' requirements on the values a scene sets (:mod:`.requirements`), each
    problem at the scene's value."""
    if not parameters:
        return
    values = {**reader.parameter_values(), **{symbol(k): v for k, v in parameters.items()}}
    concerned = [r for r in reader.requirements if {s.name for s in parameters_in(r)} & set(parameters)]
    for problem in unmet(concerned, values, lambda req: next(
            (pnode.get(s.name).location for s in parameters_in(req) if s.name in parameters), None)):
        reader.problems.add(problem.location, problem.message, problem.hint)


def _names(reader: ModelReader, node: Node, valid, what: str, kind: str) -> list[str] | None:
    """A list of names, each one of ``valid`` (an unknown name lists the valid ones)."""
    if node.value is None:
        return []
    if not node.is_sequence:
        reader.error(node, f"{what} must be a list of names", f"e.g. `[{valid[0] if valid else 'gravity'}]`")
        return None
    names, ok = [], True
    for item in node.value:
        name = item.value
        if not isinstance(name, str) or name not in valid:
            ok = False
            shown = item.text if item.text is not None else str(name)
            hint = close_matches(shown, valid)
            if hint.startswith("did you mean"):
                hint += f" (valid {kind}s: {', '.join(valid) or 'none'})"
            reader.error(item, f"unknown {kind} '{shown}' in {what}", hint)
            continue
        names.append(name)
    return names if ok else None


def _positive(reader: ModelReader, node: Node | None, what: str) -> float | None:
    if node is None:
        return None
    value = reader.expr(node, {}, what=what)
    if value is None:
        return None
    if not value.is_number or not value.is_real or not value > 0:
        reader.error(node, f"{what} must be a positive number", "e.g. `t_end: 10` and `dt: 0.01`")
        return None
    return float(value)


def _method(reader: ModelReader, node: Node | None, sname: str) -> str | None:
    if node is None:
        return None
    methods = scene_methods()
    if not isinstance(node.value, str) or node.value not in methods:
        shown = node.text if node.text is not None else str(node.value)
        reader.error(node, f"unknown method '{shown}' in scene '{sname}'", close_matches(shown, methods))
        return None
    return node.value


def _outputs(reader: ModelReader, node: Node | None, points, sname: str) -> Outputs:
    """``outputs: [coordinates, velocities, energies, points | <named point>...]``."""
    if node is None:
        return Outputs(points=())
    points = sorted(points)
    valid = list(OUTPUT_KINDS) + points
    names = _names(reader, node, valid, f"`outputs:` of scene '{sname}'", "output") or []
    chosen = [n for n in names if n in points]
    if "points" in names:
        chosen = list(points)
    return Outputs(
        coordinates="coordinates" in names,
        velocities="velocities" in names,
        energies="energies" in names,
        points=tuple(p for p in points if p in chosen),
    )


# ---------------------------------------------------------------------------------- choosing
def select_scene(model, name: str | None) -> Scene | None:
    """The scene called ``name``; without a name the model's only scene, if it has exactly one
    (else None: the whole model). An unknown name is an error listing the valid ones."""
    scenes = {s.name: s for s in model.scenes}
    if name is None:
        return next(iter(scenes.values())) if len(scenes) == 1 else None
    if name in scenes:
        return scenes[name]
    if not scenes:
        raise ModelError([Problem(None, f"{given('scene', name)}: the model {model.path} has no scenes",
                                  f"add a `scenes:` section (docs/model-format.md), or leave out {option('scene')}")])
    hint = close_matches(name, scenes)
    if hint.startswith("did you mean"):
        hint += f" (valid scenes: {', '.join(scenes)})"
    raise ModelError([Problem(None, f"{given('scene', name)}: {model.path} has no scene of that name", hint)])


def derive_scene(model, scene: Scene | None, *, cache: bool = True) -> KnownSystem:
    """The equations of a scene: only its effects are projected (and cached apart, shared
    with every other scene), parameters of switched-off effects are dropped unless something
    kept uses them (the equations, constraints and intermediates, the points asked for, the
    initial values), the scene's values become the defaults (its parameters' values and its
    ``initial:`` over the model's, in ``system.initial``), and only the named points it asks
    for are kept."""
    if scene is None:
        return model.derive(cache=cache)
    system = derive_model(model, cache=cache, effects=scene.effects)
    off = [label for label in effect_labels(model.primitive, model.effects) if label not in scene.effects]
    off_symbols = set().union(*(_effect_symbols(model, label) for label in off)) if off else set()
    points = {label: system.points[label] for label in (scene.outputs.points or ()) if label in system.points}
    kept = dataclasses.replace(system, parameters=(), requirements=(), points=points,
                               initial=initial_values(model, scene))
    used = _symbols(kept)  # equations, constraints and intermediates, kept points, initial values
    parameters = tuple(
        dataclasses.replace(p, value=scene.parameters.get(p.name, p.value))
        for p in system.parameters if p.symbol in used or p.symbol not in off_symbols)
    description = system.description.rstrip()
    if scene.description:
        description = (description + "\n\n" if description else "") + f"Scene {scene.name}: {scene.description}"
    return dataclasses.replace(system, name=f"{system.name} (scene {scene.name})", description=description,
                               parameters=parameters, points=points, initial=kept.initial)


def scene_system(model, name: str | None, *, cache: bool = True,
                 all_points: bool = False) -> tuple[Scene | None, KnownSystem]:
    """``(scene, system)``: the scene called ``name`` chosen by :func:`select_scene` (without a
    name the model's only scene, if it has exactly one; None: the whole model) and its equations
    derived by :func:`derive_scene`. ``all_points`` asks the scene for every named point. The one
    rule of every command and of the notebook (``load(path).derive(scene=...)``)."""
    scene = select_scene(model, name)
    if scene is not None and all_points:
        points = tuple(sorted(model.primitive.points()))
        scene = dataclasses.replace(scene, outputs=dataclasses.replace(scene.outputs, points=points))
    return scene, derive_scene(model, scene, cache=cache)


def initial_values(model, scene: Scene | None) -> dict:
    """The model's ``initial:``, overridden by the scene's."""
    values = dict(model.initial)
    if scene is not None:
        values.update(scene.initial)
    return values


def _effect_symbols(model, label: str) -> set:
    """The symbols an effect is written with (its definition, not its projection)."""
    for effect in model.effects:
        if effect.name == label:
            return _symbols([getattr(effect, f.name) for f in dataclasses.fields(effect)])
    part, _, own = label.partition(".")
    for p in model.primitive.parts:
        if p.name == part:
            return _symbols([p.forces.get(own), p.potentials.get(own)])
    return set()


def _symbols(value) -> set:
    """Every symbol in ``value``: an expression or matrix, and what a list, mapping or dataclass
    (a derived system, its constraints and intermediates, bodies) holds, keys and values."""
    if isinstance(value, (sympy.Basic, sympy.MatrixBase)):
        return set(value.free_symbols)
    if isinstance(value, Mapping):
        value = [*value.keys(), *value.values()]
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = [getattr(value, f.name) for f in dataclasses.fields(value)]
    if isinstance(value, (list, tuple)):
        return set().union(*(_symbols(v) for v in value)) if value else set()
    return set()


__all__ = ["KEYS", "OUTPUT_KINDS", "Outputs", "Scene", "build_scenes", "derive_scene", "initial_values", "scene_system",
           "select_scene"]
