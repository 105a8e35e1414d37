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
    direct_effects: tuple[str, ...] = ()  # effects applied in the subspace: no force on the primitive


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
    direct: bool = False  # written in generalized coordinates: fbar formed in the subspace, f is zero
    translation: tuple = ()  # dV/do under a translation o of the whole system (Effect.translation)


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
    effect_translations: Mapping[str, tuple] = field(default_factory=dict)  # dV/do per effect of a world field
    implicit: object | None = None  # core.constraints.ImplicitSubspace: the named intermediates (26)-(29)
    initial: Mapping[sympy.Symbol, sympy.Expr] = field(default_factory=dict)  # the model's initial values
    requirements: tuple = ()  # what its components need of the parameters' values (model.requirements)

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
        """``T = 1/2 Mbar_ab qdot^a qdot^b`` (24), expanded; computed once per system (the
        entries of the upper triangle expanded one by one: the same sum as expanding the
        whole product, without forming it)."""
        cached = self.__dict__.get("_kinetic_energy")
        if cached is None:
            qd, M, n = self.velocities, self.mass_matrix, len(self.coordinates)
            half = sympy.Rational(1, 2)
            terms = [sympy.expand(half * (M[i, j] + M[j, i]) * qd[i] * qd[j]) if i != j
                     else sympy.expand(half * M[i, i] * qd[i] ** 2)
                     for i in range(n) for j in range(i, n) if M[i, j] != 0 or M[j, i] != 0]
            cached = sympy.Add(*terms)
            object.__setattr__(self, "_kinetic_energy", cached)  # a frozen system: derived data only
        return cached

    def equations(self) -> list[sympy.Eq]:
        """``Mbar qddot + hbar = fbar``, one equation per coordinate."""
        lhs = self.mass_matrix * sympy.Matrix(self.accelerations) + self.velocity_terms
        return [sympy.Eq(lhs[i], self.forces[i]) for i in range(len(self.coordinates))]

    # -- conveniences for notebooks: thin delegations to kronsub.api, imported when called,
    #    so this module stays pure data and never imports the simulation ----------------------

    def symbol(self, name: str) -> sympy.Symbol:
        """The system's symbol called ``name`` (kronsub's symbols are ``real=True``)."""
        from ..api import symbol

        return symbol(self, name)

    def simulate(self, t: float = 10.0, dt: float = 0.01, method: str = "dop853", set=None, **options):
        """Simulate from the model's initial values; see :func:`kronsub.api.simulate`."""
        from ..api import simulate

        return simulate(self, t, dt, method, set, **options)

    def numeric(self, set=None):
        """Compiled ``rhs``, ``mass_matrix``, energies...; see :func:`kronsub.api.numeric`."""
        from ..api import numeric

        return numeric(self, set)

    def linearize(self, at=None, inputs=(), *, symbolic: bool = False):
        """``A``, ``B`` about an operating point; see :func:`kronsub.api.linearize`."""
        from ..api import linearize

        return linearize(self, at, inputs, symbolic=symbolic)

    def _repr_markdown_(self) -> str:
        from ..api import repr_markdown

        return repr_markdown(self)

    def _repr_latex_(self) -> str:
        from ..api import repr_latex

        return repr_latex(self)
