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
        self.mass = sympy.lambdify(args, system.mass_matrix, "numpy")
        self.rest = sympy.lambdify(args, system.forces - system.velocity_terms, "numpy")

    def __call__(self, t: np.ndarray, y: np.ndarray, param) -> np.ndarray:
        """``P`` at each row ``(t_i, y_i)``, ``y = [q; qdot]``."""
        y = np.asarray(y, dtype=float).reshape(len(t), -1)
        out = np.empty(len(t))
        for i, (ti, yi) in enumerate(zip(np.asarray(t, dtype=float), y)):
            args = (ti, *yi, *param)
            qdd = np.linalg.solve(np.asarray(self.mass(*args), dtype=float),
                                  np.asarray(self.rest(*args), dtype=float).reshape(-1))
            out[i] = float(self.power(*args, *qdd))
        return out


__all__ = ["COLUMN", "DrivePower", "driven"]
