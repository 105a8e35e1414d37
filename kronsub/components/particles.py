"""Particles: point masses in Cartesian, polar and spherical coordinates."""
from __future__ import annotations

import sympy
from sympy import cos, sin

from .base import NONNEGATIVE, Body, Component, ParameterSpec

MASS = ParameterSpec("mass", "mass of the particle", unit="kg", sign=NONNEGATIVE)


class _Cartesian(Component):
    """A point mass in Cartesian coordinates: constant metric ``m * identity``."""

    parameters = (MASS,)

    def metric(self) -> sympy.Matrix:
        return self.p["mass"] * sympy.eye(len(self.coordinates))

    def points(self):
        return {"centre": self.coordinate_symbols}

    def bodies(self):
        return (Body(self.p["mass"], self.coordinate_symbols),)


class Particle1D(_Cartesian):
    type_name = "particle1d"
    summary = "point mass on a line (coordinate x)"
    coordinates = ("x",)
    dimension = 1


class Particle2D(_Cartesian):
    type_name = "particle2d"
    summary = "point mass in the plane (coordinates x, y)"
    coordinates = ("x", "y")
    dimension = 2


class Particle3D(_Cartesian):
    type_name = "particle3d"
    summary = "point mass in space (coordinates x, y, z)"
    coordinates = ("x", "y", "z")
    dimension = 3


class ParticlePolar(Component):
    """Point mass in plane polar coordinates: ``T = m/2 (rdot^2 + r^2 angledot^2)``."""

    type_name = "particle_polar"
    summary = "point mass in plane polar coordinates (r, angle from the x axis)"
    coordinates = ("r", "angle")
    parameters = (MASS,)
    dimension = 2

    def metric(self):
        m, r = self.p["mass"], self.x["r"]
        return sympy.diag(m, m * r**2)

    def points(self):
        r, a = self.x["r"], self.x["angle"]
        return {"centre": (r * cos(a), r * sin(a))}

    def bodies(self):
        return (Body(self.p["mass"], self.points()["centre"]),)


class ParticleSpherical(Component):
    """Point mass in spherical coordinates: polar angle ``theta`` from +z, azimuth ``phi``."""

    type_name = "particle_spherical"
    summary = "point mass in spherical coordinates (r, theta from +z, phi about z)"
    coordinates = ("r", "theta", "phi")
    parameters = (MASS,)
    dimension = 3

    def metric(self):
        m, r, th = self.p["mass"], self.x["r"], self.x["theta"]
        return sympy.diag(m, m * r**2, m * r**2 * sin(th) ** 2)

    def points(self):
        r, th, ph = self.x["r"], self.x["theta"], self.x["phi"]
        return {"centre": (r * sin(th) * cos(ph), r * sin(th) * sin(ph), r * cos(th))}

    def bodies(self):
        return (Body(self.p["mass"], self.points()["centre"]),)


__all__ = ["MASS", "Particle1D", "Particle2D", "Particle3D", "ParticlePolar", "ParticleSpherical"]
