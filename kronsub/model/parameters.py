"""Reading the ``parameters:`` section, and checking the parameters' values against what the
components require of them (:mod:`.requirements`)."""
from __future__ import annotations

import sympy

from ..core.known_system import ParameterInfo
from ..core.symbols import symbol
from .reader import ModelReader
from .requirements import unmet
from .source import Node


def read_parameters(reader: ModelReader, node: Node | None) -> None:
    """The ``parameters:`` section: each a value (an expression, or none) with its unit and
    description, added to ``reader.parameters``."""
    for pname, spec in reader.mapping(node, "parameters", "write `m1: 1.0` or `m1: {value: 1.0, unit: kg}`").items():
        loc = node.key_locations[pname]
        if not reader.identifier(pname, loc, "parameter"):
            continue
        value_node, unit, description = spec, "", ""
        if spec.is_mapping:
            spec = reader.check_keys(spec, ("value", "unit", "description"), f"parameter '{pname}'")
            value_node = spec.get("value")
            unit = reader.string(spec.get("unit"), "")
            description = reader.string(spec.get("description"), "")
        value = None
        if value_node is not None and value_node.value is not None:
            value = reader.expr(value_node, {}, what=f"value of parameter '{pname}'")
        reader.declared.add(pname)
        reader.add_parameter(ParameterInfo(pname, symbol(pname), value, unit, description), location=loc)


def check_values(reader: ModelReader) -> None:
    """The components' requirements on the parameters' values (:mod:`.requirements`): a
    problem at the parameter's declaration when the value is one parameter, else where
    the value is given."""
    def declared(req):
        value = req.value
        return reader.locations.get(f"parameter:{value.name}") if isinstance(value, sympy.Symbol) else None

    for problem in unmet(reader.requirements, reader.parameter_values(), declared):
        reader.problems.add(problem.location, problem.message, problem.hint)


__all__ = ["check_values", "read_parameters"]
