"""`core.derivative.derivative` is `sympy.diff` without its logarithm detour: the very same
expressions, checked node for node on random expressions and on a spring's potential."""
import random

import pytest
import sympy

from kronsub.core.derivative import derivative, where_defined

q1, q2, q3 = sympy.symbols("q1 q2 q3", real=True)
a, b = sympy.symbols("a b", positive=True)
x = sympy.Symbol("x")
LEAVES = [q1, q2, q3, a, b, x, sympy.Integer(2), sympy.Rational(1, 3), sympy.pi, q1 - q2,
          sympy.sqrt(q1 ** 2 + q2 ** 2), sympy.Abs(q1 - q2), sympy.sign(q1), sympy.exp(q2),
          sympy.atan2(q1, q2), sympy.log(q1 ** 2 + 1)]


def _random_expr(rng: random.Random, depth: int) -> sympy.Expr:
    if depth == 0:
        return rng.choice(LEAVES)
    op = rng.choice(["add", "mul", "pow", "sin", "cos", "leaf", "power of a variable"])
    if op == "leaf":
        return rng.choice(LEAVES)
    if op in ("sin", "cos"):
        return getattr(sympy, op)(_random_expr(rng, depth - 1))
    if op == "pow":
        return _random_expr(rng, depth - 1) ** rng.choice([2, 3, -1, sympy.Rational(1, 2), sympy.Rational(-3, 2), a])
    if op == "power of a variable":
        return _random_expr(rng, depth - 1) ** _random_expr(rng, depth - 1)
    parts = [_random_expr(rng, depth - 1) for _ in range(rng.randint(2, 4))]
    if op == "mul" and rng.random() < 0.5:  # a negated sum among the factors: -(a - b)*sin(q)
        parts = [sympy.Integer(rng.choice([-1, -2, 3])), sympy.Add(*parts[:2]), *parts[2:]]
        return sympy.Mul(*parts) if len(parts) > 2 else sympy.Mul(parts[1], rng.choice(LEAVES), parts[0])
    return sympy.Add(*parts) if op == "add" else sympy.Mul(*parts)


@pytest.mark.parametrize("seed", range(4))
def test_derivative_is_the_expression_sympy_diff_builds(seed):
    rng = random.Random(seed)
    for _ in range(40):
        expr = _random_expr(rng, rng.randint(1, 4))
        for s in (q1, q2, a, x):  # sympy's, with d sign(u)/du = 0 (docs/model-format.md)
            assert sympy.srepr(derivative(expr, s)) == sympy.srepr(where_defined(sympy.diff(expr, s))), (expr, s)
            assert not derivative(expr, s).has(sympy.DiracDelta)


def test_a_springs_potential_and_a_metric_entry():
    k, l1, l2 = sympy.symbols("k l1 l2", positive=True)
    for expr in (k * (q2 - q1 + sympy.pi / 2) ** 2 / 2,
                 l1 * l2 * sympy.cos(q1 - q2) * (a + b / 2) + (l1 * sympy.sin(q1) + l2 * sympy.sin(q2)) ** 2,
                 sympy.sqrt((x - q1) ** 2 + q2 ** 2) - a,
                 # a quick-return linkage's constraint: sympy keeps -(-L sin(a)/2 + r sin(b)) cos(a)
                 -l1 * sympy.sin(q1) ** 2 / 2 - (-l1 * sympy.sin(q1) / 2 + a * sympy.sin(q2)) * sympy.sin(q1)
                 + (l1 * sympy.cos(q1) / 2 - b - a * sympy.cos(q2)) * sympy.cos(q1)):
        for s in (q1, q2, x, a):
            assert sympy.srepr(derivative(expr, s)) == sympy.srepr(sympy.diff(expr, s))
    assert derivative(q1, q1) == 1 and derivative(q1, q2) == 0 and derivative(sympy.Integer(3), q1) == 0
