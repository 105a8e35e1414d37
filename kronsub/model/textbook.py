"""A known system from its textbook equations: coordinates, metric, potential and dissipation
written as expressions in the model file (the paper's premise: "the equations of
performance of the individual parts are usually well known").

The component ``magnet: {coordinates: [y, q], metric: [[m, 0], [0, L]], potential: V,
dissipation: F, charges: [q]}`` becomes a part of the primitive with the metric ``m_ab(x)`` (its velocity
terms from Lagrange's operator (A), so a metric in the coordinates brings its forces, the
magnetic force ``i^2/2 dL/dy`` of an electromagnet among them), its own effects
``potential`` (``f_a = -dV/dx^a``) and ``dissipation`` (Rayleigh's ``f_a = -dF/dxdot^a``);
``charges:`` names the coordinates that are branch charges (for a run's energy split and the
names of their currents, which the dissipation may use: ``R*i**2/2``).
"""
from __future__ import annotations

import sympy

from ..core.currents import current_name
from ..core.derivative import derivative
from ..core.primitive import Part, christoffel_terms
from ..core.symbols import symbol, velocity_symbol
from .energy_kinds import DISSIPATIVE
from .reader import ModelReader, node_kind
from .source import Node

KEYS = ("coordinates", "metric", "potential", "dissipation", "charges", "description")


def textbook_part(reader: ModelReader, cname: str, spec: Node) -> Part | None:
    """The part of a component given by ``metric:`` (and ``potential:``, ``dissipation:``);
    None after reporting what is wrong with it."""
    spec = reader.check_keys(spec, KEYS, f"component '{cname}'")
    coordinates = _coordinates(reader, cname, spec.get("coordinates"))
    if coordinates is None:
        return None
    velocities = [velocity_symbol(q) for q in coordinates]
    configuration = {**reader.parameter_names(), **{q.name: q for q in coordinates}}
    metric = _metric(reader, cname, spec.get("metric"), configuration, len(coordinates))
    potential = dissipation = sympy.Integer(0)
    if spec.get("potential") is not None:
        potential = _expression(reader, cname, spec.get("potential"), configuration, "potential")
    charges = _charges(reader, cname, spec.get("charges"), coordinates)
    if spec.get("dissipation") is not None:
        rates = {**configuration, **{v.name: v for v in velocities}}
        # a charge's current by its name too (model/currents.py), where no name of the model has it
        rates.update({current_name(q.name): velocity_symbol(q) for q in charges or ()
                      if current_name(q.name) not in rates})
        dissipation = _expression(reader, cname, spec.get("dissipation"), rates, "dissipation")
    if metric is None or potential is None or dissipation is None or charges is None:
        return None
    forces, potentials = {}, {}
    if potential != 0:
        forces["potential"] = sympy.Matrix([sympy.expand(-derivative(potential, q)) for q in coordinates])
        potentials["potential"] = potential
    if dissipation != 0:
        forces["dissipation"] = sympy.Matrix([sympy.expand(-derivative(dissipation, v)) for v in velocities])
    return Part(name=cname, coordinates=coordinates, metric=metric,
                velocity_terms=christoffel_terms(metric, coordinates, velocities),
                forces=forces, potential=potential, potentials=potentials, charges=charges,
                effect_kinds={"dissipation": DISSIPATIVE} if "dissipation" in forces else {}, christoffel=True)


def _coordinates(reader: ModelReader, cname: str, node: Node | None):
    if node is None or not node.is_sequence or not node.value:
        reader.error(node if node is not None else reader.root, f"component '{cname}' given by its `metric:` "
                     "needs `coordinates:`, a list of names", "e.g. `coordinates: [y, q]`")
        return None
    names = []
    for item in node.value:
        if not isinstance(item.value, str):
            reader.error(item, f"coordinate name of '{cname}' must be a name, found {node_kind(item)}",
                         "use letters, digits and underscores")
            return None
        if not reader.identifier(item.value, item.location, "coordinate"):
            return None
        if item.value in names:
            reader.error(item, f"component '{cname}' names the coordinate '{item.value}' twice",
                         "give each coordinate its own name")
            return None
        names.append(item.value)
    return tuple(symbol(n) for n in names)


def _charges(reader: ModelReader, cname: str, node: Node | None, coordinates) -> tuple | None:
    """The coordinates named by ``charges:`` (branch charges: the metric's block on them is the
    inductance); None after reporting a name that is not one of the component's coordinates."""
    if node is None:
        return ()
    own = {q.name: q for q in coordinates}
    if not node.is_sequence:
        reader.error(node, f"`charges:` of '{cname}' must be a list of its coordinates, found {node_kind(node)}",
                     f"e.g. `charges: [{next(iter(own))}]`")
        return None
    charges = []
    for item in node.value:
        if not isinstance(item.value, str) or item.value not in own:
            reader.error(item, f"`charges:` of '{cname}' names {item.value!r}, which is not one of its coordinates "
                               f"({', '.join(own)})", "name the coordinates that are branch charges")
            return None
        if own[item.value] in charges:
            reader.error(item, f"`charges:` of '{cname}' names {item.value!r} twice", "list each charge once")
            continue
        charges.append(own[item.value])
    return tuple(charges)


def _expression(reader: ModelReader, cname: str, node: Node, names: dict, what: str):
    """An expression of the component in its coordinates (the dissipation also in their rates)
    and the parameters: ``names`` holds no ``t``, so a value in time is an unknown name (a
    component's equations are those of constant parameters, as for a library component's)."""
    return reader.expr(node, names, what=f"{what} of '{cname}'")


def _metric(reader: ModelReader, cname: str, node: Node | None, names: dict, n: int):
    """The ``n x n`` symmetric metric, a list of rows."""
    example = "e.g. `metric: [[m, 0], [0, L]]`, one row per coordinate"
    if node is None:
        reader.error(reader.root, f"component '{cname}' needs `metric:`", example)
        return None
    if not node.is_sequence or len(node.value) != n or any(not r.is_sequence or len(r.value) != n
                                                            for r in node.value):
        reader.error(node, f"`metric:` of '{cname}' must be {n} rows of {n} entries (one per coordinate)", example)
        return None
    rows = [[_expression(reader, cname, item, names, "metric") for item in row.value] for row in node.value]
    if any(e is None for row in rows for e in row):
        return None
    metric = sympy.Matrix(rows)
    for i in range(n):
        for j in range(i):
            if sympy.expand(metric[i, j] - metric[j, i]) != 0:
                reader.error(node.value[i].value[j], f"`metric:` of '{cname}' is not symmetric: entry ({i + 1}, "
                             f"{j + 1}) is not entry ({j + 1}, {i + 1})",
                             "the metric is that of the kinetic energy T = 1/2 m_ab xdot^a xdot^b: m_ab = m_ba")
                return None
    return metric


__all__ = ["KEYS", "textbook_part"]
