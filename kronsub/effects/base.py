"""Effects: the named loads of a model (gravity, forces, torques, springs, dampers).

An effect contributes a generalized force ``f_a`` on the primitive coordinates
(the force vector of (17)); a conservative effect also has a potential ``V``
with ``f_a = -dV/dx^a``. Every effect has a name so a scene can switch it.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..core.primitive import Primitive


@dataclass(frozen=True)
class Effect:
    """Base class: subclasses give either ``potential`` or ``generalized_force``."""

    name: str

    def potential(self, primitive: Primitive) -> sympy.Expr:
        """``V(x)``; zero for non-conservative effects."""
        return sympy.Integer(0)

    def generalized_force(self, primitive: Primitive) -> list[sympy.Expr]:
        """``f_a`` over the primitive coordinates (default: ``-dV/dx^a``)."""
        return [-g for g in primitive.gradient(self.potential(primitive))]


def dot(u, v) -> sympy.Expr:
    return sympy.Add(*[a * b for a, b in zip(u, v)])


def virtual_work_force(primitive: Primitive, point, vector) -> list[sympy.Expr]:
    """Generalized force of a force ``vector`` applied at ``point``: ``F . dp/dx^a``."""
    return [sympy.expand(dot(vector, [sympy.diff(c, q) for c in point])) for q in primitive.coordinates]
