"""The models of tests/models/sweep5/: their loaders and their hand derivations in plain sympy
(never with kronsub), for the tests by subject (tests/test_models_*.py).

The folder holds: a free `planar_body` with points of its own (linearized by hand, at an
equilibrium and at a given point with inputs in time), `rod`s with `axis: down` and an
off-axis peg, a disc rolling inside a ring (its rim on a spring), particles on a line, in the
plane and in space tied across their worlds, names other tools reserve (`nan`, `E`, `oo`,
`zoo`, `Abs`, `double`, `main`, `q`, `param`; also `linearize --symbolic`), closed loops in
space (a bead on a line turning with a turntable, a bead on a line fixed in a spinning
`rigid_body3d`, a bead on a helix given through definitions, that helix reused twice as a
placed known system), `coordinates: auto` switching in space, a body on a ball joint given by
the connection with `derive --reactions` and `simulate --reactions` in space, and a known
system of known systems with parameter overrides (also in t), selected by scenes for
`codegen --lang c`, `--lang python` and `simulate`.

Each is checked against a derivation written here in plain sympy (never with kronsub), with
tests/reference/lagrange.py: Lagrange's equations of a hand ``T`` and ``V``,
virtual power over the bodies, Lagrange multipliers on the full coordinates for closed loops.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import sympy as sp

from helpers import generated_numpy_module, Rx, Ry, Rz, scene_of, sweep_models
from reference.lagrange import (add, Constrained, damper_rows, dots, down, gradient_force, kinetic, norm, R, S,
                                spring_V, t, virtual_power, work_rows)

HERE = Path(__file__).resolve().parent.parent / "models" / "sweep5"


loaded, derived = sweep_models(HERE)


scene = scene_of(loaded)


def turn(a):
    return sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]])


def numpy_module(tmp_path, name):
    return generated_numpy_module(tmp_path, HERE / name)


@lru_cache(maxsize=None)
def plate_reference(still=False, damper=True):
    x, y, th = q = list(S("x y th"))
    m, J, a, b, k1, k2, l1, l2, c, F, tau, g = S("m J a b k1 k2 l1 l2 c F tau g")
    centre = sp.Matrix([x, y])
    p1, p2 = centre + turn(th) * sp.Matrix([a, b]), centre + turn(th) * sp.Matrix([-a, 0])
    M, h = virtual_power([(m, centre, th, J)], q)
    V = (-m * g * (x - 4 * y) / sp.sqrt(17) + spring_V(k1, p1, sp.Matrix([R(2, 5), 1]), l1)
         + spring_V(k2, sp.Matrix([-R(3, 5), R(4, 5)]), p2, l2))
    if still:
        return q, M, h, gradient_force(V, q, [0, 0, 0]), V
    rows = add(damper_rows(c if damper else 0, norm(p1 - sp.Matrix([1, -R(1, 5)])), q),
               work_rows(F * sp.sin(3 * t) * sp.Matrix([1, 2]) / sp.sqrt(5), p2, q), [0, 0, tau * sp.cos(t)])
    return q, M, h, gradient_force(V, q, rows), V


@lru_cache(maxsize=None)
def worlds_reference():
    s, u, v, p1, p2, p3 = q = list(S("s u v p1 p2 p3"))
    mc, mu_, mb, k1, k2, k3, c, Fc, g = S("mc mu_ mb k1 k2 k3 c Fc g")
    cart3, puck3, ball = sp.Matrix([s, 0, 0]), sp.Matrix([u, v, 0]), sp.Matrix([p1, p2, p3])
    T = (mc * dots(q)[0] ** 2 + mu_ * (dots(q)[1] ** 2 + dots(q)[2] ** 2) + mb * sum(x ** 2 for x in dots(q)[3:])) / 2
    V = (mb * g * p3 + mu_ * g * v + mc * g / 5 * s + spring_V(k1, ball, cart3, R(1, 2))
         + spring_V(k2, ball, puck3, R(3, 10)) + k3 * ((u - s) ** 2 + v ** 2) / 2)
    Q = add(damper_rows(c, norm(ball - puck3), q), [Fc * sp.cos(t), 0, 0, 0, 0, 0])
    return q, T, V, Q


def odd_reference():
    nan, E = q = list(S("nan E"))
    I, N, S_, O, Q, beta, gamma, zeta = S("I N S O Q beta gamma zeta")
    double, oo, zoo, Abs, main_ = S("double oo zoo Abs main")
    bob = E * down(nan)
    M, h = virtual_power([(N, O / 2 * down(nan), nan, I), (S_, bob)], q)
    V = double * (N * (-O / 2 * sp.cos(nan)) + S_ * bob[1]) + Q * (E - beta) ** 2 / 2 + Abs * (E - main_) ** 4
    rows = add(damper_rows(gamma, nan, q), damper_rows(zeta, E, q),  # the slide's length |E| = E > 0
               work_rows(sp.Matrix([oo * sp.cos(zoo * t), 0]), bob, q))
    return q, M, h, gradient_force(V, q, rows), V


@lru_cache(maxsize=None)
def turntable_reference(free=False):
    a, x, y, z = ys = list(S("a x y z"))
    Jt, mb, be, k, l0, tm, ct, g = params = S("Jt mb be k l0 tm ct g")
    p = sp.Matrix([x, y, z])
    M, h = sp.diag(Jt, mb, mb, mb), sp.zeros(4, 1)
    V = mb * g * z + spring_V(k, p, sp.Matrix([0, 0, -R(1, 2)]), l0)
    rows = [0] * 4 if free else add(damper_rows(ct, a, ys), [tm * sp.cos(t), 0, 0, 0])
    # the rod: (x, y) = z tan(be) (cos a, sin a)
    cons = [x - z * sp.tan(be) * sp.cos(a), y - z * sp.tan(be) * sp.sin(a)]
    used = params if not free else (Jt, mb, be, k, l0, g)
    return Constrained(ys, M, h, gradient_force(V, ys, rows), cons, [a, z], used)


@lru_cache(maxsize=None)
def frame_parts():
    psi, xb, yb, zb = ys = list(S("psi xb yb zb"))
    mf, A, B, C, P, al, mb, k, l0, tz, g = params = S("mf A B C P al mb k l0 tz g")
    Rf = Rz(psi) * Ry(al)
    p = sp.Matrix([xb, yb, zb])
    M, h = virtual_power([(mf, sp.zeros(3, 1), Rf, sp.Matrix([[A, 0, P], [0, B, 0], [P, 0, C]])), (mb, p)], ys)
    hub = Rf * sp.Matrix([-R(1, 10), 0, R(1, 20)])
    V = mb * g * zb + spring_V(k, hub, p, l0)
    from reference.lagrange import world_angular_velocity
    omega = world_angular_velocity(Rf, ys)
    torque = sp.Matrix([0, tz * sp.sin(t), tz])
    drive = [torque.dot(omega.diff(v)) for v in dots(ys)]
    w = Rf.T * p - sp.Matrix([0, R(1, 10), R(1, 5)])  # the bead in frame axes, from the line's point
    return ys, params, M, h, V, drive, [w[0] - w[2], w[1]]


def frame_reference(free=False):
    ys, params, M, h, V, drive, cons = frame_parts()
    f = gradient_force(V, ys, [0] * 4 if free else drive)
    return Constrained(ys, M, h, f, cons, [ys[0], ys[3]], params)


FRAME_GUESS = [0.1, 0.2, 0.1, 0.3]


def ball_joint_parts():
    xc, yc, zc, psi, th, ph = x = list(S("xc yc zc psi th ph"))
    m, h, A, C, D, F, g = S("m h A C D F g")
    Rb = Rz(psi) * Rx(th) * Rz(ph)
    I3 = sp.Matrix([[A, D, 0], [D, A, 0], [0, 0, C]])
    push = sp.Matrix([F, 0, F * sp.cos(t)])
    side = sp.Matrix([xc, yc, zc]) + Rb * sp.Matrix([R(1, 10), 0, -R(1, 5)])
    return x, (m, I3, Rb, push, side, g)


NESTED_VALUES = {"mc": 1.0, "mp": 0.5, "l": 0.8, "k": 6, "L0": 0.4, "cp": 0.05, "g": 9.81, "kL": 9, "mp2": 0.7,
                 "d": 1.5, "kc0": 2, "Jf": 0.05, "ks": 1.5, "tm": 0.3}  # as the three files give them


@lru_cache(maxsize=None)
def nested_reference(hinges=True, motor=True):
    s1, th1, s2, th2, f = q = list(S("s1 th1 s2 th2 f"))
    mc, mp, l, k, L0, cp, g, kL, mp2, d, kc0, Jf, ks, tm = S("mc mp l k L0 cp g kL mp2 d kc0 Jf ks tm")
    cart1, cart2 = sp.Matrix([s1, 0]), sp.Matrix([d + s2, 0])  # the right copy placed at (d, 0)
    bodies = [(mc, sp.Matrix([s1])), (mp, cart1 + l / 2 * down(th1), th1, mp * l ** 2 / 12),
              (mc, sp.Matrix([s2])), (mp2, cart2 + l / 2 * down(th2), th2, mp2 * l ** 2 / 12),
              (0, sp.Matrix([0]), f, Jf)]
    M, h = virtual_power(bodies, q)
    tip1, tip2 = cart1 + l * down(th1), cart2 + l * down(th2)
    V = (g * (mp * bodies[1][1][1] + mp2 * bodies[3][1][1]) + kL * (sp.sqrt(s1 ** 2) - L0) ** 2 / 2
         + k * (sp.sqrt(s2 ** 2) - L0) ** 2 / 2  # each wall spring to its own copy's origin
         + spring_V(2 * kc0, tip1, tip2, d) + ks * (f - th1) ** 2 / 2)
    rows = [0] * 5
    if hinges:
        rows = add(rows, damper_rows(cp, th1, q), damper_rows(cp, th2, q))
    if motor:
        rows = add(rows, [0, 0, 0, 0, tm * sp.sin(t)])
    return q, M, h, gradient_force(V, q, rows), V


def hand_numbers(ref, values):
    q, M, h, f, V = ref
    qd = dots(q)
    sub = {s: values[s.name] for s in (M.free_symbols | h.free_symbols | f.free_symbols | V.free_symbols)
           if s.name in values}
    args = [t, *q, *qd]
    fM, fh, ff = (sp.lambdify(args, e.xreplace(sub), "numpy") for e in (M, h, f))
    fT, fV = (sp.lambdify(args, e.xreplace(sub), "numpy") for e in (kinetic(M, q), V))
    return fM, fh, ff, fT, fV


def quiet_values():
    return {**NESTED_VALUES, "kc0": 3, "mp2": 0.9}  # the scene's values


def nested_states(seed):
    rng = np.random.default_rng(seed)
    return [(rng.uniform(0, 3), rng.uniform(-2, 2, 10)) for _ in range(6)]


@lru_cache(maxsize=None)
def helix_reference():
    s, x, y, z = ys = list(S("s x y z"))
    Js, mb, rr, p, k, cd, Fz, ks, g = params = S("Js mb rr p k cd Fz ks g")
    v = sp.Matrix(dots(ys)[1:])
    M, h = sp.diag(Js, mb, mb, mb), sp.zeros(4, 1)
    V = mb * g * z + k * (x ** 2 + y ** 2 + z ** 2) / 2 + ks * (s - 1) ** 2 / 2
    drag = -cd * norm(v) * v
    rows = [0, drag[0], drag[1], drag[2] + Fz * sp.cos(t)]
    cons = [x - rr * sp.cos(s), y - rr * sp.sin(s), z - p * s]
    return Constrained(ys, M, h, gradient_force(V, ys, rows), cons, [s], params)


HELIX_GUESS = [0.5, 0.44, 0.24, 0.075]


@lru_cache(maxsize=None)
def helix_pair_reference():
    s1, s2, x1, y1, z1, x2, y2, z2 = ys = list(S("s1 s2 x1 y1 z1 x2 y2 z2"))
    Js, mb, rr, p, k, cd, Fz, ks, g, kc = params = S("Js mb rr p k cd Fz ks g kc")
    mb2 = R(3, 5)
    left, right = sp.Matrix([x1, y1, z1]), sp.Matrix([x2, y2, z2])
    origin = sp.Matrix([R(3, 2), 0, R(1, 5)])
    M, h = sp.diag(Js, Js, mb, mb, mb, mb2, mb2, mb2), sp.zeros(8, 1)
    # each copy's central potential in its own coordinates (a translation moves its points, not its forces)
    V = (mb * g * z1 + mb2 * g * (z2 + origin[2]) + k * (left.dot(left) + right.dot(right)) / 2
         + ks * ((s1 - 1) ** 2 + (s2 - 1) ** 2) / 2 + spring_V(kc, left, origin + right, R(6, 5)))
    v1, v2 = sp.Matrix(dots(ys)[2:5]), sp.Matrix(dots(ys)[5:8])
    d1, d2 = -cd * norm(v1) * v1, -cd * norm(v2) * v2
    rows = [0, 0, d1[0], d1[1], d1[2] + Fz * sp.cos(t), d2[0], d2[1], d2[2]]
    cons = [x1 - rr * sp.cos(s1), y1 - rr * sp.sin(s1), z1 - p * s1,
            x2 - rr * sp.cos(s2), y2 - rr * sp.sin(s2), z2 - p * s2]
    return Constrained(ys, M, h, gradient_force(V, ys, rows), cons, [s1, s2], params)


CLASHING = """\
name: Reaction names that clash
parameters: {m: 1, L: 1, J: 0.1}
components:
  arm: {type: pinned_rod, parameters: {mass: m, length: L}, coordinates: [a]}
  bead: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}
  fly: {type: flywheel, parameters: {inertia: J}, coordinates: [w]}
coordinates: [a]
constraints:
  B: {pin: [bead.centre, arm.tip]}
  B_x: w - 2*a
effects:
  gravity: {type: gravity, g: 9.81}
initial: {a: 0.3, x: 0.29, y: -0.95, w: 0.6}
"""
