"""Uniform gravity on the bodies of chosen parts."""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from .base import Effect, dot


@dataclass(frozen=True)
class Gravity(Effect):
    """``V = - sum_bodies m g (d . centre)`` with ``d`` the unit direction of gravity."""

    g: sympy.Expr = sympy.Integer(0)
    direction: tuple[sympy.Expr, ...] = ()
    parts: tuple[str, ...] = ()

    conservative = True

    def potential(self, primitive):
        d = sympy.Matrix(self.direction)
        norm = sympy.sqrt(sum(c**2 for c in d))
        unit = [c / norm for c in d]
        total = sympy.Integer(0)
        for name in self.parts:
            for body in primitive.part(name).bodies:
                if body.mass != 0:
                    total -= body.mass * self.g * dot(unit, body.centre)
        return sympy.expand(total)
