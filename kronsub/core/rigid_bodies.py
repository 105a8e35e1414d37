"""Rigid bodies placed by a connection, each taken as a primitive in its own axes.

A body's primitive velocities are its centre's velocity (world axes) and its angular velocity
(body axes), ``v = [c_dot; omega] = J(x) xdot``, with the constant metric ``W = diag(m, m, m, I)``
(``I`` the inertia about the centre in body axes): Kron's non-holonomic reference frame of the
body, whose ``omega`` is the derivative of no coordinate. The connection projects it as ever,

    M(x) = sum over bodies of J^T W J                                   (9'), (D)

The body's rotation is a chain of turns about its own axes, world-from-body
``R = R_a1(angle_1) R_a2(angle_2) ...`` (an angle may be a constant: a tilt), so that

    omega = sum_j (R_(j+1) ... R_n)^T e_(a_j) d(angle_j)/dt

is a sum of rotated unit vectors, free of the ``cos^2 + sin^2`` a product ``R^T Rdot``
leaves to simplify.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import sympy

from ..components.spatial import axis_rotation
from .derivative import derivative

AXES = {"X": (1, 0, 0), "Y": (0, 1, 0), "Z": (0, 0, 1)}
"""The unit vector of each axis a turn may be about."""


@dataclass(frozen=True)
class PlacedBody:
    """A rigid body at ``x``: mass, the world position of its centre, its rotation as turns
    ``(axis, angle)`` about its own axes (world-from-body, first turn first) and its inertia
    about the centre in its axes."""

    name: str
    mass: sympy.Expr
    centre: tuple[sympy.Expr, sympy.Expr, sympy.Expr]
    turns: tuple[tuple[str, sympy.Expr], ...]
    inertia: sympy.Matrix

    def rotation(self) -> sympy.Matrix:
        """World-from-body ``R = R_a1(angle_1) R_a2(angle_2) ...``."""
        R = sympy.eye(3)
        for axis, angle in self.turns:
            R = R * axis_rotation(axis, angle)
        return R

    def weights(self) -> sympy.Matrix:
        """``W = diag(m, m, m, I)``, the metric of the body's primitive."""
        return sympy.diag(self.mass * sympy.eye(3), sympy.Matrix(self.inertia))

    def projection(self, coordinates: Sequence[sympy.Symbol]) -> sympy.Matrix:
        """``J`` (6 x n) with ``[c_dot; omega] = J xdot``, ``omega`` in body axes."""
        return linear_velocity(self.centre, coordinates).col_join(angular_velocity(self.turns, coordinates))


def linear_velocity(point: Sequence[sympy.Expr], coordinates: Sequence[sympy.Symbol]) -> sympy.Matrix:
    """``d point / dx`` (3 x n): ``point_dot = (d point/dx) xdot``."""
    return sympy.Matrix([[derivative(sympy.sympify(c), q) for q in coordinates] for c in point])


def angular_velocity(turns: Sequence[tuple[str, sympy.Expr]], coordinates: Sequence[sympy.Symbol]) -> sympy.Matrix:
    """``J_omega`` (3 x n) with ``omega = J_omega xdot`` in the axes of the last turn:
    ``sum_j (R_(j+1) ... R_n)^T e_(a_j) d angle_j / dx``."""
    columns = sympy.zeros(3, len(coordinates))
    after = sympy.eye(3)  # (R_(j+1) ... R_n)^T, built from the last turn back
    for axis, angle in reversed(tuple(turns)):
        seen = after * sympy.Matrix(AXES[axis])
        for k, q in enumerate(coordinates):
            rate = derivative(sympy.sympify(angle), q)
            if rate != 0:
                columns[:, k] += seen * rate
        after = after * axis_rotation(axis, angle).T
    return columns


def body_metric(bodies: Sequence[PlacedBody], coordinates: Sequence[sympy.Symbol]) -> sympy.Matrix:
    """``M(x) = sum J^T W J`` (9'), (D), expanded."""
    n = len(coordinates)
    M = sympy.zeros(n, n)
    for body in bodies:
        J = body.projection(coordinates)
        M += J.T * body.weights() * J
    return M.applyfunc(sympy.expand)


def point_velocity(body: PlacedBody, point: Sequence[sympy.Expr], coordinates: Sequence[sympy.Symbol]
                   ) -> sympy.Matrix:
    """``V`` (3 x n) with ``V xdot`` the velocity of the body's material point at the world
    position ``point(x)``: ``c_dot + R omega x (point - c)`` (a rolling wheel's contact point
    has none)."""
    arm = sympy.Matrix(point) - sympy.Matrix(body.centre)
    skew = sympy.Matrix([[0, -arm[2], arm[1]], [arm[2], 0, -arm[0]], [-arm[1], arm[0], 0]])
    omega = body.rotation() * angular_velocity(body.turns, coordinates)  # in world axes
    return linear_velocity(body.centre, coordinates) - skew * omega


def centre_height(bodies: Sequence[PlacedBody], up: int = 2) -> sympy.Expr:
    """``sum m c_up``: the potential of uniform gravity is ``g`` times it."""
    return sympy.Add(*[b.mass * b.centre[up] for b in bodies])


__all__ = ["AXES", "PlacedBody", "angular_velocity", "body_metric", "centre_height", "linear_velocity",
           "point_velocity"]
