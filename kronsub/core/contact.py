"""Contacts that constrain velocities: the velocity of a body's material point where it touches
the ground, which rolling without slipping sets to zero and a knife edge to zero across its
edge (:mod:`.nonholonomic` makes the speeds of them). A body is given by its centre ``c(y)`` and
world-from-body rotation ``R(y)`` in the generalized coordinates ``y``; the material point at
``P = c + r`` moves with

    v_P = dc/dt + omega x r,   [omega]_x = Rdot R^T

(in the plane ``omega x r = w (-r_y, r_x)``, ``w`` the rate of the body's angle).
"""
from __future__ import annotations

from collections.abc import Sequence

import sympy

from .simplify import compact
from .derivative import derivative
from .symbols import velocity_symbol
from .trigpoly import TrigAlgebra


def reduced(expr: sympy.Expr, coordinates: Sequence[sympy.Symbol]) -> sympy.Expr:
    """``expr`` as a polynomial in the sines and cosines of the ``coordinates``, reduced
    (``sin^2 + cos^2 = 1``) and in its shortest form (:func:`.simplify.compact`)."""
    algebra = TrigAlgebra(tuple(coordinates))
    return compact(algebra, algebra.from_expr(sympy.expand(expr)))


def rate(expr: sympy.Expr, coordinates: Sequence[sympy.Symbol]) -> sympy.Expr:
    """``d expr/dt = d expr/dy^k ydot^k`` (no time of its own)."""
    return sympy.Add(*[derivative(expr, q) * velocity_symbol(q) for q in coordinates])


def material_velocity(centre: Sequence[sympy.Expr], rotation: sympy.Matrix, offset: Sequence[sympy.Expr],
                      coordinates: Sequence[sympy.Symbol]) -> sympy.Matrix:
    """``v_P = dc/dt + omega x r`` of the body's material point at ``c + r`` (``r`` in world axes,
    the body's point there at this instant), in the plane or in space; as made, not reduced
    (:func:`reduced` gives its printed form)."""
    c, R, r = sympy.Matrix(centre), sympy.Matrix(rotation), sympy.Matrix(offset)
    v = c.applyfunc(lambda e: rate(e, coordinates))
    spin = R.applyfunc(lambda e: rate(e, coordinates)) * R.T
    if len(c) == 2:
        w = spin[1, 0]
        return v + sympy.Matrix([-w * r[1], w * r[0]])
    omega = sympy.Matrix([spin[2, 1], spin[0, 2], spin[1, 0]])
    return v + omega.cross(r)


def rim_contact(rotation: sympy.Matrix, axle: Sequence[sympy.Expr], radius: sympy.Expr,
                coordinates: Sequence[sympy.Symbol]) -> sympy.Matrix:
    """The offset from a wheel's centre to the lowest point of its rim on the ground ``z = 0``:
    ``-radius (e_z - (a.e_z) a) / sqrt(1 - (a.e_z)^2)`` with ``a`` the world axle (``R`` times
    the body-frame ``axle``, a unit vector). The root is taken as ``|cos|`` of the tilt written
    ``cos``: the wheel's plane within a right angle of the vertical (not lying flat)."""
    a = sympy.Matrix(rotation) * sympy.Matrix(axle)
    a = a / sympy.sqrt(sum(sympy.sympify(e) ** 2 for e in axle))
    up = sympy.Matrix([0, 0, 1])
    along = (up - a[2] * a).applyfunc(lambda e: reduced(e, coordinates))
    norm = sympy.sqrt(reduced(1 - a[2] ** 2, coordinates))
    norm = norm.replace(sympy.Abs, lambda e: e)  # the tilt's cosine is positive: the wheel is not flat
    return (-radius * along / norm).applyfunc(lambda e: sympy.cancel(e))


__all__ = ["material_velocity", "rate", "reduced", "rim_contact"]
