"""The contract of a library component: a known system of the simplest kind.

A component is data: it declares its coordinates, its parameters, its metric
``M(x)`` (the ``m_ab`` of (16)), its named points and its bodies (mass
distribution). It knows nothing of YAML, printing or integration.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import sympy

from ..errors import Location


def in_world(point, dimension: int) -> tuple:
    """``point`` in a world of ``dimension`` axes (at least its own): a point of the line lies on
    the x axis of the plane, a point of the plane in the ``z = 0`` plane of space (zeros appended).
    The one rule wherever points of different worlds meet: pins, springs and dampers
    (:func:`common_world`), ``pivot:``, a known system with parts on a line and in the plane."""
    return tuple(point) + (sympy.Integer(0),) * (dimension - len(point))


def common_world(a, b) -> tuple[tuple, tuple]:
    """Two points (named points' positions or fixed places) in the larger of their worlds (:func:`in_world`)."""
    dimension = max(len(a), len(b))
    return in_world(a, dimension), in_world(b, dimension)


POSITIVE, NONNEGATIVE, INERTIA, COUPLING = "positive", "nonnegative", "inertia", "coupling"
"""What a component needs of a value (:meth:`Component.requirements`): above zero (a length),
not below zero (a mass, a moment of inertia: zero is a massless part), an inertia tensor of
a body (principal moments not below zero, each at most the sum of the other two), or a
coupling no larger than what it couples (``L1 L2 - M^2`` not below zero: coupled coils)."""


@dataclass(frozen=True)
class Requirement:
    """``value`` (an expression, or a tensor, in the model's parameters) must meet ``kind``
    (:data:`POSITIVE`, :data:`NONNEGATIVE`, :data:`INERTIA`); ``what`` names it, ``location`` is
    where it is written (checked by :mod:`kronsub.model.requirements`)."""

    what: str
    value: object
    kind: str
    location: Location | None = None


@dataclass(frozen=True)
class ParameterSpec:
    """A parameter a component takes; ``default`` is an expression in the other parameters,
    ``sign`` what the physics needs of its value (:data:`POSITIVE`, :data:`NONNEGATIVE`)."""

    name: str
    description: str
    default: str | None = None
    unit: str = ""
    sign: str = ""


@dataclass(frozen=True)
class OptionSpec:
    """A choice a component offers among fixed names (``euler: ZXZ``); the first is the default.
    With ``letters``, the choice is a word of those letters, at most ``longest`` of them
    (``turns: ZXYYZ``), ``values`` holding the default alone."""

    name: str
    description: str
    values: tuple[str, ...]
    letters: str = ""
    longest: int = 0

    def allows(self, value: object) -> bool:
        """Whether ``value`` is one of the choices."""
        if not isinstance(value, str):
            return False
        if self.letters:
            return 0 < len(value) <= self.longest and all(c in self.letters for c in value)
        return value in self.values


@dataclass(frozen=True)
class Body:
    """A rigid body (or particle) of a component, for gravity and energy checks.

    ``centre`` is the world position of its mass centre, ``rotation`` the
    world-from-body rotation matrix (None for a particle), ``inertia`` the
    inertia about the centre in body axes (1x1 for planar bodies). ``name`` is empty for
    a component's own body; a known system names each of its bodies by the component it
    came from (``lower``, or ``pair.left`` a level down), so a model using it can say which.
    """

    mass: sympy.Expr
    centre: tuple[sympy.Expr, ...]
    rotation: sympy.Matrix | None = None
    inertia: sympy.Matrix | None = None
    name: str = ""


@dataclass(frozen=True)
class Component:
    """Base class of library components (subclasses set the class variables).

    An instance is a component *bound* to coordinate symbols and parameter
    expressions: ``x`` maps the component's local coordinate names to symbols,
    ``p`` its parameter names to expressions.
    """

    type_name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    coordinates: ClassVar[tuple[str, ...]] = ()
    parameters: ClassVar[tuple[ParameterSpec, ...]] = ()
    dimension: ClassVar[int] = 0  # dimension of the world its points live in
    rigid: ClassVar[bool] = False  # a rigid body: model files may fix points in it (``points:``)
    options: ClassVar[tuple[OptionSpec, ...]] = ()  # choices among names, keys beside ``type:``

    x: Mapping[str, sympy.Symbol] = field(default_factory=dict)
    p: Mapping[str, sympy.Expr] = field(default_factory=dict)
    extra_points: Mapping[str, tuple[sympy.Expr, ...]] = field(default_factory=dict)  # body-frame offsets
    choices: Mapping[str, str] = field(default_factory=dict)  # option name -> chosen value

    # -- to be declared by each component --------------------------------
    def metric(self) -> sympy.Matrix:
        """The metric ``m_ab(x)``, kinetic energy ``T = 1/2 m_ab xdot^a xdot^b`` (24)."""
        raise NotImplementedError

    def points(self) -> dict[str, tuple[sympy.Expr, ...]]:
        """Named points: world positions as functions of the coordinates (and of the
        parameters ``p``, nothing else: `ComponentPoints.symbols`)."""
        return {}

    def bodies(self) -> tuple[Body, ...]:
        """The mass distribution (used by gravity and by the energy checks)."""
        return ()

    def requirements(self) -> tuple[tuple[str, object, str], ...]:
        """``(parameter, value, kind)``: what the component needs of its parameters' values, the
        sign each :class:`ParameterSpec` declares; a subclass adds conditions among them (a 3-D
        inertia tensor, :data:`INERTIA`, named by its first entry)."""
        return tuple((ps.name, self.p[ps.name], ps.sign) for ps in self.parameters if ps.sign)

    # -- derived ---------------------------------------------------------
    def all_points(self) -> dict[str, tuple[sympy.Expr, ...]]:
        """The declared points and the model's own points fixed in the (first) body:
        ``centre + R offset`` for each body-frame offset in ``extra_points``."""
        points = dict(self.points())
        if self.extra_points:
            body = self.bodies()[0]
            centre = sympy.Matrix(body.centre)
            for name, offset in self.extra_points.items():
                points[name] = tuple(centre + body.rotation * sympy.Matrix(offset))
        return points

    @classmethod
    def chosen(cls, choices: Mapping[str, str]) -> type[Component]:
        """The class of a component with these option ``choices``: itself, unless an option
        sets its coordinates (a body's ``turns:``)."""
        return cls

    @property
    def coordinate_symbols(self) -> tuple[sympy.Symbol, ...]:
        return tuple(self.x[name] for name in self.coordinates)


class PointsOnRead(Mapping):
    """Named points built in full (``_build``) when first read."""

    def __init__(self):
        self._all: dict | None = None

    def _build(self) -> dict[str, tuple[sympy.Expr, ...]]:
        raise NotImplementedError

    def _built(self) -> dict[str, tuple[sympy.Expr, ...]]:
        if self._all is None:
            self._all = self._build()
        return self._all

    def __getitem__(self, label: str) -> tuple[sympy.Expr, ...]:
        return self._built()[label]

    def __iter__(self):
        return iter(self._built())

    def __len__(self) -> int:
        return len(self._built())

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._built()!r})"


class ComponentPoints(PointsOnRead):
    """A component's points (`Component.all_points`), built when first read, all at once.

    ``Mbar``, ``hbar`` and ``fbar`` (D), (E), (F) need none of them; the energies, the
    animation, a scene's outputs, the cache and the effects that name a point do. A planar
    body's ``x + u cos(a) - v sin(a)`` costs sympy about half a millisecond a body."""

    def __init__(self, component: Component):
        super().__init__()
        self._component = component

    def _build(self) -> dict[str, tuple[sympy.Expr, ...]]:
        return self._component.all_points()

    def symbols(self) -> set:
        """Every symbol a point may hold, without building the points: a component's points
        are functions of its coordinates, parameters and body-frame offsets alone."""
        component = self._component
        found = set(component.x.values())
        for value in [*component.p.values(), *(c for offset in component.extra_points.values() for c in offset)]:
            found |= sympy.sympify(value).free_symbols
        return found


def rotation2(angle: sympy.Expr) -> sympy.Matrix:
    """World-from-body rotation in the plane."""
    c, s = sympy.cos(angle), sympy.sin(angle)
    return sympy.Matrix([[c, -s], [s, c]])


__all__ = ["INERTIA", "NONNEGATIVE", "POSITIVE", "Body", "Component", "ComponentPoints", "OptionSpec", "ParameterSpec",
           "PointsOnRead", "Requirement", "common_world", "in_world", "rotation2"]
