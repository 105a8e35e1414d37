"""An expression's value at a point in complex doubles, with effort and range bounded.

sympy evaluates a function of a ``Float`` as it builds it, in multiprecision with an
unbounded exponent: ``exp(exp(exp(x)))`` at ``x = 1.6`` has an exponent of some 10^78
bits, and one more ``exp`` aborts the whole process inside gmp (``overflow in mpz type``).
Here every node is evaluated once (shared subexpressions too) with ``cmath``: a value
beyond the doubles raises ``OverflowError`` instead.
"""
from __future__ import annotations

import cmath
import math
from typing import Mapping

import sympy

_FUNCTIONS = {
    sympy.sin: cmath.sin, sympy.cos: cmath.cos, sympy.tan: cmath.tan,
    sympy.asin: cmath.asin, sympy.acos: cmath.acos, sympy.atan: cmath.atan,
    sympy.exp: cmath.exp, sympy.log: cmath.log,
    sympy.sinh: cmath.sinh, sympy.cosh: cmath.cosh, sympy.tanh: cmath.tanh,
    sympy.Abs: abs,
}


class Unsupported(ValueError):
    """A node ``complex_value`` does not evaluate (a Piecewise, an unknown function...)."""


def complex_value(expr: sympy.Basic, values: Mapping[sympy.Basic, float], memo: dict | None = None) -> complex:
    """The value of ``expr`` with ``values`` (symbol -> float) substituted, in complex doubles.

    Raises ``OverflowError`` when a part leaves the doubles, ``ZeroDivisionError`` on a
    division by zero, `Unsupported` for a node it does not know.
    """
    memo = {} if memo is None else memo
    hit = memo.get(expr)
    if hit is not None:
        return hit
    value = _value(expr, values, memo)
    if cmath.isinf(value):
        raise OverflowError("beyond the range of doubles")
    memo[expr] = value
    return value


def _value(e: sympy.Basic, values, memo) -> complex:
    if e in values:
        return complex(values[e])
    if e.is_Rational:
        return complex(int(e.p) / int(e.q))
    if e.is_Float or isinstance(e, sympy.NumberSymbol):
        return complex(float(e))
    if e is sympy.I:
        return 1j
    args = [complex_value(a, values, memo) for a in e.args]
    if e.is_Add:
        return sum(args, 0j)
    if e.is_Mul:
        out = 1 + 0j
        for a in args:
            out *= a
        return out
    if e.is_Pow:
        base, exponent = args
        if base == 0:
            if exponent.real < 0:
                raise ZeroDivisionError
            return 0j if exponent != 0 else 1 + 0j
        if exponent.imag == 0 and exponent.real == int(exponent.real) and abs(exponent.real) <= 64:
            return base ** int(exponent.real)
        return cmath.exp(exponent * cmath.log(base))
    if isinstance(e, sympy.atan2):
        y, x = args
        if y.imag or x.imag:
            raise Unsupported(type(e).__name__)
        return complex(math.atan2(y.real, x.real))
    if isinstance(e, sympy.sign):
        (x,) = args
        return complex((x.real > 0) - (x.real < 0)) if not x.imag else x / abs(x)
    function = _FUNCTIONS.get(type(e))
    if function is not None:
        return complex(function(*args))
    if isinstance(e, sympy.Function) and not isinstance(e, sympy.Piecewise) \
            and not any(a.imag for a in args):  # DiracDelta, Heaviside...: one step of sympy's, of doubles
        return complex(e.func(*[sympy.Float(a.real) for a in args]).evalf())
    raise Unsupported(type(e).__name__)


def graph_nodes(exprs) -> set[sympy.Basic]:
    """The distinct subexpressions of ``exprs``, each visited once (``free_symbols`` and ``has``
    walk every path, which for a chain of definitions each using the one before twice doubles
    at every step)."""
    seen: set = set()
    stack = [sympy.sympify(e) for e in exprs]
    while stack:
        node = stack.pop()
        if node not in seen:
            seen.add(node)
            stack.extend(node.args)
    return seen


__all__ = ["Unsupported", "complex_value", "graph_nodes"]
