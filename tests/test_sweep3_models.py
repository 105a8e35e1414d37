"""Third robustness sweep: textbook models of kinds the first two sweeps did not cover
(tests/models/sweep3/): known systems three levels deep, a known system reused twice and
placed, a closed loop inside a known system carrying a pendulum, pulleys and gear trains by
explicit connections, a planar body on spring-damper legs, a pendulum on a point of a
rolling body, a body on a Cardan joint with products of inertia, linear implicit
constraints (a rope over a pulley), a bead on a cone in spherical coordinates.

Each is checked against an independent derivation written here in plain sympy (never with
kronsub), with the reference helpers of test_sweep_models.py: Lagrange's equations of a hand
``T`` and ``V``, virtual power over the bodies, and Lagrange multipliers on the full
coordinates for closed loops. ``Mbar``, ``hbar``, ``fbar`` (and ``T``, ``V``) at random states
and randomly perturbed parameters; for some, the accelerations of the compiled C and of the
generated numpy module.
"""
from __future__ import annotations

import dataclasses
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

import kronsub
from helpers import Rx, Ry, Rz, generated_numpy_module
from kronsub.errors import ModelError
from kronsub.cli import main
from test_sweep_models import (Constrained, compare_explicit, dots, lagrange, largest_difference, rate_of,
                               virtual_power, walk_constrained, world_angular_velocity, worst)

HERE = Path(__file__).resolve().parent / "models" / "sweep3"
t = sp.Symbol("t")
S = sp.symbols
TOL = 1e-10


@lru_cache(maxsize=None)
def derived(name):
    return kronsub.load(HERE / name).derive()


def down(a):
    return sp.Matrix([sp.sin(a), -sp.cos(a)])


def compare_energies(system, T, V, seed, *, spread=3.0, jitter=0.3, states=6, fixed=None):
    """Largest relative difference of kronsub's ``T`` (from ``Mbar``) and ``V`` from the hand ones."""
    return largest_difference(system, [system.kinetic_energy, system.potential_energy], [sp.sympify(T), sp.sympify(V)],
                              seed, spread=spread, jitter=jitter, states=states, fixed=fixed)


def kinetic(M, q):
    qd = sp.Matrix(dots(q))
    return (qd.T * M * qd)[0, 0] / 2


def accelerations_agree(system, M, h, f, seed, *, states=5, spread=2.0, numpy_module=None):
    """kronsub's compiled right-hand side (and optionally a generated numpy module's) against
    ``M^-1 (f - h)`` of the reference at the model's parameter values."""
    num = system.numeric()
    q = [sp.Symbol(s.name) for s in system.coordinates]
    names = [p.name for p in system.parameters if p.name in num.parameters]
    args = [t, *q, *dots(q), *(sp.Symbol(n) for n in names)]
    fns = [sp.lambdify(args, sp.Matrix(e), "numpy") for e in (M, h, f)]
    pv = [num.parameters[n] for n in names]
    rng = np.random.default_rng(seed)
    n, pairs = len(q), []
    for _ in range(states):
        tt, y = rng.uniform(0, 3), rng.uniform(-spread, spread, 2 * n)
        Mr, hr, fr = (np.array(fn(tt, *y, *pv), dtype=float) for fn in fns)
        want = np.linalg.solve(Mr, fr.ravel() - hr.ravel())
        pairs.append((num.rhs(tt, y)[n:], want))
        if numpy_module is not None:
            slots = np.array([num.parameters[name] for name in numpy_module.PARAMETERS])
            pairs.append((np.asarray(numpy_module.rhs(tt, y, slots))[n:], want))
    return worst(pairs)


def numpy_module(tmp_path, name):
    return generated_numpy_module(tmp_path, HERE / name)


# ------------------------------------------------------------------------------------------
# Known systems: System I plus a rod, three levels, two copies placed
# ------------------------------------------------------------------------------------------

def test_triple_pendulum_on_system1():
    """System I (with overridden m2, a2, F) as a known system and a rod hung from its end B."""
    th, ph, ps = q = list(S("theta phi psi"))
    m1, a1, I1, I2, g, m3, L3, c3 = S("m1 a1 I1 I2 g m3 L3 c3")
    Fa, w = S("Fa w")
    m2, a2, F = sp.Rational(13, 10), sp.Rational(7, 20), Fa * sp.cos(w * t)
    c1 = a1 * down(th)
    c2 = 2 * a1 * down(th) + a2 * down(ph)
    end = c2 + a2 * down(ph)
    c3p = end + L3 / 2 * down(ps)
    M, h = virtual_power([(m1, c1, th, I1), (m2, c2, ph, I2), (m3, c3p, ps, m3 * L3 ** 2 / 12)], q)
    V = g * (m1 * c1[1] + m2 * c2[1] + m3 * c3p[1])
    rel = ps - ph
    f = sp.Matrix([-V.diff(a) + F * c2[0].diff(a) - c3 * rate_of(rel, q) * rel.diff(a) for a in q])
    system = derived("triple_pendulum.yaml")
    assert compare_explicit(system, (M, h, f), 31) < TOL
    assert compare_energies(system, kinetic(M, q), V, 31) < TOL


def cart_pendulum_parts(x, th, origin=(0, 0), mb_factor=1):
    """Bodies and potential of cart_pendulum.yaml (itself sprung_cart.yaml plus a rod and a bob)."""
    mc, mp, L, mb, g = S("mc mp L mb g")
    cart = sp.Matrix([x + origin[0], origin[1]])
    rod = cart + L / 2 * down(th)
    bob = cart + L * down(th)
    bodies = [(mc, cart), (mp, rod, th, mp * L ** 2 / 10), (mb_factor * mb, bob)]
    V = g * (mp * rod[1] + mb_factor * mb * bob[1])
    return bodies, V, cart, bob


def sprung_cart_force(x, q, push=True):
    """The wall spring (rest length l0 from x = -w), damper and push of sprung_cart.yaml: ``-dV``
    is the caller's, the potential is returned with the non-conservative forces."""
    k, l0, w, c, P, om = S("k l0 w c P om")
    V = k * (x + w - l0) ** 2 / 2  # the cart stays right of the wall
    Q = sp.Matrix([(-c * rate_of(x, q) + (P * sp.cos(om * t) if push else 0)) * x.diff(a) for a in q])
    return V, Q


@lru_cache(maxsize=None)
def cart_pendulum_reference():
    x, th = q = list(S("x th"))
    cp = S("cp")
    bodies, V, _, _ = cart_pendulum_parts(x, th)
    M, h = virtual_power(bodies, q)
    Vs, Q = sprung_cart_force(x, q)
    V = V + Vs
    f = sp.Matrix([-V.diff(a) + Q[i] - cp * dots(q)[1] * int(a == th) for i, a in enumerate(q)])
    return q, M, h, f, V


def test_cart_pendulum_two_levels():
    q, M, h, f, V = cart_pendulum_reference()
    system = derived("cart_pendulum.yaml")
    fixed = lambda rng: {"x": rng.uniform(0, 1)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 32, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 32, fixed=fixed) < TOL


@lru_cache(maxsize=None)
def two_cart_reference():
    """cart_pendulum.yaml twice (renamed, the right one placed at (d, 0) with a heavier bob and
    no push), joined by a spring of rest length d and a damper, the right bob shoved."""
    x1, th1, x2, th2 = q = list(S("x1 th1 x2 th2"))
    d, kc, cc, Q0, cp = S("d kc cc Q cp")
    b1, V1, cart1, _ = cart_pendulum_parts(x1, th1)
    b2, V2, cart2, bob2 = cart_pendulum_parts(x2, th2, origin=(d, 0), mb_factor=2)
    M, h = virtual_power(b1 + b2, q)
    Vs1, Q1 = sprung_cart_force(x1, q)
    Vs2, Q2 = sprung_cart_force(x2, q, push=False)  # the right copy's own wall is at x2 = -w
    gap = cart2[0] - cart1[0]  # > 0: the right cart stays right of the left one
    V = V1 + V2 + Vs1 + Vs2 + kc * (gap - d) ** 2 / 2
    shove = Q0 * sp.Matrix([1, 2]) / sp.sqrt(5)
    f = sp.Matrix([-V.diff(a) + Q1[i] + Q2[i] - cc * rate_of(gap, q) * gap.diff(a) + shove.dot(bob2.diff(a))
                   - cp * dots(q)[i] * int(a in (th1, th2)) for i, a in enumerate(q)])
    return q, M, h, f, V


def test_two_cart_pendulums_three_levels_placed():
    """Three levels of known systems; the second copy placed with `origin:` (its parts on a line
    and in the plane: it was refused, 'needs one entry per world axis entries')."""
    q, M, h, f, V = two_cart_reference()
    system = derived("two_cart_pendulums.yaml")
    fixed = lambda rng: {"x1": rng.uniform(0, 0.5), "x2": rng.uniform(0, 0.5)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 33, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 33, fixed=fixed) < TOL
    x1, th1, x2, th2 = (system.symbol(n) for n in ("x1", "th1", "x2", "th2"))
    d, L = system.symbol("d"), system.symbol("L")
    want = {"left.base.cart.centre": (x1, 0), "right.base.cart.centre": (x2 + d, 0),
            "right.pole.tip": (x2 + d + L * sp.sin(th2), -L * sp.cos(th2))}
    for label, (wx, wy) in want.items():  # the line's points are the plane's x axis, moved with the copy
        px, py = system.points[label]
        assert sp.simplify(px - wx) == 0 and sp.simplify(py - wy) == 0, (label, system.points[label])


def test_linearize_through_springs_of_rest_length_on_a_line():
    """`linearize` of a model whose springs on a line have a rest length (|x + w| - l0: the
    derivative of sign) stopped with an internal error (DiracDelta). A against finite
    differences of the hand equations at the equilibrium it finds."""
    q, M, h, f, _ = cart_pendulum_reference()
    system = derived("cart_pendulum.yaml")
    lin = system.linearize()
    assert lin.equilibrium
    point = {s.name: float(v) for s, v in lin.point}
    values = {p.name: float(p.value) for p in system.parameters}
    args = [t, *q, *dots(q)]
    sub = {sp.Symbol(k): v for k, v in values.items()}
    fM, fr = (sp.lambdify(args, e.subs(sub), "numpy") for e in (M, f - h))
    n, tt = len(q), float(lin.time)

    def rhs(y):
        return np.concatenate([y[n:], np.linalg.solve(np.array(fM(tt, *y), dtype=float),
                                                      np.array(fr(tt, *y), dtype=float).ravel())])

    y0 = np.array([point[s.name] for s in q] + [point[f"{s.name}_dot"] for s in q])
    assert np.max(np.abs(rhs(y0))) < 1e-9
    eps, cols = 1e-6, []
    for i in range(2 * n):
        e = np.zeros(2 * n)
        e[i] = eps
        cols.append((rhs(y0 + e) - rhs(y0 - e)) / (2 * eps))
    assert np.allclose(np.asarray(lin.A, dtype=float), np.column_stack(cols), rtol=1e-6, atol=1e-6)


# ------------------------------------------------------------------------------------------
# A closed loop inside a known system, reused with a pendulum on one of its points
# ------------------------------------------------------------------------------------------

def walk_independent(system, ref, start, guess, seed, *, step=0.1, states=8):
    """Pairs (kronsub, reference) of ``Mbar, hbar, fbar`` and the accelerations (compiled C)
    along a random walk of several independent coordinates (kept on one branch)."""
    num = system.numeric()
    pv = [num.parameters[name] for name in ref.params]
    rng = np.random.default_rng(seed)
    q, pairs = np.array(start, dtype=float), []
    for _ in range(states):
        q = q + rng.uniform(-step, step, len(q))
        u, tt = rng.uniform(-2, 2, len(q)), rng.uniform(0, 2)
        yv, ydv = ref.consistent(q, u, guess, pv)
        guess = yv
        Mb, hb, fb, acc = ref.evaluate(tt, yv, ydv, pv)
        st = np.concatenate([q, u])
        pairs += [(num.mass_matrix(q), Mb), (num.velocity_terms(st), hb), (num.forces(tt, st), fb),
                  (num.rhs(tt, st)[len(q):], acc)]
    return pairs


@lru_cache(maxsize=None)
def five_bar_reference():
    """System III (two System I's pinned at B: four coordinates, two constraints) with a rod
    hung from the left lower rod's centre, tied to it by a torsional spring; B_left - B_right = 0."""
    y, M, h, f, g_, params, _ = five_bar_pieces()
    return Constrained(y, M, h, f, g_, y[:3], params)


def five_bar_pieces():
    """``y``, ``M``, ``h``, ``f``, ``g``, the parameters and the hung rod's tip."""
    t1, t2, ps, p1, p2 = y = list(S("theta1 theta2 psi phi1 phi2"))
    m1, m2, a1, a2, I1, I2, g, F, d, mr, Lr, kr, tq = params = S("m1 m2 a1 a2 I1 I2 g F d mr Lr kr tq")
    bodies, V, Q, ends, centres = [], 0, sp.zeros(5, 1), [], []
    for th, ph, O in ((t1, p1, sp.Matrix([0, 0])), (t2, p2, sp.Matrix([2 * d, 0]))):
        c1, A = O + a1 * down(th), O + 2 * a1 * down(th)
        c2, B = A + a2 * down(ph), A + 2 * a2 * down(ph)
        bodies += [(m1, c1, th, I1), (m2, c2, ph, I2)]
        V += g * (m1 * c1[1] + m2 * c2[1])
        Q += sp.Matrix([F * c2[0].diff(a) for a in y])
        ends.append(B)
        centres.append(c2)
    ch = centres[0] + Lr / 2 * down(ps)  # hung from the left lower rod's centre (phi1 dependent)
    bodies.append((mr, ch, ps, mr * Lr ** 2 / 12))
    V += g * mr * ch[1] + kr * (ps - p1 - sp.Rational(1, 10)) ** 2 / 2
    M, h = virtual_power(bodies, y)
    f = sp.Matrix([-V.diff(a) + Q[i] + tq * int(a == t2) for i, a in enumerate(y)])
    return y, M, h, f, list(ends[0] - ends[1]), params, ch + Lr / 2 * down(ps)


def test_five_bar_slider_two_loops_at_two_levels():
    """five_bar_pendulum.yaml as a known system (itself holding System III's loop) and a slider
    on the hung rod's tip in this model; `coordinates: auto` picks theta2, psi."""
    y, M, h, f, g_, params, tip = five_bar_pieces()
    yf, cf = S("yf cf")
    t1, t2, ps, p1, p2 = y
    f = f - sp.Matrix([cf * dots(y)[0] * int(a == t1) for a in y])
    order = [t2, ps, t1, p1, p2]
    perm = [y.index(a) for a in order]
    ref = Constrained(order, M.extract(perm, perm), h.extract(perm, [0]), f.extract(perm, [0]),
                      [*g_, tip[1] + yf], [t2, ps], (*params, yf, cf))
    system = derived("five_bar_slider.yaml")
    assert [s.name for s in system.coordinates] == ["theta2", "psi"]
    branch = {s.name: float(v) for s, v in system.implicit.branch}
    guess = [-0.2, 0.2, branch["theta1"], branch["phi1"], branch["phi2"]]
    pairs = walk_independent(system, ref, [-0.2, 0.2], guess, 43, step=0.03)
    assert worst(pairs) < TOL


def test_five_bar_known_system_carrying_a_pendulum():
    """System III as a known system (its constraints brought along) and a rod hung from a point
    that moves with its dependent coordinate phi1: Mbar, hbar, fbar, compiled accelerations."""
    system = derived("five_bar_pendulum.yaml")
    assert [s.name for s in system.coordinates] == ["theta1", "theta2", "psi"]
    pairs = walk_independent(system, five_bar_reference(), [0.3, -0.2, 0.5], [0.3, -0.2, 0.5, 0.2, -0.3], 34)
    assert worst(pairs) < TOL


def reactions_agree(tmp_path, name, ref, independent, guess, labels):
    """`simulate --reactions`: the multipliers of ``M yddot + h = f + G^T mu`` in every row
    against the reference's, solved at the row's state on the full coordinates."""
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / name), "--t", "0.2", "--dt", "0.1", "--reactions",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    values = {p.name: float(p.value) for p in derived(name).parameters}
    pv = [values[n] for n in ref.params]
    pairs = []
    for row in table:
        yv, ydv = ref.consistent([row[n] for n in independent], [row[f"{n}_dot"] for n in independent], guess, pv)
        a = (row["t"], *yv, *ydv, *pv)
        M, h, f = (np.array(fn(*a), dtype=float) for fn in (ref.fM, ref.fh, ref.ff))
        G, Gdy = np.array(ref.fG(*a), dtype=float), np.array(ref.fGd(*a), dtype=float).ravel()
        nc = G.shape[0]
        K = np.block([[M, G.T], [G, np.zeros((nc, nc))]])
        mu = -np.linalg.solve(K, np.concatenate([f.ravel() - h.ravel(), -Gdy]))[len(yv):]
        pairs.append((np.array([row[n] for n in labels]), mu))
    return worst(pairs)


def test_five_bar_reactions_of_the_known_systems_pin(tmp_path):
    """The pin B, a constraint the known system brought along (``loop.B``)."""
    err = reactions_agree(tmp_path, "five_bar_pendulum.yaml", five_bar_reference(), ["theta1", "theta2", "psi"],
                          [0.3, -0.2, 0.5, 0.2, -0.3], ["mu_loop_B_x", "mu_loop_B_y"])
    assert err < 1e-8


# ------------------------------------------------------------------------------------------
# Pulleys and gears by explicit connections
# ------------------------------------------------------------------------------------------

def test_atwood_stepped_pulley():
    (a,) = q = [S("a")]
    J, r1, r2, m1, m2, x10, x20, k, l0, h, b, tm, g = S("J r1 r2 m1 m2 x10 x20 k l0 h b tm g")
    x1, x2 = x10 + r1 * a, x20 - r2 * a
    ad = dots(q)[0]
    T = J * ad ** 2 / 2 + m1 * rate_of(x1, q) ** 2 / 2 + m2 * rate_of(x2, q) ** 2 / 2
    V = g * (m1 * x1 + m2 * x2) + k * (x2 + h - l0) ** 2 / 2  # the right mass stays above the floor
    system = derived("atwood_pulley.yaml")
    fixed = lambda rng: {"a": rng.uniform(-2, 2)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, [tm - b * ad]), 35, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 35, fixed=fixed) < TOL


def test_gear_train_with_belt_and_compliant_shaft(tmp_path):
    a, b = q = list(S("a b"))
    Jm, Jp, Jg, Jb, JL, rp, rg, rb1, rb2, ks, cs, T0, kw, TL, om = S("Jm Jp Jg Jb JL rp rg rb1 rb2 ks cs T0 kw TL om")
    ad, bd = dots(q)
    gear = -rp / rg * a
    pulley = gear * rb1 / rb2
    T = (Jm + Jp) * ad ** 2 / 2 + Jg * rate_of(gear, q) ** 2 / 2 + Jb * rate_of(pulley, q) ** 2 / 2 + JL * bd ** 2 / 2
    twist = b - pulley
    V = ks * twist ** 2 / 2
    Q = [(T0 - kw * ad) * int(v == a) - TL * sp.cos(om * t) * int(v == b) - cs * rate_of(twist, q) * twist.diff(v)
         for v in q]
    M, h, f = lagrange(T, V, q, Q)
    system = derived("gear_train.yaml")
    assert compare_explicit(system, (M, h, f), 36) < TOL
    assert compare_energies(system, T, V, 36) < TOL
    assert accelerations_agree(system, M, h, f, 36, numpy_module=numpy_module(tmp_path, "gear_train.yaml")) < TOL


# ------------------------------------------------------------------------------------------
# Planar rigid bodies: a bar on spring-damper legs, a pendulum on a rolling wheel's peg
# ------------------------------------------------------------------------------------------

def test_half_car_bar_on_spring_damper_legs():
    x, y, th = q = list(S("x y th"))
    m, L, Iz, kf, kr, cr, l0, P, T0, om, g = S("m L Iz kf kr cr l0 P T0 om g")
    e = sp.Matrix([sp.cos(th), sp.sin(th)])
    centre = sp.Matrix([x, y])
    end_a, end_b = centre - L / 2 * e, centre + L / 2 * e
    mast = centre + L / 4 * e + sp.Rational(3, 10) * sp.Matrix([-sp.sin(th), sp.cos(th)])
    front = end_a - sp.Matrix([-L / 2, -sp.Rational(1, 10)])
    rear = sp.Matrix([L / 2, 0]) - end_b
    lf, lr = sp.sqrt(front.dot(front)), sp.sqrt(rear.dot(rear))
    M, h = virtual_power([(m, centre, th, Iz)], q)
    V = m * g * y + kf * (lf - l0) ** 2 / 2 + kr * (lr - l0) ** 2 / 2
    wind = sp.Matrix([P, -P / 3])
    f = sp.Matrix([-V.diff(a) - cr * rate_of(lr, q) * lr.diff(a) + wind.dot(mast.diff(a))
                   + T0 * sp.sin(om * t) * int(a == th) for a in q])
    system = derived("half_car.yaml")
    def fixed(rng):  # the legs stretched, the bar near level
        return {"x": rng.uniform(-0.3, 0.3), "y": rng.uniform(0.2, 0.8), "th": rng.uniform(-0.5, 0.5)}

    assert compare_explicit(system, (M, h, f), 37, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 37, fixed=fixed) < TOL


def test_pendulum_on_the_peg_of_a_rolling_wheel():
    a, th = q = list(S("a th"))
    Mw, R, e, m, L, k, l0, cp, tw, g = S("M R e m L k l0 cp tw g")
    centre = sp.Matrix([-R * a, R])
    peg = centre + sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]]) * sp.Matrix([e, sp.Rational(1, 50)])
    rod = peg + L / 2 * down(th)
    M, h = virtual_power([(Mw, centre, a, Mw * R ** 2 / 2), (m, rod, th, m * L ** 2 / 12)], q)
    stretch = centre[0] + 1  # the wall is at x = -1, level with the centre
    V = g * (Mw * centre[1] + m * rod[1]) + k * (stretch - l0) ** 2 / 2
    rel = th - a
    f = sp.Matrix([-V.diff(v) + tw * int(v == a) - cp * rate_of(rel, q) * rel.diff(v) for v in q])
    system = derived("wheel_pendulum.yaml")
    fixed = lambda rng: {"a": rng.uniform(-2, 2)}  # noqa: E731  (the centre right of the wall)
    assert compare_explicit(system, (M, h, f), 38, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 38, fixed=fixed) < TOL


# ------------------------------------------------------------------------------------------
# Space: a body on a Cardan joint with products of inertia, a bead on a cone
# ------------------------------------------------------------------------------------------

def test_cardan_body_with_products_of_inertia(tmp_path):
    """X-Y-Z angles (a, b, 0); the mass centre at (u, 0, -h) from the joint in body axes; the
    tensor [[A, D, F], [D, B, E], [F, E, C]] (products as entries); slanted gravity, a world
    torque vector, a spring with rest length and a force at points given from the centre."""
    a, b = q = list(S("a b"))
    m, h, u, A, B, C, D, E, F, k, l0, tx, tz, P, g = S("m h u A B C D E F k l0 tx tz P g")
    R = Rx(a) * Ry(b)
    centre = R * sp.Matrix([u, 0, -h])
    I3 = sp.Matrix([[A, D, F], [D, B, E], [F, E, C]])
    M, hh = virtual_power([(m, centre, R, I3)], q)
    down_ = sp.Matrix([1, 0, -3]) / sp.sqrt(10)
    tip = centre + R * sp.Matrix([0, sp.Rational(1, 10), -h])
    side = centre + R * sp.Matrix([sp.Rational(1, 10), 0, 0])
    gap = tip - sp.Matrix([sp.Rational(1, 5), sp.Rational(1, 10), -sp.Rational(7, 10)])
    V = -m * g * down_.dot(centre) + k * (sp.sqrt(gap.dot(gap)) - l0) ** 2 / 2
    omega = world_angular_velocity(R, q)
    torque, push = sp.Matrix([tx, 0, tz]), sp.Matrix([0, P * sp.sin(t), P])
    f = sp.Matrix([-V.diff(v) + torque.dot(omega.diff(vd)) + push.dot(side.diff(v)) for v, vd in zip(q, dots(q))])
    system = derived("cardan_body.yaml")
    assert compare_explicit(system, (M, hh, f), 39, spread=1.2) < TOL
    assert compare_energies(system, kinetic(M, q), V, 39, spread=1.2) < TOL
    assert accelerations_agree(system, M, hh, f, 39, spread=1.2,
                               numpy_module=numpy_module(tmp_path, "cardan_body.yaml")) < TOL


def test_bead_on_a_cone_in_spherical_coordinates():
    r, ph = q = list(S("r ph"))
    m, al, k, l0, cd, eps, g = S("m al k l0 cd eps g")
    th = sp.pi - al
    p = r * sp.Matrix([sp.sin(th) * sp.cos(ph), sp.sin(th) * sp.sin(ph), sp.cos(th)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    V = m * g * p[2] + k * (r - l0) ** 2 / 2 + eps * sp.cos(2 * ph)  # r > 0: the distance from the apex
    f = sp.Matrix([(-cd * v).dot(p.diff(a)) for a in q])
    M, h, fc = lagrange(T, V, q, [0, 0])
    system = derived("bead_in_cone.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.2, 2)}  # noqa: E731
    assert compare_explicit(system, (M, h, fc + f), 40, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 40, fixed=fixed) < TOL


def test_two_heavy_tops_placed_in_space_and_tied():
    """heavy_top.yaml (Z-X-Z, a product of inertia, a motor about world z) twice, the second
    placed at (D, 0, 0) in space with 3/2 the mass and no motor, crowns tied by a cord."""
    psi1, th1, ph1, psi2, th2, ph2 = q = list(S("psi1 th1 ph1 psi2 th2 ph2"))
    m, h, A, C, P, tm, g, D, kc, l0 = S("m h A C P tm g D kc l0")
    I3 = sp.Matrix([[A, P, 0], [P, A, 0], [0, 0, C]])
    bodies, V, crowns, f = [], 0, [], sp.zeros(6, 1)
    for (psi, th, ph), mass, origin, motor in (((psi1, th1, ph1), m, 0, tm), ((psi2, th2, ph2), 3 * m / 2, D, 0)):
        R = Rz(psi) * Rx(th) * Rz(ph)
        centre = sp.Matrix([origin, 0, 0]) + R * sp.Matrix([0, 0, h])
        bodies.append((mass, centre, R, I3))
        crowns.append(centre + R * sp.Matrix([0, 0, h]))
        V += mass * g * centre[2]
        omega = world_angular_velocity(R, q)
        f += sp.Matrix([motor * omega[2].diff(vd) for vd in dots(q)])
    gap = crowns[1] - crowns[0]
    V += kc * (sp.sqrt(gap.dot(gap)) - l0) ** 2 / 2
    M, hh = virtual_power(bodies, q)
    f += sp.Matrix([-V.diff(v) for v in q])
    system = derived("two_tops.yaml")
    fixed = lambda rng: {"th1": rng.uniform(0.2, 1.2), "th2": rng.uniform(0.2, 1.2)}  # noqa: E731  (off gimbal lock)
    assert compare_explicit(system, (M, hh, f), 42, spread=2, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 42, spread=2, fixed=fixed) < TOL


# ------------------------------------------------------------------------------------------
# Linear implicit constraints: a rope over a pulley joining blocks on a double wedge
# ------------------------------------------------------------------------------------------

@lru_cache(maxsize=None)
def blocks_reference():
    p, xA, yA, xB, yB = y = list(S("p xA yA xB yB"))
    mA, mB, J, r, al, bt, Ls, k, l0, c, g = params = S("mA mB J r al bt Ls k l0 c g")
    M = sp.diag(J, mA, mA, mB, mB)
    sA = -xA * sp.cos(al) - yA * sp.sin(al)  # distances from the apex along the faces
    sB = xB * sp.cos(bt) - yB * sp.sin(bt)
    g_ = [xA * sp.sin(al) - yA * sp.cos(al), xB * sp.sin(bt) + yB * sp.cos(bt), sA + sB - Ls,
          r * p + sA - sp.Rational(3, 5)]
    down_ = sp.Matrix([sp.Rational(1, 10), -1]) / sp.sqrt(sp.Rational(101, 100))
    foot = sp.Matrix([-sp.cos(al), -sp.sin(al)])
    gap = sp.Matrix([xA, yA]) - foot
    V = -g * down_.dot(mA * sp.Matrix([xA, yA]) + mB * sp.Matrix([xB, yB])) + k * (sp.sqrt(gap.dot(gap)) - l0) ** 2 / 2
    yd = dots(y)
    f = sp.Matrix([-V.diff(v) - c * yd[i] * int(v in (xB, yB)) for i, v in enumerate(y)])
    return Constrained(y, M, sp.zeros(5, 1), f, g_, [p], params)


def test_blocks_on_wedges_rope_over_pulley():
    rows = walk_constrained(derived("blocks_on_wedges.yaml"), blocks_reference(), 0.0,
                            [0.0, -0.53, -0.29, 0.69, -0.58], 41)
    assert worst(pair for row in rows for pair in row) < TOL


def test_blocks_on_wedges_reactions(tmp_path):
    """Rope tension and wedge normal forces: the faces are point_on_line joints written
    (P - Q) x d, the rope and grip plain expressions; the reference's g are sign-matched."""
    err = reactions_agree(tmp_path, "blocks_on_wedges.yaml", blocks_reference(), ["p"],
                          [0.0, -0.53, -0.29, 0.69, -0.58], ["mu_faceA", "mu_faceB", "mu_rope", "mu_grip"])
    assert err < 1e-8


# ------------------------------------------------------------------------------------------
# More models, and the defects this sweep found (those tests fail on the code before the fixes)
# ------------------------------------------------------------------------------------------

def test_animate_a_model_without_points_says_so(tmp_path):
    """gear_train.yaml (flywheels only) stopped `animate` with an internal error (exit 4,
    numpy's 'need at least one array to concatenate'); it is a plain error now."""
    pytest.importorskip("matplotlib")
    result = CliRunner().invoke(main, ["animate", str(HERE / "gear_train.yaml"), "--t", "0.1", "-o",
                                       str(tmp_path / "g.gif")])
    assert result.exit_code == 1, result.output
    assert "no named points" in result.output and "internal error" not in result.output
    assert not (tmp_path / "g.gif").exists()


def test_polar_bob_with_a_dashpot_to_a_corner():
    r, a = q = list(S("r a"))
    m, k, l0, c, P, g = S("m k l0 c P g")
    p = r * sp.Matrix([sp.cos(a), sp.sin(a)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    d = sp.Matrix([1, -4]) / sp.sqrt(17)
    V = -m * g * d.dot(p) + k * (r - l0) ** 2 / 2  # r > 0
    gap = p - sp.Matrix([sp.Rational(3, 5), -sp.Rational(3, 10)])
    length = sp.sqrt(gap.dot(gap))
    push = P * sp.Matrix([sp.cos(a), sp.sin(a)])
    Q = [-c * rate_of(length, q) * length.diff(x) + push.dot(p.diff(x)) for x in q]
    M, h, f = lagrange(T, V, q, Q)
    system = derived("polar_bob_damped.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.1, 2)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 44, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 44, fixed=fixed) < TOL


def test_two_cart_pendulums_scene_switches_off_nested_effects():
    """A scene switching off effects two levels down (`left.base.push`): the hand equations with
    those loads zero, none of their parameters left, and the total energy kept in a run."""
    from kronsub.model.scenes import derive_scene, select_scene

    q, M, h, f, V = two_cart_reference()
    model = kronsub.load(HERE / "two_cart_pendulums.yaml")
    system = derive_scene(model, select_scene(model, "conservative"))
    names = {p.name for p in system.parameters}
    assert not names & {"c", "cp", "cc", "P", "om", "Q"}, names
    off = {sp.Symbol(n): 0 for n in ("c", "cp", "cc", "P", "Q")}
    fixed = lambda rng: {"x1": rng.uniform(0, 0.5), "x2": rng.uniform(0, 0.5)}  # noqa: E731
    assert compare_explicit(system, (M, h, f.subs(off)), 45, fixed=fixed) < TOL
    run = dataclasses.replace(system, initial=dict(model.initial)).simulate(t=2.0, dt=0.5, dataframe=False)
    energy = run["total_energy"]
    assert run.complete and np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))


def test_twin_system2_closed_loops_renamed_and_placed():
    """System II (a closed loop: phi dependent) twice, dependent coordinates renamed, the right
    copy placed and overridden (m2, and its push F in t); a spring and a damper between them, a
    generalized force on a dependent coordinate and a force in a dependent velocity."""
    th1, th2, ph1, ph2 = y = list(S("th1 th2 ph1 ph2"))
    params = S("m1 m2 a1 a2 I1 I2 g F c dx ks l0 cd Fa w cb")
    m1, m2, a1, a2, I1, I2, g, F, c, dx, ks, l0, cd, Fa, w, cb = params
    bodies, V, Q, lower, g_ = [], 0, sp.zeros(4, 1), [], []
    for th, ph, O, mass, push in ((th1, ph1, 0, m2, F), (th2, ph2, dx, 3 * m2 / 2, Fa * sp.sin(w * t))):
        c1 = sp.Matrix([O, 0]) + a1 * down(th)
        c2 = sp.Matrix([O, 0]) + 2 * a1 * down(th) + a2 * down(ph)
        bodies += [(m1, c1, th, I1), (mass, c2, ph, I2)]
        V += g * (m1 * c1[1] + mass * c2[1])
        Q += sp.Matrix([push * c2[0].diff(a) for a in y])
        lower.append(c2)
        g_.append(a1 * sp.sin(th) + a2 * sp.sin(ph) - c)
    gap = lower[1] - lower[0]
    V += ks * (sp.sqrt(gap.dot(gap)) - l0) ** 2 / 2
    rel = th2 - th1
    M, h = virtual_power(bodies, y)
    end_left = 2 * a1 * down(th1) + 2 * a2 * down(ph1)
    yd = dots(y)  # the brake on the dependent ph2 and the drag in ph1's velocity
    f = sp.Matrix([-V.diff(a) + Q[i] - cd * rate_of(rel, y) * rel.diff(a) - cb * yd[3] * int(a == ph2)
                   - cb * yd[2] * end_left[0].diff(a) for i, a in enumerate(y)])
    ref = Constrained(y, M, h, f, g_, [th1, th2], params)
    system = derived("twin_system2.yaml")
    assert [s.name for s in system.coordinates] == ["th1", "th2"]
    pairs = walk_independent(system, ref, [0.3, 0.4], [0.3, 0.4, 1.1, 0.9], 46, step=0.05)
    assert worst(pairs) < TOL


def test_auto_switch_between_coarse_rows():
    """`coordinates: auto` watches G_d at the output rows; in C (dop853) with rows 0.5 s apart the
    run reached the toggle between two rows and stopped at t = 0.298 ('a singular configuration
    (toggle position) is reached ... relative size 0.075'), though a switch there goes on (rows
    0.05 apart switch at t = 0.25). Now the stretch is run again with scipy's DOP853, whose event
    stops where G_d nears singular; the rows agree with the fine run's and the energy is kept."""
    system = derived("five_bar_slider.yaml")
    quiet = {"cf": 0, "tq": 0}
    coarse = system.simulate(t=1.0, dt=0.5, set=quiet, dataframe=False)
    fine = system.simulate(t=1.0, dt=0.05, set=quiet, dataframe=False)
    assert coarse.complete, coarse.message
    assert np.allclose(coarse.y, fine.y[::10], rtol=1e-7, atol=1e-7)
    energy = coarse["total_energy"]
    assert np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))


def test_known_systems_bringing_one_parameter_with_two_values():
    """sprung_cart.yaml (k = 30, l0 = 0.4) and atwood_pulley.yaml (k = 40, l0 = 0.3) in one model:
    the shared k, l0 took the cart's values, silently (the pulley's a_ddot coefficient of a
    went from k r2^2 = 0.9 to 0.675). Now an error at the second `model:`; with overrides each
    keeps its own spring."""
    path = HERE / "cart_and_pulley.yaml"
    with pytest.raises(ModelError) as info:
        kronsub.load(path, cache=False)
    text = str(info.value)
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if "pulley: {model:" in ln)
    assert f"cart_and_pulley.yaml:{line}:" in text
    assert "parameter 'k' is 40 in 'pulley' but 30 in 'cart'" in text and "'l0'" in text and "hint:" in text
    system = derived("cart_and_pulley_fixed.yaml")
    values = {p.name: float(p.value) for p in system.parameters}
    row = system.forces[1].subs({system.symbol(k): v for k, v in values.items()})
    row = row.subs({s: 0 for s in system.velocities} | {system.symbol("x"): 0, system.symbol("t"): 0})
    a = system.symbol("a")
    stiffness = float(row.subs(a, 0) - row.subs(a, sp.Rational(1, 100))) * 100  # the pulley's spring: k r2^2
    assert stiffness == pytest.approx(values["kp"] * values["r2"] ** 2)
    assert values["k"] == 30 and values["l0"] == pytest.approx(0.4)


def test_gravity_of_this_model_on_a_known_system_on_a_line_and_in_the_plane():
    """A gravity effect naming a known system acts on its bodies; on one with parts on a line and
    in the plane (no one world) it acted on nothing, silently (V = 0 from it: the pendulum
    weightless on the Moon)."""
    from kronsub.model.scenes import derive_scene, select_scene

    x, th = q = list(S("x th"))
    g_moon = S("g_moon")
    q_, M, h, f, V = cart_pendulum_reference()
    g = S("g")
    earth = sp.Matrix([-(V - V.subs(g, 0)).diff(a) for a in q])  # the known system's own gravity
    moon = (V - V.subs(g, 0)).subs(g, g_moon)
    model = kronsub.load(HERE / "cart_pendulum_on_moon.yaml")
    system = derive_scene(model, select_scene(model, "moon"))
    fixed = lambda rng: {"x": rng.uniform(0, 1)}  # noqa: E731
    f_moon = f - earth + sp.Matrix([-moon.diff(a) for a in q])
    assert compare_explicit(system, (M, h, f_moon), 47, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V.subs(g, 0) + moon, 47, fixed=fixed) < TOL


def test_gravity_that_acts_on_no_component(tmp_path):
    """Without `components:` a gravity acts on the library components with mass only (known
    systems bring their own): over a known system alone it acted on nothing, silently, while
    docs/model-format.md said it acted on the known system's bodies. Now an error that says
    to name them."""
    text = (HERE / "cart_pendulum_on_moon.yaml").read_text().replace(", components: [rig]", "")
    path = tmp_path / "moon.yaml"
    path.write_text(text.replace("model: cart_pendulum.yaml", f"model: {HERE / 'cart_pendulum.yaml'}"))
    with pytest.raises(ModelError) as info:
        kronsub.load(path, cache=False)
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if "moon: {type: gravity" in ln)
    text = str(info.value)
    assert f"moon.yaml:{line}:" in text and "gravity 'moon' acts on no component" in text
    assert "components: [rig]" in text
