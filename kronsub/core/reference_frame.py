"""A change of velocity frame: quasi-velocities ``u = Y(x) xdot``, as many as the velocities
and no constraint among them, so ``Y`` is invertible and

    xdot = C u,   C = Y^-1

with ``C`` the Jacobian of no ``x(xbar)`` in general: Kron's non-holonomic reference frame
without a constraint (Park's d-q currents of a machine's phase currents, a body's angular
velocity of its Euler angles' rates). The projection is that of :mod:`.nonholonomic`,
``Mbar = C^T M C`` (9'), (D), ``fbar = C^T f`` (F), ``hbar`` with ``Cdot`` along the motion
(E) (Boltzmann-Hamel); the state is ``[x; u]``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import sympy

from .nonholonomic import VelocityConstraintError, VelocityTransformation, generic_rank
from .symbols import velocity_symbol


def frame_matrix(coordinates: Sequence[sympy.Symbol], speeds: Mapping[sympy.Symbol, sympy.Expr]) -> sympy.Matrix:
    """``Y(x)`` of ``u = Y(x) xdot`` for ``speeds`` (each speed to its definition), one per
    velocity; a speed not linear in the velocities, or with a term without one, raises
    :class:`VelocityConstraintError` (``kind="speeds"``, ``index`` the speed)."""
    velocities = [velocity_symbol(q) for q in coordinates]
    names = [u.name for u in speeds]
    n = len(velocities)
    if len(speeds) != n:
        raise VelocityConstraintError(
            f"{len(speeds)} speed(s) for {n} velocities and no velocity constraint",
            f"name {n} speeds, one per velocity (a change of velocity frame), or add the `velocity_constraints:` "
            "that leave fewer", kind="speeds")
    rows = []
    for i, e in enumerate(speeds.values()):
        e = sympy.expand(sympy.sympify(e))
        row = [sympy.diff(e, v) for v in velocities]
        if any(set(velocities) & r.free_symbols for r in row):
            raise VelocityConstraintError(
                f"speed '{names[i]}' is not linear in the velocities",
                "define each speed as Y(x) xdot: each velocity to the first power, times a function of the "
                "coordinates", i, kind="speeds")
        if sympy.expand(e - sum(r * v for r, v in zip(row, velocities))) != 0:
            raise VelocityConstraintError(
                f"speed '{names[i]}' has a term without a velocity", "define each speed as Y(x) xdot", i,
                kind="speeds")
        rows.append(row)
    return sympy.Matrix(rows)


def frame_transformation(coordinates: Sequence[sympy.Symbol], speeds: Mapping[sympy.Symbol, sympy.Expr],
                         values: Mapping | None = None) -> VelocityTransformation:
    """``xdot = Y^-1 u`` for ``speeds`` (:func:`frame_matrix`); speeds that are not independent
    at a generic configuration raise :class:`VelocityConstraintError` at the first that depends
    on those before it. ``values`` (parameter -> number) fixes the parameters there."""
    coordinates = tuple(coordinates)
    Y = frame_matrix(coordinates, speeds)
    n = len(coordinates)
    for k in range(n):
        if generic_rank(Y[:k + 1, :], coordinates, values) < k + 1:
            said = ("is zero" if generic_rank(Y[k, :], coordinates, values) == 0
                    else "is a combination of the speeds before it")
            raise VelocityConstraintError(
                f"speed '{list(speeds)[k].name}' {said} at every configuration: the speeds are not a frame of "
                "the velocities",
                "define independent speeds (Y(x) invertible), e.g. the velocity of a coordinate no other speed "
                "names", k, kind="speeds")
    return VelocityTransformation(coordinates=coordinates, speeds=tuple(speeds), constraint_matrix=sympy.zeros(0, n),
                                  constraint_offset=sympy.zeros(0, 1), speed_matrix=Y)

__all__ = ["frame_matrix", "frame_transformation"]
