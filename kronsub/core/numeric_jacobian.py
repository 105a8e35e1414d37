"""The Jacobian ``C = dx/dxbar`` (21) at one configuration, in floating point.

Forward mode over the expressions' tree, each distinct subexpression once: a value and its
gradient in the coordinates (sparse). Nothing symbolic is built, so the cost is the size of
the connection, not that of its symbolic derivatives (a chain of n rods: n^2 terms, where
``sympy.Matrix.jacobian`` forms n^3). Sums, products, powers and the elementary functions
follow their rules; anything else is differentiated by sympy, node by node, and evaluated.
A point outside a function's domain raises ``ValueError``, ``ZeroDivisionError``,
``OverflowError`` or ``TypeError`` (a complex value), as ``math`` does.
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import sympy

from ..budget import charge

_D = {  # f(u) -> f'(u)
    sympy.sin: (math.sin, math.cos),
    sympy.cos: (math.cos, lambda u: -math.sin(u)),
    sympy.tan: (math.tan, lambda u: 1 / math.cos(u) ** 2),
    sympy.exp: (math.exp, math.exp),
    sympy.log: (math.log, lambda u: 1 / u),
    sympy.asin: (math.asin, lambda u: 1 / math.sqrt(1 - u * u)),
    sympy.acos: (math.acos, lambda u: -1 / math.sqrt(1 - u * u)),
    sympy.atan: (math.atan, lambda u: 1 / (1 + u * u)),
    sympy.sinh: (math.sinh, math.cosh),
    sympy.cosh: (math.cosh, math.sinh),
    sympy.tanh: (math.tanh, lambda u: 1 / math.cosh(u) ** 2),
    sympy.Abs: (abs, lambda u: math.copysign(1.0, u) if u else 0.0),
    sympy.sign: (lambda u: math.copysign(1.0, u) if u else 0.0, lambda u: 0.0),
}


def jacobian(exprs: Sequence[sympy.Expr], coordinates: Sequence[sympy.Symbol],
             values: Mapping[sympy.Symbol, float]) -> list[list[float]]:
    """``d exprs_i / d coordinates_j`` where every free symbol has its value in ``values``."""
    return value_and_jacobian(exprs, coordinates, values)[1]


def value_and_jacobian(exprs: Sequence[sympy.Expr], coordinates: Sequence[sympy.Symbol],
                       values: Mapping[sympy.Symbol, float]) -> tuple[list[float], list[list[float]]]:
    """``exprs_i`` and ``d exprs_i / d coordinates_j`` where every free symbol has its value in ``values``."""
    index = {q: j for j, q in enumerate(coordinates)}
    memo: dict = {}
    at, rows = [], []
    for expr in exprs:
        value, grad = _evaluate(sympy.sympify(expr), index, values, memo)
        row = [0.0] * len(coordinates)
        for j, d in grad.items():
            row[j] = d
        at.append(value)
        rows.append(row)
    return at, rows


def _evaluate(root, index, values, memo):
    """(value, {coordinate index: derivative}) of ``root``, children first (no recursion)."""
    stack = [root]
    while stack:
        node = stack[-1]
        if node in memo:
            stack.pop()
            continue
        pending = [a for a in _children(node, index) if a not in memo]
        if pending:
            stack.extend(pending)
            continue
        stack.pop()
        memo[node] = value = _node(node, index, values, memo)
        charge(1 + len(node.args) + len(value[1]), "the Jacobian C = dx/dxbar of the connection")
    return memo[root]


def _children(node, index):
    if node in index or node.is_Symbol or not node.args:  # never ``free_symbols``: it walks every path
        return ()
    if node.is_Add or node.is_Mul or node.is_Pow or (node.func in _D and len(node.args) == 1) \
            or node.func == sympy.atan2:
        return node.args
    return ()


def _node(node, index, values, memo):
    if node in index:
        return float(values[node]), {index[node]: 1.0}
    if node.is_Symbol:
        return float(values[node]), {}
    if not node.args:  # a number
        return _float(node), {}
    if node.is_Add:
        total, grad = 0.0, {}
        for a in node.args:
            v, g = memo[a]
            total += v
            _add_into(grad, g, 1.0)
        return total, grad
    if node.is_Mul:
        parts = [memo[a] for a in node.args]
        total, grad = 1.0, {}
        for k, (_, g) in enumerate(parts):
            if g:
                _add_into(grad, g, math.prod(v for i, (v, _) in enumerate(parts) if i != k))
        for v, _ in parts:
            total *= v
        return total, grad
    if node.is_Pow:
        (b, gb), (e, ge) = memo[node.args[0]], memo[node.args[1]]
        value, grad = math.pow(b, e), {}
        if gb:
            _add_into(grad, gb, e * math.pow(b, e - 1))
        if ge:
            _add_into(grad, ge, value * math.log(b))
        return value, grad
    if node.func == sympy.atan2:
        (y, gy), (x, gx) = memo[node.args[0]], memo[node.args[1]]
        square = x * x + y * y
        grad: dict = {}
        _add_into(grad, gy, x / square)
        _add_into(grad, gx, -y / square)
        return math.atan2(y, x), grad
    if node.func in _D and len(node.args) == 1:
        f, df = _D[node.func]
        u, gu = memo[node.args[0]]
        value, grad = f(u), {}
        if gu:
            _add_into(grad, gu, df(u))
        return value, grad
    return _by_sympy(node, index, values)


def _by_sympy(node, index, values):
    """Any other function (a ``Piecewise``, ``Min``, ``floor``): sympy's derivative, evaluated."""
    at = {s: sympy.Float(values[s]) for s in node.free_symbols}
    grad = {index[q]: _float(sympy.diff(node, q).xreplace(at)) for q in node.free_symbols if q in index}
    return _float(node.xreplace(at)), {j: d for j, d in grad.items() if d}


def _float(value) -> float:
    value = value.evalf() if isinstance(value, sympy.Basic) else value
    return float(value)  # TypeError for a complex value


def _add_into(grad: dict, other: dict, factor: float) -> None:
    for j, d in other.items():
        grad[j] = grad.get(j, 0.0) + factor * d


__all__ = ["jacobian", "value_and_jacobian"]
