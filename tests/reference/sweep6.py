"""The models of tests/models/sweep6/: their loaders and their hand derivations in plain sympy
(never with kronsub), for the tests by subject (tests/test_models_*.py).

The folder holds: a double pendulum of particles on massless rods (and two of them as
placed known systems tied by a spring, under a scene), an elastic spherical pendulum under
scenes (also through `codegen --lang c`), a cart carrying two pendulums from points of its
own (linearized at its equilibrium), an elastic pendulum carrying a rod (its pin's
reactions), a Furuta pendulum of two `rigid_body3d`s (C, numpy, linearized at the upright),
one triple pendulum in absolute and in relative angles (each against the other through the
change of variables), beads on a hoop in a ring of springs, the swinging Atwood machine, a
segway (one motor torque on the wheel and against the body), a heavy top on a sliding base
(its reactions at the cup), a charge in a central and a magnetic field, and closed loops with
`derive --reactions` against the multipliers (a slider-crank whose piston lives on a line, a
four-bar with a sprung coupler); `simulate` runs against energy, momentum and canonical
angular momentum.

Each is checked against a derivation written here in plain sympy (never with kronsub), with
tests/reference/lagrange.py: Lagrange's equations of a hand ``T`` and ``V``,
virtual power over the bodies, virtual work for the non-conservative loads, Lagrange
multipliers on the full coordinates for closed loops.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import sympy as sp
from click.testing import CliRunner

from helpers import Rx, Rz, scene_of, sweep_models
from kronsub.cli import main
from reference.lagrange import (add, Constrained, damper_rows, dots, down, gradient_force, norm, R, rate_of, S,
                                spring_V, t, virtual_power, work_rows, world_angular_velocity)

HERE = Path(__file__).resolve().parent.parent / "models" / "sweep6"


loaded, derived = sweep_models(HERE)


scene = scene_of(loaded)


def particle_pendulum_parts(q1, q2, q, origin=(0, 0), heavier=1, push=True, damper=True):
    """``T, V, Q`` rows (in ``q``) and the lower bob of particle_double_pendulum.yaml, hung at ``origin``."""
    m1, m2, L1, L2, k, l0, c, F0, w, g = S("m1 m2 L1 L2 k l0 c F0 w g")
    O = sp.Matrix(origin)
    b1 = O + L1 * down(q1)
    b2 = b1 + L2 * down(q2)
    m2 = heavier * m2
    T = m1 * rate_of(b1, q).dot(rate_of(b1, q)) / 2 + m2 * rate_of(b2, q).dot(rate_of(b2, q)) / 2
    V = g * (m1 * b1[1] + m2 * b2[1]) + spring_V(k, b2, O + L1 / 2 * down(q1), l0)
    Q = add(damper_rows(c if damper else 0, q2 - q1, q),
            work_rows(sp.Matrix([F0 * sp.cos(w * t) if push else 0, 0]), b2, q))
    return T, V, Q, b2


@lru_cache(maxsize=None)
def twin_reference(quiet=False):
    q = list(S("a1 a2 b1 b2"))
    d, kc = S("d kc")
    TL, VL, QL, left = particle_pendulum_parts(q[0], q[1], q, push=not quiet, damper=not quiet)
    TR, VR, QR, right = particle_pendulum_parts(q[2], q[3], q, origin=(d, 0), heavier=2, push=False,
                                                damper=not quiet)
    V = VL + VR + spring_V(kc, left, right, d)
    return q, TL + TR, V, add(QL, QR)


@lru_cache(maxsize=None)
def elastic_reference(damper=True, swirl=True):
    r, th, ph = q = list(S("r th ph"))
    m, k, l0, c, P, w, g = S("m k l0 c P w g")
    p = r * sp.Matrix([sp.sin(th) * sp.cos(ph), sp.sin(th) * sp.sin(ph), sp.cos(th)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    V = m * g * p[2] + k * (r - l0) ** 2 / 2  # r > 0: the spring's length
    Q = add(damper_rows(c if damper else 0, r, q),
            work_rows(sp.Matrix([P * sp.cos(w * t), P * sp.sin(w * t), 0]) if swirl else sp.zeros(3, 1), p, q))
    return q, T, V, Q


def positive_r(rng):
    return {"r": rng.uniform(0.3, 2), "th": rng.uniform(0.2, 2.9)}


@lru_cache(maxsize=None)
def cart_twin_reference():
    s, p1, p2 = q = list(S("s p1 p2"))
    mc, Jc, a, hh, m1, m2, L1, L2, kt, kw, lw, cp, F0, w, g = S("mc Jc a h m1 m2 L1 L2 kt kw lw cp F0 w g")
    cart = sp.Matrix([s, 0])
    left, right = cart + sp.Matrix([-a, -hh]), cart + sp.Matrix([a, -hh])
    c1, c2 = left + L1 / 2 * down(p1), right + L2 / 2 * down(p2)
    M, h = virtual_power([(mc, cart, 0, Jc), (m1, c1, p1, m1 * L1 ** 2 / 12), (m2, c2, p2, m2 * L2 ** 2 / 12)], q)
    V = (g * (m1 * c1[1] + m2 * c2[1]) + spring_V(kt, left + L1 * down(p1), right + L2 * down(p2), 2 * a)
         + spring_V(kw, sp.Matrix([-R(3, 2), 0]), cart, lw))
    rows = add(damper_rows(cp, p1, q), work_rows(sp.Matrix([F0 * sp.sin(w * t), 0]), cart, q))
    return q, M, h, gradient_force(V, q, rows), V


@lru_cache(maxsize=None)
def furuta_reference(tether=True):
    al, th = q = list(S("al th"))
    ma, r, Ax, Ay, Az, mp, l, Bx, By, Bz, Bxy, u, w, cp, k, g = S("ma r Ax Ay Az mp l Bx By Bz Bxy u w cp k g")
    Ra, Rp = Rz(al), Rz(al) * Rx(th)
    arm = Ra * sp.Matrix([r / 2, 0, 0])
    pend = Ra * sp.Matrix([r, 0, 0]) + Rp * sp.Matrix([0, 0, -l / 2])
    tip = pend + Rp * sp.Matrix([0, 0, -l / 2])
    inertia = sp.Matrix([[Bx, Bxy, 0], [Bxy, By, 0], [0, 0, Bz]])
    M, h = virtual_power([(ma, arm, Ra, sp.diag(Ax, Ay, Az)), (mp, pend, Rp, inertia)], q)
    V = g * (ma * arm[2] + mp * pend[2])
    if tether:
        V += spring_V(k, tip, sp.Matrix([R(3, 10), R(1, 10), -R(3, 5)]))
    rows = add(damper_rows(cp, th, q), [u * sp.cos(w * t), 0])  # the arm turns about z: torque . d omega/d al_dot
    return q, M, h, gradient_force(V, q, rows), V


def triple_parts(a1, a2, a3, q):
    """``M, h, f`` in ``q`` of the triple pendulum whose absolute angles are ``a1, a2, a3`` (in ``q``)."""
    m1, m2, m3, L1, L2, L3, I3, k2, k3, c3, T0, w, P, g = S("m1 m2 m3 L1 L2 L3 I3 k2 k3 c3 T0 w P g")
    c1, e1 = L1 / 2 * down(a1), L1 * down(a1)
    c2, e2 = e1 + L2 / 2 * down(a2), e1 + L2 * down(a2)
    c3p, e3 = e2 + L3 / 2 * down(a3), e2 + L3 * down(a3)
    M, h = virtual_power([(m1, c1, a1, m1 * L1 ** 2 / 12), (m2, c2, a2, m2 * L2 ** 2 / 12), (m3, c3p, a3, I3)], q)
    V = g * (m1 * c1[1] + m2 * c2[1] + m3 * c3p[1]) + k2 * (a2 - a1 - R(1, 10)) ** 2 / 2 + k3 * (a3 - a2) ** 2 / 2
    rows = add(damper_rows(c3, a3 - a2, q), [T0 * sp.sin(w * t) * a1.diff(v) for v in q],
               work_rows(sp.Matrix([P, -P / 2]), e3, q))
    return M, h, gradient_force(V, q, rows), V


RING = {"R": 0.5, "m1": 1.0, "m2": 0.5, "m3": 0.8, "m4": 1.2, "k": 6, "l0": 0.6, "c": 0.3}  # the model's values


@lru_cache(maxsize=None)
def ring_reference(damper=True):
    u = list(S("u1 u2 u3 u4"))
    Rh, k, l0, c = S("R k l0 c")
    m = S("m1 m2 m3 m4")
    p = [Rh * sp.Matrix([sp.cos(a), sp.sin(a)]) for a in u]
    T = sum(mi * Rh ** 2 * ud ** 2 / 2 for mi, ud in zip(m, dots(u)))
    stiffness = [k, 2 * k, k, k / 2]
    V = sum(spring_V(ki, p[i], p[(i + 1) % 4], l0) for i, ki in enumerate(stiffness))
    Q = damper_rows(c if damper else 0, norm(p[1] - p[0]), u)
    return u, T, V, Q


@lru_cache(maxsize=None)
def atwood_reference(rope=True):
    r, a = q = list(S("r a"))
    m, M, L, b, g = S("m M L b g")
    bob = r * sp.Matrix([sp.cos(a), sp.sin(a)])
    T = m * rate_of(bob, q).dot(rate_of(bob, q)) / 2 + M * rate_of(r - L, q) ** 2 / 2
    V = m * g * bob[1] + M * g * (r - L)
    return q, T, V, [-b * dots(q)[0] if rope else 0, 0]


def free_run(tmp_path, model, q, energy, values):
    """`simulate --scene free` of ``model``: its rows, and the hand ``energy`` (at the model's
    parameter ``values``) at each row's state."""
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / model), "--scene", "free", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    f = sp.lambdify([*q, *dots(q)], energy.xreplace(values), "numpy")
    return table, f(*(table[s.name] for s in q), *(table[s.name + "_dot"] for s in q))


@lru_cache(maxsize=None)
def slider_crank_reference():
    th, rx, ry, ra, px = y = list(S("theta rx ry ra px"))
    m1, m2, mp, r, L, e, k, l0, tau, P, g = params = S("m1 m2 mp r L e k l0 tau P g")
    M = sp.diag(m1 * r ** 2 / 3, m2, m2, m2 * L ** 2 / 12, mp)
    tip = sp.Matrix([r * sp.sin(th), e - r * sp.cos(th)])
    half = L / 2 * sp.Matrix([sp.cos(ra), sp.sin(ra)])
    centre = sp.Matrix([rx, ry])
    g_ = [*(tip - (centre - half)), *(centre + half - sp.Matrix([px, 0]))]  # the line is the plane's x axis
    V = g * (m1 * (e - r / 2 * sp.cos(th)) + m2 * ry) + k * (R(3, 2) - px - l0) ** 2 / 2  # the piston left of the wall
    f = gradient_force(V, y, [tau, 0, 0, 0, -P * sp.sin(2 * t) ** 2])
    return Constrained(y, M, sp.zeros(5, 1), f, g_, [th], params)


SLIDER_GUESS = [0.5, 0.52, -0.06, -0.15, 0.91]


def printed_multipliers(name, ref, guess, pv, seed, step=0.4, states=6):
    """Pairs (printed, hand) of the multipliers of ``M yddot + h = f + G^T mu`` along a walk of
    the one independent coordinate: `derive --reactions` prints them in the named intermediates
    (closed form, or the linear system ``G_d^T mu = r``), which are evaluated with the dependent
    coordinates, ``lambda = dy_d/dq`` and ``gamma = yddot_d`` at ``qddot = 0`` from the hand
    constraints and ``qddot`` from the multiplier solve."""
    import json

    result = CliRunner().invoke(main, ["derive", str(HERE / name), "--reactions", "--format", "json"])
    assert result.exit_code == 0, result.output
    printed = json.loads(result.stdout)["reactions"]
    y, (q0,) = ref.y, [ref.y[i] for i in ref.ind]
    dependent = [y[i] for i in ref.dep]
    params = list(S(" ".join(ref.params)))
    names = {s.name: s for s in [*y, *dots(y), t, sp.Symbol(f"{q0.name}_ddot"), *params]}
    names.update({f"lambda_{d.name}_{q0.name}": sp.Symbol(f"lambda_{d.name}_{q0.name}") for d in dependent})
    names.update({f"gamma_{d.name}": sp.Symbol(f"gamma_{d.name}") for d in dependent})
    parse = lambda text: sp.sympify(text, locals=names)  # noqa: E731  (test code, not kronsub)
    if "linear_system" in printed:
        system = printed["linear_system"]
        A = sp.Matrix([[parse(v) for v in row] for row in system["matrix"]])
        b = sp.Matrix([parse(v) for v in system["right_hand_side"]])
        solve = lambda values: np.linalg.solve(*(np.array(e.xreplace(values).evalf(), dtype=float)  # noqa: E731
                                                 for e in (A, b))).ravel()
    else:
        mu = sp.Matrix([parse(v) for v in printed["expressions"].values()])
        solve = lambda values: np.array(mu.xreplace(values).evalf(), dtype=float).ravel()  # noqa: E731
    rng = np.random.default_rng(seed)
    q, pairs, nc = float(guess[ref.ind[0]]), [], len(ref.dep)
    for _ in range(states):
        q += rng.uniform(-step, step)
        u, tt = rng.uniform(-3, 3), rng.uniform(0, 2)
        yv, ydv = ref.consistent([q], [u], guess, pv)
        guess = yv
        a = (tt, *yv, *ydv, *pv)
        M, h, f = (np.array(fn(*a), dtype=float) for fn in (ref.fM, ref.fh, ref.ff))
        G, Gdy = np.array(ref.fG(*a), dtype=float), np.array(ref.fGd(*a), dtype=float).ravel()
        K = np.block([[M, G.T], [G, np.zeros((nc, nc))]])
        sol = np.linalg.solve(K, np.concatenate([f.ravel() - h.ravel(), -Gdy]))
        values = {names[s.name]: v for s, v in zip([*y, *dots(y), *params], [*yv, *ydv, *pv])}
        values.update({t: tt, names[f"{q0.name}_ddot"]: sol[ref.ind[0]]})
        lam = -np.linalg.solve(G[:, ref.dep], G[:, ref.ind]).ravel()
        values.update({names[f"lambda_{d.name}_{q0.name}"]: v for d, v in zip(dependent, lam)})
        gamma = -np.linalg.solve(G[:, ref.dep], Gdy)
        values.update({names[f"gamma_{d.name}"]: v for d, v in zip(dependent, gamma)})
        pairs.append((solve(values), -sol[len(y):]))  # M yddot + G^T (-mu) = f - h
    return pairs


@lru_cache(maxsize=None)
def four_bar_reference():
    t1, t2, t3 = y = list(S("theta1 theta2 theta3"))
    m1, m2, m3, l1, l2, l3, d, kt, k, c3, T0, g = params = S("m1 m2 m3 l1 l2 l3 d kt k c3 T0 g")
    c1, tip1 = l1 / 2 * down(t1), l1 * down(t1)
    c2, tip2 = tip1 + l2 / 2 * down(t2), tip1 + l2 * down(t2)
    hook = c2 + R(1, 10) * down(t2) + R(1, 20) * sp.Matrix([sp.cos(t2), sp.sin(t2)])  # body y: x turned +90 deg
    c3p, tip3 = sp.Matrix([d, 0]) + l3 / 2 * down(t3), sp.Matrix([d, 0]) + l3 * down(t3)
    M, h = virtual_power([(m1, c1, t1, m1 * l1 ** 2 / 12), (m2, c2, t2, m2 * l2 ** 2 / 12),
                          (m3, c3p, t3, m3 * l3 ** 2 / 12)], y)
    V = (g * (m1 * c1[1] + m2 * c2[1] + m3 * c3p[1]) + kt * (t2 - t1 + R(3, 2)) ** 2 / 2
         + spring_V(k, hook, sp.Matrix([R(1, 2), R(1, 2)]), R(3, 10)))
    f = gradient_force(V, y, add(damper_rows(c3, t3, y), [T0 * sp.cos(t), 0, 0]))
    return Constrained(y, M, h, f, list(tip2 - tip3), [t1], params)


FOUR_BAR_GUESS = [2.0, 0.34, -0.25]


@lru_cache(maxsize=None)
def top_reference():
    s, psi, th, phi = q = list(S("s psi th phi"))
    mc, m, hh, A, C, k, l0, c, u, F, g = S("mc m h A C k l0 c u F g")
    Rt = Rz(psi) * Rx(th) * Rz(phi)
    cup = sp.Matrix([s, 0, 0])
    centre = cup + Rt * sp.Matrix([0, 0, hh])
    rim = centre + Rt * sp.Matrix([R(1, 20), 0, R(1, 20)])
    M, h = virtual_power([(mc, sp.Matrix([s])), (m, centre, Rt, sp.diag(A, A, C))], q)
    V = m * g * centre[2] + k * (norm(sp.Matrix([s + 1])) - l0) ** 2 / 2
    omega = world_angular_velocity(Rt, q)
    figure = Rt * sp.Matrix([0, 0, 1])
    flick = sp.Matrix([0, F * sp.cos(5 * t), 0])
    rows = add(damper_rows(c, norm(sp.Matrix([s + 1])), q), [(u * figure).dot(omega.diff(v)) for v in dots(q)],
               work_rows(flick, rim, q))
    return q, M, h, gradient_force(V, q, rows), V, centre, flick


@lru_cache(maxsize=None)
def charge_reference(drag=True):
    r, th, ph = q = list(S("r th ph"))
    m, mu, eps, b, c = S("m mu eps b c")
    p = r * sp.Matrix([sp.sin(th) * sp.cos(ph), sp.sin(th) * sp.sin(ph), sp.cos(th)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    V = -mu * m / r + eps * p[2] ** 2 / 2
    F = sp.Matrix([b * v[1], -b * v[0], 0]) - (c if drag else 0) * v
    return q, T, V, work_rows(F, p, q)


RELATIVE_PIVOT = """\
name: double pendulum in relative angles on pivots
parameters: {m: 1, L: 1, g: 9.81}
components:
  r1: {type: pinned_rod, parameters: {mass: m, length: L}, coordinates: {angle: b1}}
  r2: {type: pinned_rod, parameters: {mass: m, length: L}, coordinates: {angle: b2}, pivot: r1.tip}
coordinates: COORDINATES
connection:
  b1: q1
CONNECTED
effects:
  gravity: {type: gravity}
"""
