"""Parts: the library components of a model and the known systems placed as components.

A library component (``type:``) becomes a :class:`Part` of the primitive system with its
parameters, coordinate names, points and origin; a known system (a derived model used as a
component, examples II and III) becomes one through :func:`known_system_part` and :func:`placed`.
"""
from __future__ import annotations

import dataclasses

import sympy

from ..components import REGISTRY
from ..core import canonical
from ..core.constraints import Constraint
from ..core.known_system import KnownSystem, ParameterInfo
from ..core.primitive import Part, part_from_component
from ..core.symbols import TIME, free_symbols_of, symbol, velocity_symbol
from ..errors import close_matches
from .connection import pivoted_part
from .expressions import parse_expression
from .reader import ModelReader, node_kind
from .requirements import component_requirements
from .source import Node, excerpt


def mark_broken(reader: ModelReader, cname: str, spec: Node) -> None:
    """Remember a component that failed (its problem is reported already)."""
    reader.broken_parts.add(cname)
    renames = spec.get("coordinates")
    if renames is not None and renames.is_mapping:
        reader.broken_names.update(str(v.value) for v in renames.value.values() if v.is_scalar)
    elif renames is not None and renames.is_sequence:
        reader.broken_names.update(str(v.value) for v in renames.value if v.is_scalar)


def library_component(reader: ModelReader, cname: str, spec: Node) -> Part | None:
    tnode = spec.get("type")
    cls = REGISTRY.get(tnode.value) if tnode is not None and isinstance(tnode.value, str) else None
    options = tuple(o.name for o in cls.options) if cls is not None else ()
    spec = reader.check_keys(spec, ("type", "parameters", "coordinates", "points", "pivot", "description", *options),
                             f"component '{cname}'")
    if tnode is None:
        reader.error(spec, f"component '{cname}' has no `type:`",
                     "valid types: " + ", ".join(sorted(REGISTRY)) + " (or `model: file.yaml`, or `metric:` for "
                     "a component given by its equations)")
        return None
    if not isinstance(tnode.value, str):
        reader.error(tnode, f"`type:` of component '{cname}' must be a name, found {node_kind(tnode)}",
                     "valid types: " + ", ".join(sorted(REGISTRY)))
        return None
    cls = REGISTRY.get(tnode.value)
    if cls is None:
        reader.error(tnode, f"unknown component type '{tnode.value}'", close_matches(tnode.value, REGISTRY))
        return None
    values = component_parameters(reader, cname, spec.get("parameters"), [p.name for p in cls.parameters])
    missing = [ps for ps in cls.parameters if ps.name not in values and ps.default is None]
    for ps in missing:
        reader.error(spec, f"component '{cname}' ({cls.type_name}) needs parameter '{ps.name}'",
                     f"add `{ps.name}: ...` ({ps.description}) under its `parameters:`")
    if missing or any(v is None for v in values.values()):
        return None
    params: dict[str, sympy.Expr] = {}
    for ps in cls.parameters:  # defaults are library text, in the other parameters
        params[ps.name] = values[ps.name] if ps.name in values else parse_expression(ps.default, params)
    reader.requirements += component_requirements(cname, cls(p=params), spec.get("parameters"))
    choices = component_choices(reader, cname, cls, spec)
    cls = cls.chosen(choices) if choices is not None else cls  # an option may set the coordinates
    names = coordinate_names(reader, cname, spec.get("coordinates"), cls.coordinates, f"{cname}_{{}}")
    if names is None:
        return None
    extra = body_points(reader, cname, cls, spec.get("points"), params)
    if extra is None or choices is None:
        return None
    if spec.get("pivot") is not None:
        return pivoted_part(reader, cname, cls, spec, params, names, extra)
    component = cls(x={local: symbol(n) for local, n in zip(cls.coordinates, names)}, p=params,
                    extra_points=extra, choices=choices)
    return part_from_component(cname, component)


def component_choices(reader: ModelReader, cname: str, cls, spec: Node) -> dict[str, str] | None:
    """The component's options (``euler: ZXZ``): each one of its fixed names."""
    choices: dict[str, str] = {}
    for option in cls.options:
        node = spec.get(option.name)
        if node is None:
            continue
        if option.letters and not option.allows(node.value):
            reader.error(node, f"`{option.name}:` of component '{cname}' ({cls.type_name}) must be a word of "
                         f"1 to {option.longest} of the letters {', '.join(option.letters)}, found "
                         f"{node_kind(node)}", f"{option.description}, e.g. `{option.name}: {option.values[0]}`")
            return None
        if not option.allows(node.value):
            reader.error(node, f"`{option.name}:` of component '{cname}' ({cls.type_name}) must be one of "
                         f"{', '.join(option.values)}, found {node_kind(node)}",
                         f"{option.description}; " + close_matches(str(node.value), option.values))
            return None
        choices[option.name] = node.value
    return choices


def body_points(reader: ModelReader, cname: str, cls, node: Node | None, params: dict):
    """Points a model fixes in a rigid body: ``name: [offsets in body axes]``."""
    if node is None:
        return {}
    if not cls.rigid:
        reader.error(node, f"component '{cname}' ({cls.type_name}) is not a rigid body: it takes no `points:`",
                     "add points to a rod, disc, planar_body, pinned_rod or rigid_body3d")
        return None
    entries = reader.mapping(node, f"{cname}.points", "write `points: {tip: [0.5, 0]}` (body axes)")
    points = {}
    for pname, vnode in entries.items():
        if not reader.identifier(pname, node.key_locations[pname], "point"):
            continue
        if not vnode.is_sequence or len(vnode.value) != cls.dimension:
            reader.error(vnode, f"point '{cname}.{pname}' needs {cls.dimension} body-frame offsets",
                         "e.g. `[0.5, 0]` in the plane, `[0, 0, 0.1]` in space")
            continue
        values = [reader.expr(v, reader.parameter_names(), what=f"offset of point '{pname}'") for v in vnode.value]
        if all(v is not None for v in values):
            points[pname] = tuple(values)
    return points


def component_parameters(reader: ModelReader, cname: str, node: Node | None, allowed,
                          inertial=lambda key: True) -> dict[str, sympy.Expr | None]:
    """The values given under a component's ``parameters:``. Those for which ``inertial(key)``
    (they shape the component's metric, velocity terms or points) must not depend on ``t``:
    the component's equations are those of constant parameters, so the motion a value in
    ``t`` would prescribe (a shaken pivot, a growing mass) would be silently left out."""
    values: dict[str, sympy.Expr | None] = {}
    params = reader.mapping(node, f"{cname}.parameters", "write `parameters: {mass: m1, length: 2*a1}`")
    for key, vnode in params.items():
        if key not in allowed:
            reader.error(node.key_locations[key], f"component '{cname}' has no parameter '{key}'",
                         close_matches(key, allowed))
            continue
        value = values[key] = reader.expr(vnode, what=f"parameter '{key}' of '{cname}'")
        if value is not None and TIME in free_symbols_of([value]) and inertial(key):
            reader.error(vnode, f"parameter '{key}' of '{cname}' depends on t, but a component's "
                         "parameters are constants of its inertia (its metric and points): the motion "
                         "a value in t prescribes would be missing from its equations",
                         "give it a constant value; a support moving with the system is a component of "
                         "its own (hang a pinned_rod from it with `pivot:`); a motion prescribed in t goes in the "
                         "connection or under `prescribed:`; a force in t goes under `effects:`")
            values[key] = None
    return values


def coordinate_names(reader: ModelReader, cname: str, node: Node | None, local: tuple[str, ...], default: str):
    """Names of a component's coordinates: ``{local: new}`` or a list in order."""
    names = [default.format(n) for n in local]
    if node is None:
        return names
    if node.is_sequence:
        if len(node.value) != len(local):
            reader.error(node, f"component '{cname}' has {len(local)} coordinates ({', '.join(local)}), "
                               f"{len(node.value)} names given", "give one name per coordinate, in that order")
            return None
        items = list(zip(local, node.value))
    elif node.is_mapping:
        items = []
        for key, vnode in node.value.items():
            if key not in local:
                reader.error(node.key_locations[key], f"component '{cname}' has no coordinate '{key}'",
                             close_matches(key, local))
                continue
            items.append((key, vnode))
    else:
        reader.error(node, "`coordinates:` of a component must map its coordinates to new names",
                     f"e.g. `coordinates: {{{local[0]}: q1}}`")
        return None
    failed = False
    for key, vnode in items:
        if not isinstance(vnode.value, str):
            reader.error(vnode, f"coordinate name of '{cname}.{key}' must be a name, found {node_kind(vnode)}",
                         "use letters, digits and underscores")
            failed = True
            continue
        if reader.identifier(vnode.value, vnode.location, "coordinate"):
            names[local.index(key)] = vnode.value
        else:
            failed = True
    if failed:
        return None  # the component fails: no default name stands in for the one refused
    for i, n in enumerate(names):
        if n in names[:i]:
            reader.error(node, f"component '{cname}' gives two coordinates the name '{n}'",
                         "give each coordinate its own name")
            return None
    return names


def inherit_parameter(reader: ModelReader, cname: str, mnode: Node, info: ParameterInfo) -> None:
    """Known systems share an inherited parameter by its name; two that bring it with
    different values are an error (one would silently take the other's value)."""
    first = reader.inherited.setdefault(info.name, (cname, info.value))
    if info.name in reader.declared or first[0] == cname or first[1] is None or info.value is None:
        return
    if sympy.simplify(first[1] - info.value) != 0:
        reader.error(mnode, f"parameter '{info.name}' is {excerpt(str(info.value))} in '{cname}' but "
                            f"{excerpt(str(first[1]))} in '{first[0]}': known systems share a parameter by its name",
                     f"declare `{info.name}` in this model's `parameters:` to give both one value, or give "
                     f"'{cname}' its own: `parameters: {{{info.name}: {info.name}_{cname}}}` with "
                     f"`{info.name}_{cname}` declared")


def component_origin(reader: ModelReader, cname: str, node: Node | None, dimension: int, has_points: bool = True):
    """``origin: [x, y]``: where a known system's own origin sits in this model's world."""
    if node is None:
        return None
    if not dimension:
        why = "its parts live in worlds of different dimensions" if has_points else "it has no points"
        reader.error(node, f"`origin:` of '{cname}': {why}, so there is no world to move it in",
                     "leave `origin:` out; place the parts in the known system's own file instead")
        return False
    if not node.is_sequence or len(node.value) != dimension:
        reader.error(node, f"`origin:` of '{cname}' needs {dimension} entries (one per world axis)",
                     "e.g. `origin: [2*d, 0]`: the known system is moved there, unturned")
        return False
    values = [reader.expr(v, reader.parameter_names(), what=f"origin of '{cname}'") for v in node.value]
    return False if any(v is None for v in values) else tuple(values)


def inertial_parameters(system: KnownSystem) -> set[str]:
    """Names of a known system's parameters in its metric, velocity terms, points or bodies
    (those an override in ``t`` would move without their inertial terms); the others enter its
    effects alone."""
    imp = system.implicit
    exprs = [imp.metric, imp.velocity_terms] if imp is not None else [system.mass_matrix, system.velocity_terms]
    exprs += [c for pos in system.points.values() for c in pos]
    for b in system.bodies:
        exprs += [b.mass, *b.centre] + [m for m in (b.rotation, b.inertia) if m is not None]
    used = free_symbols_of(exprs)
    return {p.name for p in system.parameters if p.symbol in used}


def known_system_part(name: str, system: KnownSystem, overrides: dict, renames: dict[str, str]) -> Part:
    """A derived system placed as a component: parameters overridden, coordinates renamed.

    A constrained system (``implicit``) is placed on its coordinates ``y`` before the
    constraints, with the metric, velocity terms and forces it carries there, and it brings
    its constraints ``g(y) = 0`` and their branch along: the model using it adds them to its
    own, so its subspace is the one-step projection of the group property (13) whatever
    else it connects or constrains (and the dependent coordinates' points stay usable)."""
    imp = system.implicit
    if imp is not None:
        coordinates, metric, velocity_terms = tuple(imp.intermediate), imp.metric, imp.velocity_terms
        forces = dict(imp.effect_forces)
        constraints, branch = tuple(imp.constraints), dict(imp.branch)
    else:
        coordinates, metric, velocity_terms = tuple(system.coordinates), system.mass_matrix, system.velocity_terms
        forces, constraints, branch = dict(system.effect_forces), (), {}
    sub = dict(overrides)
    for q in coordinates:
        new = symbol(renames.get(q.name, q.name))
        sub[q] = new
        sub[velocity_symbol(q)] = velocity_symbol(new)

    sub = {k: v for k, v in sub.items() if k != v}
    if not sub:
        return Part(name, coordinates, metric, velocity_terms, dict(system.points), tuple(system.bodies),
                    system.dimension, forces, system.potential_energy, "", dict(system.effect_potentials),
                    tuple(Constraint(f"{name}.{c.name}", c.expression, c.source) for c in constraints), branch,
                    dict(system.effect_translations),
                    assembled_potential=(coordinates, canonical.total(system.effect_potentials.values()),
                                         system.potential_energy), effect_kinds=dict(system.effect_kinds))

    def s(e):
        return sympy.sympify(e).xreplace(sub)

    bodies = tuple(dataclasses.replace(b, mass=s(b.mass), centre=tuple(s(c) for c in b.centre),
                                       rotation=b.rotation.xreplace(sub) if b.rotation is not None else None,
                                       inertia=b.inertia.xreplace(sub) if b.inertia is not None else None)
                   for b in system.bodies)
    return Part(
        name=name,
        coordinates=tuple(sub.get(q, q) for q in coordinates),
        metric=metric.xreplace(sub),
        velocity_terms=velocity_terms.xreplace(sub),
        points={label: tuple(s(c) for c in pos) for label, pos in system.points.items()},
        bodies=bodies,
        dimension=system.dimension,
        forces={label: f.xreplace(sub) for label, f in forces.items()},
        potential=s(system.potential_energy),
        type_name="",
        potentials={label: s(v) for label, v in system.effect_potentials.items()},
        constraints=tuple(Constraint(f"{name}.{c.name}", s(c.expression), c.source) for c in constraints),
        branch={sub.get(q, q): v for q, v in branch.items()},
        translations={label: tuple(s(c) for c in grad) for label, grad in system.effect_translations.items()},
        effect_kinds=dict(system.effect_kinds),
    )


def placed(part: Part, origin) -> Part:
    """A known system moved (not turned) to ``origin``: its points and mass centres shift; its
    metric, velocity terms and forces do not change (a translation is an isometry), nor does the
    potential of anything that moves with it (its springs and anchors); its own gravity's
    potential changes by ``dV/do . origin`` (``Effect.translation``), a constant."""

    def shift(pos):
        return tuple(sympy.sympify(c) + o for c, o in zip(pos, origin))

    potentials, changes = dict(part.potentials), []
    for label, grad in part.translations.items():
        changes.append(sympy.Add(*[g * o for g, o in zip(grad, origin)]))
        potentials[label] = sympy.expand(potentials.get(label, sympy.Integer(0)) + changes[-1])
    bodies = tuple(dataclasses.replace(b, centre=shift(b.centre)) for b in part.bodies)
    return dataclasses.replace(part, points={k: shift(v) for k, v in part.points.items()}, bodies=bodies,
                               potentials=potentials, potential=sympy.expand(part.potential + sympy.Add(*changes)))


__all__ = ["body_points", "component_choices", "component_origin", "component_parameters", "coordinate_names",
           "inertial_parameters", "inherit_parameter", "known_system_part", "library_component", "mark_broken",
           "placed"]
