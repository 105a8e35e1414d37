"""Reading the ``components:`` section: the parts of the primitive system, in the order written.

A library component (``type:``) is read by :mod:`.parts`, a known system (``model:``) by
:mod:`.known_systems`, a component given by its equations (``metric:``) by :mod:`.textbook`; a component that fails is remembered, so a later reference to it
reports nothing more.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..core.known_system import KnownSystem
from ..errors import Location
from .known_systems import read_known_system
from .parts import library_component, mark_broken
from .reader import ModelReader
from .source import Node
from .textbook import textbook_part


def read_components(reader: ModelReader, node: Node | None, derived: Callable[[Path], KnownSystem]) -> None:
    """The ``components:`` section: each a library component (``type:``) or a known system
    (``model:``, read by :func:`~kronsub.model.known_systems.read_known_system` with ``derived``),
    appended to ``reader.parts``."""
    comps = reader.mapping(node, "components", "write `upper: {type: pinned_rod, parameters: {...}}`")
    if node is not None and not comps and (node.is_mapping or node.value is None):
        reader.error(node, "`components:` is empty", "list at least one component")
    if node is None:
        reader.error(Location(reader.file, 1, 1), "the model has no `components:`",
                     "list the parts of the primitive system under `components:`")
    for cname, spec in comps.items():
        loc = node.key_locations[cname]
        if not reader.identifier(cname, loc, "component"):
            continue
        if not spec.is_mapping:
            reader.error(spec, f"component '{cname}' must be a mapping", "give at least `type:`")
            continue
        if spec.get("model") is not None:
            part = read_known_system(reader, cname, spec, derived)
        elif spec.get("metric") is not None:
            part = textbook_part(reader, cname, spec)
        else:
            part = library_component(reader, cname, spec)
        if part is not None:
            reader.parts.append(part)
            reader.locations[f"component:{cname}"] = loc
        else:
            reader.failed_components = True
            mark_broken(reader, cname, spec)


__all__ = ["read_components"]
