"""Applied loads: forces at points, torques on bodies, direct generalized forces."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import sympy

from ..core.derivative import derivative
from ..core.symbols import velocity_symbol
from ..core.trigpoly import TrigAlgebra
from .base import Effect, virtual_work_force


@dataclass(frozen=True)
class Force(Effect):
    """A force ``vector`` (world frame; may depend on time and state) at a named point."""

    point: str = ""
    vector: tuple[sympy.Expr, ...] = ()

    def generalized_force(self, primitive):
        return virtual_work_force(primitive, primitive.points()[self.point], self.vector)


def angular_velocity(primitive, rotation: sympy.Matrix):
    """World angular velocity of a rotation ``R(x)``: from ``Rdot R^T`` (skew), each entry
    reduced in the trigonometric algebra of the coordinates, where ``cos^2 + sin^2 = 1`` holds
    as the products are formed (exact, and far cheaper than ``simplify`` in space)."""
    rdot = sympy.Matrix(rotation.shape[0], rotation.shape[1],
                        lambda i, j: primitive.rate(rotation[i, j]))
    algebra = TrigAlgebra(primitive.coordinates)
    w = rdot * rotation.T

    def reduced(entry):
        return algebra.to_expr(algebra.from_expr(sympy.expand(entry)))

    if rotation.shape == (2, 2):
        return (reduced(w[1, 0]),)
    return (reduced(w[2, 1]), reduced(w[0, 2]), reduced(w[1, 0]))


@dataclass(frozen=True)
class Torque(Effect):
    """A torque on a body of a part (``body``: its place among the part's bodies, which a
    known system has several of): ``f_a = tau . d omega / d xdot^a``.

    In the plane ``value`` is one expression (counter-clockwise); in space a
    world-frame vector of three.
    """

    part: str = ""
    value: tuple[sympy.Expr, ...] = ()
    body: int = 0

    def generalized_force(self, primitive):
        body = primitive.part(self.part).bodies[self.body]
        omega = angular_velocity(primitive, body.rotation)
        return [sympy.expand(sum(t * derivative(w, v) for t, w in zip(self.value, omega)))
                for v in primitive.velocities]


@dataclass(frozen=True)
class GeneralizedForce(Effect):
    """A force acting directly on one primitive coordinate (or on a generalized one: a row of ``fbar``)."""

    coordinate: sympy.Symbol | None = None
    value: sympy.Expr = sympy.Integer(0)

    def generalized_force(self, primitive):
        return [self.value if q == self.coordinate else sympy.Integer(0) for q in primitive.coordinates]

    def written_in(self, through):
        """On ``q`` with ``x^a = q + c``: on ``x^a`` (its row of ``C`` is that of ``q``, so
        ``C^T f`` is ``value`` on row ``q`` as before)."""
        moved = super().written_in(through)
        if self.coordinate not in through:
            return moved
        rate = through[velocity_symbol(self.coordinate)]  # xdot^a
        (x,) = [s for s in through[self.coordinate].free_symbols if velocity_symbol(s) == rate]
        return dataclasses.replace(moved, coordinate=x)

    def direct_force(self, primitive, coordinates, moved):
        """On a generalized coordinate: ``value`` is that row of ``fbar`` (Hoffmann's eq. (4)
        one level up); on a primitive one, projected as usual."""
        if self.coordinate in primitive.coordinates:
            return None
        return [moved(self.value) if q == self.coordinate else sympy.Integer(0) for q in coordinates]


@dataclass(frozen=True)
class Potential(Effect):
    """A conservative load given by its potential energy ``V(x)``."""

    value: sympy.Expr = sympy.Integer(0)

    def potential(self, primitive):
        return self.value


__all__ = ["Force", "GeneralizedForce", "Potential", "Torque", "angular_velocity"]
