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

from dataclasses import dataclass

import numpy as np
import sympy

from ..core.nonholonomic import VelocityConstraintError, VelocityTransformation, velocity_transformation
from ..core.reference_frame import frame_matrix, frame_transformation
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
    definitions = _read_speeds(reader, speeds_node, coords, names)
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


def check_frame_start(reader: ModelReader, written: Location, spec: VelocitySpec, initial: dict) -> None:
    """A change of velocity frame (``speeds:``, written at ``written``) singular at the initial
    configuration (``det Y = 0`` there, the coordinates not given taken as 0): ``xdot = Y^-1 u``
    has no value to start from."""
    x = spec.transformation.coordinates
    point = {**_values(reader), **{q: initial.get(q, sympy.Integer(0)) for q in x}}
    Y = frame_matrix(x, dict(spec.definitions)).xreplace(point)
    if Y.free_symbols:
        return  # a parameter without a value: nothing to evaluate
    try:
        sigma = np.linalg.svd(np.array(Y.evalf(), dtype=float), compute_uv=False)
    except (TypeError, ValueError, np.linalg.LinAlgError):
        return  # no real value there: the run's start reports it
    if np.all(np.isfinite(sigma)) and sigma[-1] > SINGULAR * sigma[0]:
        return
    where = ", ".join(f"{q} = {_shown(initial.get(q, 0))}" for q in x
                      if any(q in e.free_symbols for _, e in spec.definitions))
    at = f"at the initial configuration ({where})" if where else "at the parameters' values"
    reader.error(written, f"the speeds are singular {at}: det Y = 0 there, so xdot = Y^-1 u has no value",
                 "start the coordinates where the speeds are independent, or define speeds that stay independent")


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


def _read_speeds(reader: ModelReader, node: Node | None, coords, names: dict) -> dict | None:
    """``speeds:``: a list of velocities of listed coordinates, or a mapping ``name: Y(x) xdot``."""
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
    for key, vnode in node.value.items():
        loc = node.key_locations[key]
        if not reader.identifier(key, loc, "speed"):
            continue
        if key in names and names[key] not in velocities.values():
            reader.error(loc, f"speed '{key}' is already a name of the model",
                         "give the speed a name no parameter or coordinate has")
            continue
        value = reader.expr(vnode, names, what=f"speed '{key}'")
        if value is None:
            continue
        u = velocities[key] if key in velocities else symbol(key)
        speeds[u] = sympy.sympify(value)
    return speeds


__all__ = ["VelocitySpec", "check_frame_start", "check_initial", "read_velocity_constraints", "read_velocity_frame"]
