"""Force elements between two points or along an angle: springs and dampers."""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..components.base import common_world
from ..core.derivative import derivative
from ..core.seeded import seeded
from ..core.symbols import velocity_symbol
from .base import Effect


def separation(primitive, ends):
    """``p_b - p_a``, both ends in the larger of their worlds (as a pin's, :func:`common_world`)."""
    a, b = common_world(*(primitive.points()[e] if isinstance(e, str) else e for e in ends))
    return [pb - pa for pa, pb in zip(a, b)]


def _squared_length(primitive, ends) -> sympy.Expr:
    """``|p_b - p_a|^2``."""
    return sympy.Add(*[c**2 for c in separation(primitive, ends)])


def squared_distance(primitive, effect) -> sympy.Expr | None:
    """``|p_b - p_a|^2`` of a spring or damper whose force has no value where its ends meet:
    a damper's (its force is along ``(p_b - p_a)/|p_b - p_a|``) or a spring's with a rest
    length (``k (l - length) dl/dx``, ``dl/dx`` again a unit vector); None for any other effect,
    and for a spring of zero rest length (its force ``k (p_b - p_a)`` is defined everywhere)."""
    if not isinstance(effect, Damper) and not (isinstance(effect, Spring) and effect.length != 0):
        return None
    return _squared_length(primitive, effect.ends)


@dataclass(frozen=True)
class Spring(Effect):
    """Linear spring between two points (or a point and a fixed place):
    ``V = k/2 (|p_b - p_a| - length)^2``; with zero rest length ``V = k/2 |p_b - p_a|^2``."""

    ends: tuple = ()
    stiffness: sympy.Expr = sympy.Integer(0)
    length: sympy.Expr = sympy.Integer(0)

    def potential(self, primitive):
        square = _squared_length(primitive, self.ends)
        if self.length == 0:
            return sympy.expand(self.stiffness * square / 2)
        return self.stiffness * (sympy.sqrt(square) - self.length) ** 2 / 2


@dataclass(frozen=True)
class Damper(Effect):
    """Linear damper between two points: force ``-c ldot`` along the line joining them,
    ``f_a = -c ldot dl/dx^a`` with ``l = |p_b - p_a|``."""

    ends: tuple = ()
    coefficient: sympy.Expr = sympy.Integer(0)

    @seeded
    def generalized_force(self, primitive):
        square = _squared_length(primitive, self.ends)
        # c ldot dl/dx = c (dl^2/dt)(dl^2/dx) / (4 l^2): no square roots needed
        rate = primitive.rate(square)
        # sympy.factor factors each factor of a product on its own and multiplies the results,
        # so the part shared by every component is factored once (a body's corner: 5x faster)
        shared = sympy.factor(-self.coefficient * rate / (4 * square))
        return [shared * sympy.factor(g) if g != 0 else sympy.Integer(0) for g in primitive.gradient(square)]


@dataclass(frozen=True)
class TorsionalSpring(Effect):
    """Torsional spring on an angle expression: ``V = k/2 (angle - rest)^2``."""

    angle: sympy.Expr = sympy.Integer(0)
    stiffness: sympy.Expr = sympy.Integer(0)
    rest: sympy.Expr = sympy.Integer(0)

    def potential(self, primitive):
        return self.stiffness * (self.angle - self.rest) ** 2 / 2


@dataclass(frozen=True)
class TorsionalDamper(Effect):
    """Torsional damper on an angle expression: ``f_a = -c angledot d angle/dx^a``."""

    angle: sympy.Expr = sympy.Integer(0)
    coefficient: sympy.Expr = sympy.Integer(0)

    def generalized_force(self, primitive):
        rate = primitive.rate(self.angle)
        return [sympy.expand(-self.coefficient * rate * g) for g in primitive.gradient(self.angle)]

    def direct_force(self, primitive, coordinates, moved):
        """In the subspace: ``fbar = -c angledot d angle/dxbar``, ``angle`` carried to ``xbar``."""
        angle, c = moved(self.angle), moved(self.coefficient)
        gradient = [derivative(angle, q) for q in coordinates]
        rate = sympy.Add(*[g * velocity_symbol(q) for g, q in zip(gradient, coordinates)])
        return [sympy.expand(-c * rate * g) for g in gradient]


__all__ = ["Damper", "Spring", "TorsionalDamper", "TorsionalSpring", "separation", "squared_distance"]
