"""Choosing the printed form of an entry: the compact closed forms of the paper.

The trigonometric-polynomial form is already compact for sums of angles
(``2 a1 a2 m2 cos(theta - phi)`` in (22)); where it holds multiple angles
(``m R^2 (1 - cos 2 theta)/2``) a small entry is offered to sympy's
``trigsimp`` and the shorter result kept (``m R^2 sin(theta)^2``).
"""
from __future__ import annotations

import sympy

from .inverse_trig import divide_out
from .trigpoly import TrigAlgebra, TrigPoly

SMALL = 40  # operations; larger entries keep their trigonometric-polynomial form


def compact(algebra: TrigAlgebra, p: TrigPoly) -> sympy.Expr:
    """The shortest of a few equivalent forms of ``p`` (deterministic)."""
    p = divide_out(algebra, p)
    expr = algebra.to_expr(p)
    if not algebra.has_multiple_angles(p):
        return expr
    ops = sympy.count_ops(expr)
    if ops > SMALL:
        return expr
    best, best_ops = expr, ops
    for candidate in (sympy.factor_terms(expr), sympy.trigsimp(expr)):
        c_ops = sympy.count_ops(candidate)
        if c_ops < best_ops:
            best, best_ops = candidate, c_ops
    return best
