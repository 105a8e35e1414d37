"""A polar spring and damper anchored off the origin (tests/models/polar_spring_offset.yaml):
its printed sum of forces is factored over eleven variables, where Wang's algorithm once took
minutes (kronsub/core/wang.py peels the variables of degree one first). The equations agree
with a Lagrangian written by hand, and the factorization with sympy's own."""
from __future__ import annotations

import random
import subprocess
import sys

import numpy as np
import pytest
import sympy

import kronsub
from conftest import ROOT
from kronsub.core.seeded import sympy_seeded
from kronsub.core.wang import peeled

MODEL = ROOT / "tests" / "models" / "polar_spring_offset.yaml"


def _hand_lagrangian():
    """``M``, and ``h - f`` of ``M qddot + h = f``, from ``T``, ``V`` and Rayleigh's ``D``."""
    r, a, rd, ad, m, k, L0, c, g = sympy.symbols("r a r_dot a_dot m k L0 c g")
    x, y = r * sympy.cos(a), r * sympy.sin(a)
    xd, yd = rd * sympy.cos(a) - r * ad * sympy.sin(a), rd * sympy.sin(a) + r * ad * sympy.cos(a)
    T = m * (xd**2 + yd**2) / 2
    V = m * g * y + k * (sympy.sqrt((x - 1) ** 2 + y**2) - L0) ** 2 / 2
    length = sympy.sqrt(x**2 + (y - 1) ** 2)
    rate = (x * xd + (y - 1) * yd) / length  # d|p - (0, 1)|/dt
    D = c * rate**2 / 2
    q, qd = [r, a], [rd, ad]
    M = sympy.Matrix(2, 2, lambda i, j: sympy.diff(T, qd[i], qd[j]))
    # d/dt dT/dqd - dT/dq = M qdd + (dM/dq qd) qd - dT/dq
    h = [sum(sympy.diff(sympy.diff(T, qd[i]), q[j]) * qd[j] for j in range(2)) - sympy.diff(T, q[i])
         for i in range(2)]
    f = [-sympy.diff(V, q[i]) - sympy.diff(D, qd[i]) for i in range(2)]
    names = (r, a, rd, ad, m, k, L0, c, g)
    return names, M, [h[i] - f[i] for i in range(2)]


def test_equations_match_a_hand_lagrangian():
    system = kronsub.load(MODEL, cache=False).derive()
    names, M, residual = _hand_lagrangian()
    by_name = {s.name: s for s in (*system.coordinates, *system.velocities, *(p.symbol for p in system.parameters))}
    ours = [by_name[s.name] for s in names]
    mine_M = sympy.lambdify(ours, system.mass_matrix, "numpy")
    mine_r = sympy.lambdify(ours, [hb - fb for hb, fb in zip(system.velocity_terms, system.forces)], "numpy")
    hand_M, hand_r = sympy.lambdify(names, M, "numpy"), sympy.lambdify(names, residual, "numpy")
    rng = np.random.default_rng(31)
    for _ in range(20):
        point = [*rng.uniform(0.3, 2.0, 1), *rng.uniform(-3, 3, 3), *rng.uniform(0.2, 3.0, 5)]
        np.testing.assert_allclose(np.asarray(mine_M(*point), float), np.asarray(hand_M(*point), float),
                                   rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.asarray(mine_r(*point), float).ravel(),
                                   np.asarray(hand_r(*point), float).ravel(), rtol=1e-12, atol=1e-12)


def test_derive_finishes():
    """A hang guard: the derivation and its printed form take seconds (minutes before)."""
    done = subprocess.run([sys.executable, "-m", "kronsub", "derive", "--no-cache", str(MODEL)],
                          capture_output=True, text=True, timeout=90)
    assert done.returncode == 0, done.stderr
    assert "## Equations of motion" in done.stdout


def test_peeled_wang_gives_sympys_factors():
    """The peeled factorization is sympy's, to the printed expression, on random products."""
    V = sympy.symbols("a b c d e f")
    rnd = random.Random(5)

    def poly():
        vs = rnd.sample(V, rnd.randint(1, 4))
        return sum(rnd.randint(-3, 3) * sympy.Mul(*[v ** rnd.randint(0, 2) for v in vs])
                   for _ in range(rnd.randint(1, 4)))

    for _ in range(120):
        expr = sympy.expand(sympy.Mul(*[poly() ** rnd.randint(1, 2) for _ in range(rnd.randint(1, 3))]))
        with sympy_seeded():
            with peeled():
                ours = sympy.factor(expr)
        sympy.core.random.seed(1)
        assert sympy.srepr(ours) == sympy.srepr(sympy.factor(expr))


@pytest.mark.parametrize("expr", ["(x**2 - y**2)*(x*z + y)*(2*z - x)*3", "-(p*c + r)*(s - 1)*(s + 1)*(k*r + L)**2"])
def test_peeled_wang_known_factors(expr):
    e = sympy.sympify(expr)
    with peeled():
        assert sympy.factor(sympy.expand(e)) == sympy.factor(e)


def test_the_factorization_is_charged_to_the_work_budget():
    from kronsub import budget

    x, y, z = sympy.symbols("x y z")
    expr = sympy.expand((x * y + 1) * (x * y - 1) * (x * z - y))
    with budget.limited(units=3), peeled():
        with pytest.raises(budget.WorkBudgetExceeded, match="the factorization of an entry's printed form"):
            sympy.factor(expr)
