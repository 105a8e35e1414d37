"""A rigid body in space, parametrised by its centre and Z-Y-X Euler angles."""
from __future__ import annotations

import sympy
from sympy import cos, sin

from .base import Body, Component, ParameterSpec

# the products of inertia enter the tensor with a plus sign (SymPy's inertia())
PRODUCT_OF_INERTIA = ("product of inertia, the tensor entry as given in [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], "
                      "[Ixz, Iyz, Izz]] (SymPy's inertia() convention); for P = integral of {} dm give -P")


def euler_zyx(psi, theta, phi) -> sympy.Matrix:
    """World-from-body rotation ``Rz(psi) Ry(theta) Rx(phi)`` (yaw, pitch, roll)."""
    rz = sympy.Matrix([[cos(psi), -sin(psi), 0], [sin(psi), cos(psi), 0], [0, 0, 1]])
    ry = sympy.Matrix([[cos(theta), 0, sin(theta)], [0, 1, 0], [-sin(theta), 0, cos(theta)]])
    rx = sympy.Matrix([[1, 0, 0], [0, cos(phi), -sin(phi)], [0, sin(phi), cos(phi)]])
    return rz * ry * rx


class RigidBody3D(Component):
    """Rigid body in space: centre (x, y, z) and Z-Y-X Euler angles (psi, theta, phi).

    Body angular velocity ``omega = E (psidot, thetadot, phidot)`` with
    ``E = [[-sin th, 0, 1], [cos th sin ph, cos ph, 0], [cos th cos ph, -sin ph, 0]]``,
    so the metric is ``diag(m, m, m) (+) E^T I E``; it is singular at
    ``theta = +-pi/2`` (gimbal lock).

    The inertia tensor about the mass centre in body axes is, as given,
    ``I = [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]]`` (SymPy's ``inertia()``
    convention): the products of inertia enter with a plus sign. A textbook product of
    inertia defined as the integral ``P_xy = int x y dm`` is the entry ``-P_xy``: give
    ``Ixy: -P_xy``.
    """

    type_name = "rigid_body3d"
    summary = "rigid body in space (x, y, z, Z-Y-X Euler angles psi, theta, phi)"
    coordinates = ("x", "y", "z", "psi", "theta", "phi")
    parameters = (
        ParameterSpec("mass", "mass", unit="kg"),
        ParameterSpec("Ixx", "moment of inertia about body x", unit="kg m^2"),
        ParameterSpec("Iyy", "moment of inertia about body y", unit="kg m^2"),
        ParameterSpec("Izz", "moment of inertia about body z", unit="kg m^2"),
        ParameterSpec("Ixy", PRODUCT_OF_INERTIA.format("x y"), "0", "kg m^2"),
        ParameterSpec("Iyz", PRODUCT_OF_INERTIA.format("y z"), "0", "kg m^2"),
        ParameterSpec("Ixz", PRODUCT_OF_INERTIA.format("x z"), "0", "kg m^2"),
    )
    dimension = 3
    rigid = True

    def inertia(self) -> sympy.Matrix:
        p = self.p
        return sympy.Matrix([[p["Ixx"], p["Ixy"], p["Ixz"]],
                             [p["Ixy"], p["Iyy"], p["Iyz"]],
                             [p["Ixz"], p["Iyz"], p["Izz"]]])

    def metric(self):
        th, ph = self.x["theta"], self.x["phi"]
        E = sympy.Matrix([[-sin(th), 0, 1],
                          [cos(th) * sin(ph), cos(ph), 0],
                          [cos(th) * cos(ph), -sin(ph), 0]])
        rot = (E.T * self.inertia() * E).applyfunc(sympy.expand)
        return sympy.diag(self.p["mass"] * sympy.eye(3), rot)

    def rotation(self) -> sympy.Matrix:
        return euler_zyx(self.x["psi"], self.x["theta"], self.x["phi"])

    def points(self):
        return {"centre": (self.x["x"], self.x["y"], self.x["z"])}

    def bodies(self):
        return (Body(self.p["mass"], self.points()["centre"], self.rotation(), self.inertia()),)
