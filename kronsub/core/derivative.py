"""``d expr / d s`` as ``sympy.diff`` gives it, without its detour through a logarithm.

Sympy differentiates a power ``b**e`` as ``b**e * (de/ds log(b) + db/ds e/b)`` even when
``e`` is constant: it builds ``log(b)``, asks the assumptions system about ``b`` on the way
(tens of milliseconds for ``(a2 - a1)**2``), then multiplies it by zero. A spring's
potential, a damper's rate and the metric's derivatives are full of such powers. Here sums,
products and powers with a constant exponent follow sympy's own rules term by term (the
same expressions, built in the same order), and anything else is left to ``sympy.diff``.

Where a derivative does not exist everywhere, it is taken where it does (the rule of
docs/model-format.md, "Expressions"): ``d sign(u)/du = 0`` away from ``u = 0``, so
``d |u|/du = sign(u)``. Sympy's ``DiracDelta`` (an impulse at the switch) has no place in
equations of motion and no numeric backend evaluates it: :func:`where_defined` drops it, and
every derivative kronsub takes (this one, :func:`jacobian`, :func:`matrix_derivative`) goes
through it.
"""
from __future__ import annotations

import sympy

_ZERO, _ONE = sympy.S.Zero, sympy.S.One


def derivative(expr: sympy.Expr, s: sympy.Symbol) -> sympy.Expr:
    """``sympy.diff(expr, s)`` for a symbol ``s``: the very same expression."""
    expr = sympy.sympify(expr)
    if s not in expr.free_symbols:
        return _ZERO
    if expr is s:
        return _ONE
    if expr.is_Add:  # Add._eval_derivative
        return sympy.Add(*[derivative(a, s) for a in expr.args])
    if expr.is_Mul:  # Mul._eval_derivative_n_times, n = 1: each factor's derivative in its place
        args = expr.args
        terms = []
        for i, arg in enumerate(args):
            d = derivative(arg, s)
            if d is not _ZERO:  # sympy's product with a zero factor, then left out of the sum
                terms.append(sympy.Mul(*args[:i], d, *args[i + 1:]))
        return sympy.Add(*terms)
    if expr.is_Pow and s not in expr.exp.free_symbols:  # Pow._eval_derivative, de/ds = 0
        base, exp = expr.args
        return expr * (derivative(base, s) * exp / base)
    return where_defined(sympy.diff(expr, s))


def where_defined(d):
    """A derivative (expression or matrix) where it exists: each ``DiracDelta(u)`` (and its
    derivatives ``DiracDelta(u, k)``), which sympy gives for ``d sign(u)/du`` and
    ``d Heaviside(u)/du``, is 0 (their value at every ``u != 0``)."""
    return d.replace(sympy.DiracDelta, lambda *args: _ZERO) if d.has(sympy.DiracDelta) else d


def jacobian(m: sympy.Matrix, wrt) -> sympy.Matrix:
    """``m.jacobian(wrt)`` where it exists (:func:`where_defined`); of no entries, or with
    respect to nothing, the empty matrix of its shape (sympy refuses a 0 x 1 column)."""
    wrt = list(wrt)
    m = sympy.Matrix(m)
    if not m.rows or not m.cols or not wrt:
        return sympy.zeros(len(m), len(wrt))
    return where_defined(m.jacobian(sympy.Matrix(wrt)))


def matrix_derivative(m: sympy.Matrix, wrt) -> sympy.Matrix:
    """``dm/dwrt`` where it exists: a Jacobian for a sequence of symbols, else ``m.diff(wrt)``."""
    if isinstance(wrt, (list, tuple, sympy.MatrixBase)):
        return jacobian(m, wrt)
    return where_defined(m.diff(wrt))


__all__ = ["derivative", "jacobian", "matrix_derivative", "where_defined"]
