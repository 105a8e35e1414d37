"""Reading the ``effects:`` section (:func:`read_effects`): one builder per effect type (the effect
registry, ``BUILDERS``)."""
from __future__ import annotations

import sympy

from ..core.symbols import free_symbols_of, velocity_symbol
from ..effects.base import Effect
from ..components.base import POSITIVE
from ..effects.electrical import Capacitor, Gyrator, Resistor, VoltageSource
from ..effects.elements import Damper, Spring, TorsionalDamper, TorsionalSpring, separation
from ..effects.gravity import Gravity
from ..effects.loads import Force, GeneralizedForce, Potential, Torque
from ..errors import close_matches
from .reader import ModelReader
from .requirements import Requirement
from .source import Node

DEFAULT_DOWN = {1: (-1,), 2: (0, -1), 3: (0, 0, -1)}
WORLDS = {1: "line", 2: "plane", 3: "space"}
IN_WORLD = {1: {2: "the plane's x axis", 3: "space's x axis"}, 2: {3: "space's z = 0 plane"}}
"""Where a smaller world lies in a larger one (:func:`~kronsub.components.base.in_world`)."""


def _required(reader: ModelReader, spec: Node, key: str, ename: str, hint: str) -> Node | None:
    node = spec.get(key)
    if node is None:
        reader.error(spec, f"effect '{ename}' needs `{key}:`", hint)
    return node


def _vector(reader: ModelReader, node: Node, what: str):
    if not node.is_sequence or not node.value:
        reader.error(node, f"{what} must be a list of components, e.g. `[F, 0]`", "write `[x, y]` or `[x, y, z]`")
        return None
    values = [reader.expr(item, what=what) for item in node.value]
    return None if any(v is None for v in values) else tuple(values)


def zero_vector(reader: ModelReader, node: Node, d, what: str, example: str = "[0, -1]") -> bool:
    """Whether the direction ``d`` is the zero vector, or no real vector (:func:`unreal_vector`),
    at the parameters' values, which is reported at ``node`` (a direction is divided by its
    length: the zero one gave NaN forces or constraints)."""
    if unreal_vector(reader, node, d, what):
        return True
    numbers = [_complex(e) for e in _at_values(reader, d)]
    if not (sympy.Add(*[c**2 for c in d]).is_zero or all(z is not None and z == 0 for z in numbers)):
        return False
    reader.error(node, f"{what} is the zero vector, which points nowhere",
                 f"give a direction with a nonzero entry, e.g. `{example}` (its length does not matter)")
    return True


def unreal_vector(reader: ModelReader, node: Node, d, what: str) -> bool:
    """Whether the vector ``d`` has an entry that is no finite real number at the parameters'
    values (``sqrt(-a)``), which is reported at ``node``: a complex or infinite offset or
    direction made complex or NaN forces and constraints."""
    numbers = [_complex(e) for e in _at_values(reader, d)]
    if not any(z is not None and (z != z or abs(z) == float("inf") or abs(z.imag) > 1e-12 * max(1.0, abs(z)))
               for z in numbers):
        return False
    shown = ", ".join(sympy.sstr(e) for e in d)
    reader.error(node, f"{what} [{shown}] is not a real vector at the parameters' values",
                 "give each entry a finite real value: check sqrt, log, asin and acos of the parameters")
    return True


def _at_values(reader: ModelReader, d) -> list:
    values = {s: v for s, v in reader.parameter_values().items() if sympy.sympify(v).is_number}
    return [sympy.sympify(c).xreplace(values) for c in d]


def _complex(e) -> complex | None:
    """``e`` as a complex number, None while it still has symbols in it."""
    try:
        return complex(e.evalf()) if not e.free_symbols else None
    except (TypeError, ValueError, OverflowError):
        return complex(float("nan"))


def _direction(reader: ModelReader, node: Node, what: str):
    """A direction: a vector that is not zero."""
    d = _vector(reader, node, what)
    return None if d is None or zero_vector(reader, node, d, what) else d


def _positional(reader: ModelReader, node: Node, value, primitive, ename: str, what: str):
    """``value`` if it has no velocity in it, else ``None`` (reported at ``node``): a potential,
    a spring's or a torsional spring's terms and a torsional damper's angle are functions of
    the configuration (and ``t``); with a velocity inside, ``-dV/dx`` (and ``angledot``)
    would leave out its ``d/dt dV/dxdot`` terms, silently."""
    if value is None:
        return None
    rates = set(primitive.velocities) | {velocity_symbol(q) for q in reader.subspace_names.values()}
    used = sorted(s.name for s in free_symbols_of([value]) & rates)
    if not used:
        return value
    reader.error(node, f"{what} of '{ename}' depends on the velocity '{used[0]}'",
                 "it is a function of the coordinates (and t) alone; a load in the velocities is a "
                 "`force`, `generalized_force`, `damper` or `torsional_damper` (in its `coefficient:`)")
    return None


def _point(reader: ModelReader, node: Node, primitive, ename: str):
    """A named point ``component.point``, or a fixed place given as a list."""
    if node.is_sequence:
        return _vector(reader, node, f"fixed point of '{ename}'")
    name = str(node.value)
    points = primitive.points()
    if name not in points and reader.is_broken(name):
        return None  # its component's problem is reported already
    if name not in points:

        reader.error(node, f"unknown point '{name}' in effect '{ename}'", close_matches(name, points))
        return None
    return name


def _gravity(reader: ModelReader, ename, spec, primitive):
    """Gravity on the chosen components (default: every library component with mass).

    Known systems bring their own effects, so they are included only when named.
    Without ``direction:`` the components fall "down" in their world (-x on a line, -y in the
    plane, -z in space); over components of different worlds it needs a ``direction:``. A
    component in a smaller world than the direction's lies in it as everywhere (a line on the
    x axis): it feels the part of gravity along its world, none across it.
    """

    if spec.get("g") is not None:
        g = _positional(reader, spec.get("g"), reader.expr(spec.get("g"), what="g"), primitive, ename, "`g:`")
        if g is None:
            return None
    elif "g" in reader.parameters:
        g = reader.parameters["g"].symbol
    else:
        g = None
        reader.error(spec, f"gravity '{ename}' needs `g:`", "give `g: 9.81` or declare a parameter `g`")
    reported = len(reader.problems.problems)  # a gravity on nothing is an error, unless said already
    names = [p.name for p in primitive.parts]
    cnode = spec.get("components")
    if cnode is None:
        chosen = [p.name for p in primitive.parts if p.type_name and any(b.mass != 0 for b in p.bodies)]
    elif not cnode.is_sequence:
        reader.error(cnode, f"`components:` of gravity '{ename}' must be a list", f"e.g. `components: [{names[0]}]`")
        return None
    else:
        chosen = []
        for n in cnode.value:
            if str(n.value) not in names and reader.is_broken(str(n.value)):
                continue  # its component's problem is reported already
            if str(n.value) not in names:
                reader.error(n, f"unknown component '{n.value}' in gravity '{ename}'", close_matches(str(n.value), names))
            else:
                chosen.append(str(n.value))
    direction = None
    if spec.get("direction") is not None:
        direction = _direction(reader, spec.get("direction"), "direction of gravity")
        if direction is None or _positional(reader, spec.get("direction"), sympy.Matrix(direction), primitive,
                                            ename, "the direction") is None:
            return None
    worlds = sorted({primitive.part(n).dimension for n in chosen if primitive.part(n).dimension})
    if direction is None and len(worlds) > 1:
        _mixed_worlds(reader, spec, ename, primitive, chosen, worlds)
        return None
    parts = []
    for name in chosen:
        part = primitive.part(name)
        if not part.dimension:
            continue  # nothing of it moves in a world (a flywheel on its axis)
        d = direction if direction is not None else DEFAULT_DOWN.get(part.dimension)
        if len(d) < part.dimension:
            if cnode is not None:
                reader.error(spec, f"gravity '{ename}' has a {len(d)}-D direction but component "
                                   f"'{name}' lives in {part.dimension}-D",
                             "give a direction with one entry per world axis of the component")
            continue
        if not _along(d, part.dimension):
            if cnode is not None:
                reader.error(spec, f"gravity '{ename}' does nothing on component '{name}': its direction is "
                                   f"across the {WORLDS[part.dimension]} the component moves in "
                                   f"({IN_WORLD[part.dimension][len(d)]})",
                             f"leave '{name}' out of `components:`, or give a direction with a part along its "
                             f"{WORLDS[part.dimension]}")
            continue
        parts.append((name, tuple(d)))
    if direction is not None and not parts and worlds and cnode is None:
        reader.error(spec.get("direction"), f"gravity '{ename}' acts on no component: its direction has "
                     f"{len(direction)} entries, but the components live in "
                     + " and ".join(f"{w}-D" for w in worlds),
                     "give a direction with one entry per world axis, e.g. `[0, -1]` in the plane")
        return None
    if not parts and len(reader.problems.problems) == reported and not reader.failed_components:
        known = [p.name for p in primitive.parts if not p.type_name and any(b.mass != 0 for b in p.bodies)]
        why = ("without `components:` it acts on the library components with mass, and known systems "
               "bring their own gravity" if cnode is None else "nothing of the components named moves in a world")
        reader.error(spec, f"gravity '{ename}' acts on no component: {why}",
                     f"name the components it acts on, e.g. `components: [{known[0]}]`" if known and cnode is None
                     else "leave it out, or name components with mass")
        return None
    if g is None:
        return None
    return Gravity(ename, g=g, parts=tuple(parts))


def _along(d, dimension: int) -> bool:
    """Whether gravity along ``d`` has a part in a component's world of ``dimension`` axes: the
    world's first axes (:func:`~kronsub.components.base.in_world`), a line on the x axis."""
    return not sympy.Add(*[c**2 for c in d[:dimension]]).is_zero


def _mixed_worlds(reader: ModelReader, spec: Node, ename: str, primitive, chosen, worlds) -> None:
    """Report a gravity without ``direction:`` over components of different worlds: each world's
    own "down" (along a line, -y in the plane, -z in space) disagrees with the others', since a
    line lies on the plane's x axis and the plane in space's z = 0 plane."""
    by_world = "; ".join(f"{WORLDS[w]}: " + ", ".join(n for n in chosen if primitive.part(n).dimension == w)
                         for w in worlds)
    example = str(list(DEFAULT_DOWN[worlds[-1]]))
    reader.error(spec, f"gravity '{ename}' has no `direction:` and acts on components of different worlds "
                       f"({by_world})",
                 f"give `direction:` in the {WORLDS[worlds[-1]]}, e.g. `{example}`: a line lies on the plane's x "
                 f"axis (a horizontal rail, which feels none of it), the plane in space's z = 0 plane; or list one "
                 f"world's components in `components:`")


def _force(reader: ModelReader, ename, spec, primitive):
    pnode = _required(reader, spec, "point", ename, "e.g. `point: lower.centre`")
    if pnode is None:
        return None
    point = _point(reader, pnode, primitive, ename)
    if "vector" in spec.value:
        vector = _vector(reader, spec.get("vector"), f"force vector of '{ename}'")
    elif "direction" in spec.value and "magnitude" in spec.value:
        d = _direction(reader, spec.get("direction"), f"direction of '{ename}'")
        mag = reader.expr(spec.get("magnitude"), what=f"magnitude of '{ename}'")
        vector = None
        if d is not None and mag is not None:
            norm = sympy.sqrt(sum(c**2 for c in d))
            vector = tuple(mag * c / norm for c in d)
    else:
        reader.error(spec, f"force '{ename}' needs `vector:` or `direction:` and `magnitude:`",
                     "e.g. `vector: [F, 0]`")
        return None
    if isinstance(point, tuple):
        reader.error(pnode, f"force '{ename}' must act at a named point of a component",
                     "e.g. `point: lower.centre`; a force at a fixed place does no work")
        return None
    if point is None or vector is None:
        return None
    if len(vector) != len(primitive.points()[point]):
        reader.error(spec, f"force '{ename}' has {len(vector)} components but point '{point}' has "
                           f"{len(primitive.points()[point])}", "give one component per world axis")
        return None
    return Force(ename, point=point, vector=vector)


def named_body(reader: ModelReader, node: Node, primitive, what: str, unknown: str = ""):
    """The body ``node`` names, as ``(part, index)``: a component's own (``lower``), or one of a
    known system's by its dotted name (``s.lower``, ``pair.left.pole``; ``s`` alone when it has
    just one body). None after reporting why: unknown (``unknown``: the message then), or a
    known system of several bodies."""
    name = str(node.value)
    bodies = primitive.bodies_by_name()
    if name in bodies:
        return bodies[name]
    inner = [label for label in bodies if label.startswith(name + ".")]
    if len(inner) == 1:
        return bodies[inner[0]]
    if inner:
        reader.error(node, f"{what}: component '{name}' is a known system of {len(inner)} bodies",
                     "say which one: " + ", ".join(f"`{label}`" for label in inner))
        return None
    names = [p.name for p in primitive.parts if p.bodies] + [label for label in bodies if "." in label]
    reader.error(node, unknown or f"unknown component '{name}'", close_matches(name, names))
    return None


def _torque(reader: ModelReader, ename, spec, primitive):
    cnode = _required(reader, spec, "component", ename, "e.g. `component: wheel`")
    vnode = _required(reader, spec, "value", ename, "e.g. `value: tau`")
    if cnode is None or vnode is None:
        return None
    found = named_body(reader, cnode, primitive, f"torque '{ename}'")
    if found is None:
        return None
    part, index = found
    if part.bodies[index].rotation is None:
        reader.error(cnode, f"component '{cnode.value}' has no rotating body to take a torque",
                     "apply a torque to a rod, disc, body, pinned rod or flywheel")
        return None
    value = _vector(reader, vnode, "torque") if vnode.is_sequence else reader.expr(vnode, what="torque")
    if value is None:
        return None
    value = value if isinstance(value, tuple) else (value,)
    axes = 1 if part.bodies[index].rotation.shape == (2, 2) else 3
    if len(value) != axes:
        reader.error(vnode, f"torque '{ename}' on '{part.name}' needs {axes} component(s), found {len(value)}",
                     "one value about the plane's normal for planar bodies; [x, y, z] in space")
        return None
    return Torque(ename, part=part.name, value=value, body=index)


def _spring(reader: ModelReader, ename, spec, primitive, damper=False):
    bnode = _required(reader, spec, "between", ename, "e.g. `between: [upper.tip, [0, 0]]`")
    if bnode is None:
        return None
    if not bnode.is_sequence or len(bnode.value) != 2:
        reader.error(bnode, f"`between:` of '{ename}' must list two points", "e.g. `between: [a.tip, b.centre]`")
        return None
    ends = tuple(_point(reader, n, primitive, ename) for n in bnode.value)
    key = "coefficient" if damper else "stiffness"
    knode = _required(reader, spec, key, ename, f"e.g. `{key}: k`")
    if knode is None or any(e is None for e in ends):
        return None
    together = _always_together(primitive, ends)
    if together:
        kind = "damper" if damper else "spring"
        reader.error(bnode, f"the two ends of {kind} '{ename}' are the same point, whatever the motion",
                     f"a {kind} acts between two points that move apart: join it to another point, or remove it")
    k = reader.expr(knode, what=key)
    if not damper:
        k = _positional(reader, knode, k, primitive, ename, "the stiffness")
    if k is None or together:
        return None
    if damper:
        return Damper(ename, ends=ends, coefficient=k)
    length = (_positional(reader, spec.get("length"), reader.expr(spec.get("length"), what="rest length"), primitive,
                          ename, "the rest length") if "length" in spec.value else sympy.Integer(0))
    return None if length is None else Spring(ename, ends=ends, stiffness=k, length=length)


def _always_together(primitive, ends) -> bool:
    """Whether the two ends of a spring or damper are one point in every configuration (the
    same point named twice, or two fixed places that are one): its length is always 0, so it
    does nothing, or (a damper's direction, a spring's with a rest length) is 0/0."""
    return all(sympy.expand(c) == 0 for c in separation(primitive, ends))


def _torsional(reader: ModelReader, ename, spec, primitive, damper=False):
    anode = _required(reader, spec, "angle", ename, "e.g. `angle: phi - theta` (primitive coordinates)")
    key = "coefficient" if damper else "stiffness"
    knode = _required(reader, spec, key, ename, f"e.g. `{key}: k`")
    if anode is None or knode is None:
        return None
    angle, k = reader.expr(anode, what="angle"), reader.expr(knode, what=key)
    angle = _positional(reader, anode, angle, primitive, ename, "the angle")
    if not damper:
        k = _positional(reader, knode, k, primitive, ename, "the stiffness")
    if angle is None or k is None:
        return None
    if damper:
        return TorsionalDamper(ename, angle=angle, coefficient=k)
    rest = (_positional(reader, spec.get("rest"), reader.expr(spec.get("rest"), what="rest angle"), primitive,
                        ename, "the rest angle") if "rest" in spec.value else sympy.Integer(0))
    return None if rest is None else TorsionalSpring(ename, angle=angle, stiffness=k, rest=rest)


def _generalized(reader: ModelReader, ename, spec, primitive):
    cnode = _required(reader, spec, "coordinate", ename, "e.g. `coordinate: lower.phi`")
    vnode = _required(reader, spec, "value", ename, "e.g. `value: -c*phi_dot`")
    if cnode is None or vnode is None:
        return None
    name = str(cnode.value)
    q = reader.primitive_names.get(name, reader.subspace_names.get(name))
    if q is None:
        reader.error(cnode, f"'{name}' is not a primitive or generalized coordinate",
                     close_matches(name, [*reader.primitive_names, *reader.subspace_names]))
        return None
    value = reader.expr(vnode, what="generalized force")
    return None if value is None else GeneralizedForce(ename, coordinate=q, value=value)


def _potential(reader: ModelReader, ename, spec, primitive):
    vnode = _required(reader, spec, "value", ename, "e.g. `value: k*x**4/4`")
    if vnode is None:
        return None
    value = _positional(reader, vnode, reader.expr(vnode, what="potential"), primitive, ename, "the potential")
    return None if value is None else Potential(ename, value=value)


def _charge(reader: ModelReader, spec: Node, primitive, ename: str, key: str = "charge"):
    """The charge a circuit element acts along: an expression in the coordinates (a branch's
    ``q``, a loop charge, a difference of two), never in their rates."""
    node = _required(reader, spec, key, ename, "e.g. `charge: coil.q` (a branch's charge, or a loop charge)")
    if node is None:
        return None
    return _positional(reader, node, reader.expr(node, what=f"charge of '{ename}'"), primitive, ename, "the charge")


def _element_value(reader: ModelReader, spec: Node, primitive, ename: str, key: str, unit: str, sign: str = ""):
    """A circuit element's value (``capacitance:``, ``resistance:``, ``voltage:``): a function of
    the configuration and ``t``; with ``sign``, what its value must be once the parameters are
    numbers (a negative resistance would create energy)."""
    node = _required(reader, spec, key, ename, f"e.g. `{key}: {unit}`")
    if node is None:
        return None
    value = _positional(reader, node, reader.expr(node, what=key), primitive, ename, f"the {key}")
    if value is not None and sign:
        reader.requirements.append(Requirement(f"{key} of '{ename}'", value, sign, node.location))
    return value


def _capacitor(reader: ModelReader, ename, spec, primitive):
    charge = _charge(reader, spec, primitive, ename)
    capacitance = _element_value(reader, spec, primitive, ename, "capacitance", "C", POSITIVE)
    if charge is None or capacitance is None:
        return None
    return Capacitor(ename, charge=charge, capacitance=capacitance)


def _resistor(reader: ModelReader, ename, spec, primitive):
    charge = _charge(reader, spec, primitive, ename)
    resistance = _element_value(reader, spec, primitive, ename, "resistance", "R", POSITIVE)
    if charge is None or resistance is None:
        return None
    return Resistor(ename, charge=charge, resistance=resistance)


def _voltage_source(reader: ModelReader, ename, spec, primitive):
    charge = _charge(reader, spec, primitive, ename)
    vnode = _required(reader, spec, "voltage", ename, "e.g. `voltage: E*sin(w*t)`")
    voltage = reader.expr(vnode, what="voltage") if vnode is not None else None
    if charge is None or voltage is None:
        return None
    return VoltageSource(ename, charge=charge, voltage=voltage)


def _gyrator(reader: ModelReader, ename, spec, primitive):
    bnode = _required(reader, spec, "between", ename, "e.g. `between: [armature.q, shaft.angle]`")
    if bnode is None:
        return None
    if not bnode.is_sequence or len(bnode.value) != 2:
        reader.error(bnode, f"`between:` of '{ename}' must list two coordinates (expressions)",
                     "e.g. `between: [armature.q, shaft.angle]`: the current and the speed it couples")
        return None
    ends = [_positional(reader, n, reader.expr(n, what=f"end of '{ename}'"), primitive, ename, "an end")
            for n in bnode.value]
    constant = _element_value(reader, spec, primitive, ename, "constant", "k")
    if any(e is None for e in ends) or constant is None:
        return None
    return Gyrator(ename, first=ends[0], second=ends[1], constant=constant)


BUILDERS = {
    "gravity": (_gravity, ("g", "direction", "components")),
    "force": (_force, ("point", "vector", "direction", "magnitude")),
    "torque": (_torque, ("component", "value")),
    "spring": (_spring, ("between", "stiffness", "length")),
    "damper": (lambda l, n, s, p: _spring(l, n, s, p, damper=True), ("between", "coefficient")),
    "torsional_spring": (_torsional, ("angle", "stiffness", "rest")),
    "torsional_damper": (lambda l, n, s, p: _torsional(l, n, s, p, damper=True), ("angle", "coefficient")),
    "generalized_force": (_generalized, ("coordinate", "value")),
    "potential": (_potential, ("value",)),
    "capacitor": (_capacitor, ("charge", "capacitance")),
    "resistor": (_resistor, ("charge", "resistance")),
    "voltage_source": (_voltage_source, ("charge", "voltage")),
    "gyrator": (_gyrator, ("between", "constant")),
}


def build_effect(reader: ModelReader, ename: str, spec: Node, primitive) -> Effect | None:
    """Build one named effect from its YAML mapping (problems go to the reader)."""

    if not spec.is_mapping:
        reader.error(spec, f"effect '{ename}' must be a mapping", "e.g. `{type: gravity, g: g}`")
        return None
    tnode = spec.get("type")
    if tnode is None:
        reader.error(spec, f"effect '{ename}' has no `type:`", "valid types: " + ", ".join(sorted(BUILDERS)))
        return None
    entry = BUILDERS.get(str(tnode.value))
    if entry is None:
        reader.error(tnode, f"unknown effect type '{tnode.value}'", close_matches(str(tnode.value), BUILDERS))
        return None
    builder, keys = entry
    spec = reader.check_keys(spec, ("type", "description") + keys, f"effect '{ename}'")
    return builder(reader, ename, spec, primitive)


def read_effects(reader: ModelReader, node: Node | None, primitive, coords) -> list[Effect]:
    """The effects, written in the primitive coordinates or in the subspace's ``coords``
    (those are applied directly in the subspace: core/subspace.py)."""
    for q in coords:
        reader.subspace_names[q.name] = q
        reader.names.setdefault(q.name, q)
        reader.names.setdefault(velocity_symbol(q).name, velocity_symbol(q))
    effects = []
    for ename, spec in reader.mapping(node, "effects", "write `gravity: {type: gravity, g: g}`").items():
        loc = node.key_locations[ename]
        if not reader.identifier(ename, loc, "effect"):
            continue
        effect = build_effect(reader, ename, spec, primitive)
        if effect is not None:
            reader.locations[f"effect:{ename}"] = loc
            effects.append(effect)
    return effects


__all__ = ["BUILDERS", "DEFAULT_DOWN", "IN_WORLD", "WORLDS", "build_effect", "named_body", "read_effects",
           "unreal_vector", "zero_vector"]
