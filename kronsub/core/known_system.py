"""A known system: the result of a derivation, itself usable as a component.

``Mbar qddot + hbar = fbar`` with ``fbar`` the sum of the named effects'
generalized forces (10'), (C)-(F). Pure data: printing, simulating and the notebook's
conveniences live above it (:mod:`kronsub.emitters`, :mod:`kronsub.simulation`,
:class:`kronsub.api.System`).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Mapping

import sympy

from ..components.base import Body, Requirement
from .currents import printed_velocities
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
    christoffel: bool = False  # primitive_velocity_terms are the Christoffel terms (A) of primitive_metric


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
    translation: tuple[sympy.Expr, ...] = ()  # dV/do under a translation o of the whole system (Effect.translation)


@dataclass(frozen=True)
class Constraint:
    """One scalar constraint ``g = 0``; ``source`` says where it came from (a joint, the file)."""

    name: str
    expression: sympy.Expr
    source: str = ""


@dataclass(frozen=True)
class ImplicitSubspace:
    """The implicit part of a derived system: what its named intermediates mean (26)-(29).

    ``Mbar``, ``hbar`` and ``fbar`` of the system are written in the independent
    coordinates, the dependent coordinates, ``Lambda`` (``sensitivities``, k x n) and
    ``gamma`` (``convective``, k); to evaluate them at a state, find ``y_d`` with
    ``g(xbar, y_d) = 0`` on the branch through ``branch``, then
    ``G_d Lambda = -G_i`` and ``G_d gamma = quadratic``
    (:func:`kronsub.core.constraints.project_implicit` makes it).
    """

    independent: tuple[sympy.Symbol, ...]
    dependent: tuple[sympy.Symbol, ...]
    constraints: tuple[Constraint, ...]
    jacobian_dependent: sympy.Matrix  # G_d = dg/dy_d (k x k)
    jacobian_independent: sympy.Matrix  # G_i = dg/dxbar (k x n)
    sensitivities: sympy.Matrix  # Lambda, k x n matrix of symbols
    convective: tuple[sympy.Symbol, ...]  # gamma, k symbols
    quadratic: tuple[sympy.Expr, ...]  # -(ydot^T d2g/dy2 ydot) with ydot = C xbardot, in Lambda
    closed_form: tuple[tuple[sympy.Symbol, sympy.Expr], ...] = ()  # y_d = y_d(xbar) where unique
    branch: tuple[tuple[sympy.Symbol, float], ...] = ()  # y_d at the initial configuration
    choice: str = "given"  # "given" (coordinates listed) or "auto" (pivoted at the initial configuration)
    definitions: tuple[tuple[sympy.Symbol, sympy.Expr], ...] = field(default=())  # printed closed forms
    intermediate: tuple[sympy.Symbol, ...] = ()  # y, in the order of the connection's C columns
    # the system on y before the constraints (for the reactions of viewpoint (alpha))
    metric: sympy.Matrix | None = None
    velocity_terms: sympy.Matrix | None = None
    forces: sympy.Matrix | None = None
    effect_forces: Mapping[str, sympy.Matrix] = field(default_factory=dict)  # f per effect, on y

    @property
    def intermediates(self) -> tuple[sympy.Symbol, ...]:
        """``y_d``, ``Lambda`` (row-major) and ``gamma``: the order of generated code's ``w[]``."""
        return self.dependent + tuple(self.sensitivities) + self.convective

    @property
    def residuals(self) -> tuple[sympy.Expr, ...]:
        return tuple(c.expression for c in self.constraints)


@dataclass(frozen=True)
class SpeedEquations:
    """A system under velocity constraints ``A(x) xdot + b = 0``, written in its speeds ``u``
    (:mod:`.nonholonomic`): the kinematic equations ``xdot = C u + d`` and

        Mbar udot + hbar = fbar,  Mbar = C^T M C (9'), (D),  fbar = C^T f (8'), (F)

    with ``hbar`` taking ``Cdot`` along the motion (Boltzmann-Hamel). The known system that
    carries it keeps ``M``, ``h``, ``f`` in the coordinates ``x`` (before the constraints), as
    an implicit subspace keeps the system on ``y``. ``definitions`` gives each speed as
    ``Y(x) xdot``; ``constraint_names`` the velocity constraints' names in row order.
    """

    speeds: tuple[sympy.Symbol, ...]
    definitions: tuple[tuple[sympy.Symbol, sympy.Expr], ...]
    constraint_names: tuple[str, ...]
    constraint_matrix: sympy.Matrix  # A
    constraint_offset: sympy.Matrix  # b
    # what the equations in the speeds are projected from, when first read: ``source.equations()``
    # gives ``transformation`` (C), ``offset`` (d), ``kinematics`` (xdot = C u + d), ``mass_matrix``
    # (Mbar), ``velocity_terms`` (hbar), ``effect_forces`` (fbar of each effect) and
    # ``kinetic_energy`` (T(x, C u + d)); a linearisation reads none of them
    source: object
    holonomic: tuple[Constraint, ...] = ()  # configuration constraints g(x, t) = 0 kept beside them
    dependent: tuple[sympy.Symbol, ...] = ()  # one coordinate per configuration constraint, set by it
    # the velocity constraints A xdot + b as numbers are taken from (a contact's rows as made, not
    # reduced: A and b are their printed forms, made when first read); empty: from A and b
    rows: tuple[sympy.Expr, ...] = ()

    @functools.cached_property
    def projected(self) -> dict:
        """The equations in the speeds, projected once."""
        return self.source.equations()

    @property
    def transformation(self) -> sympy.Matrix:
        return self.projected["transformation"]

    @property
    def offset(self) -> sympy.Matrix:
        return self.projected["offset"]

    @property
    def kinematics(self) -> sympy.Matrix:
        return self.projected["kinematics"]

    @property
    def mass_matrix(self) -> sympy.Matrix:
        return self.projected["mass_matrix"]

    @property
    def velocity_terms(self) -> sympy.Matrix:
        return self.projected["velocity_terms"]

    @property
    def effect_forces(self) -> Mapping[str, sympy.Matrix]:
        return self.projected["effect_forces"]

    @property
    def kinetic_energy(self) -> sympy.Expr:
        return self.projected["kinetic_energy"]

    @property
    def forces(self) -> sympy.Matrix:
        """``fbar`` in the speeds: the sum over the effects."""
        total = sympy.zeros(len(self.speeds), 1)
        for f in self.effect_forces.values():
            total += f
        return total


@dataclass(frozen=True)
class KnownSystem:
    """The equations of motion of a derived system, ready to be a component of the next.

    ``mass_matrix`` is ``Mbar = Cᵀ M C`` (9'), (D): the metric of the subspace, the primitive's
    metric ``M`` carried by the transformation ``C`` (what a component calls its metric);
    ``velocity_terms`` is ``hbar`` (E) and ``effect_forces`` the ``fbar`` of each named effect (F).
    ``effect_translations`` holds, per effect of a world field, ``dV/do`` under a translation
    ``o`` of the whole system; ``requirements`` what its components need of the parameters'
    values (:class:`~kronsub.components.base.Requirement`, checked by the model above);
    ``initial`` the model's initial values; ``currents`` the coordinates that are branch
    charges (of the primitive, the subspace and a closed loop's dependent ones), each with the
    printed name of its velocity, the current (:mod:`.currents`).
    """

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
    effect_translations: Mapping[str, tuple[sympy.Expr, ...]] = field(default_factory=dict)
    implicit: ImplicitSubspace | None = None  # the named intermediates (26)-(29)
    initial: Mapping[sympy.Symbol, sympy.Expr] = field(default_factory=dict)
    requirements: tuple[Requirement, ...] = ()
    speeds: SpeedEquations | None = None  # under velocity constraints: the equations in the speeds
    currents: Mapping[str, str] = field(default_factory=dict)  # charge coordinate -> its current's name
    effect_kinds: Mapping[str, str] = field(default_factory=dict)  # effect -> its energy's kind (electric, dissipative)

    @property
    def velocities(self) -> tuple[sympy.Symbol, ...]:
        return tuple(velocity_symbol(q) for q in self.coordinates)

    @property
    def printed_names(self) -> dict[sympy.Symbol, str]:
        """The velocity symbols printed under a name of their own (the currents), by symbol."""
        return printed_velocities(self.currents)

    def name_of(self, velocity: sympy.Symbol) -> str:
        """The printed name of a velocity (or any symbol): a charge's current, else its own."""
        return self.printed_names.get(velocity, velocity.name)

    def printed_name(self, name: str) -> str:
        """The printed name of the quantity a user's ``name`` stands for: a charge's ``q_dot``
        (still read) is its current ``i_q``, ``q_ddot`` the current's rate; others as given."""
        return {s.name: printed for s, printed in self.printed_names.items()}.get(name, name)

    def symbol_name(self, name: str) -> str:
        """The name of the symbol a user's ``name`` stands for: a current ``i_q`` is the charge's
        velocity ``q_dot``, its rate ``i_q_dot`` ``q_ddot``; others as given."""
        return {printed: s.name for s, printed in self.printed_names.items()}.get(name, name)

    @property
    def accelerations(self) -> tuple[sympy.Symbol, ...]:
        return tuple(acceleration_symbol(q) for q in self.coordinates)

    @property
    def state_velocities(self) -> tuple[sympy.Symbol, ...]:
        """The velocity part of the first-order state: ``qdot``, or the speeds ``u`` under
        velocity constraints (the state ``[q; u]``)."""
        return self.speeds.speeds if self.speeds is not None else self.velocities

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


__all__ = ["Constraint", "ImplicitSubspace", "KnownSystem", "ParameterInfo", "ProjectedEffect", "SpeedEquations",
           "Transition"]
