"""Initial values: a model's (or a scene's) ``initial:`` section, by coordinate and velocity."""
from __future__ import annotations

import sympy

from ..core.symbols import velocity_symbol
from ..errors import close_matches
from .reader import ModelReader
from .source import Node


def read_initial(reader: ModelReader, node: Node | None, coords, speeds=()) -> dict[sympy.Symbol, sympy.Expr]:
    """The ``initial:`` values (of a model or a scene) by coordinate, velocity (a charge's
    also by its current's name, :mod:`.currents`) or named speed (``speeds:``) symbol; each a
    number or an expression of the parameters."""
    initial: dict[sympy.Symbol, sympy.Expr] = {}
    allowed = {q.name: q for q in coords}
    allowed.update({velocity_symbol(q).name: velocity_symbol(q) for q in coords})
    allowed.update({u.name: u for u in speeds})
    allowed.update({reader.currents[q.name]: velocity_symbol(q) for q in coords if q.name in reader.currents})
    for key, vnode in reader.mapping(node, "initial", "write `initial: {theta: 0.1, theta_dot: 0}`").items():
        if key not in allowed and reader.is_broken(key):
            continue
        if key not in allowed:
            reader.error(node.key_locations[key], f"'{key}' is not a coordinate or velocity of this model",
                           close_matches(key, allowed))
            continue
        value = reader.expr(vnode, reader.parameter_names(), what=f"initial value of '{key}'")
        if value is not None:
            initial[allowed[key]] = value
    return initial


__all__ = ["read_initial"]
