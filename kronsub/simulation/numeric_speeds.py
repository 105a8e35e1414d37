"""Runs of a system under velocity constraints projected numerically at every evaluation, in numpy.

The equations in the speeds, ``Mbar udot = fbar - hbar`` with ``Mbar = C^T M C`` (9'), (D),
``hbar = C^T (M (Cdot u + ddot) + h)`` (E), ``fbar = C^T f`` (8'), (F), are projected
symbolically for the numpy module; for a large system (a bicycle's rolling contacts) that
projection (the solve of ``[A; Y] xdot = [-b; u]`` and the products of its long entries) is
far beyond the work budget, and the generated C makes it in numbers at run time
(:mod:`kronsub.emitters.projected_speeds`). Without a C compiler, this route evaluates the small
pieces at each state, the primitive's metric and velocity terms, the forces, the rows of the constraints and their
derivatives (:class:`~kronsub.core.nonholonomic_linearize.SteadyMotionRates`, compiled by
lambdify per piece), and forms ``C``, ``Cdot u + ddot``, ``Mbar`` and ``fbar - hbar`` in numbers,
after the held coordinates are put on their configuration constraints by Newton's method
(:mod:`kronsub.core.held`), as the generated right-hand side does.

Which systems are too large is decided by :func:`~kronsub.core.projection_work.projected_in_numbers`.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import sympy

from ..core.constraints import ConstraintFailure
from ..core.held import held_coordinates
from ..core.known_system import KnownSystem
from ..core.linearize_numerics import LinearizationError
from ..core.nonholonomic_linearize import steady_motion_rates
from ..core.symbols import TIME
from .failure import Singular

__all__ = ["NumericSpeeds"]


class NumericSpeeds:
    """The right-hand side ``[xdot; udot]`` of ``system`` in its state ``[x; u]`` at the parameter
    values ``param`` (in the order of ``system.parameters``), and its energies, in numbers."""

    def __init__(self, system: KnownSystem, param):
        self.system = system
        values = {p.symbol: float(v) for p, v in zip(system.parameters, param)}
        self.n = len(system.coordinates)
        self.rates = steady_motion_rates(system, values)
        self.held = held_coordinates(system, values)
        numbers = {s: sympy.Float(v, 17) for s, v in values.items()}
        self.potential = sympy.lambdify([TIME, list(system.coordinates)],
                                        sympy.sympify(system.potential_energy).xreplace(numbers), "numpy")

    def on_constraints(self, t: float, q) -> np.ndarray:
        """``q`` with its held coordinates on ``g(q, t) = 0`` (Newton's method from their values)."""
        return self.held.project(t, q) if self.held is not None else np.asarray(q, dtype=float)

    def rhs(self, t: float, y) -> np.ndarray:
        """``[xdot; udot]`` at ``(t, y)``; a state where the speeds do not fix the velocities, or
        ``Mbar`` is singular, raises :class:`.failure.Singular`."""
        y = np.asarray(y, dtype=float)
        try:
            q = self.on_constraints(t, y[:self.n])
            out = self.rates.rates(q, y[self.n:], t)
        except (ConstraintFailure, LinearizationError, np.linalg.LinAlgError) as exc:
            raise Singular(t, y) from exc
        return out.real

    def restart(self, _tol: float) -> Callable[[float, np.ndarray], np.ndarray]:
        return self.rhs

    def energies(self, t, Y) -> tuple[np.ndarray, np.ndarray]:
        """``(T, V)`` (24) at each row of ``Y`` (rows on the configuration constraints already)."""
        n = self.n
        T = np.array([self.rates.kinetic_energy(y[:n], y[n:], float(ti)) for ti, y in zip(t, Y)])
        V = np.array([float(self.potential(float(ti), list(y[:n]))) for ti, y in zip(t, Y)])
        return T, V
