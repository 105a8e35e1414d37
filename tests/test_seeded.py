"""sympy's random numbers are drawn from a fixed seed where kronsub calls what uses them
(Wang's factorization picks evaluation points at random: the factors never change, the time
did, from 2 s to over 5 minutes for one spring's reaction), and given back afterwards."""
from __future__ import annotations

import sympy
from sympy.core import random as sympy_random

from kronsub.core import simplify
from kronsub.core.seeded import sympy_seeded


def test_the_same_draws_inside_and_the_state_given_back():
    sympy_random.seed(7)
    sympy_random.rng.random()
    before = sympy_random.rng.getstate(), sympy_random._assumptions_rng.getstate()
    draws = []
    for _ in range(2):
        with sympy_seeded():
            draws.append([sympy_random.randint(0, 10**9) for _ in range(3)])
    assert draws[0] == draws[1]
    assert (sympy_random.rng.getstate(), sympy_random._assumptions_rng.getstate()) == before


def test_factoring_starts_from_the_seed_every_time(monkeypatch):
    """`simplify._factor` (the search for a shorter printed entry) draws the same numbers
    whatever sympy drew before it."""
    seen = []
    real = sympy.factor

    def spy(expr, *args, **kwargs):
        seen.append(sympy_random.randint(0, 10**9))
        return real(expr, *args, **kwargs)

    monkeypatch.setattr(sympy, "factor", spy)
    a, b = sympy.symbols("a b")
    for warm in (3, 11):
        sympy_random.seed(warm)
        assert simplify._factor(sympy.sin(a) ** 2 * b - b) == -b * sympy.cos(a) ** 2
    assert seen[0] == seen[1]
