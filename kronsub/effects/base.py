"""Effects: the named loads of a model (gravity, forces, torques, springs, dampers).

An effect contributes a generalized force ``f_a`` on the primitive coordinates
(the force vector of (17)); a conservative effect also has a potential ``V``
with ``f_a = -dV/dx^a``. Every effect has a name so a scene can switch it. An effect
written in generalized coordinates is applied in the subspace instead (:meth:`Effect.direct_force`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import sympy

from ..core.derivative import derivative
from ..core.primitive import Primitive


@dataclass(frozen=True)
class Effect:
    """Base class: subclasses give either ``potential`` or ``generalized_force``."""

    name: str

    def potential(self, primitive: Primitive) -> sympy.Expr:
        """``V(x)``; zero for non-conservative effects."""
        return sympy.Integer(0)

    def translation(self, primitive: Primitive) -> tuple[sympy.Expr, ...]:
        """``dV/do``, the change of ``V`` per unit of a translation ``o`` of the whole system
        with everything of it (its points, bodies, anchors): nonzero only for a field fixed in
        the world, gravity (a known system placed with ``origin:`` carries it, ``placed``)."""
        return ()

    def generalized_force(self, primitive: Primitive) -> list[sympy.Expr]:
        """``f_a`` over the primitive coordinates (default: ``-dV/dx^a``)."""
        return [-g for g in primitive.gradient(self.potential(primitive))]

    def force_and_potential(self, primitive: Primitive) -> tuple[list[sympy.Expr], sympy.Expr]:
        """``(f_a, V)``, with ``V`` built once for the default force ``f_a = -dV/dx^a``."""
        V = self.potential(primitive)
        if type(self).generalized_force is Effect.generalized_force:
            return [-g for g in primitive.gradient(V)], V
        return self.generalized_force(primitive), V

    def symbols(self) -> set:
        """Every symbol in the effect's own fields (its angle, stiffness, vector, coordinate...)."""
        found: set = set()

        def walk(value):
            if isinstance(value, sympy.Basic):
                found.update(value.free_symbols)
            elif isinstance(value, (tuple, list)):
                for item in value:
                    walk(item)

        for f in dataclasses.fields(self):
            walk(getattr(self, f.name))
        return found

    def written_in(self, through: dict) -> "Effect":
        """The same effect with ``through`` (symbol -> expression) put in every field."""

        def put(value):
            if isinstance(value, sympy.Basic):
                return value.xreplace(through)
            if isinstance(value, (tuple, list)):
                return type(value)(put(item) for item in value)
            return value

        return dataclasses.replace(self, **{f.name: put(getattr(self, f.name)) for f in dataclasses.fields(self)})

    def direct_force(self, primitive: Primitive, coordinates, moved) -> list[sympy.Expr] | None:
        """``fbar`` applied directly in the subspace, for an effect written (partly) in the
        generalized coordinates ``xbar``; ``moved`` carries an expression to the subspace
        (``x -> x(xbar)``, ``xdot -> C xbardot``). A conservative effect gives
        ``fbar = -dV(x(xbar), xbar)/dxbar``, which is ``C^T f`` (8') when ``V`` is in ``x`` alone.
        None: the effect is projected as usual, ``fbar = C^T f`` (its force acts on the
        primitive; ``xbar`` only in its magnitude)."""
        if type(self).generalized_force is not Effect.generalized_force:
            return None
        V = moved(self.potential(primitive))
        return [-derivative(V, q) for q in coordinates]


def dot(u, v) -> sympy.Expr:
    return sympy.Add(*[a * b for a, b in zip(u, v)])


def virtual_work_force(primitive: Primitive, point, vector) -> list[sympy.Expr]:
    """Generalized force of a force ``vector`` applied at ``point``: ``F . dp/dx^a``."""
    return [sympy.expand(dot(vector, [derivative(c, q) for c in point])) for q in primitive.coordinates]


__all__ = ["Effect", "dot", "virtual_work_force"]
