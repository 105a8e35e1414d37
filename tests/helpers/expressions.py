"""Random expressions for the printer and operation tests (tests/test_printed.py, tests/test_operations.py)."""
from __future__ import annotations

import random

import sympy

x, y, z, a, b = sympy.symbols("x y z a b", real=True)
ATOMS = [x, y, z, a, b, sympy.sin(x - y), sympy.cos(x), sympy.cos(2 * x - y), sympy.sqrt(1 - x ** 2),
         sympy.exp(a), sympy.Abs(y), sympy.pi, sympy.sqrt(2), sympy.Rational(3, 7), sympy.Float("0.125")]


def random_coefficient(rng: random.Random, huge: bool = True):
    """A random number of the kinds the printers treat apart (huge ones only if ``huge``)."""
    kind = rng.randrange(6) if huge else rng.choice((0, 1, 2, 4, 5))
    if kind == 0:
        return sympy.Integer(rng.randint(-9, 9) or 1)
    if kind == 1:
        return sympy.Rational(rng.randint(-50, 50) or 1, rng.randint(1, 60))
    if kind == 2:  # beyond 2**53: rounding of p/q is where a shortcut would differ
        return sympy.Rational(rng.getrandbits(90) + 1, rng.getrandbits(70) + 1) * rng.choice((1, -1))
    if kind == 3:  # beyond the shortcut's range: sympy's own path
        return sympy.Integer(rng.getrandbits(1100) + 1)
    if kind == 4:
        return sympy.Float(rng.uniform(-3, 3))
    return rng.choice((sympy.pi, sympy.sqrt(3), sympy.Rational(1, 3) * sympy.sqrt(2)))


def random_sum(rng: random.Random, depth: int = 2):
    """A random sum of products of :data:`ATOMS` and numbers, nested ``depth`` deep."""
    terms = []
    for _ in range(rng.randint(1, 6)):
        factors = [random_coefficient(rng, huge=depth == 2)]  # no root of a huge integer
        for _ in range(rng.randint(0, 3)):
            atom = rng.choice(ATOMS)
            if depth and rng.random() < 0.25:
                atom = random_sum(rng, depth - 1)
            factors.append(atom ** rng.choice((1, 1, 2, 3, -1, sympy.Rational(1, 2))))
        terms.append(sympy.Mul(*factors))
    return sympy.Add(*terms)
