"""Coordinates held by configuration constraints beside velocity constraints, in numbers.

A system in its speeds (:mod:`.nonholonomic`) with configuration constraints ``g(x, t) = 0``
(25) keeps every coordinate in its state ``[x; u]``: the kinematic equations
``xdot = C u + d`` have ``G C = 0`` and ``G d + dg/dt = 0`` (the constraints' rates are rows of
``A``), so ``g`` is constant along the exact motion, and the dependent coordinates ``x_D`` (one
per constraint) follow the others. An integrator's error would let ``g`` drift; here ``x_D`` is
instead solved from ``g(x_K, x_D, t) = 0`` by Newton's method wherever the equations are
evaluated, started from the integrated ``x_D`` (no warm start to keep), as for a closed loop's
dependent coordinates (26). The integrated ``x_D`` is then only the starting guess and the
rows a run returns are put on ``g = 0`` the same way, so that ``g`` holds to Newton's tolerance
and ``A xdot + b = 0`` to rounding at every row, whatever the integrator's error.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .constraints import ConstraintFailure, NumericConstraints
from .known_system import KnownSystem
from .symbols import TIME

NEWTON_TOLERANCE = 1e-12
"""Newton's step below this (times 1 + |x_D|) ends the iteration: the next would be ~1e-24."""
NEWTON_STEPS = 50


class HeldCoordinates:
    """``x_D`` of a system in its speeds on ``g(x, t) = 0`` at fixed parameter ``values``
    (symbol -> number); ``held`` are their indices in the coordinates."""

    def __init__(self, system: KnownSystem, values: Mapping):
        s = system.speeds
        self.coordinates = tuple(system.coordinates)
        self.held = [self.coordinates.index(d) for d in s.dependent]
        self.numeric = NumericConstraints(s.holonomic, self.coordinates + (TIME,), dict(values))

    def project(self, t: float, q) -> np.ndarray:
        """``q`` with its held coordinates on ``g(q, t) = 0``, from their values in ``q``
        (raises :class:`~.constraints.ConstraintFailure`)."""
        y = np.append(np.asarray(q, dtype=float), float(t))
        return self.numeric.solve(y, self.held, tol=NEWTON_TOLERANCE, max_iter=NEWTON_STEPS)[:-1]

    def rows(self, t, Y) -> np.ndarray:
        """The rows ``[q; u]`` of a run with each ``q`` on ``g = 0`` (a row where Newton's
        method fails is kept as integrated)."""
        Y = np.array(Y, dtype=float)
        n = len(self.coordinates)
        for i, (ti, row) in enumerate(zip(np.atleast_1d(t), Y)):
            try:
                Y[i, :n] = self.project(float(ti), row[:n])
            except ConstraintFailure:
                pass
        return Y


def held_coordinates(system: KnownSystem, values: Mapping) -> HeldCoordinates | None:
    """The :class:`HeldCoordinates` of ``system``, or None when no configuration constraint
    stands beside its velocity constraints."""
    if system.speeds is None or not system.speeds.holonomic:
        return None
    return HeldCoordinates(system, values)


__all__ = ["HeldCoordinates", "NEWTON_STEPS", "NEWTON_TOLERANCE", "held_coordinates"]
