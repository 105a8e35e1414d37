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


def complex_jacobian(exprs, symbols, values: Mapping[sympy.Basic, float]) -> list[list[complex]]:
    """``[[d e / d s for s in symbols] for e in exprs]`` at ``values``, in complex doubles.

    Forward differentiation over the expression graph: each shared subexpression is
    evaluated once with its gradient, so the effort is the size of the graph times the
    number of ``symbols`` (a chain of definitions each using the one before twice is
    linear, where its printed form doubles at each step). Raises as `complex_value`.
    """
    seeds = {s: (complex(values[s]), tuple(1 + 0j if t == s else 0j for t in symbols)) for s in symbols}
    memo: dict = {}
    zero = (0j,) * len(symbols)
    rows = []
    for e in exprs:
        value, grad = _dual(sympy.sympify(e), values, seeds, zero, memo)
        rows.append(list(grad))
    return rows


def _dual(e: sympy.Basic, values, seeds, zero, memo) -> tuple[complex, tuple]:
    hit = memo.get(e)
    if hit is not None:
        return hit
    if e in seeds:
        out = seeds[e]
    elif e in values or not e.args:
        out = complex_value(e, values), zero
    else:
        out = _dual_node(e, [_dual(a, values, seeds, zero, memo) for a in e.args], zero)
    if cmath.isinf(out[0]) or any(cmath.isinf(g) for g in out[1]):
        raise OverflowError("beyond the range of doubles")
    memo[e] = out
    return out


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


def _scaled(grad: tuple, factor: complex) -> tuple:
    return tuple(g * factor for g in grad)


def _summed(grads) -> tuple:
    return tuple(sum(column, 0j) for column in zip(*grads))


def _dual_node(e: sympy.Basic, args: list, zero: tuple) -> tuple[complex, tuple]:
    values = [v for v, _ in args]
    if e.is_Add:
        return sum(values, 0j), _summed([g for _, g in args])
    if e.is_Mul:  # d(prod) = sum_i d a_i * prod_{k != i} a_k, by prefix and suffix products
        before, after = [1 + 0j], [1 + 0j]
        for v in values:
            before.append(before[-1] * v)
        for v in reversed(values):
            after.append(after[-1] * v)
        after.reverse()
        return before[-1], _summed([_scaled(g, before[i] * after[i + 1]) for i, (_, g) in enumerate(args)])
    if e.is_Pow:
        (b, db), (x, dx) = args
        if b == 0:
            raise ZeroDivisionError
        value = b ** int(x.real) if (x.imag == 0 and x.real == int(x.real) and abs(x.real) <= 64) \
            else cmath.exp(x * cmath.log(b))
        grad = _scaled(db, x * value / b)
        if any(dx):
            grad = _summed([grad, _scaled(dx, value * cmath.log(b))])
        return value, grad
    if isinstance(e, sympy.atan2):
        (y, dy), (x, dx) = args
        if y.imag or x.imag:
            raise Unsupported("atan2")
        r2 = x * x + y * y
        if r2 == 0:
            raise ZeroDivisionError
        return complex(math.atan2(y.real, x.real)), _summed([_scaled(dy, x / r2), _scaled(dx, -y / r2)])
    if len(args) != 1:
        raise Unsupported(type(e).__name__)
    (x, dx), = args
    rule = _DERIVATIVES.get(type(e))
    if rule is None:
        raise Unsupported(type(e).__name__)
    value, slope = rule(x)
    return value, _scaled(dx, slope)


def _abs(x: complex) -> tuple[complex, complex]:
    if x.imag:
        raise Unsupported("Abs")
    return complex(abs(x.real)), complex((x.real > 0) - (x.real < 0))


def _sign(x: complex) -> tuple[complex, complex]:
    if x.imag:
        raise Unsupported("sign")
    return complex((x.real > 0) - (x.real < 0)), 0j


_DERIVATIVES = {  # f -> x -> (f(x), f'(x))
    sympy.sin: lambda x: (cmath.sin(x), cmath.cos(x)),
    sympy.cos: lambda x: (cmath.cos(x), -cmath.sin(x)),
    sympy.tan: lambda x: (cmath.tan(x), 1 + cmath.tan(x) ** 2),
    sympy.asin: lambda x: (cmath.asin(x), 1 / cmath.sqrt(1 - x * x)),
    sympy.acos: lambda x: (cmath.acos(x), -1 / cmath.sqrt(1 - x * x)),
    sympy.atan: lambda x: (cmath.atan(x), 1 / (1 + x * x)),
    sympy.exp: lambda x: (cmath.exp(x), cmath.exp(x)),
    sympy.log: lambda x: (cmath.log(x), 1 / x),
    sympy.sinh: lambda x: (cmath.sinh(x), cmath.cosh(x)),
    sympy.cosh: lambda x: (cmath.cosh(x), cmath.sinh(x)),
    sympy.tanh: lambda x: (cmath.tanh(x), 1 - cmath.tanh(x) ** 2),
    sympy.Abs: _abs,
    sympy.sign: _sign,
}
