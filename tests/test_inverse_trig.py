"""Inverse trigonometric functions in the trigonometric algebra (kronsub/core/inverse_trig.py):
exact division of trigonometric polynomials, canonical radicands, multiple angles."""
from __future__ import annotations

import numpy as np
import pytest
import sympy
from sympy import acos, asin, atan2, cos, sin, sqrt

from kronsub.core.inverse_trig import Radicands, divide_out, exact_quotient
from kronsub.core.trigpoly import TrigAlgebra

a, b, c, k = sympy.symbols("a b c k", real=True)


def _value(expr, point):
    return complex(expr.subs({s: sympy.Rational(str(float(v))) for s, v in point.items()}).evalf(30))


def _close(x, y, point):
    return abs(_value(x, point) - _value(y, point)) <= 1e-20 * max(1.0, abs(_value(y, point)))


@pytest.mark.parametrize("p, q", [
    (1 - sin(b) ** 2 * sin(c) ** 2, cos(a) * sin(b) + k * cos(2 * c) - 3),
    (2 + cos(a - b), sin(a / 2) * k ** 2 + cos(b)),
    (cos(a) ** 2 * k + sin(b), sin(a + b - c) + 1),
])
def test_a_product_divides_by_its_factor_exactly(p, q):
    algebra = TrigAlgebra((a, b, c))
    P, Q = algebra.from_expr(p), algebra.from_expr(q)
    quotient = exact_quotient(P * Q, P)
    assert quotient is not None
    difference = quotient - Q
    assert difference.is_zero()


def test_no_quotient_when_the_division_is_not_exact():
    algebra = TrigAlgebra((a, b))
    P = algebra.from_expr(1 - sin(a) ** 2 * sin(b) ** 2)
    assert exact_quotient(algebra.from_expr(cos(a) + k), P) is None
    assert exact_quotient(P * algebra.from_expr(cos(a)) + algebra.from_expr(sin(b)), P) is None


def test_equal_radicands_become_one_atom_and_cancel():
    """``cos(atan2(y, x)) sqrt(1 - u^2)`` with ``x^2 + y^2 = 1 - u^2`` (the rows of a rotation)."""
    algebra = TrigAlgebra((b, c))
    radicands = Radicands(algebra, [atan2(sin(b) * cos(c), cos(b))])
    x, y, u = cos(b), sin(b) * cos(c), sin(b) * sin(c)
    expr = cos(atan2(y, x)) * sqrt(1 - u ** 2)  # = x / sqrt(x^2 + y^2) * sqrt(1 - u^2) = x
    p = algebra.from_expr(radicands.rewrite(expr))
    assert algebra.to_expr(p) == cos(b)


def test_negative_powers_are_divided_out_where_exact():
    algebra = TrigAlgebra((b, c))
    radicands = Radicands(algebra, [asin(sin(b) * sin(c))])
    u = sin(b) * sin(c)
    q = cos(b) + sin(c) ** 2
    expr = sympy.expand(q * (1 - u ** 2)) / (sin(b) ** 2 * cos(c) ** 2 + cos(b) ** 2) + sqrt(1 - u ** 2)
    p = divide_out(algebra, algebra.from_expr(radicands.rewrite(expr)))
    out = algebra.to_expr(p)
    point = {b: 0.7, c: -0.4}
    assert _close(out, q + sqrt(1 - u ** 2), point)
    assert not any(e.exp.is_negative for e in out.atoms(sympy.Pow))  # the quotient is gone


def test_multiples_of_inverse_functions_are_expanded():
    algebra = TrigAlgebra((b,))
    radicands = Radicands(algebra, [acos(cos(b) / 2)])
    expr = sin(2 * acos(cos(b) / 2))  # = 2 (cos b / 2) sqrt(1 - cos^2 b / 4)
    out = algebra.to_expr(algebra.from_expr(radicands.rewrite(expr)))
    assert not out.has(acos)
    for value in np.linspace(-3, 3, 7):
        assert _close(out, expr, {b: value})


def test_a_connection_without_inverse_functions_is_left_alone():
    algebra = TrigAlgebra((a,))
    radicands = Radicands(algebra, [sin(a), cos(a) ** 2])
    assert not radicands.active and algebra.prepare is None
    expr = 1 / sqrt(2 - sin(a) ** 2)
    assert radicands.rewrite(expr) is expr
