"""Prescribed motions: the ``prescribed:`` section, ``q: q(t)`` for a coordinate driven by a
given function of time, composed into the connection ``x = x(xbar, t)`` (:mod:`..core.rheonomic`)."""
from __future__ import annotations

import sympy

from ..core.rheonomic import prescribe
from ..core.symbols import TIME, free_symbols_of, velocity_symbol
from .reader import ModelReader
from .source import Node


def read_prescribed(reader: ModelReader, node: Node | None, coords) -> dict[sympy.Symbol, sympy.Expr]:
    """``{q: q(t)}``: each key a listed coordinate, each value an expression of the parameters and ``t``."""
    motions: dict[sympy.Symbol, sympy.Expr] = {}
    by_name = {q.name: q for q in coords}
    names = {**reader.parameter_names(), "t": TIME}
    for key, vnode in reader.mapping(node, "prescribed", "write one `coordinate: function of t` per line").items():
        loc = node.key_locations[key]
        q = by_name.get(key)
        if q is None:
            reader.error(loc, f"prescribed '{key}' is not a listed coordinate",
                         "list it under `coordinates:` and give its motion here; the others stay free")
            continue
        value = reader.expr(vnode, names, what=f"motion of '{key}'")
        if value is not None:
            motions[q] = sympy.sympify(value)
    if motions and len(motions) == len(coords):
        reader.error(node.location, "every coordinate is prescribed: nothing is left to move freely",
                     "leave at least one coordinate free (a fully prescribed motion has no equations of motion)")
    return motions


def check_effects(reader: ModelReader, node: Node, effects, motions) -> None:
    """An effect may not name a prescribed coordinate: its motion is given, no equation of it
    is derived, so a load on it would act nowhere."""
    named = {s for q in motions for s in (q, velocity_symbol(q))}
    for effect in effects:
        used = sorted(s.name for s in effect.symbols() & named)
        if used:
            reader.error(node.key_locations.get(effect.name, node.location),
                         f"effect '{effect.name}' names the prescribed coordinate {', '.join(map(repr, used))}",
                         "write it in the primitive coordinates (the connection carries the motion), or "
                         "leave the coordinate free")


def driven_connection(connection: dict, coords, motions: dict) -> tuple[dict, tuple]:
    """The connection with the prescribed coordinates' motions put in, and the free coordinates."""
    return prescribe(connection, coords, motions)


def names_time(connection: dict) -> bool:
    return TIME in free_symbols_of(list(connection.values()))


__all__ = ["check_effects", "driven_connection", "names_time", "read_prescribed"]
