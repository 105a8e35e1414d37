"""The primitive system: the direct product of known components (Example III).

Its metric is block diagonal, its velocity terms and forces are stacked; in
Kron's words the primitive is "the system consisting of the parts not
interconnected, the forces being the same as those acting externally".
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import sympy

from ..components.base import Body, Component, ComponentPoints, PointsOnRead
from . import canonical
from .deferred import DeferredMatrix
from .derivative import derivative
from .symbols import free_symbols_of, velocity_symbol


def christoffel_terms(metric: sympy.Matrix, coordinates, velocities) -> sympy.Matrix:
    """Velocity terms of a holonomic metric, from Lagrange's operator (A):

    ``h_a = (d_c m_ab - 1/2 d_a m_bc) xdot^b xdot^c``, so that
    ``D(dT/dxdot^a) - dT/dx^a = m_ab xddot^b + h_a``.
    """
    n = len(coordinates)
    if all(not metric[i, j].has(*coordinates) for i in range(n) for j in range(n)):
        return sympy.zeros(n, 1)
    h = []
    for a in range(n):
        total = sympy.Integer(0)
        for b in range(n):
            for c in range(n):
                term = derivative(metric[a, b], coordinates[c]) - derivative(metric[b, c], coordinates[a]) / 2
                if term != 0:
                    total += term * velocities[b] * velocities[c]
        h.append(sympy.expand(total))
    return sympy.Matrix(h)


@dataclass(frozen=True)
class Part:
    """One known system placed in a primitive, with its coordinates bound to symbols."""

    name: str
    coordinates: tuple[sympy.Symbol, ...]
    metric: sympy.Matrix
    velocity_terms: sympy.Matrix
    points: Mapping[str, tuple[sympy.Expr, ...]] = field(default_factory=dict)
    bodies: tuple[Body, ...] = ()
    dimension: int = 0
    forces: Mapping[str, sympy.Matrix] = field(default_factory=dict)  # a known system's own effects
    potential: sympy.Expr = sympy.Integer(0)
    type_name: str = ""
    potentials: Mapping[str, sympy.Expr] = field(default_factory=dict)  # ``potential`` per own effect
    # a constrained known system placed on its coordinates y before the constraints: the
    # constraints g(y) = 0 it carries (core.constraints.Constraint) and its branch (y_d values)
    constraints: tuple = ()
    branch: Mapping[sympy.Symbol, float] = field(default_factory=dict)
    translations: Mapping[str, tuple] = field(default_factory=dict)  # ``dV/do`` per own effect (gravity's)
    # ``(coordinates, sum of potentials, V)``: what :func:`.subspace.assemble` made of that sum
    # when the known system was derived, so that a model reusing it as it is need not redo it
    assembled_potential: tuple = ()
    charges: tuple[sympy.Symbol, ...] = ()  # coordinates that are branch charges (a textbook component's `charges:`)
    effect_kinds: Mapping[str, str] = field(default_factory=dict)  # own effect -> its energy's kind (model/energy_kinds.py)
    local_names: tuple[str, ...] = ()  # a library component's own names of its coordinates (``turn1``)
    christoffel: bool = False  # velocity_terms are the Christoffel terms (A) of metric

    @property
    def velocities(self) -> tuple[sympy.Symbol, ...]:
        return tuple(velocity_symbol(q) for q in self.coordinates)


def body_label(part: Part, body: Body) -> str:
    """A component's body is named as the component; a known system's as ``part.component``
    (dotted further for a known system inside it)."""
    return f"{part.name}.{body.name}" if body.name else part.name


def part_from_component(name: str, component: Component) -> Part:
    """Place a library component in a primitive: its velocity terms, the Christoffel terms of its
    metric (A), are formed when first read."""
    coords = component.coordinate_symbols
    metric = sympy.Matrix(component.metric())
    h = DeferredMatrix(len(coords), 1, lambda: christoffel_terms(metric, coords, [velocity_symbol(q) for q in coords]))
    return Part(name, coords, metric, h, ComponentPoints(component), tuple(component.bodies()),
                component.dimension, type_name=component.type_name, local_names=tuple(component.coordinates),
                christoffel=True)


def point_symbols(points: Mapping) -> set:
    """Every symbol a part's points may hold; a component's are known without building them
    (`ComponentPoints.symbols`)."""
    if isinstance(points, ComponentPoints):
        return points.symbols()
    return free_symbols_of([c for pos in points.values() for c in pos])


class PrimitivePoints(PointsOnRead):
    """Every named point of a primitive, as ``part.point``. Reading one builds the points of
    its part alone (`ComponentPoints`); listing them builds every part's."""

    def __init__(self, parts: tuple[Part, ...]):
        super().__init__()
        self._parts = parts

    def _build(self) -> dict[str, tuple[sympy.Expr, ...]]:
        return {f"{part.name}.{label}": pos for part in self._parts for label, pos in part.points.items()}

    def __getitem__(self, label: str) -> tuple[sympy.Expr, ...]:
        if self._all is not None:
            return self._all[label]
        for part in reversed(self._parts):  # the last part of the label wins, as in the listing
            prefix = f"{part.name}."
            if label.startswith(prefix) and label[len(prefix):] in part.points:
                return part.points[label[len(prefix):]]
        raise KeyError(label)


@dataclass(frozen=True)
class Primitive:
    """Direct product of parts: block-diagonal metric, stacked velocity terms (Example III)."""

    parts: tuple[Part, ...]

    @property
    def coordinates(self) -> tuple[sympy.Symbol, ...]:
        return tuple(q for part in self.parts for q in part.coordinates)

    @property
    def velocities(self) -> tuple[sympy.Symbol, ...]:
        return tuple(velocity_symbol(q) for q in self.coordinates)

    @property
    def metric(self) -> sympy.Matrix:
        """The block-diagonal ``M`` of the parts' metrics (Example III); a single part's own."""
        if len(self.parts) == 1:
            return self.parts[0].metric
        size = len(self.coordinates)
        entries = [sympy.Integer(0)] * (size * size)
        for offset, part in self.blocks():
            rows = part.metric.tolist()
            for i, row in enumerate(rows):
                entries[(offset + i) * size + offset:(offset + i) * size + offset + len(row)] = row
        return canonical.matrix(size, size, entries)

    @property
    def velocity_terms(self) -> sympy.Matrix:
        return sympy.Matrix.vstack(*[part.velocity_terms for part in self.parts])

    def part(self, name: str) -> Part:
        for part in self.parts:
            if part.name == name:
                return part
        raise KeyError(name)

    def blocks(self):
        """``(offset, part)`` for each diagonal block of the metric."""
        offset = 0
        for part in self.parts:
            yield offset, part
            offset += len(part.coordinates)

    def points(self) -> PrimitivePoints:
        """Every named point, as ``part.point`` (each part's built when first read)."""
        return PrimitivePoints(self.parts)

    def bodies_by_name(self) -> dict[str, tuple[Part, int]]:
        """Every body, by the name a model gives it (`body_label`): its part and its place there."""
        return {body_label(part, body): (part, i) for part in self.parts for i, body in enumerate(part.bodies)}

    def gradient(self, expr: sympy.Expr) -> list[sympy.Expr]:
        """``d expr / d x^a`` over the primitive coordinates."""
        present = sympy.sympify(expr).free_symbols
        return [derivative(expr, q) if q in present else sympy.Integer(0) for q in self.coordinates]

    def rate(self, expr: sympy.Expr) -> sympy.Expr:
        """Time derivative of a function of the coordinates: ``(d expr/d x^a) xdot^a``."""
        return sympy.Add(*[g * v for g, v in zip(self.gradient(expr), self.velocities)])


__all__ = ["Part", "Primitive", "PrimitivePoints", "body_label", "christoffel_terms", "part_from_component",
           "point_symbols"]
