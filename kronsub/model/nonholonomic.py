"""Reading ``velocity_constraints:`` and ``speeds:``: non-holonomic constraints
``A(x) xdot + b(x, t) = 0`` on the generalized coordinates and the speeds ``u`` they leave,
made into ``xdot = C(x) u + d`` by :mod:`..core.nonholonomic` (Kron's non-holonomic reference
frame: ``C`` is the Jacobian of no connection).

Each constraint is named and written as an expression ``= 0`` in the coordinates, their
velocities (``x_dot``), the parameters and ``t``, or as a contact joint (:mod:`.contacts`:
``rolls_on``, ``knife_edge``). ``speeds:`` is optional: a list of
velocities (``[yaw_dot, lean_dot]``) keeps those as the speeds; a mapping names
quasi-velocities by their definitions ``Y(x) xdot`` (``v: cos(theta)*x_dot + sin(theta)*y_dot``);
without it kronsub keeps the velocities of the first coordinates the constraints leave free.

``speeds:`` alone, without ``velocity_constraints:``, names as many quasi-velocities as there
are velocities, an invertible ``u = Y(x) xdot``: a change of velocity frame
(:mod:`..core.reference_frame`), Park's d-q currents of a machine's phase currents.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import sympy

from ..core.nonholonomic import VelocityConstraintError, VelocityTransformation, generic_values, velocity_transformation
from ..core.scales import row_sizes, rows_scaled
from ..core.reference_frame import frame_transformation
from ..core.symbols import TIME, symbol, velocity_symbol
from ..errors import Location
from .contacts import read_contact
from .reader import ModelReader, node_kind
from .source import Node

SINGULAR = 1e-12
"""Smallest singular value of ``Y`` at the initial configuration, relative to its largest, below
which a frame is singular there (a double's rounding of ``cos(pi/2)`` is 6e-17)."""


@dataclass(frozen=True)
class VelocitySpec:
    """What ``velocity_constraints:`` (and ``speeds:``) gave: ``xdot = C u + d`` and the names."""

    transformation: VelocityTransformation
    constraint_names: tuple[str, ...]
    definitions: tuple[tuple[sympy.Symbol, sympy.Expr], ...]  # each speed as Y(x) xdot
    frame: bool = False  # speeds without velocity constraints: a change of velocity frame


def read_velocity_constraints(reader: ModelReader, node: Node, speeds_node: Node | None, coords,
                              primitive, connection, holonomic=(), constraints_at=None) -> VelocitySpec | None:
    """The section read and analysed: each constraint (an expression, or a contact joint of
    :mod:`.contacts` on the ``primitive`` through the ``connection``) linear in the velocities,
    none integrable, the speeds spanning the null space of ``A``; every failure a located error.
    ``holonomic`` are the configuration constraints ``(name, g(x, t))`` of ``constraints:``
    (written at ``constraints_at``) in the coordinates: their rates join as the last rows."""
    velocities = {velocity_symbol(q).name: velocity_symbol(q) for q in coords}
    names = {**reader.parameter_names(), **{q.name: q for q in coords}, **velocities, "t": TIME}
    entries = reader.mapping(node, "velocity_constraints",
                             "write one `name: expression` per constraint, the expression = 0, e.g. "
                             "`no_slip: x_dot - r*phi_dot*cos(theta)`")
    if node is not None and node.value is not None and not entries and node.is_mapping:
        reader.error(node, "`velocity_constraints:` is empty", "write at least one `name: expression`")
    exprs, labels, where, printed = [], [], [], []
    for key, vnode in entries.items():
        loc = node.key_locations[key]
        if not reader.identifier(key, loc, "velocity constraint"):
            continue
        if vnode.is_mapping:  # a contact joint: rolling, a knife edge
            made = read_contact(reader, key, vnode, primitive, connection, coords, [g for _, g in holonomic])
            for label, value, at, form in made or ():
                exprs.append(value)
                labels.append(label)
                where.append(at)
                printed.append(form)
            continue
        value = reader.expr(vnode, names, what=f"velocity constraint '{key}'")
        if value is None:
            continue
        exprs.append(sympy.sympify(value))
        labels.append(key)
        where.append(loc)
        printed.append(None)
    definitions = _read_speeds(reader, speeds_node, coords, names, [key for key in entries if isinstance(key, str)])
    if reader.problems or not exprs:
        return None
    values = {p.symbol: p.value for p in reader.parameters.values()
              if p.value is not None and sympy.sympify(p.value).is_number}
    try:
        velocity = velocity_transformation(exprs, coords, definitions, values, [g for _, g in holonomic], printed)
    except VelocityConstraintError as exc:
        if exc.kind == "speeds" and speeds_node is not None and exc.index is not None and speeds_node.is_mapping:
            at = speeds_node.key_locations[list(speeds_node.value)[exc.index]]
        elif exc.kind == "speeds" and speeds_node is not None:
            at = speeds_node
        elif exc.kind == "holonomic" and constraints_at is not None:
            at = constraints_at
        elif exc.index is not None and exc.kind == "constraint":
            at = where[exc.index]
        else:
            at = node
        message = str(exc)
        if exc.index is not None and exc.kind == "constraint":
            message = message.replace(f"velocity constraint {exc.index + 1}",
                                      f"velocity constraint '{labels[exc.index]}'")
        reader.error(at, message, exc.hint)
        return None
    if definitions is None:
        definitions = {u: u for u in velocity.speeds}
    return VelocitySpec(transformation=velocity, constraint_names=tuple(labels) + tuple(n for n, _ in holonomic),
                        definitions=tuple(definitions.items()))


def read_velocity_frame(reader: ModelReader, node: Node, coords, written: Location) -> VelocitySpec | None:
    """``speeds:`` (``node``, its key ``written``) without ``velocity_constraints:``: named
    quasi-velocities, one per velocity, an invertible linear map of them (a change of velocity
    frame); every failure a located error at the speed it concerns, or at ``written``."""
    velocities = {velocity_symbol(q).name: velocity_symbol(q) for q in coords}
    names = {**reader.parameter_names(), **{q.name: q for q in coords}, **velocities, "t": TIME}
    definitions = _read_speeds(reader, node, coords, names)
    if reader.problems or definitions is None:
        return None
    keys = list(node.value)
    try:
        velocity = frame_transformation(coords, definitions, _values(reader))
    except VelocityConstraintError as exc:
        at = node.key_locations[keys[exc.index]] if exc.index is not None else written
        reader.error(at, str(exc), exc.hint)
        return None
    return VelocitySpec(transformation=velocity, constraint_names=(), definitions=tuple(definitions.items()),
                        frame=True)


def check_start(reader: ModelReader, written: Location, spec: VelocitySpec, initial: dict,
                chosen: bool = True) -> None:
    """Speeds singular at the initial configuration (the coordinates not given taken as 0, ``t =
    0``), reported at ``written``: ``[A; Y] xdot = [-b; u]`` (``Y`` alone for a change of velocity
    frame, ``det Y = 0``) has no solution there, or no real one, so ``xdot = C u + d`` has no value
    to start from. ``chosen``: the model named its speeds (else kronsub chose them, at a generic
    configuration, and the hint names velocities that serve at the start)."""
    velocity = spec.transformation
    x = velocity.coordinates
    point = {**_values(reader), TIME: sympy.Integer(0), **{q: initial.get(q, sympy.Integer(0)) for q in x}}
    analysed_A, analysed_b = velocity.analysed()  # not the printed form: it may be long to make
    A = analysed_A.xreplace(point)
    stacked = A.col_join(velocity.speed_matrix.xreplace(point))
    offset = analysed_b.xreplace(point)
    if stacked.free_symbols or offset.free_symbols:
        return  # a parameter without a value: nothing to evaluate
    where = ", ".join(f"{q} = {_shown(initial.get(q, 0))}" for q in x
                      if any(q in e.free_symbols for e in list(analysed_A) + list(velocity.speed_matrix)
                             + list(analysed_b)))
    at = f"at the initial configuration ({where})" if where else "at the parameters' values"
    numbers = _complex_array(stacked)
    offsets = _complex_array(offset) if offset.rows else np.zeros(0)
    if numbers is None or offsets is None or np.any(np.abs(numbers.imag) > 1e-12 * np.maximum(1, np.abs(numbers))) \
            or np.any(np.abs(offsets.imag) > 1e-12 * np.maximum(1, np.abs(offsets))):
        reader.error(written, f"the {'speeds' if spec.frame else 'velocity constraints or the speeds'} have no real "
                     f"value {at}", "check the arguments of sqrt, log, asin and acos, and divisions, there")
        return
    generic = analysed_A.col_join(velocity.speed_matrix)  # each row's size over generic configurations
    sizes = row_sizes([v.real for v in generic_values(generic, x, _values(reader))])
    sigma = np.linalg.svd(rows_scaled(numbers.real, sizes), compute_uv=False)
    if sigma[-1] > SINGULAR * sigma[0]:
        return
    if spec.frame:
        reader.error(written, f"the speeds are singular {at}: det Y = 0 there, so xdot = Y^-1 u has no value",
                     "start the coordinates where the speeds are independent, or define speeds that stay independent")
        return
    hint = "start the coordinates elsewhere, or choose speeds that are independent there"
    serving = None if chosen else regular_speeds(numbers.real[:A.rows, :], x,
                                                  None if sizes is None else sizes[:A.rows])
    if serving:
        hint += ", e.g. `speeds: [" + ", ".join(serving) + "]`"
    reader.error(written, f"the speeds are singular {at}: [A; Y] xdot = [-b; u] has no solution there, so "
                 "xdot = C u + d has no value", hint)


def _complex_array(matrix: sympy.Matrix):
    """``matrix`` as a complex array, None when an entry has no finite value."""
    try:
        values = np.array(matrix.evalf(), dtype=complex)
    except (TypeError, ValueError, OverflowError):
        return None
    return values if np.all(np.isfinite(values)) else None


def regular_speeds(A: np.ndarray, x, sizes: np.ndarray | None, best: bool = False) -> list[str] | None:
    """Velocities that, as the speeds, leave ``[A; Y]`` regular for the number matrix ``A`` (its
    rows' sizes ``sizes``, :func:`~kronsub.core.nonholonomic.row_sizes`): the first coordinates'
    whose complement's columns of ``A`` are independent; with ``best``, those whose complement's
    columns are the furthest from dependent (the largest ratio of smallest to largest singular value)."""
    m, n = A.shape
    found, furthest = None, SINGULAR
    for dependent in itertools.combinations(reversed(range(n)), m):
        block = rows_scaled(A, sizes)[:, sorted(dependent)]
        sigma = np.linalg.svd(block, compute_uv=False)
        if m and sigma[-1] > furthest * sigma[0]:
            found = [velocity_symbol(x[j]).name for j in range(n) if j not in dependent]
            if not best:
                return found
            furthest = sigma[-1] / sigma[0]
    return found


def _shown(value) -> str:
    """A starting value as written: a number in its shortest decimal form."""
    value = sympy.sympify(value)
    return repr(float(value)) if value.is_Float or (value.is_Rational and not value.is_Integer) else str(value)


def _values(reader: ModelReader) -> dict:
    return {p.symbol: p.value for p in reader.parameters.values()
            if p.value is not None and sympy.sympify(p.value).is_number}


def check_initial(reader: ModelReader, node: Node | None, coords, spec: VelocitySpec) -> None:
    """An initial value of a velocity that is not a speed: the constraints fix it from the speeds
    (``xdot = C u + d``), so a value given for it would be ignored."""
    speeds = set(spec.transformation.speeds)
    fixed = {velocity_symbol(q).name for q in coords} - {u.name for u in speeds}
    for key in (node.value if node is not None and node.is_mapping else {}):
        if key in fixed:
            fixing = "the velocity constraints fix it" if spec.constraint_names else "the speeds fix it"
            reader.error(node.key_locations[key], f"'{key}' is not a speed: {fixing}",
                         "give the speeds' initial values (" + ", ".join(u.name for u in spec.transformation.speeds)
                         + f"); {key} follows from the kinematic equations xdot = C u")


def _read_speeds(reader: ModelReader, node: Node | None, coords, names: dict, constraint_names=()) -> dict | None:
    """``speeds:``: a list of velocities of listed coordinates, or a mapping ``name: Y(x) xdot``
    (each named apart from the names kronsub gives: the speeds' rates ``v_dot``, the coordinates'
    accelerations, the multipliers ``mu_<constraint>`` of ``constraint_names``; a coordinate's
    velocity ``x_dot`` as a name only for that velocity)."""
    if node is None or node.value is None:
        return None
    velocities = {velocity_symbol(q).name: velocity_symbol(q) for q in coords}
    speeds: dict = {}
    if node.is_sequence:
        for item in node.value:
            name = item.value
            if not isinstance(name, str) or name not in velocities:
                shown = f"'{name}'" if isinstance(name, str) and name.isidentifier() else node_kind(item)
                reader.error(item, f"speed {shown} is not the velocity of a listed coordinate",
                             "name velocities such as `x_dot` of the coordinates under `coordinates:`, or give "
                             "each speed its definition: `speeds: {v: cos(theta)*x_dot + sin(theta)*y_dot}`")
                continue
            if velocities[name] in speeds:
                reader.error(item, f"speed '{name}' is listed twice", "list each speed once")
                continue
            speeds[velocities[name]] = velocities[name]
        return speeds
    if not node.is_mapping:
        reader.error(node, "`speeds:` must be a list of velocities or a mapping of definitions, found "
                     f"{node_kind(node)}",
                     "e.g. `speeds: [yaw_dot, spin_dot]` or `speeds: {v: cos(theta)*x_dot + sin(theta)*y_dot}`")
        return speeds
    generated = {**{f"{q.name}_ddot": f"the acceleration of coordinate '{q.name}'" for q in coords},
                 **{f"{k}_dot": f"the rate of speed '{k}'" for k in node.value if isinstance(k, str)},
                 **{f"mu_{c}": f"the multiplier of velocity constraint '{c}'" for c in constraint_names}}
    for key, vnode in node.value.items():
        loc = node.key_locations[key]
        if not reader.identifier(key, loc, "speed"):
            continue
        if key in names and names[key] not in velocities.values():
            reader.error(loc, f"speed '{key}' is already a name of the model",
                         "give the speed a name no parameter or coordinate has")
            continue
        if key in generated:
            reader.error(loc, f"speed '{key}' is the name kronsub gives {generated[key]}",
                         "give the speed a name of its own")
            continue
        value = reader.expr(vnode, names, what=f"speed '{key}'")
        if value is None:
            continue
        if key in velocities and sympy.expand(sympy.sympify(value) - velocities[key]) != 0:
            reader.error(loc, f"speed '{key}' is the velocity of coordinate '{key[:-len('_dot')]}', defined as "
                         "something else", f"define it as `{key}: {key}`, or give the speed a name of its own")
            continue
        u = velocities[key] if key in velocities else symbol(key)
        speeds[u] = sympy.sympify(value)
    return speeds


__all__ = ["VelocitySpec", "check_initial", "check_start", "read_velocity_constraints", "read_velocity_frame", "regular_speeds"]
