"""Viewpoint (alpha): the workless reactions kept as unknowns (Hoffmann, "R and -R at A and A'").

With the motion of the projected system known (``qddot = Mbar^-1 (fbar - hbar)``, viewpoint
(beta)), the reactions are what the primitive needs on top of its own forces to move along
the subspace:

- an explicit connection ``x = x(q)``: ``r = M xddot + h - f`` on every primitive coordinate,
  with ``xddot = C qddot + Cdot qdot`` (and the drive's ``d(xdot)/dt`` for ``x = x(q, t)``, where
  ``C^T r = 0`` still holds and ``s^T r`` is the power the drive puts in, :mod:`.rheonomic`); ``C^T r = 0`` (the reactions do no work, (C)). For a
  free body's centre coordinates this is the joint force on the body, for an angle the moment.
- velocity constraints ``A xdot + b = 0`` (:mod:`.nonholonomic`): the multipliers ``mu`` with
  ``M xddot + h = f + A^T mu``, in the speeds and their rates; for a contact point's velocity, the
  contact force along each direction constrained.
- implicit constraints ``g(y) = 0``: the multipliers ``mu`` with ``M_y yddot + h_y = f_y + G^T mu``,
  from the dependent rows ``G_d^T mu = (M_y yddot + h_y - f_y)_d``, ``yddot = [qddot; lambda qddot
  + gamma]``. For a ``pin: [P, Q]`` the pair ``(mu_x, mu_y)`` is the force of the joint on the body
  of ``P`` (and minus it on that of ``Q``).

The expressions are in the state, the accelerations ``<q>_ddot`` (which the equations of
motion give) and the named intermediates.
"""
from __future__ import annotations

import sympy

from ..errors import KronsubError
from .constraints import multiplier_name
from .derivative import derivative
from .known_system import KnownSystem
from .nonholonomic import velocity_multipliers
from .rheonomic import depends_on_time
from .symbols import TIME, acceleration_symbol, velocity_symbol
from .simplify import compact
from .trigpoly import TrigAlgebra

SYMBOLIC_INVERSE = 3


class ReactionsUnavailable(KronsubError):
    """The reactions of viewpoint (alpha) need every effect's force on the primitive."""


def reactions(system: KnownSystem) -> list[tuple[str, sympy.Expr]] | "MultiplierSystem":
    """``(name, expression)`` per reaction: ``R_<x>`` per primitive coordinate, or ``mu_<constraint>``;
    a :class:`MultiplierSystem` for a closed loop of more than `SYMBOLIC_INVERSE` dependent coordinates."""
    if system.implicit is not None:
        return _multipliers(system)
    if system.speeds is not None:
        return velocity_multipliers(system)
    return _connection_reactions(system)


def _tidy(coords, expr):
    algebra = TrigAlgebra(coords)
    return compact(algebra, algebra.from_expr(sympy.expand(expr)))


def _connection_reactions(system: KnownSystem):
    tr = system.transition
    if tr is None:
        return []
    if tr.direct_effects:
        raise ReactionsUnavailable(
            f"the reactions of {system.name} are not defined: the effects "
            + ", ".join(f"'{e}'" for e in tr.direct_effects) + " are written in generalized coordinates and "
            "act in the subspace only, with no force on the primitive for R = M xddot + h - f\n"
            "  hint: write them in the primitive coordinates (through the connection) to get the reactions")
    q = system.coordinates
    qd = [velocity_symbol(c) for c in q]
    qdd = [acceleration_symbol(c) for c in q]
    C = tr.transformation
    connection = dict(tr.connection)
    x = tr.primitive_coordinates
    xdot = [sum((C[a, j] * qd[j] for j in range(len(q))), sympy.Integer(0)) for a in range(len(x))]
    driven = depends_on_time(connection)  # x = x(q, t): xdot + dx/dt, xddot + d(xdot)/dt (rheonomic)
    if driven:
        xdot = [v + derivative(connection[xa], TIME) for v, xa in zip(xdot, x)]
    xddot = []
    for a in range(len(x)):
        total = sum((C[a, j] * qdd[j] for j in range(len(q))), sympy.Integer(0))
        total += sum((derivative(xdot[a], c) * v for c, v in zip(q, qd)), sympy.Integer(0))
        if driven:
            total += derivative(xdot[a], TIME)
        xddot.append(total)
    sub = {xa: connection[xa] for xa in x}
    sub.update({velocity_symbol(xa): xdot[a] for a, xa in enumerate(x)})
    f = sympy.zeros(len(x), 1)
    for vec in tr.primitive_forces.values():
        f += vec
    M = tr.primitive_metric
    out = []
    for a, xa in enumerate(x):
        r = sum((M[a, b] * xddot[b] for b in range(len(x)) if M[a, b] != 0), sympy.Integer(0))
        r = sympy.sympify(r + tr.primitive_velocity_terms[a] - f[a]).xreplace(sub)
        out.append((f"R_{xa.name}", _tidy(q, r)))
    return out


class MultiplierSystem:
    """The multipliers' linear system ``G_d^T mu = r`` (``r = (M_y yddot + h_y - f_y)_d``), for
    more than `SYMBOLIC_INVERSE` dependent coordinates, where the closed form of the inverse
    would swell: printed as it stands and solved numerically at each row."""

    def __init__(self, names, matrix: sympy.Matrix, rows: sympy.Matrix):
        self.names, self.matrix, self.rows = list(names), matrix, rows


def multiplier_system(system: KnownSystem) -> MultiplierSystem:
    """``G_d^T mu = r`` from the dependent rows of ``M_y yddot + h_y = f_y + G^T mu``, with
    ``yddot = [qddot; lambda qddot + gamma]`` (Hoffmann (27)-(28))."""
    imp = system.implicit
    y = imp.intermediate
    n = len(imp.independent)
    qdd = [acceleration_symbol(c) for c in imp.independent]
    qd = [velocity_symbol(c) for c in imp.independent]
    lam, gam = imp.sensitivities, imp.convective
    yddot, ydot = {}, {}
    for j, c in enumerate(imp.independent):
        yddot[c], ydot[velocity_symbol(c)] = qdd[j], qd[j]
    for a, d in enumerate(imp.dependent):
        yddot[d] = sum((lam[a, j] * qdd[j] for j in range(n)), sympy.Integer(0)) + gam[a]
        ydot[velocity_symbol(d)] = sum((lam[a, j] * qd[j] for j in range(n)), sympy.Integer(0))
    index = {c: i for i, c in enumerate(y)}
    rows = []
    for d in imp.dependent:
        i = index[d]
        r = sum((imp.metric[i, b] * yddot[c] for b, c in enumerate(y) if imp.metric[i, b] != 0), sympy.Integer(0))
        rows.append(sympy.sympify(r + imp.velocity_terms[i] - imp.forces[i]).xreplace(ydot))
    names = [multiplier_name(c.name) for c in imp.constraints]
    return MultiplierSystem(names, imp.jacobian_dependent.T, sympy.Matrix(rows))


def _multipliers(system: KnownSystem):
    """``mu = G_d^-T r`` in closed form, or (beyond `SYMBOLIC_INVERSE` dependent coordinates)
    the :class:`MultiplierSystem` to solve."""
    eqs = multiplier_system(system)
    k = len(eqs.names)
    if k > SYMBOLIC_INVERSE:
        return eqs
    Gt = eqs.matrix
    inverse = Gt.adjugate() / Gt.det(method="berkowitz") if k > 1 else sympy.Matrix([[1 / Gt[0, 0]]])
    mu = inverse * eqs.rows
    y = system.implicit.intermediate
    out = []
    for a, nm in enumerate(eqs.names):
        num, den = sympy.fraction(sympy.together(mu[a]))
        out.append((nm, sympy.factor_terms(_tidy(y, num) / _tidy(y, den))))
    return out


__all__ = ["MultiplierSystem", "multiplier_system", "reactions"]
