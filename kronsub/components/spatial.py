"""A rigid body in space, parametrised by its centre and three Euler angles (Z-Y-X unless
the model chooses another of the twelve sequences with ``euler:``), or by its centre and a
chain of turns about its own axes (``turned_body``, ``turns:``)."""
from __future__ import annotations

from typing import ClassVar

import sympy
from sympy import cos, sin

from .base import INERTIA, NONNEGATIVE, Body, Component, OptionSpec, ParameterSpec

SEQUENCES = ("ZYX", "ZXY", "YXZ", "YZX", "XYZ", "XZY",  # Tait-Bryan: three different axes
             "ZXZ", "ZYZ", "XYX", "XZX", "YXY", "YZY")  # proper Euler: first axis repeated
"""The twelve Euler sequences of rotations about body axes (intrinsic), first rotation first."""

# the products of inertia enter the tensor with a plus sign (SymPy's inertia())
PRODUCT_OF_INERTIA = ("product of inertia, the tensor entry as given in [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], "
                      "[Ixz, Iyz, Izz]] (SymPy's inertia() convention); for P = integral of {} dm give -P")


def axis_rotation(axis: str, angle) -> sympy.Matrix:
    """Rotation by ``angle`` about the coordinate axis ``X``, ``Y`` or ``Z``."""
    c, s = cos(angle), sin(angle)
    if axis == "X":
        return sympy.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "Y":
        return sympy.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return sympy.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def euler_rotation(sequence: str, psi, theta, phi) -> sympy.Matrix:
    """World-from-body rotation ``R_a(psi) R_b(theta) R_c(phi)`` for the sequence ``abc``."""
    a, b, c = sequence
    return axis_rotation(a, psi) * axis_rotation(b, theta) * axis_rotation(c, phi)


def euler_rates(sequence: str, theta, phi) -> sympy.Matrix:
    """``E`` with body angular velocity ``omega = E (psidot, thetadot, phidot)``: the columns
    are the three rotation axes seen in the body, ``R_c(phi)^T R_b(theta)^T e_a``,
    ``R_c(phi)^T e_b`` and ``e_c``."""
    a, b, c = sequence
    unit = {k: sympy.Matrix([int(k == "X"), int(k == "Y"), int(k == "Z")]) for k in "XYZ"}
    rc, rb = axis_rotation(c, phi).T, axis_rotation(b, theta).T
    return sympy.Matrix.hstack(rc * rb * unit[a], rc * unit[b], unit[c])


def turn_rates(axes: str, angles) -> sympy.Matrix:
    """``E`` (3 x n) with body angular velocity ``omega = E (angle_1dot, ..., angle_ndot)`` for the
    rotation ``R_a1(angle_1) ... R_an(angle_n)`` (turns about the body's own axes, first turn
    first): column ``j`` is the axis of turn ``j`` seen in the body,
    ``R_an(angle_n)^T ... R_a(j+1)(angle_(j+1))^T e_aj``. Three turns are :func:`euler_rates`."""
    unit = {k: sympy.Matrix([int(k == "X"), int(k == "Y"), int(k == "Z")]) for k in "XYZ"}
    columns = []
    after = sympy.eye(3)  # (R_(j+1) ... R_n)^T, built from the last turn back
    for axis, angle in reversed(tuple(zip(axes, angles))):
        columns.append(after * unit[axis])
        after = after * axis_rotation(axis, angle).T
    return sympy.Matrix.hstack(*reversed(columns))


class RigidBody3D(Component):
    """Rigid body in space: centre (x, y, z) and Euler angles (psi, theta, phi).

    The rotation is ``R_a(psi) R_b(theta) R_c(phi)`` for the sequence ``abc`` chosen by
    ``euler:`` (default ``ZYX``: yaw, pitch, roll). Body angular velocity
    ``omega = E (psidot, thetadot, phidot)``; for Z-Y-X
    ``E = [[-sin th, 0, 1], [cos th sin ph, cos ph, 0], [cos th cos ph, -sin ph, 0]]``.
    The metric is ``diag(m, m, m) (+) E^T I E``; it is singular where ``E`` is (gimbal
    lock): ``theta = +-pi/2`` for the six sequences of three different axes, ``theta = 0, pi``
    for the six with the first axis repeated (Z-X-Z...).

    The inertia tensor about the mass centre in body axes is, as given,
    ``I = [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]]`` (SymPy's ``inertia()``
    convention): the products of inertia enter with a plus sign. A textbook product of
    inertia defined as the integral ``P_xy = int x y dm`` is the entry ``-P_xy``: give
    ``Ixy: -P_xy``.
    """

    type_name = "rigid_body3d"
    summary = "rigid body in space (x, y, z, Euler angles psi, theta, phi; Z-Y-X unless `euler:` says)"
    coordinates = ("x", "y", "z", "psi", "theta", "phi")
    parameters = (
        ParameterSpec("mass", "mass", unit="kg", sign=NONNEGATIVE),
        ParameterSpec("Ixx", "moment of inertia about body x", unit="kg m^2"),
        ParameterSpec("Iyy", "moment of inertia about body y", unit="kg m^2"),
        ParameterSpec("Izz", "moment of inertia about body z", unit="kg m^2"),
        ParameterSpec("Ixy", PRODUCT_OF_INERTIA.format("x y"), "0", "kg m^2"),
        ParameterSpec("Iyz", PRODUCT_OF_INERTIA.format("y z"), "0", "kg m^2"),
        ParameterSpec("Ixz", PRODUCT_OF_INERTIA.format("x z"), "0", "kg m^2"),
    )
    options: ClassVar[tuple[OptionSpec, ...]] = (
        OptionSpec("euler", "the Euler sequence of (psi, theta, phi), rotations about body axes", SEQUENCES),
    )
    dimension = 3
    rigid = True

    @property
    def sequence(self) -> str:
        return self.choices.get("euler", SEQUENCES[0])

    def inertia(self) -> sympy.Matrix:
        p = self.p
        return sympy.Matrix([[p["Ixx"], p["Ixy"], p["Ixz"]],
                             [p["Ixy"], p["Iyy"], p["Iyz"]],
                             [p["Ixz"], p["Iyz"], p["Izz"]]])

    def requirements(self):
        """The mass's sign, and the tensor's: that of a body (the moments' signs with it)."""
        return super().requirements() + (("Ixx", self.inertia(), INERTIA),)

    def metric(self):
        E = euler_rates(self.sequence, self.x["theta"], self.x["phi"])
        rot = (E.T * self.inertia() * E).applyfunc(sympy.expand)
        return sympy.diag(self.p["mass"] * sympy.eye(3), rot)

    def rotation(self) -> sympy.Matrix:
        return euler_rotation(self.sequence, self.x["psi"], self.x["theta"], self.x["phi"])

    def points(self):
        return {"centre": (self.x["x"], self.x["y"], self.x["z"])}

    def bodies(self):
        return (Body(self.p["mass"], self.points()["centre"], self.rotation(), self.inertia()),)


MOST_TURNS = 8
"""The longest chain of turns a ``turned_body`` takes (a bicycle's front wheel needs six)."""


class TurnedBody(RigidBody3D):
    """Rigid body in space placed by its centre (x, y, z) and a chain of turns about its own
    axes, ``turns: ZXYYZ`` (default ``ZYX``), one coordinate each: ``turn1``, ``turn2``, ...

    The rotation is ``R = R_a1(turn1) R_a2(turn2) ...`` (world-from-body, first turn first), the
    body angular velocity ``omega = E turndot`` (:func:`turn_rates`), the metric
    ``diag(m, m, m) (+) E^T I E`` (9'), (D), as for :class:`RigidBody3D` (whose three Euler angles
    are the chain of three turns). A turn the connection holds at a constant (a head angle, a
    tilt) places the body's axes where its inertia is easiest given; more than three turns make
    the metric singular in the turns themselves, which the connection takes away (it is the
    metric's projection, ``C^T m C``, that must be regular). Inertia as :class:`RigidBody3D`'s.
    """

    type_name = "turned_body"
    summary = ("rigid body in space (x, y, z, and turn1, turn2, ... about its own axes as `turns:` says; "
               "ZYX unless it says)")
    coordinates = ("x", "y", "z", "turn1", "turn2", "turn3")
    options: ClassVar[tuple[OptionSpec, ...]] = (
        OptionSpec("turns", "the axes of the body's turns about its own axes, first turn first, one "
                   "coordinate turn1, turn2, ... each", ("ZYX",), letters="XYZ", longest=MOST_TURNS),
    )

    @classmethod
    def chosen(cls, choices):
        axes = choices.get("turns", cls.options[0].values[0])
        if axes == cls.options[0].values[0]:
            return cls
        turns = tuple(f"turn{k + 1}" for k in range(len(axes)))
        return type(cls.__name__, (cls,), {"coordinates": ("x", "y", "z") + turns, "__module__": cls.__module__})

    @property
    def axes(self) -> str:
        return self.choices.get("turns", self.options[0].values[0])

    def angles(self) -> tuple[sympy.Symbol, ...]:
        return tuple(self.x[name] for name in self.coordinates[3:])

    def metric(self):
        E = turn_rates(self.axes, self.angles())
        rot = (E.T * self.inertia() * E).applyfunc(sympy.expand)
        return sympy.diag(self.p["mass"] * sympy.eye(3), rot)

    def rotation(self) -> sympy.Matrix:
        R = sympy.eye(3)
        for axis, angle in zip(self.axes, self.angles()):
            R = R * axis_rotation(axis, angle)
        return R


__all__ = ["MOST_TURNS", "PRODUCT_OF_INERTIA", "SEQUENCES", "RigidBody3D", "TurnedBody", "axis_rotation",
           "euler_rates", "euler_rotation", "turn_rates"]
