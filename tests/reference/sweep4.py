"""The models of tests/models/sweep4/: their loaders and their hand derivations in plain sympy
(never with kronsub), for the tests by subject (tests/test_models_*.py).

The folder holds: two-loop linkages (a Stephenson six-bar, a V-twin sharing one
crank), a known closed loop renamed with a second loop around it, a four-bar whose coupler
carries a pendulum, implicit constraints mixing lengths and angles, a closed loop in space
(a rod on a ball joint, its tip on a tilted plane), a gyroscope on gimbals in Z-X-Y angles
with an offset mass centre, a free body in X-Z-X angles, forces in the velocities (quadratic
drag, abs) and in time, central potentials in polar and spherical coordinates, component
parameters given by expressions of shared ones, zero coefficients and zero-length springs,
and scenes over a known system.

Each is checked against a derivation written here in plain sympy (never with kronsub), with
tests/reference/lagrange.py: Lagrange's equations of a hand ``T`` and ``V``,
virtual power over the bodies, Lagrange multipliers on the full coordinates for closed
loops (and the reactions of `simulate --reactions` against them).
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import sympy as sp

from helpers import generated_numpy_module, Rx, Ry, Rz, sweep_models
from reference.lagrange import (Constrained, damper_rows, dots, down, gradient_force, rate_of, S, t,
                                virtual_power, world_angular_velocity)

HERE = Path(__file__).resolve().parent.parent / "models" / "sweep4"


loaded, derived = sweep_models(HERE)


def across(a):
    """A pinned rod's body y axis (its x axis, ``down(a)``, turned a quarter counter-clockwise)."""
    return sp.Matrix([sp.cos(a), sp.sin(a)])


@lru_cache(maxsize=None)
def gimbal_reference():
    psi, th, ph = q = list(S("psi theta phi"))
    Jo, mi, Ai, Bi, Ci, m, A, C, P, e, tm, kg, cg, F0, g = S("Jo mi Ai Bi Ci m A C P e tm kg cg F0 g")
    Ri, R = Rz(psi) * Rx(th), Rz(psi) * Rx(th) * Ry(ph)
    centre = Ri * sp.Matrix([0, 0, -e])
    bodies = [(0, sp.Matrix([0]), psi, Jo), (mi, sp.zeros(3, 1), Ri, sp.diag(Ai, Bi, Ci)),
              (m, centre, R, sp.Matrix([[A, 0, P], [0, C, 0], [P, 0, A]]))]
    M, h = virtual_power(bodies, q)
    V = m * g * centre[2] + kg * (th - sp.Rational(1, 10)) ** 2 / 2
    omega = world_angular_velocity(R, q)
    torque = tm * R * sp.Matrix([0, 1, 0])
    nose = centre + R * sp.Matrix([0, sp.Rational(1, 10), sp.Rational(1, 20)])
    push = sp.Matrix([F0 * sp.cos(t), 0, -F0])
    f = gradient_force(V, q, [torque.dot(omega.diff(vd)) + push.dot(nose.diff(v)) + d
                              for v, vd, d in zip(q, dots(q), damper_rows(cg, psi + th / 2, q))])
    return q, M, h, f, V


def numpy_module(tmp_path, name):
    return generated_numpy_module(tmp_path, HERE / name)


def kepler_reference():
    r, a = q = list(S("r a"))
    m, mu, eps, T0, tau, cr = S("m mu eps T0 tau cr")
    p = r * sp.Matrix([sp.cos(a), sp.sin(a)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    V = -mu * m / r + m * eps / r ** 2
    thrust = T0 * sp.exp(-t / tau) * sp.Matrix([-sp.sin(a), sp.cos(a)])
    rd = dots(q)[0]
    Q = [thrust.dot(p.diff(x)) - cr * sp.Abs(rd) * rd * int(x == r) for x in q]
    return q, T, V, Q


def torsion_parts(th1, th2, rho):
    a, kt, k0, cr, c0, g = S("a kt k0 cr c0 g")
    q = [th1, th2]
    m1, m2 = 2 * rho * a, 3 * rho * a
    c1, tip1 = a * down(th1), 2 * a * down(th1)
    c2, tip2 = tip1 + 3 * a / 2 * down(th2), tip1 + 3 * a * down(th2)
    bodies = [(m1, c1, th1, m1 * (2 * a) ** 2 / 12), (m2, c2, th2, m2 * (3 * a) ** 2 / 12)]
    gap = tip2 - sp.Matrix([sp.Rational(3, 10), -sp.Rational(3, 2)])
    V = g * (m1 * c1[1] + m2 * c2[1]) + kt * (th1 + th2 / 2 - sp.sin(th1) / 3 - sp.Rational(1, 5)) ** 2 / 2 \
        + k0 * gap.dot(gap) / 2
    rows = [x + y for x, y in zip(damper_rows(cr, th2 - th1, q), damper_rows(c0, th1 - 2 * th2, q))]
    return bodies, V, rows


@lru_cache(maxsize=None)
def scene_reference():
    u, v, fw = q = list(S("u v f"))
    Jf, ks, tm = S("Jf ks tm")
    bodies, V, rows = torsion_parts(u, v, sp.Rational(3, 2))
    M, h = virtual_power(bodies + [(0, sp.Matrix([0]), fw, Jf)], q)
    V = V + ks * (fw - u) ** 2 / 2
    motor = [0, 0, tm * sp.cos(t)]
    return q, M, h, V, [*rows, 0], motor


@lru_cache(maxsize=None)
def six_bar_reference():
    y = list(S("th1 th2 th3 th4 th5"))
    th1, th2, th3, th4, th5 = y
    params = S("m1 m2 m3 m4 m5 l1 l2 l3 l4 l5 d ex ey tm cm k g")
    m1, m2, m3, m4, m5, l1, l2, l3, l4, l5, d, ex, ey, tm, cm, k, g = params
    A = l1 * down(th1)
    c2 = A + l2 / 2 * down(th2)
    ear = c2 + sp.Rational(1, 5) * down(th2) + sp.Rational(1, 4) * across(th2)
    D, E = sp.Matrix([d, 0]), sp.Matrix([ex, ey])
    c3, c4, c5 = D + l3 / 2 * down(th3), ear + l4 / 2 * down(th4), E + l5 / 2 * down(th5)
    bodies = [(m1, l1 / 2 * down(th1), th1, m1 * l1 ** 2 / 12), (m2, c2, th2, m2 * l2 ** 2 / 12),
              (m3, c3, th3, m3 * l3 ** 2 / 12), (m4, c4, th4, m4 * l4 ** 2 / 12), (m5, c5, th5, m5 * l5 ** 2 / 12)]
    M, h = virtual_power(bodies, y)
    joint = ear + l4 * down(th4)
    gap = joint - sp.Matrix([sp.Rational(9, 5), -sp.Rational(6, 5)])
    V = g * sum(b[0] * b[1][1] for b in bodies) + k * gap.dot(gap) / 2
    f = gradient_force(V, y, [(tm - cm * dots(y)[0]) * int(a == th1) for a in y])
    g_ = [*(A + l2 * down(th2) - D - l3 * down(th3)), *(joint - E - l5 * down(th5))]
    return Constrained(y, M, h, f, g_, [th1], params)


@lru_cache(maxsize=None)
def v_twin_reference():
    y = list(S("th ps1 ps2 x1 y1 x2 y2"))
    th, ps1, ps2, x1, y1, x2, y2 = y
    params = S("m1 J r mr L mp be P1 P2 cp g")
    m1, J, r, mr, L, mp, be, P1, P2, cp, g = params
    A = r * down(th)
    c1, c2 = A + L / 2 * down(ps1), A + L / 2 * down(ps2)
    p1, p2 = sp.Matrix([x1, y1]), sp.Matrix([x2, y2])
    bodies = [(m1, r / 2 * down(th), th, m1 * r ** 2 / 12 + J), (mr, c1, ps1, mr * L ** 2 / 12),
              (mr, c2, ps2, mr * L ** 2 / 12), (mp, p1), (mp, p2)]
    M, h = virtual_power(bodies, y)
    V = g * sum(b[0] * b[1][1] for b in bodies)
    yd = dots(y)
    loads = [(p1, -P1 * sp.Matrix([sp.sin(be), sp.cos(be)]) - cp * sp.Matrix(yd[3:5])),
             (p2, P2 * sp.Matrix([sp.sin(be), -sp.cos(be)]) - cp * sp.Matrix(yd[5:7]))]
    f = gradient_force(V, y, [sum(F.dot(p.diff(a)) for p, F in loads) for a in y])
    g_ = [*(A + L * down(ps1) - p1), *(A + L * down(ps2) - p2),
          y1 * sp.sin(be) - x1 * sp.cos(be), -x2 * sp.cos(be) - y2 * sp.sin(be)]  # d x (P - O)
    return Constrained(y, M, h, f, g_, [th], params)


V_TWIN_GUESS = [0.3, 2.625, 3.787, 0.291, 0.291, -0.256, 0.256]


@lru_cache(maxsize=None)
def four_bar_parts(a, b, c):
    """Bodies, potential (gravity) and pin gap of models/examples/four_bar.yaml."""
    m1, m2, m3, l1, l2, l3, d, g = S("m1 m2 m3 l1 l2 l3 d g")
    A = l1 * down(a)
    D = sp.Matrix([d, 0])
    bodies = [(m1, l1 / 2 * down(a), a, m1 * l1 ** 2 / 12), (m2, A + l2 / 2 * down(b), b, m2 * l2 ** 2 / 12),
              (m3, D + l3 / 2 * down(c), c, m3 * l3 ** 2 / 12)]
    V = g * sum(x[0] * x[1][1] for x in bodies)
    return bodies, V, list(A + l2 * down(b) - D - l3 * down(c))
