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
        """``(part name, d)`` per part, ``d`` the unit direction in that part's world (each
        direction normed once: a chain's links share one)."""
        units: dict = {}
        for name, direction in self.parts:
            unit = units.get(direction)
            if unit is None:
                norm = sympy.sqrt(sum(c**2 for c in direction))
                unit = units[direction] = [c / norm for c in direction]
            yield name, unit

    def potential(self, primitive):
        terms = [-(body.mass * self.g * dot(unit, body.centre)) for name, unit in self._units()
                 for body in primitive.part(name).bodies if body.mass != 0]
        return sympy.expand(sympy.Add(*terms))  # one sum, not one per body

    def translation(self, primitive):
        """``dV/do = -g sum m d``: the weight of the bodies it acts on, against ``d``."""
        total: list[list] = []
        for name, unit in self._units():
            mass = sympy.Add(*[b.mass for b in primitive.part(name).bodies])
            total += [[] for _ in range(len(unit) - len(total))]
            for i, c in enumerate(unit):
                total[i].append(-(mass * self.g * c))
        return tuple(sympy.expand(sympy.Add(*t)) for t in total)


__all__ = ["Gravity"]
