"""Which coordinates of a model are charges, and the names of their currents.

A coordinate is a branch charge when a circuit part carries it (an ``inductor``, a
``branch``, ``coupled_inductors``) or a component from its textbook equations lists it under
``charges:``. A generalized coordinate is a charge when the connection (7) writes only charges
with it: a loop charge of Kron's mesh transformation, a node equation's charge (a closed
loop's intermediate coordinates). The velocity of each is its current, printed and read as
``i_<name>`` (:func:`kronsub.core.currents.current_name`); the name ``q_dot`` still reads as
the same quantity. A current whose name is already a name of the model keeps ``q_dot``, with
a located warning.
"""
from __future__ import annotations

import warnings

import sympy

from ..core.currents import current_name, rate_name
from ..core.primitive import Primitive
from ..core.symbols import velocity_symbol
from .circuits import CIRCUIT_TYPES
from .names import SUFFIXES
from .reader import ModelReader


class CurrentNameWarning(UserWarning):
    """A charge whose current cannot take its name (the name is already the model's)."""


def primitive_charges(primitive: Primitive) -> list[sympy.Symbol]:
    """The primitive coordinates that are branch charges, in the primitive's order."""
    return [q for part in primitive.parts
            for q in (part.coordinates if part.type_name in CIRCUIT_TYPES else part.charges)]


def subspace_charges(connection, charges, coords) -> list[sympy.Symbol]:
    """The coordinates of ``coords`` that the connection ``x = x(xbar)`` writes into charges
    only (a primitive coordinate not in ``connection`` is its own image)."""
    charges = set(charges)
    if not charges:  # (a model without circuit parts: nothing to walk)
        return []
    writers: dict = {}  # coordinate -> the primitive coordinates whose image names it
    for x, e in connection.items():
        for s in sympy.sympify(e).free_symbols:
            writers.setdefault(s, []).append(x)
    found = []
    for q in coords:
        written = writers.get(q) or ([q] if q not in connection else [])
        if written and all(x in charges for x in written):
            found.append(q)
    return found


def name_currents(reader: ModelReader, charges, coords, speeds: frozenset[str] = frozenset()) -> None:
    """Give each charge of ``charges`` its current's name in ``reader.currents`` and make the
    name read as the charge's velocity in the model's expressions (``reader.names``). A name
    among ``speeds`` (those a change of velocity frame defines, Park's ``i_d``...) is the speed's:
    the charge whose current it would name keeps ``q_dot`` (it is no state there)."""
    taken = set(reader.names) | set(reader.parameters) | set(reader.definition_keys) | set(reader.currents.values())
    for q in (*coords, *reader.primitive_names.values()):
        taken.update(q.name + suffix for suffix, _ in (("", ""), *SUFFIXES))
    for q in charges:
        if q.name in reader.currents:
            continue
        name = current_name(q.name)
        if name in speeds or rate_name(name) in speeds:
            reader.currents[q.name] = velocity_symbol(q).name
            continue
        if name in taken or rate_name(name) in taken:
            owner = next((part.name for part in reader.parts if q in part.coordinates), None)
            where = (reader.locations.get(f"coordinate:{q.name}") or reader.locations.get(f"component:{owner}")
                     or reader.locations.get("coordinates") or reader.root.location)
            warnings.warn(CurrentNameWarning(
                f"{where}: the current of the charge '{q.name}' is printed '{q.name}_dot': its name "
                f"'{name}' is already a name of the model (rename that name to print it as a current)"),
                stacklevel=2)
            name = velocity_symbol(q).name
        reader.currents[q.name] = name
        taken.update((name, rate_name(name)))
        reader.names[name] = velocity_symbol(q)


__all__ = ["CurrentNameWarning", "name_currents", "primitive_charges", "subspace_charges"]
