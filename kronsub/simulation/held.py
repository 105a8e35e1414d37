"""Runs of systems in their speeds with configuration constraints beside the velocity
constraints (:mod:`kronsub.core.held`): the initial configuration put on ``g(x, 0) = 0`` (the
held coordinates by Newton's method from the values given, the others kept, the speeds free
already), and a run's rows put on ``g = 0`` as the generated right-hand side puts the states
it evaluates.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..core.constraints import ConstraintFailure
from ..core.held import HeldCoordinates, held_coordinates
from ..core.known_system import KnownSystem
from .constrained import ConstraintError
from .values import RunValues

__all__ = ["held_of", "hold_start"]

NOTED = 1e-12  # a correction of the initial configuration above this (times 1 + |value|) is reported


def held_of(system: KnownSystem, values: RunValues) -> HeldCoordinates | None:
    """The held coordinates of ``system`` at the run's parameter values, or None."""
    return held_coordinates(system, {p.symbol: float(v) for p, v in zip(system.parameters, values.parameters)})


def hold_start(system: KnownSystem, values: RunValues) -> tuple[RunValues, list[str]]:
    """``values`` with the held coordinates of ``y0`` on ``g(x, 0) = 0``, and notes on the corrections."""
    held = held_of(system, values)
    if held is None:
        return values, []
    n = len(system.coordinates)
    q0 = np.array(values.y0[:n], dtype=float)
    try:
        q = held.project(0.0, q0)
    except ConstraintFailure as exc:
        names = ", ".join(f"'{c.name}'" for c in system.speeds.holonomic)
        raise ConstraintError(f"the initial configuration violates the configuration constraints {names} and "
                              f"Newton's method finds none near it ({exc.message})") from None
    notes = [f"{system.coordinates[j].name} {q0[j]:.6g} -> {q[j]:.12g} (correction {abs(q[j] - q0[j]):.3g})"
             for j in held.held if abs(q[j] - q0[j]) > NOTED * (1 + abs(q0[j]))]
    return dataclasses.replace(values, y0=tuple(float(v) for v in np.concatenate([q, values.y0[n:]]))), notes
