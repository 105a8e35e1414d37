"""The reactions of viewpoint (alpha) under velocity constraints, in numbers at one state.

With the motion in the speeds known (viewpoint (beta): ``udot = Mbar^-1 (fbar - hbar)``), the
constraints' multipliers ``nu`` are what the system in its coordinates ``x`` needs on top of its
own forces to move so:

    xdot = C u + d,   xddot = C udot + Cdot u + ddot
    M xddot + h = f + S_c^T nu,   S_c = [A; G]

``A`` the velocity constraints' rows ``A xdot + b`` (as made, :func:`.nonholonomic_linearize.velocity_rows`)
and ``G = dg/dx`` the configuration constraints' rates, in the order and scale of the constraint
matrix the symbolic multipliers solve (:func:`.nonholonomic.velocity_multipliers`: the velocity
constraints first), so both give the same numbers under the same names. ``C^T (M xddot + h - f) = 0``
is the equations of motion, so the residual lies in the range of ``S_c^T`` (``S_c C = 0``, full row
rank); ``nu`` is its least-squares solve by a QR of ``S_c^T``. The pieces are those of the rates
(:meth:`.nonholonomic_linearize.SteadyMotionRates.parts`); the symbolic projection is never formed.
"""
from __future__ import annotations

import numpy as np

from .known_system import KnownSystem
from .linearize_numerics import LinearizationError
from .nonholonomic_linearize import MotionParts

RANK_TOLERANCE = 1e-12
"""Smallest diagonal entry of the QR's ``R`` (relative to its largest) of constraints called independent."""

__all__ = ["RANK_TOLERANCE", "constraint_rows", "multiplier_names", "multipliers"]


def multiplier_names(system: KnownSystem) -> list[str]:
    """``mu_<constraint>`` per constraint of a system in its speeds: the velocity constraints, then
    the configuration constraints (the names of :func:`.nonholonomic.velocity_multipliers`)."""
    return [f"mu_{name}" for name in system.speeds.constraint_names]


def constraint_rows(frame: np.ndarray, held: int, speeds: int) -> np.ndarray:
    """``S_c = [A; G]`` from ``S = [G; A; Y]`` (``held`` rows of ``G``, ``speeds`` rows of ``Y``)."""
    n = frame.shape[0]
    return np.vstack([frame[held:n - speeds], frame[:held]])


def multipliers(parts: MotionParts, speed_rates: np.ndarray, held: int) -> np.ndarray:
    """``nu`` of ``S_c^T nu = M xddot + h - f``, ``xddot = C udot + Cdot u + ddot``, at the state of
    ``parts`` with ``udot = speed_rates``; constraints dependent there raise :class:`LinearizationError`."""
    C = parts.transformation.real
    xddot = C @ np.asarray(speed_rates, dtype=float) + parts.convective.real
    residual = parts.metric.real @ xddot + parts.velocity_terms.real - parts.force.real
    rows = constraint_rows(parts.frame.real, held, C.shape[1])
    if not rows.shape[0]:
        return np.zeros(0)
    Q, R = np.linalg.qr(rows.T)
    diagonal = np.abs(np.diag(R))
    if not np.all(np.isfinite(diagonal)) or diagonal.min() <= RANK_TOLERANCE * diagonal.max():
        raise LinearizationError("the constraints are not independent here: their multipliers are not defined")
    return np.linalg.solve(R, Q.T @ residual)
