"""Circuit elements acting on a branch's charge: capacitor, resistor, voltage source, and the
electromechanical coupling of a DC machine.

Each acts along a ``charge``, an expression in the coordinates (a branch's ``q``, or a loop
charge of the subspace): a capacitor is a potential (its elastance ``1/C`` a stiffness), a
resistor Rayleigh's dissipation ``R i^2/2`` (a damping), a source a generalized force ``e(t)``
(a voltage), each ``f_a = (...) dq/dx^a``, projected like any force, ``fbar = Cᵀ f`` (8').
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..core.derivative import derivative
from ..core.symbols import velocity_symbol
from .base import Effect


def _gradient_and_rate(expression, coordinates):
    """``(d e/dx^a, edot)`` of an expression of the coordinates."""
    gradient = [derivative(expression, q) for q in coordinates]
    return gradient, sympy.Add(*[g * velocity_symbol(q) for g, q in zip(gradient, coordinates)])


@dataclass(frozen=True)
class Capacitor(Effect):
    """A capacitor on a charge: ``V = q^2/(2 C)``, the electric energy (the voltage across it,
    ``q/C``, opposes the current)."""

    charge: sympy.Expr = sympy.Integer(0)
    capacitance: sympy.Expr = sympy.Integer(1)

    def potential(self, primitive):
        return self.charge**2 / (2 * self.capacitance)


@dataclass(frozen=True)
class Resistor(Effect):
    """A resistor on a charge: Rayleigh's dissipation ``R i^2/2``, ``f_a = -R i di/dxdot^a``
    with ``i = qdot``; it dissipates the power ``R i^2``."""

    charge: sympy.Expr = sympy.Integer(0)
    resistance: sympy.Expr = sympy.Integer(0)

    def generalized_force(self, primitive):
        gradient, current = _gradient_and_rate(self.charge, primitive.coordinates)
        return [sympy.expand(-self.resistance * current * g) for g in gradient]

    def direct_force(self, primitive, coordinates, moved):
        """In the subspace: ``fbar = -R i dq/dxbar``, the charge carried to ``xbar``."""
        gradient, current = _gradient_and_rate(moved(self.charge), coordinates)
        resistance = moved(self.resistance)
        return [sympy.expand(-resistance * current * g) for g in gradient]


@dataclass(frozen=True)
class VoltageSource(Effect):
    """An electromotive force ``e(t)`` driving a charge: ``f_a = e dq/dx^a`` (a voltage is the
    generalized force of a charge); it delivers the power ``e i``."""

    charge: sympy.Expr = sympy.Integer(0)
    voltage: sympy.Expr = sympy.Integer(0)

    def generalized_force(self, primitive):
        gradient, _ = _gradient_and_rate(self.charge, primitive.coordinates)
        return [sympy.expand(self.voltage * g) for g in gradient]

    def direct_force(self, primitive, coordinates, moved):
        gradient, _ = _gradient_and_rate(moved(self.charge), coordinates)
        voltage = moved(self.voltage)
        return [sympy.expand(voltage * g) for g in gradient]


@dataclass(frozen=True)
class Gyrator(Effect):
    """A power-conserving coupling of two coordinates ``a``, ``b`` with constant ``k``:
    ``f = -k bdot da/dx + k adot db/dx``, whose power ``adot (-k bdot) + bdot (k adot)`` is
    zero (a skew, gyroscopic force). A DC machine: ``a`` the armature charge, ``b`` the shaft
    angle, the back-EMF ``-k omega`` and the torque ``k i``."""

    first: sympy.Expr = sympy.Integer(0)
    second: sympy.Expr = sympy.Integer(0)
    constant: sympy.Expr = sympy.Integer(0)

    def _force(self, first, second, constant, coordinates):
        ga, rate_a = _gradient_and_rate(first, coordinates)
        gb, rate_b = _gradient_and_rate(second, coordinates)
        return [sympy.expand(constant * (rate_a * b - rate_b * a)) for a, b in zip(ga, gb)]

    def generalized_force(self, primitive):
        return self._force(self.first, self.second, self.constant, primitive.coordinates)

    def direct_force(self, primitive, coordinates, moved):
        return self._force(moved(self.first), moved(self.second), moved(self.constant), coordinates)


__all__ = ["Capacitor", "Gyrator", "Resistor", "VoltageSource"]
