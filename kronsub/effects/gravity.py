"""Uniform gravity on the bodies of chosen parts."""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from .base import Effect, dot


@dataclass(frozen=True)
class Gravity(Effect):
    """``V = - sum_bodies m g (d . centre)`` with ``d`` the unit direction of gravity.

    ``parts`` pairs each component with the direction of gravity in its world.
    """

    g: sympy.Expr = sympy.Integer(0)
    parts: tuple[tuple[str, tuple[sympy.Expr, ...]], ...] = ()

    def _units(self):
        """``(part name, d)`` per part, ``d`` the unit direction in that part's world."""
        for name, direction in self.parts:
            norm = sympy.sqrt(sum(c**2 for c in direction))
            yield name, [c / norm for c in direction]

    def potential(self, primitive):
        total = sympy.Integer(0)
        for name, unit in self._units():
            for body in primitive.part(name).bodies:
                if body.mass != 0:
                    total -= body.mass * self.g * dot(unit, body.centre)
        return sympy.expand(total)

    def translation(self, primitive):
        """``dV/do = -g sum m d``: the weight of the bodies it acts on, against ``d``."""
        total: list = []
        for name, unit in self._units():
            mass = sympy.Add(*[b.mass for b in primitive.part(name).bodies])
            total += [sympy.Integer(0)] * (len(unit) - len(total))
            for i, c in enumerate(unit):
                total[i] -= mass * self.g * c
        return tuple(sympy.expand(t) for t in total)
