"""The energy of a run with circuit parts split by kind, and the power its dissipation takes.

The kinetic energy ``T = 1/2 Mbar_ab qdot^a qdot^b`` (24) holds the inductors' magnetic
energy ``1/2 iᵀ L i`` over the branch currents ``i = d x_c(xbar)/dt`` (the charges ``x_c`` of
the circuit parts carried by the connection (7)); the potential ``V`` holds the capacitors'
electric energy ``q^2/(2 C)``. What is left of ``T + V`` is mechanical. The dissipated power
is ``-fbarᵀ qdot`` of the resistors and dampers (twice Rayleigh's function for a linear one),
the effects' kinds recorded by the derived system (:mod:`kronsub.model.energy_kinds`, a known
system's own effects among them), so that ``d/dt (T + V) = P_sources - P_dissipated - P_loads`` along a run.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy

from ..core.known_system import KnownSystem
from ..core.derivative import derivative
from ..core.symbols import TIME
from ..model.currents import primitive_charges
from ..model.energy_kinds import DISSIPATIVE, ELECTRIC

COLUMNS = ("magnetic_energy", "electric_energy", "mechanical_energy", "dissipated_power")


@dataclass(frozen=True)
class EnergySplit:
    """The columns as one function of ``(q, qdot, p, t)``."""

    function: object  # (q..., qdot..., p..., t) -> (magnetic, electric, mechanical, dissipated)

    def columns(self, t, Y, param) -> np.ndarray:
        """The rows of :data:`COLUMNS` at the times ``t`` and states ``Y`` (one per row)."""
        Y = np.asarray(Y, dtype=float).reshape(len(t), -1)
        p = np.asarray(param, dtype=float).tolist()
        return np.array([self._row(time, y, p) for time, y in zip(np.asarray(t, dtype=float).tolist(), Y.tolist())],
                        dtype=float).reshape(len(t), len(COLUMNS))

    def _row(self, time: float, y: list, p: list) -> list:
        """One row; NaN where it has no finite value (a capacitance through zero: a division by zero)."""
        try:
            return self.function(*y, *p, time)
        except (ArithmeticError, ValueError):
            return [float("nan")] * len(COLUMNS)


def energy_split(model, system: KnownSystem) -> EnergySplit | None:
    """The split of ``system`` (derived from ``model``), or None when the model has no circuit
    part, or is a closed loop whose dependent coordinates have no closed form (node equations
    have one: their charges are then written in the loop charges)."""
    transition = system.transition
    if model is None or transition is None:
        return None
    charges = primitive_charges(model.primitive)
    if not charges:
        return None
    resolved = closed_forms(system)
    if resolved is None:
        return None
    connection = {x: sympy.sympify(image).xreplace(resolved) for x, image in transition.connection}
    index = {x: a for a, x in enumerate(transition.primitive_coordinates)}
    qdot = sympy.Matrix(system.velocities)
    # i = dx_c/dxbar qdot, without a drive's dx_c/dt (as T is 1/2 qdotᵀ Mbar qdot)
    currents = sympy.Matrix([sympy.Add(*[derivative(connection[x], q) * v for q, v in zip(system.coordinates, qdot)])
                             for x in charges])
    inductance = transition.primitive_metric.extract([index[x] for x in charges], [index[x] for x in charges])
    magnetic = sympy.expand((currents.T * inductance.xreplace(connection) * currents)[0, 0] / 2)
    kinds = system.effect_kinds
    electric = sympy.Add(*[v for label, v in system.effect_potentials.items() if kinds.get(label) == ELECTRIC])
    dissipated = sympy.Add(*[-(f.T * qdot)[0, 0] for label, f in system.effect_forces.items()
                             if kinds.get(label) == DISSIPATIVE])
    mechanical = sympy.expand(system.kinetic_energy - magnetic) + (system.potential_energy - electric)
    args = [*system.coordinates, *system.velocities, *(p.symbol for p in system.parameters), TIME]
    columns = [sympy.sympify(e).xreplace(resolved) for e in (magnetic, electric, mechanical, dissipated)]
    return EnergySplit(sympy.lambdify(args, columns, "math"))


def closed_forms(system: KnownSystem) -> dict | None:
    """What the named intermediates of a closed loop are in the coordinates, where its dependent
    coordinates have closed forms ``y_d = y_d(xbar)`` (Kirchhoff's node equations, linear):
    ``y_d`` and ``Lambda = dy_d/dxbar`` (26)-(29); ``{}`` without constraints, None when some
    dependent coordinate has none (the split is not made)."""
    imp = system.implicit
    if imp is None:
        return {}
    closed = dict(imp.closed_form)
    if set(imp.dependent) - set(closed):
        return None
    resolved = dict(closed)
    for a, d in enumerate(imp.dependent):
        for j, q in enumerate(imp.independent):
            resolved[imp.sensitivities[a, j]] = derivative(closed[d], q)
    return resolved


def charge_coordinates(system: KnownSystem) -> frozenset[str]:
    """The names of the generalized coordinates that are branch charges: the loop charges
    (the derived system's record, :mod:`kronsub.model.currents`)."""
    return frozenset(q.name for q in system.coordinates if q.name in system.currents)


__all__ = ["COLUMNS", "EnergySplit", "charge_coordinates", "closed_forms", "energy_split"]
