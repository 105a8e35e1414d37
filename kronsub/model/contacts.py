"""Contact joints under ``velocity_constraints:``: a wheel rolling on the ground and a knife edge,
each made into velocity constraints from the body's material point at the contact
(:mod:`..core.contact`).

- ``{rolls_on: plane, body: B, radius: r, axle: [0, 1, 0]}``: a body in space (``rigid_body3d``)
  whose rim of radius ``r`` about the body-frame ``axle`` (default its y axis) rolls without
  slipping on the ground ``z = 0``: the rim's lowest point does not move, two constraints
  ``<name>.x``, ``<name>.y`` (its height is a configuration constraint, which the connection
  keeps: the rim must touch the ground there, or a configuration constraint beside it that
  says so, ``constraints:``, as a bicycle's front wheel).
- ``{knife_edge: B, at: [u, v], direction: [du, dv]}``: the point of planar body ``B`` at the
  body-frame offset ``at`` (default its centre) moves along the body-frame ``direction``
  (default its x axis) only, not across it: one constraint ``<name>``.
"""
from __future__ import annotations

import random

import sympy

from ..core.contact import material_velocity, reduced, rim_contact
from ..errors import close_matches
from .effects import named_body, unreal_vector, zero_vector
from .reader import ModelReader, node_kind
from .source import Node

KEYS = {"rolls_on": ("rolls_on", "body", "radius", "axle"), "knife_edge": ("knife_edge", "at", "direction")}
SURFACES = ("plane",)


def read_contact(reader: ModelReader, name: str, node: Node, primitive, connection, coords, holonomic=()):
    """``[(label, expression = 0, where, printed)]`` of the contact joint ``node`` (named ``name``),
    or None after reporting why; ``holonomic`` are the configuration constraints ``g(x) = 0``
    beside it. ``expression`` is the material velocity as made, ``printed()`` its reduced form
    (:func:`.contact.reduced`), made when the constraints are printed."""
    kinds = [k for k in KEYS if k in node.value]
    if len(kinds) != 1:
        reader.error(node, f"velocity constraint '{name}' must be an expression or one joint: "
                           + " or ".join(f"`{k}:`" for k in KEYS),
                     "e.g. `{knife_edge: body, at: [-a, 0]}` or `{rolls_on: plane, body: wheel, radius: r}`")
        return None
    node = reader.check_keys(node, KEYS[kinds[0]], f"velocity constraint '{name}'")
    if kinds[0] == "rolls_on":
        return _rolls_on(reader, name, node, primitive, connection, coords, holonomic)
    return _knife_edge(reader, name, node, primitive, connection, coords)


def _body(reader: ModelReader, name: str, node: Node | None, where: Node, primitive, what: str):
    """``(part, body)`` of a rigid body named at ``node``; None after reporting."""
    if node is None or not isinstance(node.value, str):
        reader.error(node if node is not None else where, f"{what} '{name}' needs a component, a rigid body",
                     close_matches(str(node.value) if node is not None else "", [p.name for p in primitive.parts]))
        return None
    found = named_body(reader, node, primitive, f"{what} '{name}'")
    if found is None:
        return None
    part, index = found
    body = part.bodies[index]
    if body.rotation is None:
        reader.error(node, f"{what} '{name}': component '{node.value}' has no contact point: it is not a rigid body",
                     "roll a rigid_body3d wheel (`rolls_on:`), or slide a planar body on a knife edge")
        return None
    return part, body


def _vector(reader: ModelReader, node: Node | None, name: str, what: str, size: int, default):
    if node is None:
        return default
    if not node.is_sequence or len(node.value) != size:
        reader.error(node, f"{what} of velocity constraint '{name}' must be a list of {size} numbers or "
                     f"expressions, found {node_kind(node)}", "one entry per body axis, e.g. "
                     + ("`[0, 1, 0]`" if size == 3 else "`[1, 0]`"))
        return None
    values = [reader.expr(v, reader.parameter_names(), what=f"{what} of velocity constraint '{name}'")
              for v in node.value]
    return None if any(v is None for v in values) else tuple(sympy.sympify(v) for v in values)


def _in_subspace(expr, connection):
    return sympy.sympify(expr).xreplace(connection)


SAME_POINTS = 3  # random points at which a rim's height is compared with a configuration constraint


def held_by(height: sympy.Expr, holonomic, coords, values) -> bool:
    """Whether a configuration constraint ``g = 0`` of ``holonomic`` is the rim's ``height = 0``:
    ``height / g`` the same number, not zero, at random points of the coordinates (the
    parameters at their ``values``)."""
    rng = random.Random(19440101)
    points = [{**{q: sympy.Float(rng.uniform(-0.4, 0.4)) for q in coords}, **values} for _ in range(SAME_POINTS)]
    for g in holonomic:
        ratios = []
        for point in points:
            top, bottom = complex(height.xreplace(point).evalf()), complex(sympy.sympify(g).xreplace(point).evalf())
            ratios.append(top / bottom if bottom != 0 else float("nan"))
        if all(abs(r - ratios[0]) <= 1e-9 * abs(ratios[0]) for r in ratios) and abs(ratios[0]) > 0:
            return True
    return False


def _rolls_on(reader: ModelReader, name, node, primitive, connection, coords, holonomic=()):
    surface = node.get("rolls_on")
    if surface is None or surface.value not in SURFACES:
        reader.error(surface if surface is not None else node,
                     f"velocity constraint '{name}' rolls on {surface.value!r}" if surface is not None else
                     f"velocity constraint '{name}' needs `rolls_on:`", "roll on `plane`: the ground z = 0")
        return None
    found = _body(reader, name, node.get("body"), node, primitive, "rolling joint")
    if found is None:
        return None
    part, body = found
    bnode = node.get("body")
    if part.dimension != 3:
        reader.error(bnode, f"rolling joint '{name}': component '{bnode.value}' is planar",
                     "a wheel rolling on a line of the plane is a configuration constraint (x = -r angle): write "
                     "it in the connection; roll a rigid_body3d on the plane")
        return None
    rnode = node.get("radius")
    if rnode is None:
        reader.error(bnode, f"rolling joint '{name}': component '{bnode.value}' has no contact point without a rim",
                     "give the rim's `radius:` (and its `axle:` in body axes, default [0, 1, 0])")
        return None
    radius = reader.expr(rnode, reader.parameter_names(), what=f"radius of velocity constraint '{name}'")
    axle = _vector(reader, node.get("axle"), name, "axle", 3, (0, 1, 0))
    if radius is None or axle is None:
        return None
    if node.get("axle") is not None and zero_vector(reader, node.get("axle"), axle, f"axle of '{name}'", "[0, 1, 0]"):
        return None
    R = body.rotation.xreplace(connection)
    centre = [_in_subspace(e, connection) for e in body.centre]
    offset = rim_contact(R, axle, sympy.sympify(radius), coords)
    height = reduced(centre[2] + offset[2], coords)
    values = {p.symbol: sympy.Float(sympy.sympify(p.value).evalf(17), 17) for p in reader.parameters.values()
              if p.value is not None and sympy.sympify(p.value).is_number}
    if height != 0 and not held_by(height, holonomic, coords, values):
        reader.error(bnode, f"rolling joint '{name}': the rim of '{bnode.value}' is at height {height} above the "
                     "ground, not on it", "keep it on the ground in the connection: the centre's z is "
                     "radius times the cosine of the wheel's tilt, or write its height = 0 under `constraints:`")
        return None
    v = material_velocity(centre, R, offset, coords)
    where = node.location
    return [(f"{name}.{axis}", v[i], where, _reduced_later(v[i], coords)) for i, axis in enumerate("xy")]


def _reduced_later(expr, coords):
    """``reduced(expr)`` when called."""
    return lambda: reduced(expr, coords)


def _knife_edge(reader: ModelReader, name, node, primitive, connection, coords):
    found = _body(reader, name, node.get("knife_edge"), node, primitive, "knife edge")
    if found is None:
        return None
    part, body = found
    if part.dimension != 2:
        reader.error(node.get("knife_edge"), f"knife edge '{name}' on a body in space is not supported yet",
                     "put the knife edge on a planar body (planar_body, disc, rod)")
        return None
    at = _vector(reader, node.get("at"), name, "at", 2, (0, 0))
    direction = _vector(reader, node.get("direction"), name, "direction", 2, (1, 0))
    if at is None or direction is None:
        return None
    if node.get("at") is not None and unreal_vector(reader, node.get("at"), at, f"at of '{name}'"):
        return None
    if node.get("direction") is not None and zero_vector(reader, node.get("direction"), direction,
                                                         f"direction of '{name}'", "[1, 0]"):
        return None
    R = body.rotation.xreplace(connection)
    centre = [_in_subspace(e, connection) for e in body.centre]
    v = material_velocity(centre, R, R * sympy.Matrix(at), coords)
    d = R * sympy.Matrix(direction)
    d = d / sympy.sqrt(sum(sympy.sympify(e) ** 2 for e in direction))
    across = d[0] * v[1] - d[1] * v[0]
    return [(name, across, node.location, _reduced_later(across, coords))]


__all__ = ["KEYS", "SAME_POINTS", "held_by", "read_contact"]
