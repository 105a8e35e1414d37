"""A known system: the result of a derivation, itself usable as a component.

``Mbar qddot + hbar = fbar`` with ``fbar`` the sum of the named effects'
generalized forces (10'), (C)-(F).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import sympy

from ..components.base import Body
from .symbols import acceleration_symbol, velocity_symbol


@dataclass(frozen=True)
class ParameterInfo:
    """A model parameter as carried by a derived system (for defaults and documentation)."""

    name: str
    symbol: sympy.Symbol
    value: sympy.Expr | None = None
    unit: str = ""
    description: str = ""


@dataclass(frozen=True)
class Transition:
    """What the projection started from, kept for display: the primitive and ``C``."""

    primitive_coordinates: tuple[sympy.Symbol, ...]
    primitive_metric: sympy.Matrix
    primitive_velocity_terms: sympy.Matrix
    primitive_forces: Mapping[str, sympy.Matrix]
    connection: tuple[tuple[sympy.Symbol, sympy.Expr], ...]
    transformation: sympy.Matrix  # C = dx/dxbar (7'), (21)
    parts: tuple[tuple[str, str], ...] = ()  # (part name, type) in primitive order


@dataclass(frozen=True)
class ProjectedEffect:
    """One effect carried to the subspace: ``f`` on the primitive (17), ``fbar = C^T f`` (8'), (F)
    and its potential ``V(x(xbar))`` (not yet simplified; zero for a non-conservative effect).

    ``fbar`` is the sum of these over the effects, so each is derived and cached on its own
    and a scene adds up only the ones it switches on.
    """

    label: str
    primitive_force: sympy.Matrix
    force: sympy.Matrix
    potential: sympy.Expr = sympy.Integer(0)


@dataclass(frozen=True)
class KnownSystem:
    """The equations of motion of a derived system, ready to be a component of the next."""

    name: str
    coordinates: tuple[sympy.Symbol, ...]
    mass_matrix: sympy.Matrix
    velocity_terms: sympy.Matrix
    effect_forces: Mapping[str, sympy.Matrix]
    potential_energy: sympy.Expr = sympy.Integer(0)
    points: Mapping[str, tuple[sympy.Expr, ...]] = field(default_factory=dict)
    bodies: tuple[Body, ...] = ()
    dimension: int = 0
    parameters: tuple[ParameterInfo, ...] = ()
    transition: Transition | None = None
    description: str = ""
    effect_potentials: Mapping[str, sympy.Expr] = field(default_factory=dict)  # V per effect
    implicit: object | None = None  # core.constraints.ImplicitSubspace: the named intermediates (26)-(29)

    @property
    def velocities(self) -> tuple[sympy.Symbol, ...]:
        return tuple(velocity_symbol(q) for q in self.coordinates)

    @property
    def accelerations(self) -> tuple[sympy.Symbol, ...]:
        return tuple(acceleration_symbol(q) for q in self.coordinates)

    @property
    def forces(self) -> sympy.Matrix:
        """``fbar``: the sum of every effect's generalized force (F)."""
        total = sympy.zeros(len(self.coordinates), 1)
        for f in self.effect_forces.values():
            total += f
        return total

    @property
    def kinetic_energy(self) -> sympy.Expr:
        """``T = 1/2 Mbar_ab qdot^a qdot^b`` (24)."""
        qd = sympy.Matrix(self.velocities)
        return sympy.expand((qd.T * self.mass_matrix * qd)[0, 0] / 2)

    def equations(self) -> list[sympy.Eq]:
        """``Mbar qddot + hbar = fbar``, one equation per coordinate."""
        lhs = self.mass_matrix * sympy.Matrix(self.accelerations) + self.velocity_terms
        return [sympy.Eq(lhs[i], self.forces[i]) for i in range(len(self.coordinates))]
