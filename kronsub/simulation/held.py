"""Runs of systems in their speeds with configuration constraints beside the velocity
constraints (:mod:`kronsub.core.held`): the initial configuration put on ``g(x, 0) = 0`` (the
held coordinates by Newton's method from the values given, the others kept, the speeds free
already), and a run's rows put on ``g = 0`` as the generated right-hand side puts the states
it evaluates.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Collection

import numpy as np

from ..core.constraints import ConstraintFailure
from ..core.held import HeldCoordinates, held_coordinates
from ..core.known_system import KnownSystem
from ..errors import assignment
from .constrained import TOLERANCE, ConstraintError
from .values import RunValues

__all__ = ["diagnose", "held_of", "hold_start"]

NOTED = 1e-12  # a correction of the initial configuration above this (times 1 + |value|) is reported
NEARLY_SINGULAR = 1e-3  # dg/dx_D this small against dg/dx (relative, smallest singular value): x_D not fixed


def held_of(system: KnownSystem, values: RunValues) -> HeldCoordinates | None:
    """The held coordinates of ``system`` at the run's parameter values, or None."""
    return held_coordinates(system, {p.symbol: float(v) for p, v in zip(system.parameters, values.parameters)})


def hold_start(system: KnownSystem, values: RunValues, given: Collection[str] = (),
               held: HeldCoordinates | None = None) -> tuple[RunValues, list[str]]:
    """``values`` with the held coordinates of ``y0`` on ``g(x, 0) = 0``, and notes on the
    corrections; a held coordinate ``given`` (by name: ``--set``) that is more than
    :data:`~.constrained.TOLERANCE` off is refused, as a closed loop's dependent one is.
    ``held``: the held coordinates at the run's parameter values, when already made."""
    held = held if held is not None else held_of(system, values)
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
    notes = []
    for j in held.held:
        name, correction = system.coordinates[j].name, abs(q[j] - q0[j])
        if name in given and correction > TOLERANCE * (1 + abs(q0[j])):
            names = ", ".join(f"'{c.name}'" for c in system.speeds.holonomic)
            raise ConstraintError(f"{assignment('set', name, f'{q0[j]:g}')} is {correction:.3g} away from the configuration "
                                  f"constraints {names} (the nearest consistent value is {q[j]:.6g}); corrections "
                                  f"above {TOLERANCE:g} (1 + |value|) are refused")
        if correction > NOTED * (1 + abs(q0[j])):
            notes.append(f"{name} {q0[j]:.6g} -> {q[j]:.12g} (correction {correction:.3g})")
    return dataclasses.replace(values, y0=tuple(float(v) for v in np.concatenate([q, values.y0[n:]]))), notes


def diagnose(system: KnownSystem, held: HeldCoordinates, t: float, y) -> str | None:
    """Why a run stopped at ``(t, y)`` when the held coordinates are to blame: Newton's method
    on ``g = 0`` fails there, or ``G_D = dg/dx_D`` is nearly singular against ``G`` (the
    constraints no longer fix the held coordinates: a toggle of this choice); else None."""
    n = len(system.coordinates)
    q = np.asarray(y, dtype=float)[:n]
    names = ", ".join(f"'{c.name}'" for c in system.speeds.holonomic)
    dependent = ", ".join(d.name for d in system.speeds.dependent)
    where = ", ".join(f"{c.name}={v:.6g}" for c, v in zip(system.coordinates, q))
    hint = (f"the configuration constraints {names} do not fix {dependent} there (each holds the last coordinate "
            "listed in `coordinates:` whose column of dg/dx is independent: order `coordinates:` so that those "
            "are ones the constraints fix all along the motion)")
    G = held.numeric.jacobian(np.append(q, float(t)))[:, :n]
    if np.all(np.isfinite(G)) and G.size:
        ratio = np.linalg.svd(G[:, held.held], compute_uv=False)[-1] / max(np.linalg.norm(G, 2), 1e-300)
        if ratio < NEARLY_SINGULAR:
            return (f"dg/d({dependent}) is nearly singular (relative size {ratio:.2g}) at t = {t:.6g}, {where}: "
                    + hint)
    try:
        held.project(t, q)
    except ConstraintFailure as exc:
        return f"{exc.message} at t = {t:.6g}, {where}: " + hint
    return None
