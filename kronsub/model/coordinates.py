"""The coordinates of a model: the generalized ones listed under ``coordinates:``, and the names
by which expressions know the primitive system's (``theta`` and ``upper.theta``)."""
from __future__ import annotations

import sympy

from ..components import REGISTRY
from ..core.primitive import Part, Primitive
from ..core.symbols import TIME, symbol, velocity_symbol
from ..errors import Location
from .names import Declared, generated_name_clashes
from .reader import ModelReader, node_kind
from .source import Node


def read_coordinates(reader: ModelReader, node: Node | None) -> tuple[sympy.Symbol, ...]:
    """The ``coordinates:`` section as a list: the generalized coordinates of the new system,
    known by their names (and their velocities by ``<name>_dot``) from here on."""
    if node is None:
        reader.error(Location(reader.file, 1, 1), "the model has no `coordinates:`",
                     "list the generalized coordinates of the new system, e.g. `coordinates: [theta, phi]`")
        return ()
    if not node.is_sequence or not node.value:
        reader.error(node, "`coordinates:` must be a non-empty list of names", "e.g. `coordinates: [theta, phi]`")
        return ()
    coords, listed = [], set()
    for item in node.value:
        name = item.value
        if not isinstance(name, str):
            reader.error(item, f"a coordinate must be a name, found {node_kind(item)}",
                         "e.g. `coordinates: [theta, phi]`")
            continue
        if not reader.identifier(name, item.location, "coordinate"):
            reader.broken_names.update((name, f"{name}_dot"))  # reported once, not again where it is used
            continue
        if name in reader.parameters:
            reader.error(item, f"'{name}' is both a parameter and a coordinate", "rename one of them")
            continue
        if name in listed:
            reader.error(item, f"coordinate '{name}' is listed twice", "list each coordinate once")
            continue
        listed.add(name)
        coords.append(symbol(name))
        reader.locations[f"coordinate:{name}"] = item.location
    for q in coords:
        reader.names[q.name] = q
        reader.names[velocity_symbol(q).name] = velocity_symbol(q)
    reader.locations["coordinates"] = node.location
    return tuple(coords)


def name_primitive_coordinates(reader: ModelReader, primitive: Primitive) -> None:
    """Primitive coordinates are known by their names and as ``component.local``."""
    seen: dict[sympy.Symbol, str] = {}
    for part in primitive.parts:
        for q in part.coordinates:
            if q in seen and seen[q] != part.name:
                reader.error(reader.root.key_locations.get("components", reader.root.location),
                             f"coordinate name '{q}' is used by components '{seen[q]}' and '{part.name}'",
                             f"rename one under its `coordinates:`, e.g. `coordinates: {{...: {q}_{part.name}}}`")
            seen[q] = part.name
            if q.name in reader.parameters:
                reader.error(reader.root.key_locations.get("components", reader.root.location),
                             f"coordinate name '{q}' of '{part.name}' is also a parameter", "rename one")
    reader.primitive_names: dict[str, sympy.Symbol] = {}
    for part in primitive.parts:
        local = local_names(part)
        for q, lname in zip(part.coordinates, local):
            reader.primitive_names.setdefault(q.name, q)
            reader.primitive_names[f"{part.name}.{q.name}"] = q
            reader.primitive_names.setdefault(f"{part.name}.{lname}", q)
    # effects act on the primitive: their expressions name primitive coordinates only
    reader.names = {"t": TIME, **reader.parameter_names()}
    for key, q in reader.primitive_names.items():
        reader.names[key] = q
        reader.names[f"{key}_dot"] = velocity_symbol(q)


def check_generated_names(reader: ModelReader, coords, primitive: Primitive) -> None:
    """No model name may be the velocity or acceleration name of a coordinate (names.py)."""
    coordinates = [Declared(q.name, "coordinate", reader.locations.get(f"coordinate:{q.name}")) for q in coords]
    coords = set(coords)
    for part in primitive.parts:
        where = reader.locations.get(f"component:{part.name}")
        coordinates += [Declared(q.name, "coordinate", where, f"component '{part.name}'")
                        for q in part.coordinates if q not in coords]
    parameters = [Declared(name, "parameter", reader.locations.get(f"parameter:{name}")) for name in reader.parameters]
    for problem in generated_name_clashes(parameters + coordinates, coordinates):
        reader.problems.add(problem.location, problem.message, problem.hint)


def local_names(part: Part) -> tuple[str, ...]:
    """The coordinate names of ``part`` in its component type (``theta`` of a ``pinned_rod``)."""
    if part.local_names:
        return part.local_names
    cls = REGISTRY.get(part.type_name)
    return cls.coordinates if cls is not None else tuple(q.name for q in part.coordinates)


__all__ = ["check_generated_names", "local_names", "name_primitive_coordinates", "read_coordinates"]
