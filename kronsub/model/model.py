"""The parsed model: immutable, validated, with every expression already in sympy.

Data flows one way: YAML -> :class:`Model` -> primitive -> subspace ->
equations. Deriving returns a new :class:`~kronsub.core.known_system.KnownSystem`.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field
from typing import Mapping

import sympy

from ..components.base import Requirement
from ..core.finite import state_values
from ..core.known_system import Constraint, KnownSystem, ParameterInfo
from ..core.primitive import Primitive
from ..effects.base import Effect
from ..effects.elements import Damper, squared_distance
from ..errors import Location, Problem
from .derive import content_key, derive_model
from .nonholonomic import VelocitySpec
from .scenes import Scene
from .file_reading import SourceFile


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
    constraints: tuple[Constraint, ...]  # in y
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
    key_texts: tuple[str, ...] = ()  # what `content_hash` is made of: the file's text, its sub-models' keys
    locations: Mapping[str, Location] = field(default_factory=dict)
    scenes: tuple[Scene, ...] = ()  # in file order
    implicit: ImplicitSpec | None = None  # constraints: g(y) = 0
    requirements: tuple[Requirement, ...] = ()  # checked on values
    source: SourceFile | None = None  # the file as read (None when its text was given)
    uses: tuple[SourceFile, ...] = ()  # the model files it uses as known systems, recursively, each once
    joints: tuple = ()  # where the joints of `constraints:` act (model.constraints.Joint), for drawing
    velocity: VelocitySpec | None = None  # velocity_constraints: xdot = C u + d
    currents: Mapping[str, str] = field(default_factory=dict)  # charge coordinate -> its current's name (model/currents.py)

    @functools.cached_property
    def content_hash(self) -> str:
        """The model's cache key (:func:`~kronsub.model.derive.content_key`), made when first
        asked for: a derivation without the cache never needs it (nor hashes kronsub's code)."""
        return content_key(*self.key_texts) if self.key_texts else ""

    def derive(self, *, cache: bool = True) -> KnownSystem:
        """The equations of motion by projection onto the subspace (9'), (E), (F)."""
        system = derive_model(self, cache=cache)  # in the active work budget, or a default one
        return dataclasses.replace(system, initial=dict(self.initial)) if self.initial else system

    def parameter_values(self) -> dict[sympy.Symbol, sympy.Expr]:
        """Default values of the parameters that have one."""
        return {p.symbol: p.value for p in self.parameters if p.value is not None}

    def coincident_ends(self, system: KnownSystem, t: float, y, param) -> Problem | None:
        """The first spring (with a rest length) or damper of this model, switched on in
        ``system``, whose two ends coincide at time ``t``, state ``y = [q; qdot]`` and parameter
        values ``param`` (in the order of ``system.parameters``): there its force points along
        ``(p_b - p_a)/|p_b - p_a|``, which is 0/0, so the equations are NaN. Reported at the
        effect's entry; None when no such effect meets its other end (or with implicit
        constraints, whose dependent coordinates are not in ``y``)."""
        q = system.coordinates
        values = state_values(system, t, y, param)
        for effect in self.effects:
            square = squared_distance(self.primitive, effect)
            if square is None or effect.name not in system.effect_forces:
                continue
            square = sympy.sympify(square).xreplace(dict(self.connection)).xreplace(values)
            if square.free_symbols or not square.is_number:
                continue
            try:
                distance = math.sqrt(float(square))  # in doubles: 0 where C divides by 0
            except (TypeError, ValueError, OverflowError):
                continue
            if distance != 0.0:
                continue
            kind = "damper" if isinstance(effect, Damper) else "spring"
            state = ", ".join(f"{s.name}={float(v):.6g}" for s, v in zip(q, y))
            hint = ("move one end, or start from a state where the ends are apart; a spring of rest length 0 "
                    "(leave out `length:`) pulls with k*d and is defined where its ends meet"
                    if kind == "spring" else
                    "move one end, or start from a state where the ends are apart: a damper acts along the "
                    "line between its ends, which two coincident ends do not have")
            return Problem(self.locations.get(f"effect:{effect.name}", Location(self.path)),
                           f"the ends of {kind} '{effect.name}' coincide at t = {float(t):.6g} ({state}): its "
                           "force is along the line between them, which has no direction there (0/0)", hint)
        return None


__all__ = ["ImplicitSpec", "Model"]
