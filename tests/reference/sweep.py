"""The models of tests/models/sweep/: their loaders and their hand derivations in plain sympy
(never with kronsub), for the tests by subject (tests/test_models_*.py).

Models kronsub was not built around: a spring pendulum, a top sideways, a disc on a seesaw, a
bead on a hoop, a box on springs in space, slider-cranks, four-bars and a quick return.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import sympy as sp

import kronsub
from helpers.compare import walk_constrained
from reference.lagrange import Constrained, dots, rate_of, S

SWEEP = Path(__file__).resolve().parent.parent / "models" / "sweep"


@lru_cache(maxsize=None)
def derived(name):
    return kronsub.load(SWEEP / name).derive(scene=False)  # the whole model, also of a model with one scene


@lru_cache(maxsize=None)
def slider_crank_reference():
    th, rx, ry, ra, px, py = y = list(S("theta rx ry ra px py"))
    m1, m2, mp, r, L, e, k, l0, c, tau, g = params = S("m1 m2 mp r L e k l0 c tau g")
    M = sp.diag(m1 * r ** 2 / 3, m2, m2, m2 * L ** 2 / 12, mp, mp)
    tip = sp.Matrix([r * sp.sin(th), -r * sp.cos(th)])
    axis = L / 2 * sp.Matrix([sp.cos(ra), sp.sin(ra)])
    piston = sp.Matrix([px, py])
    g_ = [*(tip - (sp.Matrix([rx, ry]) - axis)), *(sp.Matrix([rx, ry]) + axis - piston), py - e]
    gap = piston - sp.Matrix([sp.Rational(13, 10), e])
    length = sp.sqrt(gap.dot(gap))
    V = g * (-m1 * r / 2 * sp.cos(th) + m2 * ry + mp * py) + k * (length - l0) ** 2 / 2
    f = sp.Matrix([-V.diff(a) - c * rate_of(length, y) * length.diff(a) + tau * int(a == th) for a in y])
    return Constrained(y, M, sp.zeros(6, 1), f, g_, [th], params)


@lru_cache(maxsize=None)
def slider_crank_rows():
    return walk_constrained(derived("offset_slider_crank.yaml"), slider_crank_reference(), 0.5,
                            [0.5, 0.44, -0.14, 0.11, 0.79, -0.1], 11)


@lru_cache(maxsize=None)
def four_bar_rows():
    a1, cx, cy, a2, a3 = y = list(S("a1 cx cy a2 a3"))
    m1, m2, m3, l1, l2, l3, d, h, k, c, g = params = S("m1 m2 m3 l1 l2 l3 d h k c g")
    M = sp.diag(m1 * l1 ** 2 / 3, m2, m2, m2 * l2 ** 2 / 12, m3 * l3 ** 2 / 3)
    down = lambda a: sp.Matrix([sp.sin(a), -sp.cos(a)])  # noqa: E731
    half = l2 / 2 * sp.Matrix([sp.cos(a2), sp.sin(a2)])
    centre, D = sp.Matrix([cx, cy]), sp.Matrix([d, h])
    g_ = [*(l1 * down(a1) - (centre - half)), *(centre + half - (D + l3 * down(a3)))]
    V = g * (-m1 * l1 / 2 * sp.cos(a1) + m2 * cy + m3 * (h - l3 / 2 * sp.cos(a3))) + k * (a3 + sp.Rational(1, 5)) ** 2 / 2
    f = sp.Matrix([-V.diff(a) - c * dots(y)[0] * int(a == a1) for a in y])
    system = derived("four_bar_free_coupler.yaml")
    assert [s.name for s in system.coordinates] == ["a1"]  # coordinates: auto
    ref = Constrained(y, M, sp.zeros(5, 1), f, g_, [a1], params)
    return walk_constrained(system, ref, 2.0, [2.0, 0.73, -0.23, -0.69, 0.36], 12, step=0.2)
