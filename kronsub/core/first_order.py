"""First-order coordinates: where the metric is singular and the dissipation is not.

A loop of resistors and capacitors has no inductance, a massless node between a spring and a
damper no mass: the coordinate's row and column of ``Mbar`` vanish, and its equation of
``Mbar qddot + hbar = fbar`` (10') has no acceleration in it,

    0 = r_J(t, q, qdot_I, qdot_J),        r = fbar - hbar,

a relation among the velocities. Where it is affine in the velocities ``qdot_J`` of those
coordinates with ``D = -dr_J/dqdot_J`` regular (Rayleigh's dissipation positive on them:
``D`` is the resistance matrix of the loops), it gives them,

    qdot_J = D^-1 r_J(t, q, qdot_I, 0),

and the other coordinates move by the regular block, ``Mbar_II qddot_I = r_I`` (regular where
the null space of ``Mbar`` is spanned by those coordinates): a mixed first- and second-order
system in the state ``(q, qdot_I)``. A relation not affine in ``qdot_J``, or a singular ``D``,
is refused here with the coordinates named. A singular ``Mbar`` whose null space is not made
of whole coordinates (a loop without inductance that shares its charge with one that has
some) has no zero row: the model's check reports it for circuits
(:mod:`kronsub.model.circuits`), a run where ``Mbar`` is not positive definite otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..errors import KronsubError
from .known_system import KnownSystem


@dataclass(frozen=True)
class FirstOrder:
    """The first-order coordinates of a system (their indices) and their velocities
    ``qdot_J = D^-1 r_J(t, q, qdot_I, 0)`` in the time, the coordinates, the other velocities
    and the parameters."""

    indices: tuple[int, ...]
    velocities: tuple[sympy.Expr, ...]

    def substitution(self, system: KnownSystem) -> dict:
        """``qdot_J -> qdot_J(t, q, qdot_I)``."""
        return {system.velocities[j]: v for j, v in zip(self.indices, self.velocities)}


class FirstOrderError(KronsubError):
    """A singular metric that is not a set of first-order coordinates."""


def zero_rows(system: KnownSystem) -> tuple[int, ...]:
    """The coordinates whose row of ``Mbar`` is zero (identically, after expansion). A diagonal
    entry that is not zero at one set of values rules its row out without expanding it. A system
    in its speeds has none: its state is ``[q; u]``, its equations those in the speeds."""
    if system.speeds is not None:
        return ()
    M = system.mass_matrix
    n = len(system.coordinates)
    return tuple(j for j in range(n) if _vanishes(M[j, j]) and all(_vanishes(M[j, k]) for k in range(n)))


def _vanishes(entry: sympy.Expr) -> bool:
    if entry == 0:
        return True
    if entry.is_Number:
        return False
    probe = {s: sympy.Rational(3 + k, 7 + 2 * k) for k, s in enumerate(sorted(entry.free_symbols, key=str))}
    try:
        if abs(complex(entry.xreplace(probe).evalf(15))) > 1e-9:
            return False
    except (TypeError, ValueError, ZeroDivisionError):
        pass
    return sympy.expand(entry) == 0


def first_order(system: KnownSystem) -> FirstOrder | None:
    """The system's first-order coordinates (None when ``Mbar`` has no zero row); see the module.

    Raises :class:`FirstOrderError` naming the coordinates where the velocities cannot be
    solved for, or with implicit constraints (not combined here)."""
    rows = zero_rows(system)
    if not rows:
        return None
    names = ", ".join(system.coordinates[j].name for j in rows)
    names = f"the coordinates {names} have" if len(rows) > 1 else f"the coordinate {names} has"
    if system.implicit is not None:
        raise FirstOrderError(f"{names} no inertia (zero rows of Mbar) in a system "
                              "with implicit constraints, which kronsub does not integrate as a first-order system; "
                              "write the connection explicitly (loop charges) instead of node constraints")
    velocities = [system.velocities[j] for j in rows]
    r = sympy.Matrix([system.forces[j] - system.velocity_terms[j] for j in rows])
    D = -r.jacobian(velocities)
    if D.free_symbols & set(velocities) or any(entry.has(sympy.Derivative) for entry in D):
        raise FirstOrderError(f"{names} no inertia, and the equations there are not linear in the "
                              "velocities: kronsub solves them for the velocities only from a dissipation "
                              "quadratic in those velocities (a resistor's R i^2/2, a damper's c v^2/2)")
    zero = {v: sympy.Integer(0) for v in velocities}
    rest = r.xreplace(zero)
    if D.det() == 0:
        raise FirstOrderError(f"{names} no inertia and no dissipation (zero rows of Mbar, and a zero "
                              "determinant of -d(fbar - hbar)/dqdot there): the velocities are not determined; give "
                              "an inductance (mass) or a resistance (damping) there")
    solved = D.LUsolve(rest) if len(rows) > 1 else rest / D[0, 0]
    return FirstOrder(rows, tuple(sympy.cancel(e) if len(rows) > 1 else e for e in solved))


__all__ = ["FirstOrder", "FirstOrderError", "first_order", "zero_rows"]
