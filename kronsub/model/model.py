"""The parsed model: immutable, validated, with every expression already in sympy.

Data flows one way: YAML -> :class:`Model` -> primitive -> subspace ->
equations. Deriving returns a new :class:`~kronsub.core.known_system.KnownSystem`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import sympy

from ..core.known_system import KnownSystem, ParameterInfo
from ..core.primitive import Primitive
from ..effects.base import Effect
from ..errors import Location


@dataclass(frozen=True)
class ImplicitSpec:
    """What ``constraints:`` gave: the coordinates ``y`` the constraints ``g(y) = 0`` act on
    (after the connection), split into independent and dependent ones (25), (26).

    ``branch`` holds the dependent coordinates at the initial configuration ``configuration``
    (found by Newton's method); ``closed_form`` the ones sympy solved uniquely on that branch.
    """

    intermediate: tuple[sympy.Symbol, ...]
    independent: tuple[sympy.Symbol, ...]
    dependent: tuple[sympy.Symbol, ...]
    constraints: tuple  # core.constraints.Constraint, in y
    branch: tuple[tuple[sympy.Symbol, float], ...] = ()
    closed_form: tuple[tuple[sympy.Symbol, sympy.Expr], ...] = ()
    choice: str = "given"
    configuration: tuple[tuple[sympy.Symbol, float], ...] = ()


@dataclass(frozen=True)
class Model:
    """A model file, loaded: the primitive, the connection and the effects."""

    name: str
    description: str
    path: str
    parameters: tuple[ParameterInfo, ...]
    primitive: Primitive
    coordinates: tuple[sympy.Symbol, ...]
    connection: Mapping[sympy.Symbol, sympy.Expr]
    effects: tuple[Effect, ...]
    initial: Mapping[sympy.Symbol, sympy.Expr] = field(default_factory=dict)
    content_hash: str = ""
    locations: Mapping[str, Location] = field(default_factory=dict)
    scenes: tuple = ()  # of :class:`~kronsub.model.scenes.Scene`, in file order
    implicit: ImplicitSpec | None = None  # constraints: g(y) = 0

    def derive(self, *, cache: bool = True) -> KnownSystem:
        """The equations of motion by projection onto the subspace (9'), (E), (F)."""
        import dataclasses

        from ..core.trigpoly import ExpansionTooLarge
        from .derive import derive_model

        try:
            system = derive_model(self, cache=cache)
        except ExpansionTooLarge as exc:
            raise exc.at(Location(self.path)) from None
        return dataclasses.replace(system, initial=dict(self.initial)) if self.initial else system

    def parameter_values(self) -> dict[sympy.Symbol, sympy.Expr]:
        """Default values of the parameters that have one."""
        return {p.symbol: p.value for p in self.parameters if p.value is not None}
