"""The remembered operation count (kronsub/core/operations.py) is sympy's ``count_ops``."""
from __future__ import annotations

import random
from pathlib import Path

import pytest
import sympy

import kronsub
from helpers.expressions import random_sum
from kronsub.core.operations import count_ops

REPO = Path(__file__).resolve().parent.parent
x, y = sympy.symbols("x y")
f = sympy.Function("f")

EDGES = [
    sympy.Integer(0), sympy.Integer(1), sympy.Integer(-1), sympy.Rational(-1, 3), sympy.Float(-2.5),
    -x, -x - y, -x + y, x - y, 1 / x, -1 / x, 2 / x, -2 / (3 * x), x / y, -x / y, x ** -2,
    x * y ** sympy.Rational(-1, 2), sympy.exp(x), sympy.exp(-x), sympy.E, sympy.E ** (x * y),
    sympy.Pow(sympy.E, x, evaluate=False), sympy.Max(x, y, 1), sympy.Min(x, y), f(x, y) + f(-x),
    sympy.Derivative(f(x), x), sympy.Integral(x, (x, 0, 1)), sympy.Abs(-x - y), sympy.sqrt(1 - x ** 2),
    sympy.Mul(-1, x + y, evaluate=False), sympy.Mul(2, x + y, evaluate=False), -(x + y) / (x - y),
    sympy.sin(x) ** 2 + sympy.cos(x) ** 2 - 1, (x - 1) * (x + 1) / (2 * y), sympy.pi * x / 2,
    -y / x ** 2, -sympy.sqrt(x) / y, -y * sympy.exp(-x), -x * y / 2, -x ** y * y, -x ** (-y) * y,
    -sympy.Rational(3, 2) * x ** sympy.Rational(3, 2) * sympy.sin(y) ** 2, -x ** -1, -(x + y) ** -3,
    # products of numbers left unevaluated (sympy's fraction() multiplies them out)
    sympy.Mul(1, 2, 3, evaluate=False), sympy.Mul(-1, 2, 3, evaluate=False), sympy.Mul(-3, -3, 2, 3, evaluate=False),
    sympy.Mul(sympy.sqrt(2), sympy.sqrt(2), evaluate=False), sympy.Mul(-1, sympy.sqrt(3), sympy.sqrt(3), evaluate=False),
    sympy.Mul(sympy.I, sympy.I, evaluate=False), x + sympy.Mul(sympy.I, sympy.I, evaluate=False),
]


@pytest.mark.parametrize("expr", EDGES, ids=[str(e) for e in EDGES])
def test_edges(expr):
    assert count_ops(expr) == sympy.count_ops(expr)


@pytest.mark.parametrize("seed", range(4))
def test_random_expressions(seed):
    rng = random.Random(300 + seed)
    for _ in range(150):
        e = random_sum(rng)
        assert count_ops(e) == sympy.count_ops(e), e
        assert count_ops(-e) == sympy.count_ops(-e), -e
        assert count_ops(1 / e) == sympy.count_ops(1 / e), 1 / e


def test_other_arguments_go_to_sympy():
    assert count_ops([x + y, sympy.sin(x)]) == 2
    assert count_ops(sympy.Eq(x + y, 1)) == sympy.count_ops(sympy.Eq(x + y, 1))


@pytest.mark.parametrize("name", ["models/hoffmann/system2.yaml", "models/examples/watt_governor.yaml",
                                  "models/examples/slider_crank.yaml"])
def test_bundled_models(name):
    system = kronsub.load(REPO / name).derive()
    for e in [*system.mass_matrix, *system.velocity_terms, *system.forces, system.potential_energy]:
        assert count_ops(e) == sympy.count_ops(e), e


def test_rational_multiples_of_products():
    """A product with a rational coefficient is counted without building ``-a`` and the
    numerator of ``fraction`` (a large system's entries, e.g. ``l1*l2*(m2 + 2*m3)*cos(q1 - q2)/2``):
    every sign, numerator and denominator, over factors sympy joins (``x**2*x**2``) or
    distributes (``2*(x + y)``) when it rebuilds them, checked against sympy."""
    rng = random.Random(20261128)
    z = sympy.Symbol("z")
    pool = [x, y, x + y, x - 2 * y, y ** 2, sympy.sqrt(x), 1 / y, sympy.sin(x - y), sympy.cos(x), sympy.exp(x),
            sympy.Mul(x, y, evaluate=False), -x - y, z ** sympy.Rational(3, 2)]
    coefficients = [sympy.Integer(-1), sympy.Integer(2), sympy.Integer(-3), sympy.Rational(1, 2),
                    sympy.Rational(-1, 3), sympy.Rational(3, 4), sympy.Rational(-5, 6)]
    for _ in range(400):
        c = rng.choice(coefficients)
        factors = [rng.choice(pool) for _ in range(rng.randint(1, 4))]
        for e in (sympy.Mul(c, *factors), sympy.Mul(c, *factors, evaluate=False)):
            assert count_ops(e) == sympy.count_ops(e), e
            assert count_ops(e + x) == sympy.count_ops(e + x), e + x
