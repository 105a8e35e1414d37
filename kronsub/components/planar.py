"""Planar rigid bodies: free bodies (x, y, angle), rods, discs, pinned rods, flywheels.

Angles are counter-clockwise. A free body's ``angle`` turns its body axes
from the world axes; body-frame offsets of its points rotate with it.
"""
from __future__ import annotations

import sympy
from sympy import Rational, cos, sin

from .base import NONNEGATIVE, POSITIVE, Body, Component, OptionSpec, ParameterSpec, rotation2

MASS = ParameterSpec("mass", "mass of the body", unit="kg", sign=NONNEGATIVE)


class PlanarBody(Component):
    """A rigid body in the plane: ``M = diag(m, m, I)`` about its mass centre."""

    type_name = "planar_body"
    summary = "rigid body in the plane (x, y of the mass centre, angle); given inertia"
    coordinates = ("x", "y", "angle")
    parameters = (MASS, ParameterSpec("inertia", "moment of inertia about the mass centre", unit="kg m^2",
                                          sign=NONNEGATIVE))
    dimension = 2
    rigid = True

    def inertia(self) -> sympy.Expr:
        return self.p["inertia"]

    def body_points(self) -> dict[str, tuple[sympy.Expr, sympy.Expr]]:
        """Points fixed in the body, as offsets in body axes from the mass centre."""
        return {"centre": (sympy.Integer(0), sympy.Integer(0))}

    def metric(self):
        m = self.p["mass"]
        return sympy.diag(m, m, self.inertia())

    def points(self):
        x, y, a = self.x["x"], self.x["y"], self.x["angle"]
        c, s = sympy.cos(a), sympy.sin(a)
        return {name: (x + u * c - v * s, y + u * s + v * c) for name, (u, v) in self.body_points().items()}

    def bodies(self):
        return (Body(self.p["mass"], (self.x["x"], self.x["y"]), rotation2(self.x["angle"]),
                     sympy.Matrix([[self.inertia()]])),)


class Rod(PlanarBody):
    """A rod, ends ``a`` (at -length/2 along its axis) and ``b`` (at +length/2).

    Its axis is the body x axis, so ``angle`` is the axis' angle from the world x axis; with
    ``axis: down`` it is the body -y axis, so ``angle`` is measured from the downward vertical
    as a ``pinned_rod``'s (Hoffmann's System I): ``a`` is then the upper end at rest.
    """

    type_name = "rod"
    summary = "planar rod (x, y of its centre, angle of its axis); ends a, b"
    parameters = (MASS, ParameterSpec("length", "length", unit="m", sign=POSITIVE),
                  ParameterSpec("inertia", "moment of inertia about the centre", "mass*length**2/12", "kg m^2",
                                NONNEGATIVE))
    options = (OptionSpec("axis", "the rod's axis in its body frame: body x (its angle from the world x axis) "
                                  "or down, body -y (its angle from the downward vertical)", ("x", "down")),)

    def body_points(self):
        h = self.p["length"] / 2
        z = sympy.Integer(0)
        if self.choices.get("axis", "x") == "down":
            return {"centre": (z, z), "a": (z, h), "b": (z, -h)}
        return {"centre": (z, z), "a": (-h, z), "b": (h, z)}


class Disc(PlanarBody):
    """A disc; ``rim`` is the point on its body x axis."""

    type_name = "disc"
    summary = "planar disc (x, y of its centre, angle); point rim on its body x axis"
    parameters = (MASS, ParameterSpec("radius", "radius", unit="m", sign=POSITIVE),
                  ParameterSpec("inertia", "moment of inertia about the centre", "mass*radius**2/2", "kg m^2",
                                NONNEGATIVE))

    def body_points(self):
        z = sympy.Integer(0)
        return {"centre": (z, z), "rim": (self.p["radius"], z)}


class PinnedRod(Component):
    """Rod turning about a fixed pivot at one end (compound pendulum).

    ``angle`` is measured from the downward vertical (-y), counter-clockwise:
    the tip is at ``pivot + length (sin angle, -cos angle)``.
    Metric ``I + m (length/2)^2`` (the first entry of (16)).
    """

    type_name = "pinned_rod"
    summary = "rod pinned at one end (angle from the downward vertical)"
    coordinates = ("angle",)
    parameters = (MASS, ParameterSpec("length", "length", unit="m", sign=POSITIVE),
                  ParameterSpec("inertia", "moment of inertia about the centre", "mass*length**2/12", "kg m^2",
                                NONNEGATIVE),
                  ParameterSpec("pivot_x", "x of the fixed pivot", "0", "m"),
                  ParameterSpec("pivot_y", "y of the fixed pivot", "0", "m"))
    dimension = 2
    rigid = True

    def metric(self):
        m, L = self.p["mass"], self.p["length"]
        return sympy.Matrix([[self.p["inertia"] + m * (L / 2) ** 2]])

    def _along(self, distance):
        a = self.x["angle"]
        return (self.p["pivot_x"] + distance * sin(a), self.p["pivot_y"] - distance * cos(a))

    def points(self):
        L = self.p["length"]
        return {"pivot": self._along(0), "centre": self._along(L * Rational(1, 2)), "tip": self._along(L)}

    def bodies(self):
        rotation = rotation2(self.x["angle"] - sympy.pi / 2)
        return (Body(self.p["mass"], self.points()["centre"], rotation, sympy.Matrix([[self.p["inertia"]]])),)


class Flywheel(Component):
    """A rotor turning about a fixed axis: ``T = J angledot^2 / 2``."""

    type_name = "flywheel"
    summary = "rotor on a fixed axis (angle)"
    coordinates = ("angle",)
    parameters = (ParameterSpec("inertia", "moment of inertia about the axis", unit="kg m^2",
                                sign=NONNEGATIVE),)
    dimension = 0

    def metric(self):
        return sympy.Matrix([[self.p["inertia"]]])

    def bodies(self):
        z = sympy.Integer(0)
        return (Body(z, (z, z), rotation2(self.x["angle"]), sympy.Matrix([[self.p["inertia"]]])),)


__all__ = ["Disc", "Flywheel", "MASS", "PinnedRod", "PlanarBody", "Rod"]
