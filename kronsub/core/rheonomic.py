"""Prescribed (rheonomic) motions: a connection that depends on time, ``x = x(xbar, t)``.

With ``C = dx/dxbar`` (7'), (21) and the velocity of the drive ``s = dx/dt`` the velocity
(19), (20) gains a term and the acceleration two:

    xdot  = C xbardot + s
    xddot = C xbarddot + a,   a = d(xdot)/dxbar^k xbardot^k + d(xdot)/dt

(``a`` is ``Cdot xbardot`` of (E) with the drive's ``2 dC/dt xbardot + d2x/dt2`` in it). The
projection keeps its form:

    Mbar = C^T M C                                   (9'), (D)
    hbar = C^T (M a + h(x(xbar, t), xdot))           (E)
    fbar = C^T f(x(xbar, t), xdot, t)                (8'), (F)

The kinetic energy is no longer conserved: the drive's reaction on the primitive,
``R = M xddot + h - f`` (``C^T R = 0`` along the motion), puts in the power ``P = s^T R``.
A coordinate prescribed as a function of time, ``q = q(t)``, is the connection composed
with it; the generalized force that drives it (inverse dynamics) is ``Q_q = C_q^T R`` with
``C_q = dx/dq`` taken before ``q`` is replaced.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import sympy

from .derivative import derivative, jacobian, where_defined
from .symbols import TIME, acceleration_symbol, free_symbols_of, velocity_symbol


@dataclass(frozen=True)
class RheonomicProjection:
    """``Mbar xbarddot + hbar = fbar`` of a time-dependent connection, with what the drive adds.

    ``drive_velocity`` is ``s = dx/dt``; ``drive_terms`` is the part of ``hbar`` that comes
    from the drive alone (``hbar`` minus its value with ``t`` frozen in the connection), the
    extra terms ``derive`` shows; ``power`` is ``P = s^T R`` written in ``xbar``,
    ``xbardot``, ``xbarddot`` and ``t``.
    """

    coordinates: tuple[sympy.Symbol, ...]
    transformation: sympy.Matrix  # C = dx/dxbar
    drive_velocity: sympy.Matrix  # s = dx/dt
    convective: sympy.Matrix  # a = Cdot xbardot + the drive's terms
    mass_matrix: sympy.Matrix
    velocity_terms: sympy.Matrix
    forcing: sympy.Matrix
    drive_terms: sympy.Matrix
    reaction: sympy.Matrix  # R = M xddot + h - f on the primitive
    power: sympy.Expr


def depends_on_time(connection: Mapping) -> bool:
    """Whether some image of the connection names ``t`` (each shared subexpression looked at once:
    definitions that each use the one before twice make a tree of 2^n leaves of n nodes)."""
    return TIME in free_symbols_of(connection.values())


def prescribe(connection: Mapping, coordinates: Sequence[sympy.Symbol],
              motions: Mapping[sympy.Symbol, sympy.Expr]) -> tuple[dict, tuple[sympy.Symbol, ...]]:
    """The connection with each prescribed coordinate ``q`` replaced by its motion ``q(t)``,
    and the coordinates left free."""
    unknown = [q for q in motions if q not in coordinates]
    if unknown:
        raise ValueError(f"prescribed coordinate(s) {', '.join(map(str, unknown))} are not coordinates")
    replace = {q: sympy.sympify(m) for q, m in motions.items()}
    return ({x: sympy.sympify(e).xreplace(replace) for x, e in connection.items()},
            tuple(q for q in coordinates if q not in motions))


def project_rheonomic(x: Sequence[sympy.Symbol], metric: sympy.Matrix, velocity_terms: sympy.Matrix,
                      force: sympy.Matrix, connection: Mapping, coordinates: Sequence[sympy.Symbol]
                      ) -> RheonomicProjection:
    """(9'), (D)-(F) for ``x = x(xbar, t)``: ``metric``, ``velocity_terms`` and ``force`` are the
    primitive's ``M(x)``, ``h(x, xdot)``, ``f(x, xdot, t)`` (velocities named by
    :func:`velocity_symbol`); ``connection`` maps every ``x^a`` to its image in ``xbar`` and ``t``."""
    x, xbar = tuple(x), tuple(coordinates)
    xdot = [velocity_symbol(s) for s in x]
    qdot = sympy.Matrix([velocity_symbol(q) for q in xbar])
    qddot = sympy.Matrix([acceleration_symbol(q) for q in xbar])
    images = sympy.Matrix([sympy.sympify(connection[s]) for s in x])
    C = jacobian(images, xbar)
    s = where_defined(images.diff(TIME))
    velocity = C * qdot + s
    a = jacobian(velocity, xbar) * qdot + where_defined(velocity.diff(TIME))
    moved = {**{xa: images[i] for i, xa in enumerate(x)}, **{v: velocity[i] for i, v in enumerate(xdot)}}

    def at(m: sympy.Matrix) -> sympy.Matrix:
        return sympy.Matrix(m).xreplace(moved)

    M, h, f = at(metric), at(velocity_terms), at(force)
    mass = _simplified(C.T * M * C)
    hbar = _simplified(C.T * (M * a + h))
    fbar = _simplified(C.T * f)
    frozen = project_frozen(x, metric, velocity_terms, connection, xbar)
    reaction = M * (C * qddot + a) + h - f
    return RheonomicProjection(coordinates=xbar, transformation=C, drive_velocity=s, convective=a,
                               mass_matrix=mass, velocity_terms=hbar, forcing=fbar,
                               drive_terms=_simplified(hbar - frozen), reaction=reaction,
                               power=sympy.expand((s.T * reaction)[0, 0]))


def project_frozen(x, metric, velocity_terms, connection, coordinates) -> sympy.Matrix:
    """``hbar`` with the connection's ``t`` held fixed (the scleronomic part): what the
    projection would give at each instant without the drive's velocity."""
    frozen_time = sympy.Dummy("t_frozen")
    fixed = {s: sympy.sympify(connection[s]).xreplace({TIME: frozen_time}) for s in x}
    images = sympy.Matrix([fixed[s] for s in x])
    C = jacobian(images, tuple(coordinates))
    qdot = sympy.Matrix([velocity_symbol(q) for q in coordinates])
    velocity = C * qdot
    a = jacobian(velocity, tuple(coordinates)) * qdot
    moved = {**{xa: images[i] for i, xa in enumerate(x)}, **{velocity_symbol(xa): velocity[i] for i, xa in enumerate(x)}}
    M, h = sympy.Matrix(metric).xreplace(moved), sympy.Matrix(velocity_terms).xreplace(moved)
    return (C.T * (M * a + h)).xreplace({frozen_time: TIME})


def driving_force(x: Sequence[sympy.Symbol], metric: sympy.Matrix, velocity_terms: sympy.Matrix,
                  force: sympy.Matrix, connection: Mapping, coordinates: Sequence[sympy.Symbol],
                  motions: Mapping[sympy.Symbol, sympy.Expr]) -> tuple[RheonomicProjection, dict]:
    """Inverse dynamics of a prescribed motion: the projection with ``motions`` composed in, and
    for each prescribed ``q`` the generalized force ``Q_q = C_q^T R`` that keeps it on ``q(t)``
    (in the free coordinates, their velocities and accelerations, and ``t``)."""
    composed, free = prescribe(connection, coordinates, motions)
    projection = project_rheonomic(x, metric, velocity_terms, force, composed, free)
    replace = {q: sympy.sympify(m) for q, m in motions.items()}
    forces = {}
    for q in motions:
        column = sympy.Matrix([derivative(connection[s], q).xreplace(replace) for s in x])
        forces[q] = sympy.expand((column.T * projection.reaction)[0, 0])
    return projection, forces


def _simplified(m: sympy.Matrix) -> sympy.Matrix:
    return m.applyfunc(lambda e: sympy.trigsimp(sympy.expand(e)))


__all__ = ["RheonomicProjection", "depends_on_time", "driving_force", "prescribe", "project_frozen",
           "project_rheonomic"]
