"""Circuit branches as primitive systems: a branch's coordinate is its charge ``q``, its
velocity the current ``i = qdot``, its inductance the metric (magnetic energy
``T = 1/2 L_ab i^a i^b``, the electrical reading of (24)).

Kron's primitive network is the branches not interconnected; Kirchhoff's laws are the
connection (the mesh transformation, branch charges as combinations of loop charges, (7)),
so the projected metric ``Mbar = Cᵀ L C`` is the loop inductance matrix. Capacitors,
resistors and sources act on a branch's charge as effects (``effects/electrical.py``).
"""
from __future__ import annotations

import sympy

from .base import COUPLING, POSITIVE, Component, ParameterSpec

INDUCTANCE = ParameterSpec("inductance", "self-inductance of the branch", unit="H", sign=POSITIVE)

class Inductor(Component):
    """A branch with self-inductance ``L``: metric ``[L]``, energy ``L i^2/2``."""

    type_name = "inductor"
    summary = "circuit branch with self-inductance L (coordinate q, the charge; current i = qdot)"
    coordinates = ("q",)
    parameters = (INDUCTANCE,)

    def metric(self) -> sympy.Matrix:
        return sympy.Matrix([[self.p["inductance"]]])


class Branch(Component):
    """A branch without inductance (a capacitor's, a resistor's or a source's): its charge is
    a coordinate with a zero metric, which the connection must carry into loops that have
    inductance (else the projected metric is singular)."""

    type_name = "branch"
    summary = "circuit branch without inductance (coordinate q, the charge): carries capacitors, resistors, sources"
    coordinates = ("q",)

    def metric(self) -> sympy.Matrix:
        return sympy.zeros(1, 1)


class CoupledInductors(Component):
    """Two coils with mutual inductance ``M``: metric ``[[L1, M], [M, L2]]``, energy
    ``(L1 i1^2 + 2 M i1 i2 + L2 i2^2)/2``. ``M`` is negative when the coils are wound against
    each other (the dot convention)."""

    type_name = "coupled_inductors"
    summary = "two circuit branches coupled by mutual inductance M (coordinates q1, q2)"
    coordinates = ("q1", "q2")
    parameters = (
        ParameterSpec("inductance1", "self-inductance of the first coil", unit="H", sign=POSITIVE),
        ParameterSpec("inductance2", "self-inductance of the second coil", unit="H", sign=POSITIVE),
        ParameterSpec("mutual", "mutual inductance M, M^2 <= L1 L2", default="0", unit="H"),
    )

    def metric(self) -> sympy.Matrix:
        L1, L2, M = self.p["inductance1"], self.p["inductance2"], self.p["mutual"]
        return sympy.Matrix([[L1, M], [M, L2]])

    def requirements(self):
        """The signs, and ``L1 L2 - M^2`` not below zero (the magnetic energy is never
        negative), named by ``mutual``."""
        L1, L2, M = self.p["inductance1"], self.p["inductance2"], self.p["mutual"]
        return super().requirements() + (("mutual", L1 * L2 - M**2, COUPLING),)
