"""Known systems as components: a derived model placed in another (examples II and III).

The component's ``model:`` names a model file, relative to the model that uses it; that model is
derived (by the loader, recursively) and becomes a :class:`~kronsub.core.primitive.Part` of the
primitive system through :func:`~kronsub.model.parts.known_system_part`, with its parameters
overridden or inherited, its coordinates renamed and its origin placed.
"""
from __future__ import annotations

import dataclasses
import functools
import os
from pathlib import Path
from typing import Callable

from ..budget import WorkBudgetExceeded
from ..core.known_system import KnownSystem
from ..core.primitive import Part
from ..core.symbols import symbol
from ..errors import ModelError
from .files import looks_like_model, resolved_path
from .uses import MAX_MODEL_DEPTH
from .parts import (component_origin, component_parameters, coordinate_names, inertial_parameters,
                    inherit_parameter, known_system_part, placed)
from .reader import ModelReader, node_kind
from .requirements import body_requirements
from .file_reading import read_model_text, system_root
from .source import Node


def read_known_system(reader: ModelReader, cname: str, spec: Node, derived: Callable[[Path], KnownSystem]
                      ) -> Part | None:
    """The component ``cname`` whose ``model:`` is a model file: that model derived by
    ``derived`` (which keys it into this model's key), its parameters overridden or inherited, its
    coordinates renamed, placed at its ``origin:``; None when a problem was recorded."""
    spec = reader.check_keys(spec, ("model", "parameters", "coordinates", "origin", "description"),
                             f"component '{cname}'")
    mnode = spec.get("model")
    if not isinstance(mnode.value, str) or not mnode.value:
        reader.error(mnode, f"`model:` of component '{cname}' must be a file name, found {node_kind(mnode)}",
                     "write e.g. `model: system1.yaml` (relative to this model file)")
        return None
    if "\0" in mnode.value:  # no file name holds one (the system calls refuse it)
        reader.error(mnode, f"`model:` of component '{cname}' has a NUL character, which no file name can hold",
                     "write the file name without `\\0` or `\\x00` escapes")
        return None
    sub_path = (reader.path.parent / mnode.value)
    resolved = resolved_path(sub_path)
    if resolved in reader.stack:
        chain = " -> ".join(Path(p).name for p in reader.stack + (resolved,))
        reader.error(mnode, f"model files form a cycle: {chain}", "a model cannot contain itself")
        return None
    if len(reader.stack) >= MAX_MODEL_DEPTH:
        reader.error(mnode, f"too many levels of `model:` files: '{mnode.value}' would be level "
                          f"{len(reader.stack) + 1}, and the limit is {MAX_MODEL_DEPTH}",
                     "a known system may use known systems, but not this many levels down: write the parts "
                     "of some levels into one model file")
        return None
    if not os.path.lexists(sub_path) and system_root(sub_path) is None:  # read_model_text says what it is
        reader.error(mnode, f"model file '{mnode.value}' not found (looked at {sub_path})",
                     "paths are relative to this model file")
        return None
    try:
        if not looks_like_model(read_model_text(sub_path, mnode.text_location or mnode.location)):
            reader.error(mnode, f"model file '{mnode.value}' is not a kronsub model: no line of it begins "
                              "with a model section", "a model file starts its lines with `name:`, "
                              "`components:`, `coordinates:`...; check the path (nothing of another file "
                              "is shown)")
            return None
        system = derived(sub_path)
    except WorkBudgetExceeded:
        raise
    except ModelError as exc:
        reader.problems.extend(exc)
        return None
    if system.speeds is not None:  # its equations hold in its speeds, which a known system does not carry
        reader.error(mnode, f"model file '{mnode.value}' has velocity constraints: as a known system it is not "
                     "supported yet", "write its components and velocity constraints in this model")
        return None
    # parameters: overrides, the rest inherited
    allowed = [p.name for p in system.parameters]
    inertial = functools.cache(lambda: inertial_parameters(system))  # asked only of an override in t
    overrides = component_parameters(reader, cname, spec.get("parameters"), allowed,
                                     inertial=lambda key: key in inertial())
    for info in system.parameters:
        if info.name not in overrides:
            inherit_parameter(reader, cname, mnode, info)
            reader.add_parameter(info, inherited=True, location=spec.location)
    # a constrained system is placed on y: its dependent coordinates can be renamed too
    local = tuple(q.name for q in (system.implicit.intermediate if system.implicit is not None
                                   else system.coordinates))
    names = coordinate_names(reader, cname, spec.get("coordinates"), local, "{}")
    origin = component_origin(reader, cname, spec.get("origin"), system.dimension, bool(system.points))
    if names is None or any(v is None for v in overrides.values()) or origin is False:
        return None
    part = known_system_part(cname, system, {symbol(k): v for k, v in overrides.items()},
                             dict(zip(local, names)))
    # its charges stay charges here (their currents named in this model, model/currents.py)
    part = dataclasses.replace(part, charges=tuple(q for q, name in zip(part.coordinates, local)
                                                   if name in system.currents))
    for body in part.bodies:
        reader.requirements += body_requirements(f"{cname}.{body.name}" if body.name else cname, body,
                                                 (spec.get("parameters") or spec).location)
    return placed(part, origin) if origin else part


__all__ = ["read_known_system"]
