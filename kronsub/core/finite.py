"""Why the equations have no finite value at a point, in words: a number beyond the range of
doubles (an overflow, from huge parameter values or states) or a function outside its domain
(a square root of a negative number, an asin of more than 1, a division by zero).

The equations are evaluated exactly enough to tell the two apart: every subexpression, innermost
first, in 30-digit floating point with an unbounded exponent (sympy's ``Float``), so a value
beyond the double range is seen as such and not as ``inf``.
"""
from __future__ import annotations

import math
import sys
from typing import NamedTuple

import mpmath
import numpy as np
import sympy

from .symbols import TIME

DOUBLE_MAX = sys.float_info.max
"""The largest double, 1.8e308: a value beyond it is ``inf`` in the compiled equations."""

_DIGITS = 30


class Cause(NamedTuple):
    """Why a quantity has no finite double value: ``overflow`` (else a domain problem), what
    happened and a hint, in words; as text, both on one line."""

    overflow: bool
    what: str
    hint: str
    label: str = ""  # the quantity: "Mbar[x, y]", "fbar[x]"...
    effect: str = ""  # the effect whose force it is, by its name in the model ("" for none)

    def __str__(self) -> str:
        return f"{self.what} ({self.hint})"

    def stated(self) -> str:
        """The sentence a stopped run gives."""
        return f"the equations have no {'finite' if self.overflow else 'real'} value at this state: {self}"


class _Found(Exception):
    """``kind`` ("domain", "overflow") at ``node``, whose ``value`` (or that of its ``part``:
    "factors" of a product, "terms" of a sum) is not a finite double."""

    def __init__(self, kind: str, node, value, part: str = ""):
        super().__init__(kind)
        self.kind, self.node, self.value, self.part = kind, node, value, part


class _Unknown(Exception):
    """A symbol without a value, or a subexpression sympy cannot evaluate: no verdict."""


def nonfinite_cause(quantities, values) -> Cause | None:
    """Why the first of ``quantities`` (``(label, expr)`` pairs, or ``(label, expr, effect)``
    for the force of a named effect) without a finite double value has none at ``values``
    (symbol -> float), with a hint; None when there is no such quantity, or no verdict (a
    symbol without a value)."""
    given = dict(values)
    for symbol, value in given.items():
        if not math.isfinite(value):
            return Cause(math.isinf(value), f"{symbol.name} is {value}", "give it a finite value")
    memo: dict = {}
    for label, expr, *effect in quantities:
        try:
            _value(sympy.sympify(expr), given, memo)
        except _Unknown:
            continue
        except _Found as found:
            return _describe(label, found, given)._replace(effect=effect[0] if effect else "")
    return None


def state_values(system, t: float, y, param) -> dict:
    """``t``, the state ``y = [q; qdot]`` (or ``q`` alone) and the parameter values ``param`` (in
    the order of ``system.parameters``), by their symbols, as floats."""
    values = {TIME: float(t)}
    rates = tuple(system.speeds.speeds) if system.speeds is not None else tuple(system.velocities)
    values.update(zip(tuple(system.coordinates) + rates, (float(v) for v in y)))
    values.update(zip((p.symbol for p in system.parameters), (float(v) for v in param)))
    return values


def at_state(system, t: float, y, param, intermediates=None) -> Cause | None:
    """:func:`nonfinite_cause` for the equations of ``system`` (``Mbar``, ``fbar``, ``hbar``, the
    energies) at time ``t``, state ``y = [q; qdot]`` and parameter values ``param`` (in the order
    of ``system.parameters``). ``fbar`` is looked at effect by effect first (10'), so a force
    without a value names its effect; then as the sum (which may overflow where no term does).
    With implicit constraints, ``intermediates`` gives the named intermediates at the state
    (``y_d``, ``Lambda``, ``gamma``: symbol -> float), without which there is no verdict."""
    values = {**{s: float(v) for s, v in (intermediates or {}).items()}, **state_values(system, t, y, param)}
    equations, quantities = system, []
    if system.speeds is not None:  # the state is [x; u]: xdot = C u + d and the equations in the speeds
        equations = system.speeds
        quantities = [(f"{q.name}_dot of the kinematic equations", e)
                      for q, e in zip(system.coordinates, equations.kinematics)]
    q = tuple(equations.speeds) if system.speeds is not None else tuple(system.coordinates)
    n = len(q)
    quantities += [(f"Mbar[{q[i].name}, {q[j].name}]", equations.mass_matrix[i, j]) for i in range(n)
                   for j in range(i + 1)]
    for name, force in equations.effect_forces.items():
        quantities += [(f"fbar[{q[i].name}] of effect '{name}'", force[i], name) for i in range(n)]
    forces = equations.forces
    quantities += [(f"fbar[{q[i].name}]", forces[i]) for i in range(n)]
    quantities += [(f"hbar[{q[i].name}]", equations.velocity_terms[i]) for i in range(n)]
    quantities += [("the kinetic energy", equations.kinetic_energy), ("the potential energy", system.potential_energy)]
    return nonfinite_cause(quantities, values)


def _value(node, values, memo):
    """The value of ``node`` at ``values``; raises :class:`_Found` at the innermost subexpression
    that overflows or leaves its domain."""
    if node in memo:
        return memo[node]
    if node.is_Symbol:
        if node not in values:
            raise _Unknown(node)
        out = sympy.Float(values[node], _DIGITS)
    elif node.is_Number or node.is_NumberSymbol:
        out = node if node.is_Rational else sympy.Float(node.evalf(_DIGITS), _DIGITS)
    elif not node.args:  # true, false, I...
        out = node
    else:
        args = [_value(a, values, memo) for a in node.args]
        try:
            out = node.func(*args)
            out = out.evalf(_DIGITS) if isinstance(out, sympy.Expr) else out
            if isinstance(node, sympy.atan2) and out is sympy.nan:
                out = sympy.Integer(0)  # atan2(0, 0) is 0 in C
        except (TypeError, ValueError, ZeroDivisionError) as exc:
            raise _Unknown(node) from exc
        if isinstance(out, sympy.Expr):  # (a condition of a Piecewise is not checked)
            if not out.is_number:
                raise _Unknown(node)
            if out.has(sympy.zoo, sympy.nan, sympy.oo, -sympy.oo) or not out.is_extended_real:
                raise _Found("domain", node, out)
            if abs(out) > DOUBLE_MAX:
                raise _Found("overflow", node, out)
            _partial_overflow(node, args)
    memo[node] = out
    return out


def _partial_overflow(node, args) -> None:
    """A product or sum in range whose doubles may overflow on the way, in whatever order the
    compiled code takes: its nonzero factors' product (``huge * sin(0)`` is ``inf * 0 = NaN``),
    or the sum of its terms of one sign, beyond the range."""
    if node.is_Mul:
        product = sympy.Mul(*[a for a in args if a != 0]).evalf(_DIGITS)
        if abs(product) > DOUBLE_MAX:
            raise _Found("overflow", node, product, "factors")
    elif node.is_Add:
        for same in (sympy.Add(*[a for a in args if a > 0]), sympy.Add(*[a for a in args if a < 0])):
            if abs(same.evalf(_DIGITS)) > DOUBLE_MAX:
                raise _Found("overflow", node, same.evalf(_DIGITS), "terms")


def _short(node) -> str:
    text = str(node)
    return text if len(text) <= 60 else text[:57] + "..."


def _largest(node, values) -> str:
    """The values of ``node``'s symbols of at least 1e10, or else its largest one: the likely
    culprits of an overflow."""
    symbols = sorted((s for s in node.free_symbols if s in values), key=lambda s: (-abs(values[s]), s.name))
    huge = [s for s in symbols if abs(values[s]) >= 1e10] or symbols[:1]
    return ", ".join(f"{s.name}={values[s]:.6g}" for s in huge)


def _describe(label: str, found: _Found, values) -> Cause:
    node = _short(found.node)
    if found.kind == "overflow":
        culprits = _largest(found.node, values)
        what = {"": f"{node} is", "factors": f"the nonzero factors of {node} multiply to",
                "terms": f"the terms of one sign of {node} add up to"}[found.part]
        return Cause(True, f"{label} overflows the range of doubles: {what} "
                           f"{mpmath.nstr(mpmath.mpf(found.value), 3)} (beyond {DOUBLE_MAX:.3g})"
                           + (f" with {culprits}" if culprits else ""),
                     "give the parameters and the initial state smaller values, in other units", label)
    what = "a division by zero" if found.value.has(sympy.zoo) else "outside its domain"
    return Cause(False, f"{node} in {label} is {what}", "check the initial values and the parameters", label)


def rank_loss(system, t: float, y, param) -> str | None:
    """Why ``Mbar(q)`` has no Cholesky factor at time ``t`` and a finite state ``y = [q; qdot]``
    (:func:`describe_rank_loss`); None when it is not the matrix, or with implicit
    constraints (whose dependent coordinates are not known here)."""
    if system.implicit is not None:
        return None
    q, n = system.coordinates, len(system.coordinates)
    values = {s: sympy.Float(v, _DIGITS) for s, v in state_values(system, t, y, param).items()}
    try:
        M = np.array([[float(sympy.sympify(system.mass_matrix[i, j]).xreplace(values).evalf(_DIGITS))
                       for j in range(n)] for i in range(n)])
    except (TypeError, ValueError):
        return None
    return describe_rank_loss(M, [s.name for s in q]) if np.all(np.isfinite(M)) else None


def describe_rank_loss(M, names) -> str | None:
    """``M`` (the mass matrix at a configuration) singular or indefinite, in words: the
    direction of motion it gives no inertia (the eigenvector of its smallest eigenvalue, its
    largest entry 1), as at a coordinate singularity. None when ``M`` is positive definite to
    working accuracy."""
    w, V = np.linalg.eigh((M + M.T) / 2)
    scale = float(np.max(np.abs(w)))
    k = int(np.argmin(w))
    if scale > 0 and w[k] > 1e-9 * scale:
        return None
    if scale > 0 and w[k] < -1e-6 * scale:
        return (f"Mbar has a negative eigenvalue here ({w[k]:.3g}, the largest {scale:.3g}): "
                "is a mass or an inertia among the parameters negative?")
    v = V[:, k] / V[int(np.argmax(np.abs(V[:, k]))), k]
    along = ", ".join(f"{names[i]} {v[i]:+.3g}" for i in range(len(names)) if abs(v[i]) >= 1e-6)
    return (f"Mbar loses rank here: a motion along ({along}) has no inertia, as at a singularity of "
            "the coordinates (Euler angles in gimbal lock, spherical coordinates at a pole) or where "
            "nothing with mass moves that way")


__all__ = ["Cause", "DOUBLE_MAX", "at_state", "describe_rank_loss", "nonfinite_cause", "rank_loss", "state_values"]
