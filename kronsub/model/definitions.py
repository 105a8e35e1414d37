"""Reading ``definitions:``: named helper expressions, substituted where they are used.

A definition is shorthand, not a new coordinate or parameter: ``beta: asin(r*sin(theta)/l)``
lets the connection, the effects, the constraints and the initial values write ``beta``
where they would write the expression, and the expression is put in its place. A
definition may use the parameters, ``t``, the generalized coordinates, the primitive
coordinates (and their ``_dot`` velocities) and other definitions (no cycles); where it is
used, it may use only what that place may (an effect, primitive coordinates; an initial
value, parameters). Expressions go through the whitelisted parser like every other.
"""
from __future__ import annotations

import sympy

from ..core.symbols import TIME, velocity_symbol
from .expressions import FUNCTIONS, parse_expression
from .reader import ModelReader
from .source import Node

_HINT = "write `name: expression`, e.g. `beta: asin(r*sin(theta)/l)`"


def read_definitions(reader: ModelReader, node: Node | None, coords, primitive) -> None:
    """Parse ``definitions:`` into ``reader.definitions``: each name's placeholder and its
    expansion (definitions used inside it expanded too); cycles and name clashes are problems."""
    entries = reader.mapping(node, "definitions", _HINT)
    if not entries:
        return
    universal = _usable_names(reader, coords)
    taken = _taken_names(reader, universal, primitive)
    placeholders: dict[str, sympy.Symbol] = {}
    for name in entries:
        loc = node.key_locations[name]
        if not reader.identifier(name, loc, "definition"):
            continue
        if name in taken:
            reader.error(loc, f"definition '{name}' has the name of {taken[name]}",
                         "give the definition a name of its own")
            continue
        placeholders[name] = sympy.Dummy(name, real=True)
        reader.locations[f"definition:{name}"] = loc
    raw: dict[str, sympy.Expr | None] = {}
    for name, placeholder in placeholders.items():
        raw[name] = _parse(reader, entries[name], {**universal, **placeholders}, f"definition '{name}'")
    uses = {name: [other for other, ph in placeholders.items() if expr is not None and ph in expr.free_symbols]
            for name, expr in raw.items()}
    order, cycles = _order(uses)
    for cycle in cycles:
        reader.error(reader.locations[f"definition:{cycle[0]}"],
                     "definitions form a cycle: " + " -> ".join(cycle + [cycle[0]]),
                     "a definition cannot use itself, directly or through other definitions")
    expanded: dict[str, sympy.Expr | None] = {}
    for name in order:
        expr = raw[name]
        if expr is None or any(expanded.get(other) is None for other in uses[name]):
            expanded[name] = None  # its problem (or that of one it uses) is reported already
            continue
        expanded[name] = expr.xreplace({placeholders[other]: expanded[other] for other in uses[name]})
    reader.definitions = {name: (placeholders[name], expanded.get(name)) for name in placeholders}


def _usable_names(reader: ModelReader, coords) -> dict[str, sympy.Basic]:
    """What a definition may use: t, parameters, generalized and primitive coordinates and
    their velocities (``reader.names`` holds the primitive ones by now)."""
    names: dict[str, sympy.Basic] = {"t": TIME, **reader.parameter_names()}
    for q in list(coords) + [angle for _, _, angle, _, _ in reader.pivots]:
        names.setdefault(q.name, q)
        names.setdefault(velocity_symbol(q).name, velocity_symbol(q))
    for key, value in reader.names.items():
        names.setdefault(key, value)
    return names


def _taken_names(reader: ModelReader, universal: dict, primitive) -> dict[str, str]:
    """Names a definition may not take, with what they are."""
    taken: dict[str, str] = {name: f"the function '{name}'" for name in FUNCTIONS}
    taken.update({"t": "time 't'", "pi": "the constant 'pi'"})
    for name in universal:
        if name in reader.parameters:
            taken[name] = f"the parameter '{name}'"
        elif "." not in name and name not in taken:
            kind = "velocity" if name.endswith("_dot") else "coordinate"
            taken[name] = f"the {kind} '{name}'"
    for part in primitive.parts:
        taken.setdefault(part.name, f"the component '{part.name}'")
    for name in list(universal):
        if "." not in name and not name.endswith("_dot") and name not in reader.parameters and name != "t":
            taken.setdefault(f"{name}_ddot", f"the acceleration '{name}_ddot'")
    return taken


def _parse(reader: ModelReader, vnode: Node, names: dict, what: str) -> sympy.Expr | None:
    if not vnode.is_scalar or vnode.value is None or isinstance(vnode.value, bool):
        reader.error(vnode, f"{what} must be an expression (a number or a formula)", _HINT)
        return None
    text = vnode.text if vnode.text is not None else str(vnode.value)
    try:
        return sympy.sympify(parse_expression(text, names, vnode.text_location or vnode.location, what=what))
    except Exception as exc:  # ModelError: parse_expression raises nothing else
        problems = getattr(exc, "problems", None)
        if problems is None:
            raise
        for problem in problems:
            name = problem.message.partition("unknown name '")[2].partition("'")[0]
            if name and reader.is_broken(name):
                continue  # a consequence of a component reported already
            reader.problems.problems.append(problem)
        return None


def _order(uses: dict[str, list[str]]) -> tuple[list[str], list[list[str]]]:
    """The definitions in an order where each comes after those it uses, and the cycles."""
    order: list[str] = []
    state: dict[str, int] = {}  # 1 visiting, 2 done
    cycles: list[list[str]] = []

    def visit(name: str, path: list[str]) -> None:
        state[name] = 1
        for other in uses.get(name, ()):
            if state.get(other) == 1:
                cycle = path[path.index(other):] if other in path else [other]
                if not any(set(cycle) == set(c) for c in cycles):
                    cycles.append(cycle)
            elif other not in state:
                visit(other, path + [other])
        state[name] = 2
        order.append(name)

    for name in uses:
        if name not in state:
            visit(name, [name])
    in_cycle = {n for c in cycles for n in c}
    # a definition on a cycle (or using one) has no expansion
    blocked = set(in_cycle)
    changed = True
    while changed:
        changed = False
        for name in uses:
            if name not in blocked and any(o in blocked for o in uses[name]):
                blocked.add(name)
                changed = True
    return [n for n in order if n not in blocked] + [n for n in order if n in blocked and n not in in_cycle] \
        + [n for n in order if n in in_cycle], cycles


__all__ = ["read_definitions"]
