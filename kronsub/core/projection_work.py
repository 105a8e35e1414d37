"""How large the projection onto the speeds is, and from which size it is made in numbers.

Under velocity constraints ``A(x) xdot + b = 0`` the equations in the speeds are
``Mbar = C^T M C`` (9'), (D), ``hbar = C^T (M (Cdot u + ddot) + h)`` (E), ``fbar = C^T f``
(8'), (F), with ``C``, ``d`` the solve of ``[A; Y] xdot = [-b; u]``
(:mod:`.nonholonomic`). Formed symbolically, that solve and the products of its entries grow
with the constraints' rows and the square of the coordinates: :func:`projection_work` measures
it, and from :data:`NUMERIC_FROM` the projection is made in numbers at each evaluation (a run,
a linearisation) and printed in that implicit form, never expanded.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import sympy

from ..budget import DEFAULT_UNITS, WorkBudgetExceeded
from .known_system import KnownSystem

NUMERIC_FROM = 10_000
"""Projection work (:func:`projection_work`) from which the projection onto the speeds is made
in numbers: the rolling disc's is 300, a rolling joint's disc 2 225, the Whipple bicycle's 33 792."""


def projection_work(system: KnownSystem) -> int:
    """The size of the symbolic projection in the speeds: the distinct subexpressions of the
    velocity constraints' rows (as made, :attr:`~.known_system.SpeedEquations.rows`, else
    ``A xdot + b``) times ``n^2``, ``n`` the coordinates (the solve of ``[A; Y]``); 0 for a
    system without velocity constraints."""
    s = system.speeds
    if s is None or not s.constraint_names:
        return 0
    rows = s.rows or tuple(s.constraint_matrix * sympy.Matrix(list(system.velocities)) + s.constraint_offset)
    seen: set = set()
    for row in rows:
        seen.update(sympy.preorder_traversal(sympy.sympify(row)))
    return len(seen) * len(system.coordinates) ** 2


def projected_in_numbers(system: KnownSystem) -> bool:
    """Whether the projection of ``system`` onto its speeds is made in numbers, not symbolically:
    velocity constraints whose :func:`projection_work` is at least :data:`NUMERIC_FROM`."""
    return projection_work(system) >= NUMERIC_FROM


ADVICE = ("its equations in the speeds are too large to form symbolically (projection work {work}; from "
          "{numeric_from} they are formed in numbers at each evaluation): run it with `kronsub simulate`, linearise "
          "it with `kronsub linearize`, print its equations in their implicit form with `kronsub derive`; or raise "
          "the budget with --budget UNITS (default {default:,})")
"""The hint of a work budget spent on a system whose projection onto the speeds is made in numbers."""


@contextmanager
def numeric_route_advice(system: KnownSystem) -> Iterator[None]:
    """A work budget spent inside the block on ``system`` (generated code, an accuracy experiment:
    the symbolic projection onto the speeds) says, when that projection is made in numbers
    (:func:`projected_in_numbers`), which commands take the numeric route (:data:`ADVICE`)."""
    try:
        yield
    except WorkBudgetExceeded as exc:
        work = projection_work(system)
        if work < NUMERIC_FROM:
            raise
        raise exc.advised(ADVICE.format(work=work, numeric_from=NUMERIC_FROM, default=DEFAULT_UNITS)) from None


__all__ = ["ADVICE", "NUMERIC_FROM", "numeric_route_advice", "projected_in_numbers", "projection_work"]
