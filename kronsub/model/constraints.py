"""Reading ``constraints:``: implicit constraints ``g(x) = 0`` (eq. 25) and joint shorthands.

Each entry is named. An expression is one constraint ``g = 0`` on the primitive
coordinates (``loop: a1*sin(theta) + a2*sin(phi) - c``); a joint is built from named
points:

- ``pin: [P, Q]``: the two points coincide (one equation per world axis, named
  ``<name>.x``, ``<name>.y``...); ``Q`` may be a fixed place ``[x, y]``.
- ``point_on_line: {point: P, through: Q, direction: [dx, dy]}``: ``P`` stays on the line
  through ``Q`` (a named point or a fixed place) along ``direction`` (world axes; it may
  depend on the coordinates, for a moving line). One equation in the plane, two in space
  (``<name>.1``, ``<name>.2``).
- ``slider: {point: P, body: B, through: [u, v], direction: [du, dv]}``: ``P`` stays on the
  line fixed in component ``B`` through the body-frame offset ``through`` (default its
  centre) along the body-frame ``direction`` (default its x axis). One equation in the
  plane, two in space (a ``rigid_body3d``).

Then the analysis at the initial configuration (with the parameters' default values):
Newton's method finds the configuration on the constraints nearest the one given, the
rank of ``G = dg/dy`` is checked (redundant constraints are named), and the dependent
coordinates are those not listed under ``coordinates:`` or, with ``coordinates: auto``,
the best-conditioned columns of ``G`` by pivoted QR.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy

from ..components.base import common_world, in_world
from ..core.constraints import Constraint, ConstraintFailure, NumericConstraints, closed_forms, multiplier_name
from ..core.symbols import free_symbols_of
from ..errors import close_matches
from .effects import named_body, zero_vector
from .reader import ModelReader
from .source import Node

JOINT_KEYS = {"pin": (), "point_on_line": ("point", "through", "direction"),
              "slider": ("point", "body", "through", "direction")}
"""The joints (``name: {joint: ...}`` under ``constraints:``) and the keys of their mappings (a pin
takes a list of two points instead)."""
JOINTS = tuple(JOINT_KEYS)
AXES = "xyz"


@dataclass(frozen=True)
class Joint:
    """Where a joint acts, in primitive coordinates and world axes, for drawing: ``point`` is
    ``P``; for a pin ``other`` is ``Q`` (a named point or a fixed place) and ``direction`` is
    empty; for a line (``point_on_line``, ``slider``) ``other`` is a place on the line and
    ``direction`` its world direction (a slider's turns with its body)."""

    name: str
    kind: str
    point: tuple
    other: tuple
    direction: tuple = ()


def read_constraints(reader: ModelReader, node: Node, primitive) -> list[Constraint]:
    """The constraints of the model, in primitive coordinates, each with its location kept."""
    out: list[Constraint] = []
    entries = reader.mapping(node, "constraints", "write `name: expression` (= 0) or `name: {pin: [P, Q]}`")
    names = {k: v for k, v in reader.parameter_names().items()}
    names.update(reader.primitive_names)
    for cname, spec in entries.items():
        loc = node.key_locations[cname]
        if not reader.identifier(cname, loc, "constraint"):
            continue
        reader.locations[f"constraint:{cname}"] = loc
        if spec.is_mapping:
            keys = [k for k in spec.value if k != "description"]
            if len(keys) != 1 or keys[0] not in JOINTS:
                bad = next((k for k in keys if k not in JOINTS), keys[0] if keys else "")
                reader.error(spec.key_locations.get(bad, spec.location) if bad else spec,
                             f"constraint '{cname}' must be an expression or one joint ({', '.join(JOINTS)})",
                             close_matches(bad, JOINTS) if bad else "e.g. `B: {pin: [left.b, right.b]}`")
                continue
            kind = keys[0]
            built = _JOINT_BUILDERS[kind](reader, cname, spec.get(kind), primitive, names)
            if built is not None:
                out.extend(built)
            continue
        value = reader.expr(spec, names, what=f"constraint '{cname}'")
        if value is None:
            continue
        value = sympy.sympify(value)
        if not (free_symbols_of([value]) & set(primitive.coordinates)):
            reader.error(spec, f"constraint '{cname}' does not involve any coordinate",
                         "write g(x) with `g = 0`, e.g. `a1*sin(theta) + a2*sin(phi) - c`")
            continue
        out.append(Constraint(cname, value, "expression"))
    return out


def _point(reader: ModelReader, node: Node, primitive, cname: str, names):
    """A named point (``component.point``) or a fixed place ``[x, y]``: its world position."""
    if node is not None and node.is_sequence:
        values = [reader.expr(v, names, what=f"fixed place in constraint '{cname}'") for v in node.value]
        return None if any(v is None for v in values) else tuple(values)
    points = primitive.points()
    label = None if node is None else node.value
    if not isinstance(label, str) or label not in points:
        reader.error(node if node is not None else reader.root, f"unknown point '{label}' in constraint '{cname}'",
                     close_matches(str(label), points))
        return None
    return points[label]


def _vector(reader: ModelReader, node: Node, cname: str, what: str, names):
    if node is None or not node.is_sequence or not node.value:
        reader.error(node if node is not None else reader.root,
                     f"{what} of constraint '{cname}' must be a list, e.g. `[0, 1]`", "one entry per world axis")
        return None
    values = [reader.expr(v, names, what=f"{what} of constraint '{cname}'") for v in node.value]
    return None if any(v is None for v in values) else tuple(values)


def _pin(reader: ModelReader, cname, node, primitive, names):
    if node is None or not node.is_sequence or len(node.value) != 2:
        reader.error(node if node is not None else reader.root, f"pin '{cname}' needs two points",
                     "e.g. `pin: [left.lower.end, right.lower.end]` or a fixed place `[0, 0]`")
        return None
    p = _point(reader, node.value[0], primitive, cname, names)
    q = _point(reader, node.value[1], primitive, cname, names)
    if p is None or q is None:
        return None
    p, q = common_world(p, q)
    dim = len(p)
    source = f"pin: [{_text(node.value[0])}, {_text(node.value[1])}]"
    reader.joints.append(Joint(cname, "pin", p, q))
    out = []
    for axis in range(dim):
        e = sympy.sympify(p[axis] - q[axis])
        if e != 0:
            out.append(Constraint(f"{cname}.{AXES[axis]}" if dim > 1 else cname, e, source))
    return out


def _line(reader: ModelReader, cname, node, names, what):
    if node is None or not node.is_mapping:
        reader.error(node if node is not None else reader.root, f"{what} '{cname}' needs a mapping",
                     "e.g. `{point: lower.end, through: [1.2, 0], direction: [0, 1]}`")
        return None
    return node


def _cross(d, v):
    """``d x v`` in the plane (a scalar): zero when ``v`` is along ``d``."""
    return sympy.sympify(d[0] * v[1] - d[1] * v[0])


def _unit(d):
    norm2 = sympy.sympify(sum(c**2 for c in d))
    if norm2.is_number and norm2 != 0:
        return tuple(c / sympy.sqrt(norm2) for c in d)
    return d


def _complement(d):
    """Two vectors orthogonal to a constant ``d`` in space and to each other: ``d x e_a`` with
    ``e_a`` the axis along which ``d`` is smallest, then ``d x (d x e_a)``."""
    d = sympy.Matrix(d)
    a = min(range(3), key=lambda i: (abs(float(d[i])), i))
    e1 = d.cross(sympy.Matrix([1 if i == a else 0 for i in range(3)]))
    e2 = d.cross(e1)
    return tuple(sympy.simplify(c) for c in e1), tuple(sympy.simplify(c) for c in e2)


def _on_line(v, d, values) -> list[sympy.Expr]:
    """``v`` along ``d``: one equation in the plane (``d x v``), two in space.

    In space, a constant ``d`` gives ``e1 . v = e2 . v = 0`` with ``e1``, ``e2`` spanning its
    complement; a moving ``d`` the two components of ``v x d`` across the axis ``k`` along which
    ``d`` is largest with the parameters' values and the coordinates at zero (both vanish, with
    ``d_k != 0``, only when ``v`` is along ``d``)."""
    if len(d) == 2:
        return [_cross(d, v)]
    d = [sympy.sympify(c) for c in d]
    if all(c.is_number for c in d):
        return [sympy.sympify(sum(e * w for e, w in zip(basis, v))) for basis in _complement(d)]
    numbers = []
    for c in d:
        value = c.xreplace(values)
        value = value.xreplace({s: 0 for s in free_symbols_of([value])})
        try:
            numbers.append(abs(float(value)))
        except (TypeError, ValueError):
            numbers.append(0.0)
    k = max(range(3), key=lambda i: (numbers[i], -i))
    cross = sympy.Matrix(v).cross(sympy.Matrix(d))
    return [sympy.sympify(cross[i]) for i in range(3) if i != k]


def _values(reader: ModelReader) -> dict:
    return {p.symbol: p.value for p in reader.parameters.values()
            if p.value is not None and sympy.sympify(p.value).is_number}


def _named(cname: str, equations, source: str) -> list[Constraint]:
    """``cname`` for one equation; ``cname.1``, ``cname.2`` for the two of a line in space."""
    if len(equations) == 1:
        return [Constraint(cname, equations[0], source)]
    return [Constraint(f"{cname}.{i + 1}", e, source) for i, e in enumerate(equations)]


def _point_on_line(reader: ModelReader, cname, node, primitive, names):
    node = _line(reader, cname, node, names, "point_on_line")
    if node is None:
        return None
    node = reader.check_keys(node, JOINT_KEYS["point_on_line"], f"point_on_line '{cname}'")
    p = _point(reader, node.get("point"), primitive, cname, names)
    through = node.get("through")
    q = _point(reader, through, primitive, cname, names) if through is not None else None
    d = _vector(reader, node.get("direction") or node, cname, "direction", names)
    if through is None:
        reader.error(node, f"point_on_line '{cname}' needs `through:`", "a named point or a fixed place [x, y]")
    if p is None or q is None or d is None:
        return None
    dim = max(len(p), len(q), 2)
    if dim > 3 or len(d) != dim:
        reader.error(node.get("direction") or node, f"direction of point_on_line '{cname}' needs {dim} entries "
                     f"(one per world axis of its points), found {len(d)}",
                     "e.g. `direction: [0, 1]` in the plane, `[0, 0, 1]` in space")
        return None
    if zero_vector(reader, node.get("direction") or node, d, f"direction of point_on_line '{cname}'", "[0, 1]"):
        return None
    p, q, d = in_world(p, dim), in_world(q, dim), _unit(d)
    v = tuple(a - b for a, b in zip(p, q))
    reader.joints.append(Joint(cname, "point_on_line", p, q, d))
    return _named(cname, _on_line(v, d, _values(reader)), f"point_on_line: {_text(node.get('point'))}")


def _slider(reader: ModelReader, cname, node, primitive, names):
    node = _line(reader, cname, node, names, "slider")
    if node is None:
        return None
    node = reader.check_keys(node, JOINT_KEYS["slider"], f"slider '{cname}'")
    p = _point(reader, node.get("point"), primitive, cname, names)
    bnode = node.get("body")
    part = index = None
    needs = f"slider '{cname}' needs `body:` a component"
    if bnode is None or not isinstance(bnode.value, str):
        reader.error(bnode if bnode is not None else node, needs,
                     close_matches(str(bnode.value) if bnode is not None else "", [x.name for x in primitive.parts]))
    elif (found := named_body(reader, bnode, primitive, f"slider '{cname}'", unknown=needs)) is not None:
        part, index = found
        if part.bodies[index].rotation is None or part.dimension not in (2, 3):
            reader.error(bnode, f"slider '{cname}': component '{bnode.value}' is not a rigid body",
                         "use a rod, disc, planar_body, pinned_rod or rigid_body3d")
            part = None
    if part is None:
        return None
    dim = part.dimension
    zero, one = sympy.Integer(0), sympy.Integer(1)
    through = (_vector(reader, node.get("through"), cname, "through", reader.parameter_names())
               if node.get("through") is not None else (zero,) * dim)
    d = (_vector(reader, node.get("direction"), cname, "direction", reader.parameter_names())
         if node.get("direction") is not None else (one,) + (zero,) * (dim - 1))
    if p is None or through is None or d is None:
        return None
    if zero_vector(reader, node.get("direction"), d, f"direction of slider '{cname}'", "[0, 1]"):
        return None
    for what, vec in (("through", through), ("direction", d)):
        if len(vec) != dim:
            reader.error(node.get(what), f"{what} of slider '{cname}' needs {dim} entries (body axes of "
                         f"'{part.name}'), found {len(vec)}", "one entry per body axis")
            return None
    if len(p) > dim:
        reader.error(node.get("point"), f"slider '{cname}': the point is in space but '{part.name}' is planar",
                     "slide on a rigid_body3d, or use a planar point")
        return None
    body = part.bodies[index]
    R = body.rotation
    q = sympy.Matrix(body.centre) + R * sympy.Matrix(through)
    v = sympy.Matrix(in_world(p, dim)) - q
    source = f"slider: {_text(node.get('point'))} on {part.name}"
    reader.joints.append(Joint(cname, "slider", in_world(p, dim), tuple(q), tuple(R * sympy.Matrix(_unit(d)))))
    if dim == 2:
        return [Constraint(cname, _cross(R * sympy.Matrix(_unit(d)), v), source)]
    # in space: v in the body's axes is along the (constant) body-frame direction
    if not all(sympy.sympify(c).is_number for c in d):
        reader.error(node.get("direction"), f"direction of slider '{cname}' must be numbers in space",
                     "the line is fixed in the body: give its body-frame direction, e.g. `[1, 0, 0]`")
        return None
    return _named(cname, _on_line(tuple(R.T * v), _unit(d), {}), source)


_JOINT_BUILDERS = {"pin": _pin, "point_on_line": _point_on_line, "slider": _slider}


def _text(node: Node | None) -> str:
    if node is None:
        return ""
    if node.is_sequence:
        return "[" + ", ".join(_text(v) for v in node.value) + "]"
    return str(node.text if node.text is not None else node.value)


# --------------------------------------------------------------------------------------------
# The analysis at the initial configuration
# --------------------------------------------------------------------------------------------

def analyse(reader: ModelReader, constraints, y, independent, auto: bool, initial: dict, where):
    """Dependent coordinates, the branch (their values at the initial configuration) and the
    closed forms; every problem reported at ``where`` naming the constraints involved.

    Returns ``(independent, dependent, branch, closed_form, configuration)`` or None after a problem.
    """
    k, ny = len(constraints), len(y)
    listed = ", ".join(f"'{c.name}'" for c in constraints)
    if k >= ny:
        reader.error(where, f"too many constraints: {k} ({listed}) on {ny} coordinates "
                            f"({', '.join(q.name for q in y)})",
                     "a system needs at least one degree of freedom: remove constraints or add components")
        return None
    if not auto:
        dependent = tuple(q for q in y if q not in independent)
        if k > len(dependent):
            reader.error(where, f"more constraints ({k}: {listed}) than dependent coordinates "
                                f"({len(dependent)}: {', '.join(q.name for q in dependent) or 'none'})",
                         f"list {ny - k} independent coordinates under `coordinates:`, or `coordinates: auto`")
            return None
        if k < len(dependent):
            reader.error(where, f"the independent coordinates do not determine the others: {len(dependent)} "
                                f"dependent coordinates ({', '.join(q.name for q in dependent)}) but {k} "
                                f"constraint{'s' if k != 1 else ''} ({listed})",
                         f"list {ny - k} independent coordinates under `coordinates:`, or `coordinates: auto`")
            return None
    values = {}
    for p in reader.parameters.values():
        if p.value is not None and sympy.sympify(p.value).is_number:
            values[p.symbol] = p.value
    try:
        numeric = NumericConstraints(constraints, y, values)
    except ConstraintFailure as exc:
        reader.error(where, f"the constraints ({listed}) need values of the parameters {exc.message} to fix "
                            "the branch at the initial configuration", "give them a `value:`")
        return None
    y0 = np.array([float(sympy.sympify(initial.get(q, 0)).xreplace(values)) for q in y])
    free = list(range(ny)) if auto else [i for i, q in enumerate(y) if q not in independent]
    try:
        y1 = numeric.solve(y0, free)
    except ConstraintFailure as exc:
        reader.error(where, f"inconsistent constraints ({listed}): no configuration near the initial one "
                            f"satisfies them ({exc.message})",
                     "check the constraints and the initial values (`initial:`), which pick the branch")
        return None
    bad = numeric.redundant_rows(y1)
    if bad:
        _redundant(reader, where, numeric, bad, constraints)
        return None
    if auto:
        dep_idx = numeric.pivot(y1)
        # the branch at the initial configuration: the independent coordinates as given, not
        # where the search over every coordinate left them (when they can be held there)
        start = np.array([y1[i] if i in dep_idx else y0[i] for i in range(ny)])
        try:
            y2 = numeric.solve(start, list(dep_idx))
            if np.linalg.matrix_rank(numeric.jacobian(y2)[:, list(dep_idx)]) == k:
                y1 = y2
        except ConstraintFailure:
            pass
        dependent = tuple(y[i] for i in sorted(dep_idx))  # in the order of y, as when they are given
        independent = tuple(q for i, q in enumerate(y) if i not in dep_idx)
    else:
        dep_idx = [i for i, q in enumerate(y) if q in dependent]
        G = numeric.jacobian(y1)[:, dep_idx]
        if np.linalg.matrix_rank(G) < k:
            better = [y[i].name for i in range(ny) if i not in numeric.pivot(y1)]
            reader.error(where, f"the independent coordinates do not determine the others: dg/d("
                                f"{', '.join(q.name for q in dependent)}) is singular at the initial "
                                f"configuration for the constraints {listed}",
                         f"choose other independent coordinates, e.g. `coordinates: [{', '.join(better)}]`, "
                         "or `coordinates: auto`")
            return None
    # 12 significant digits: the branch only selects the root, and its printed value stays
    # byte-identical whatever the order of the floating-point sums
    size = 1.0 + float(np.max(np.abs(y1)))
    y1 = np.array([0.0 if abs(v) < 1e-13 * size else float(f"{v:.12g}") for v in y1])
    branch = tuple((y[i], float(y1[i])) for i in dep_idx)
    point = {q: float(v) for q, v in zip(y, y1)}
    closed = closed_forms(constraints, independent, dependent, point, values)
    return independent, dependent, branch, closed, point


def _redundant(reader: ModelReader, where, numeric, bad, constraints):
    names = numeric.names(bad)
    others = numeric.names([i for i in range(len(constraints)) if i not in bad])
    reader.error(where, f"redundant constraints: {names} {'depends' if len(bad) == 1 else 'depend'} on "
                        f"{others or 'the others'} (the Jacobian dg/dx is rank-deficient at the initial "
                        "configuration)", f"remove {names}")


def check_multiplier_names(reader: ModelReader, constraints, carried) -> None:
    """Two constraints whose multipliers get one name (a joint `B`'s `B.x` and a constraint
    `B_x` are both `mu_B_x`) would be one entry of the reactions: refused, naming both."""
    seen: dict[str, Constraint] = {}
    own = {id(c) for c in carried}
    owner = {id(c): part.name for part in reader.parts for c in part.constraints}  # the component of each
    for c in constraints:
        name = multiplier_name(c.name)
        first = seen.setdefault(name, c)
        if first is c:
            continue
        here = next((x for x in (c, first) if id(x) not in own), None)
        if here is None:  # both from known systems: at the component entries that bring them in
            parts = [owner.get(id(x), x.name.split(".", 1)[0]) for x in (first, c)]
            at = [reader.locations.get(f"component:{p}") for p in parts]
            came = (f"both come from the component '{parts[0]}'" if parts[0] == parts[1] else
                    f"they come from the component '{parts[0]}'" + (f" (at {at[0]})" if at[0] else "")
                    + f" and this one, '{parts[1]}'")
            reader.error(at[1] or at[0] or reader.root, f"constraints '{first.name}' and '{c.name}' have the "
                         f"same multiplier name '{name}' in the reactions: {came}",
                         "rename one of the components: a known system's constraints are named after its "
                         "component (`left.cx`, multiplier `mu_left_cx`)")
            continue
        key = here.name if f"constraint:{here.name}" in reader.locations else here.name.rsplit(".", 1)[0]
        reader.error(reader.locations.get(f"constraint:{key}", reader.root), f"constraints '{first.name}' and "
                     f"'{c.name}' have the same multiplier name '{name}' in the reactions",
                     "rename one of them (a joint `B` names its equations `B.x`, `B.y`, whose multipliers "
                     "are `mu_B_x`, `mu_B_y`)")


__all__ = ["AXES", "JOINTS", "Joint", "analyse", "check_multiplier_names", "read_constraints"]
