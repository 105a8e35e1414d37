"""The connection: the primitive coordinates as functions of the subspace's, ``x = x(y)``.

The model's ``connection:`` section (Kron's transformation, whose Jacobian is ``C = dx/dy``), the
pivots that hang a part from a moving point, the intermediate coordinates of a closed loop and
their split into independent and dependent ones (:class:`ImplicitSpec`).
"""
from __future__ import annotations

import sympy

from ..components.base import in_world
from ..components.planar import PinnedRod, Rod
from ..core.constraints import Constraint
from ..core.primitive import Part, Primitive, part_from_component
from ..core.symbols import TIME, free_symbols_of, symbol
from ..errors import Location, close_matches, near_names
from .constraints import analyse
from .model import ImplicitSpec
from .reader import ModelReader
from .source import Node


def read_connection(reader: ModelReader, node: Node | None, primitive: Primitive, coords) -> dict:
    connection: dict[sympy.Symbol, sympy.Expr] = {}
    where: dict[sympy.Symbol, Location] = {}
    generalized = {q.name: q for q in coords}
    attempted: set[sympy.Symbol] = set()
    unknown_keys: list[str] = []
    entries = reader.mapping(node, "connection", "write one `primitive_coordinate: expression` per line")
    if node is not None:
        reader.locations["connection"] = node.location
    for key, vnode in entries.items():
        loc = node.key_locations[key]
        x = reader.primitive_names.get(key)
        if x is None:
            unknown_keys.append(key)
            if reader.is_broken(key) or reader.failed_components:
                continue  # most likely a coordinate of the component that failed, reported already
            if any(angle.name == key for _, _, angle, _, _ in reader.pivots):
                continue  # a pivoted part's angle: reported by read_pivot_angles
            reader.error(loc, f"'{key}' is not a coordinate of the primitive system",
                         close_matches(key, [k for k in reader.primitive_names if "." in k] +
                                       [q.name for q in primitive.coordinates]))
            continue
        if x in connection:
            reader.error(loc, f"primitive coordinate '{x}' is connected twice (first at line {where[x].line})",
                         "connect each primitive coordinate once")
            continue
        attempted.add(x)
        value = reader.expr(vnode, {**reader.parameter_names(), **generalized, "t": TIME},
                            what=f"connection of '{key}'")
        if value is None:
            continue
        connection[x] = sympy.sympify(value)
        where[x] = loc
    for x, (expr, ploc) in reader.auto_connection.items():
        if x in connection:
            reader.error(where[x], f"primitive coordinate '{x}' is set by `pivot:` and cannot be connected",
                         "remove it from `connection:`")
            continue
        connection[x] = expr
    if reader.auto_connection:  # a pivot on a connected point: compose until only xbar remains
        for _ in range(len(reader.auto_connection) + 1):
            done = {x: e.xreplace(connection) for x, e in connection.items()}
            if done == connection:
                break
            connection = done
    for x in primitive.coordinates:
        if x in connection or x in attempted:
            continue
        if x.name in generalized:
            connection[x] = x  # identity maps may be written short
        else:
            owner = next(p.name for p in primitive.parts if x in p.coordinates)
            if any(near_names(key, [x.name, f"{owner}.{x.name}"]) for key in unknown_keys):
                continue  # the misspelt key reported above was meant for it: one typo, one error
            reader.error(node.location if node is not None else reader.locations[f"component:{owner}"],
                         f"primitive coordinate '{owner}.{x}' is not connected",
                         f"add `{x}: <expression in {', '.join(generalized)}>` under `connection:`, "
                         "or name it like a generalized coordinate for an identity map")
    used = free_symbols_of(connection.values())
    if attempted - set(connection) or unknown_keys or reader.failed_components or not coords:
        return connection  # after another error this check would only mislead
    for q in coords:
        if q not in used:
            reader.error(reader.locations.get("coordinates", reader.root.location),
                         f"generalized coordinate '{q}' does not appear in the connection",
                         "every generalized coordinate must move some primitive coordinate")
    return connection


def pivoted_part(reader: ModelReader, cname: str, cls, spec: Node, params: dict, names: list[str],
                 extra: dict) -> Part | None:
    """A pinned part hanging from a moving point: in the primitive a free rod whose centre and
    axis the connection ties to the pivot point and the part's own angle (Kron's way)."""
    pnode = spec.get("pivot")
    if cls is not PinnedRod:
        reader.error(pnode, f"component '{cname}' ({cls.type_name}) takes no `pivot:`",
                     "only a pinned_rod hangs from a point")
        return None
    given = spec.get("parameters")
    for key in ("pivot_x", "pivot_y"):
        if given is not None and given.is_mapping and key in given.value:
            reader.error(given.key_locations[key], f"component '{cname}' has `pivot:`; `{key}` is not used",
                         f"remove `{key}`")
            return None
    if not isinstance(pnode.value, str):
        reader.error(pnode, f"`pivot:` of '{cname}' must name a point, e.g. `pivot: cart.centre`",
                     "a moving point `component.point`; a fixed pivot is `pivot_x`, `pivot_y`")
        return None
    hidden = {local: symbol(f"{cname}_{local if local != 'angle' else 'axis'}") for local in Rod.coordinates}
    rod = Rod(x=hidden, p={"mass": params["mass"], "length": params["length"], "inertia": params["inertia"]},
              extra_points=extra)
    part = part_from_component(cname, rod)
    pts = dict(part.points)
    points = {"pivot": pts.pop("a"), "centre": pts.pop("centre"), "tip": pts.pop("b"), **pts}
    import dataclasses

    angle = symbol(names[0])
    reader.pivots.append((cname, pnode, angle, params["length"], hidden))
    return dataclasses.replace(part, points=points)


def read_pivot_angles(reader: ModelReader, node: Node | None, y) -> None:
    """A pivoted part's angle is a coordinate of the subspace (``y``; without constraints a
    generalized coordinate): its connection lines are written in it. Left out, it would be a
    frozen symbol; given by the connection, it is no primitive coordinate."""
    entries = node.value if node is not None and node.is_mapping else {}
    for cname, pnode, angle, _, _ in reader.pivots:
        hint = (f"list '{angle}' under `coordinates:`; for an angle given by other coordinates "
                f"(a relative angle), make '{cname}' a `rod` with `axis: down` and connect its x, y and angle")
        if angle.name in entries:
            reader.error(node.key_locations[angle.name], f"'{angle}' is the angle of '{cname}', which hangs "
                         f"from `pivot: {pnode.value}`: the pivot sets its place from that angle, which cannot "
                         "itself be connected", hint)
        elif angle not in y:
            reader.error(pnode, f"the angle '{angle}' of '{cname}' (hung from `pivot: {pnode.value}`) is not a "
                         "generalized coordinate", hint)


def pivot_connection(reader: ModelReader, primitive: Primitive) -> None:
    """Connection lines of the pivoted parts: centre = pivot + L/2 (sin a, -cos a), axis = a - pi/2."""
    points = primitive.points()
    for cname, pnode, angle, length, hidden in reader.pivots:
        label = pnode.value
        if label not in points or label.startswith(f"{cname}."):
            reader.error(pnode, f"unknown pivot point '{label}' of '{cname}'",
                         close_matches(label, [p for p in points if not p.startswith(f"{cname}.")]))
            continue
        pos = tuple(points[label])
        if len(pos) > 2:
            reader.error(pnode, f"pivot '{label}' of '{cname}' is a point in space", "a pinned_rod is planar")
            continue
        px, py = in_world(pos, 2)
        half = length / 2
        reader.auto_connection[hidden["x"]] = (px + half * sympy.sin(angle), pnode.location)
        reader.auto_connection[hidden["y"]] = (py - half * sympy.cos(angle), pnode.location)
        reader.auto_connection[hidden["angle"]] = (angle - sympy.pi / 2, pnode.location)


def read_intermediate(reader: ModelReader, node: Node | None, primitive: Primitive, coords) -> tuple[sympy.Symbol, ...]:
    """The coordinates ``y`` the constraints act on, in the order the model declares its parts:
    the primitive coordinates not given by the connection, a pivoted part's angle in the place of
    the coordinates its pivot gives, then any other listed ones."""
    connected = set(reader.auto_connection)
    for key in reader.mapping(node, "connection", "write one `primitive_coordinate: expression` per line"):
        if key in reader.primitive_names:
            connected.add(reader.primitive_names[key])
    angle_of = {x: angle for _, _, angle, _, hidden in reader.pivots for x in hidden.values()}
    y = []
    for x in primitive.coordinates:
        if x in angle_of and angle_of[x] not in y:
            y.append(angle_of[x])
        elif x not in connected and x not in angle_of:
            y.append(x)
    for _, _, angle, _, _ in reader.pivots:
        if angle not in y:
            y.append(angle)
    for q in coords:
        if q not in y:
            y.append(q)
    for q in y:
        reader.names.setdefault(q.name, q)
    return tuple(y)


def implicit_spec(reader: ModelReader, node: Node, constraints, connection, y, coords, auto: bool,
                  initial) -> ImplicitSpec | None:
    """Constraints in ``y``, the dependent coordinates and the branch (25)-(27)."""
    where = reader.root.key_locations.get("constraints") or reader.root.key_locations["components"]
    if not constraints:
        reader.error(where, "`constraints:` is empty", "remove it, or write `name: expression` (= 0)")
        return None
    in_y = tuple(Constraint(c.name, sympy.sympify(c.expression).xreplace(connection), c.source)
                 for c in constraints)
    for c in in_y:
        if not (free_symbols_of([c.expression]) & set(y)):
            reader.error(reader.locations.get(f"constraint:{c.name.split('.')[0]}", where),
                         f"constraint '{c.name}' does not involve any coordinate after the connection",
                         "a constraint on connected coordinates only is already satisfied or never")
            return None
    for q in coords:
        if q not in y:
            reader.error(reader.locations.get("coordinates", where),
                         f"independent coordinate '{q}' is not a coordinate of the constrained system",
                         "choose among " + ", ".join(s.name for s in y))
            return None
    # the branch of a constrained known system is the first guess of its dependent coordinates
    guesses = {q: v for part in reader.parts for q, v in part.branch.items() if q in set(y)}
    guesses.update(initial)
    result = analyse(reader, in_y, y, tuple(coords), auto, guesses, where)
    if result is None:
        return None
    independent, dependent, branch, closed, point = result
    return ImplicitSpec(intermediate=tuple(y), independent=tuple(independent), dependent=tuple(dependent),
                        constraints=in_y, branch=branch, closed_form=closed,
                        choice="auto" if auto else "given", configuration=tuple(point.items()))


__all__ = ["implicit_spec", "pivot_connection", "pivoted_part", "read_connection", "read_intermediate",
           "read_pivot_angles"]


__all__ = ["implicit_spec", "pivot_connection", "pivoted_part", "read_connection", "read_intermediate",
           "read_pivot_angles"]
