"""The power a prescribed motion puts in, ``P = s^T R`` (:mod:`..core.rheonomic`), per row of a run.

With the drive's velocity ``s = dx/dt`` and the reaction on the primitive
``R = M xddot + h - f`` (``C^T R = 0`` along the motion, (C)), ``P`` is the rate at which the
drive does work on the primitive: ``d(T + V)/dt = P`` for ``T = 1/2 xdot^T M xdot`` with the
drive's velocity in ``xdot`` and forces from a potential. ``xbarddot`` comes from the
equations ``Mbar xbarddot = fbar - hbar`` (10') at each row.
"""
from __future__ import annotations

import numpy as np
import sympy

from ..core.known_system import KnownSystem
from ..core.rheonomic import depends_on_time, project_rheonomic
from ..core.symbols import TIME

COLUMN = "drive_power"


def driven(system: KnownSystem) -> bool:
    """A connection in time ``x = x(xbar, t)`` without implicit constraints (the prescribed motions
    the loader accepts)."""
    tr = system.transition
    return tr is not None and system.implicit is None and depends_on_time(dict(tr.connection))


class DrivePower:
    """``P(t, y)`` of a driven system, vectorised over rows; made once per run."""

    def __init__(self, system: KnownSystem):
        tr = system.transition
        x = tuple(tr.primitive_coordinates)
        force = sympy.zeros(len(x), 1)
        for name, f in tr.primitive_forces.items():
            if name not in tr.direct_effects:
                force += sympy.Matrix(f)
        projection = project_rheonomic(x, tr.primitive_metric, tr.primitive_velocity_terms, force,
                                       dict(tr.connection), system.coordinates)
        args = (TIME, *system.coordinates, *system.velocities, *(p.symbol for p in system.parameters))
        self.n = len(system.coordinates)
        self.power = sympy.lambdify((*args, *system.accelerations), projection.power, "numpy")
        self.mass = [sympy.lambdify(args, e, "numpy") for e in system.mass_matrix]
        self.rest = [sympy.lambdify(args, e, "numpy") for e in system.forces - system.velocity_terms]

    def __call__(self, t: np.ndarray, y: np.ndarray, param) -> np.ndarray:
        """``P`` at each row ``(t_i, y_i)``, ``y = [q; qdot]``, all rows at once."""
        t = np.asarray(t, dtype=float)
        rows = len(t)
        if not rows:
            return np.zeros(0)
        y = np.asarray(y, dtype=float).reshape(rows, -1)
        args = (t, *y.T, *param)

        def each(f):  # a constant entry gives a scalar: one value per row
            return np.broadcast_to(np.asarray(f(*args), dtype=float), (rows,))

        mass = np.stack([each(f) for f in self.mass], axis=-1).reshape(rows, self.n, self.n)
        rest = np.stack([each(f) for f in self.rest], axis=-1).reshape(rows, self.n, 1)
        try:
            qdd = np.linalg.solve(mass, rest)[:, :, 0]
        except np.linalg.LinAlgError:  # a singular Mbar at some row: no power known there
            qdd = np.array([_solved(m, r) for m, r in zip(mass, rest)]).reshape(rows, self.n)
        return np.broadcast_to(np.asarray(self.power(*args, *qdd.T), dtype=float), (rows,)).copy()


def _solved(mass: np.ndarray, rest: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(mass, rest)[:, 0]
    except np.linalg.LinAlgError:
        return np.full(len(rest), np.nan)


__all__ = ["COLUMN", "DrivePower", "driven"]
