"""Fifth robustness sweep: models of kinds the first four sweeps did not cover
(tests/models/sweep5/): a free `planar_body` with points of its own (linearized by hand, at an
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
the reference helpers of the earlier sweeps: Lagrange's equations of a hand ``T`` and ``V``,
virtual power over the bodies, Lagrange multipliers on the full coordinates for closed loops.
The defects this sweep found have their tests at the end (and in the linearize test of the
turntable).
"""
from __future__ import annotations

import ctypes
import json
import shutil
import subprocess
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

from helpers import Rx, Ry, Rz, generated_numpy_module, scene_of, sweep_models
from kronsub.cli import main
from test_sweep3_models import accelerations_agree, kinetic, walk_independent as walk
from test_sweep_models import (Constrained, compare_explicit, dots, lagrange, largest_difference, rate_of,
                               virtual_power, worst)

HERE = Path(__file__).resolve().parent / "models" / "sweep5"
t = sp.Symbol("t")
S = sp.symbols
TOL = 1e-10

loaded, derived = sweep_models(HERE)
scene = scene_of(loaded)


def down(a):
    return sp.Matrix([sp.sin(a), -sp.cos(a)])


def turn(a):
    return sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]])


def norm(v):
    return sp.sqrt(v.dot(v))


def spring_V(k, p, q, length=0):
    return k * (norm(p - q) - length) ** 2 / 2


def damper_rows(c, length, q):
    return [-c * rate_of(length, q) * length.diff(a) for a in q]


def work_rows(F, p, q):
    return [F.dot(p.diff(a)) for a in q]


def gradient_force(V, q, extra):
    return sp.Matrix([-V.diff(a) + extra[i] for i, a in enumerate(q)])


def add(*rows):
    return [sum(r) for r in zip(*rows)]


def compare_energies(system, T, V, seed, *, fixed=None):
    return largest_difference(system, [system.kinetic_energy, system.potential_energy], [sp.sympify(T), sp.sympify(V)],
                              seed, states=6, fixed=fixed)


def numpy_module(tmp_path, name):
    return generated_numpy_module(tmp_path, HERE / name)


R = sp.Rational


# ------------------------------------------------------------------------------------------
# The plane: a free planar body, rods with axis down, a rolling disc
# ------------------------------------------------------------------------------------------

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


def test_planar_body_tethered(tmp_path):
    q, M, h, f, V = plate_reference()
    system = derived("planar_body_tethered.yaml")
    assert compare_explicit(system, (M, h, f), 501) < TOL
    assert compare_energies(system, kinetic(M, q), V, 501) < TOL


def test_planar_body_linearized_by_hand(tmp_path):
    """`linearize --scene still`: the equilibrium kronsub finds is one of the hand equations
    (``f(q*) = 0``) and ``A`` is the hand Jacobian ``[[0, I], [M^-1 d(f - h)/dq, M^-1 d(f - h)/dqdot]]``."""
    q, M, h, f, _ = plate_reference(still=True)
    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(HERE / "planar_body_tethered.yaml"), "--scene", "still",
                                       "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    point = data["operating_point"]
    values = {p.name: float(p.value) for p in derived("planar_body_tethered.yaml").parameters}
    qd = dots(q)
    sub = {s: values[s.name] for s in (f.free_symbols | M.free_symbols) if s.name in values}
    qstar = {s: float(point[s.name]) for s in q}
    zero = {v: 0.0 for v in qd}
    residual = np.array((f - h).xreplace(sub).xreplace(qstar).xreplace(zero).evalf(), dtype=float)
    assert np.max(np.abs(residual)) < 1e-9, residual
    rhs = M.inv() * (f - h)
    y = q + qd
    J = rhs.jacobian(y).xreplace(sub).xreplace(qstar).xreplace(zero)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [np.array(J.evalf(), dtype=float)]])
    ours = np.array(data["A"], dtype=float)
    assert np.allclose(ours, A, rtol=1e-8, atol=1e-8), (ours, A)


def test_rods_with_axis_down_and_an_off_axis_peg():
    al, be = q = list(S("al be"))
    m1, m2, L1, L2, e, k, kt, ct, T0, g = S("m1 m2 L1 L2 e k kt ct T0 g")
    c1 = L1 / 2 * down(al)
    c2 = L1 * down(al) + L2 / 2 * down(be)
    # axis down: the rod along body -y, so body x is across it; the peg at (e, -L2/4) in body axes
    peg = c2 + turn(be) * sp.Matrix([e, -L2 / 4])
    M, h = virtual_power([(m1, c1, al, m1 * L1 ** 2 / 12), (m2, c2, be, m2 * L2 ** 2 / 10)], q)
    V = (g * (m1 * c1[1] + m2 * c2[1]) + spring_V(k, peg, sp.Matrix([R(9, 10), -R(19, 10)]), R(3, 10))
         + kt * (be - al - R(1, 5)) ** 2 / 2)
    f = gradient_force(V, q, add(damper_rows(ct, al, q), [0, T0 * sp.sin(2 * t)]))
    system = derived("rods_axis_down.yaml")
    assert compare_explicit(system, (M, h, f), 502) < TOL
    assert compare_energies(system, kinetic(M, q), V, 502) < TOL


def test_disc_rolling_inside_a_ring():
    (u,) = q = [S("u")]
    m, r, Rr, k, T0, g = S("m r Rr k T0 g")
    centre = (Rr - r) * down(u)
    spin = -(Rr - r) / r * u
    rim = centre + r * sp.Matrix([sp.cos(spin), sp.sin(spin)])
    M, h = virtual_power([(m, centre, spin, m * r ** 2 / 2)], q)
    V = m * g * centre[1] + spring_V(k, rim, sp.zeros(2, 1), R(1, 2))
    f = gradient_force(V, q, [T0 * spin.diff(u)])
    system = derived("disc_in_ring.yaml")
    assert compare_explicit(system, (M, h, f), 503) < TOL
    assert compare_energies(system, kinetic(M, q), V, 503) < TOL


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


def test_line_plane_and_space_tied_across_worlds(tmp_path):
    q, T, V, Q = worlds_reference()
    M, h, f = lagrange(T, V, q, Q)
    system = derived("line_plane_space.yaml")
    assert compare_explicit(system, (M, h, f), 504) < TOL
    assert compare_energies(system, T, V, 504) < TOL


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


def test_names_other_tools_reserve(tmp_path):
    """Coordinates `nan`, `E` (numpy's and SymPy's constants), parameters `I`, `oo`, `zoo`,
    `Abs` (SymPy's), `double`, `main` (C's) and primitive coordinates `q`, `param` (the
    generated code's arguments): derived, the numpy module and the compiled C agree with the hand equations."""
    q, M, h, f, V = odd_reference()
    system = derived("odd_names.yaml")
    fixed = lambda rng: {"E": rng.uniform(0.2, 2)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 505, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 505, fixed=fixed) < TOL
    module = numpy_module(tmp_path, "odd_names.yaml")
    assert accelerations_agree(system, M, h, f, 505, spread=0.9, numpy_module=module) < TOL


@pytest.mark.parametrize("kind, name", [("parameter", "return"), ("parameter", "None"), ("coordinate", "lambda")])
def test_a_python_keyword_as_a_name_is_an_error_where_an_expression_uses_it(tmp_path, kind, name):
    """Expressions are read with Python's syntax, where a keyword is no name: one declared
    may stay unused (tests/models/internal_names.yaml), and an expression using it is an
    error at the keyword with a hint to rename it (a parameter `None` was told "use 1 or 0")."""
    text = (HERE / "odd_names.yaml").read_text()
    if kind == "parameter":
        text = text.replace("  zoo: {value", f"  {name}: {{value: 1}}\n  zoo: {{value", 1)
        unused = text
        text = text.replace("vector: [oo*cos(zoo*t), 0]", f"vector: [oo*cos(zoo*t), {name}]")
    else:
        text = unused = text.replace("nan", name)
    path = tmp_path / "k.yaml"
    if kind == "parameter":
        path.write_text(unused)
        assert CliRunner().invoke(main, ["derive", str(path), "--format", "json"]).exit_code == 0
    path.write_text(text)
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if f"{name})" in ln or f", {name}]" in ln)
    assert f"k.yaml:{line}:" in result.output
    assert f"'{name}' is a reserved word and cannot be used as a name" in result.output
    assert f"hint: rename it, e.g. '{name}_'" in result.output and "Traceback" not in result.output


# ------------------------------------------------------------------------------------------
# Space: closed loops (a moving line, a slider on a turning body), a ball joint's reactions
# ------------------------------------------------------------------------------------------

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


def test_bead_on_a_turntable_rod_moving_line_in_space():
    system = derived("turntable_bead.yaml")
    pairs = walk(system, turntable_reference(), [0.2, 0.6], [0.2, 0.4, 0.1, 0.6], 506, step=0.15)
    assert worst(pairs) < TOL


@lru_cache(maxsize=None)
def frame_parts():
    psi, xb, yb, zb = ys = list(S("psi xb yb zb"))
    mf, A, B, C, P, al, mb, k, l0, tz, g = params = S("mf A B C P al mb k l0 tz g")
    Rf = Rz(psi) * Ry(al)
    p = sp.Matrix([xb, yb, zb])
    M, h = virtual_power([(mf, sp.zeros(3, 1), Rf, sp.Matrix([[A, 0, P], [0, B, 0], [P, 0, C]])), (mb, p)], ys)
    hub = Rf * sp.Matrix([-R(1, 10), 0, R(1, 20)])
    V = mb * g * zb + spring_V(k, hub, p, l0)
    from test_sweep_models import world_angular_velocity
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


def test_bead_on_a_slider_in_a_spinning_tilted_frame():
    system = derived("spinning_frame_slider.yaml")
    assert worst(walk(system, frame_reference(), [0.1, 0.3], FRAME_GUESS, 507, step=0.3)) < TOL


@pytest.mark.parametrize("name", ["turntable_bead.yaml"])  # the spinning frame's: the auto test below
def test_closed_loops_in_space_keep_energy_in_their_free_scene(tmp_path, name):
    """`simulate --scene free` (gravity and a spring only): the total energy is kept, and the
    hand constraints hold in every row of the CSV."""
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / name), "--scene", "free", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    energy = table["total_energy"]
    assert len(energy) == 9 and np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))
    ref = turntable_reference(free=True) if name == "turntable_bead.yaml" else frame_reference(free=True)
    values = {p.name: float(p.value) for p in derived(name).parameters}
    pv = [values[n] for n in ref.params]
    residual = [np.array(ref.fg(0.0, *[row[s.name] for s in ref.y], *np.zeros(len(ref.y)), *pv), dtype=float)
                for row in table]
    assert np.max(np.abs(residual)) < 1e-9
    # and the hand energy at each row's state
    T_V = []
    for row in table:
        ind = [ref.y[i].name for i in ref.ind]
        yv, ydv = ref.consistent([row[n] for n in ind], [row[f"{n}_dot"] for n in ind],
                                 [row[s.name] for s in ref.y], pv)
        Mv = np.array(ref.fM(0.0, *yv, *ydv, *pv), dtype=float)
        T_V.append(ydv @ Mv @ ydv / 2)
    assert np.allclose(table["kinetic_energy"], T_V, rtol=1e-9, atol=1e-9)


def ball_joint_parts():
    xc, yc, zc, psi, th, ph = x = list(S("xc yc zc psi th ph"))
    m, h, A, C, D, F, g = S("m h A C D F g")
    Rb = Rz(psi) * Rx(th) * Rz(ph)
    I3 = sp.Matrix([[A, D, 0], [D, A, 0], [0, 0, C]])
    push = sp.Matrix([F, 0, F * sp.cos(t)])
    side = sp.Matrix([xc, yc, zc]) + Rb * sp.Matrix([R(1, 10), 0, -R(1, 5)])
    return x, (m, I3, Rb, push, side, g)


def test_ball_joint_body_equations():
    x, (m, I3, Rb, push, side, g) = ball_joint_parts()
    q = x[3:]
    centre = Rb * sp.Matrix([0, 0, -S("h")])
    M, h = virtual_power([(m, centre, Rb, I3)], q)
    side_q = side.xreplace(dict(zip(x[:3], centre)))
    V = m * g * centre[2]
    f = gradient_force(V, q, work_rows(push, side_q, q))
    system = derived("ball_joint_body.yaml")
    fixed = lambda rng: {"th": rng.uniform(0.2, 2.9)}  # noqa: E731  (Z-X-Z: singular at th = 0, pi)
    assert compare_explicit(system, (M, h, f), 508, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 508, fixed=fixed) < TOL


def test_ball_joint_reactions_in_space(tmp_path):
    """`derive --reactions`: ``R = M xddot + h - f`` on the six primitive coordinates of the body,
    from a hand primitive (virtual power over the free body) along the hand motion; on the
    centre's coordinates that is the joint force, ``m a_c + m g e_z - F``."""
    x, (m, I3, Rb, push, side, g) = ball_joint_parts()
    q, hh = x[3:], S("h")
    Mx, hx = virtual_power([(m, sp.Matrix(x[:3]), Rb, I3)], x)
    fx = sp.Matrix([-m * g * int(a == x[2]) for a in x]) + sp.Matrix(work_rows(push, side, x))
    centre = Rb * sp.Matrix([0, 0, -hh])
    connection = dict(zip(x[:3], centre))
    qd, qdd = dots(q), [sp.Symbol(f"{s.name}_ddot") for s in q]
    Jc = sp.Matrix([*centre, *q]).jacobian(q)
    xdot = Jc * sp.Matrix(qd)
    xddot = Jc * sp.Matrix(qdd) + xdot.jacobian(q) * sp.Matrix(qd)
    sub = {**connection, **{sp.Symbol(f"{a.name}_dot"): xdot[i] for i, a in enumerate(x)}}
    r_hand = (Mx * xddot + hx - fx).xreplace(sub)
    M, h = virtual_power([(m, centre, Rb, I3)], q)
    f = sp.Matrix(work_rows(push, side.xreplace(connection), q)) - sp.Matrix([(m * g * centre[2]).diff(a) for a in q])
    result = CliRunner().invoke(main, ["derive", str(HERE / "ball_joint_body.yaml"), "--reactions", "--format", "json"])
    assert result.exit_code == 0, result.output
    expressions = json.loads(result.stdout)["reactions"]["expressions"]
    assert list(expressions) == [f"R_{a.name}" for a in x]
    names = {s.name: s for s in [*x, *qd, *qdd, t, *S("m h A C D F g")]}
    ours = sp.Matrix([sp.sympify(expressions[f"R_{a.name}"], locals=names) for a in x])  # test code, not kronsub
    values = {names[p.name]: float(p.value) for p in derived("ball_joint_body.yaml").parameters}
    args = [t, *q, *qd, *qdd]
    f_ours, f_hand = (sp.lambdify(args, e.xreplace(values), "numpy") for e in (ours, r_hand))
    f_M, f_rhs = (sp.lambdify([t, *q, *qd], e.xreplace(values), "numpy") for e in (M, f - h))
    joint = sp.lambdify(args, (m * xddot[:3, :] + sp.Matrix([0, 0, m * g]) - push).xreplace(values), "numpy")

    def hand_acc(tt, qv, qdv):
        Mv = np.array(f_M(tt, *qv, *qdv), dtype=float)
        return np.linalg.solve(Mv, np.array(f_rhs(tt, *qv, *qdv), dtype=float).ravel())

    rng = np.random.default_rng(509)
    pairs = []
    for _ in range(6):
        tt, qv, qdv = rng.uniform(0, 3), rng.uniform(-3, 3, 3), rng.uniform(-2, 2, 3)
        qv[1] = rng.uniform(0.2, 2.9)
        acc = hand_acc(tt, qv, qdv)
        a = (tt, *qv, *qdv, *acc)
        mine = np.array(f_ours(*a), dtype=float).ravel()
        pairs += [(mine, np.array(f_hand(*a), dtype=float).ravel()),
                  (mine[:3], np.array(joint(*a), dtype=float).ravel())]
    assert worst(pairs) < 1e-9
    # the same reactions in every row of `simulate --reactions`, at the row's state
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / "ball_joint_body.yaml"), "--t", "0.3", "--dt", "0.1",
                                       "--reactions", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    rows = []
    for row in table:
        tt, qv, qdv = row["t"], [row[s.name] for s in q], [row[f"{s.name}_dot"] for s in q]
        hand = np.array(f_hand(tt, *qv, *qdv, *hand_acc(tt, qv, qdv)), dtype=float).ravel()
        rows.append((np.array([row[f"R_{a.name}"] for a in x]), hand))
    assert len(rows) == 4 and worst(rows) < 1e-9


# ------------------------------------------------------------------------------------------
# A known system of known systems under scenes: codegen --scene, C and Python
# ------------------------------------------------------------------------------------------

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


def test_nested_known_systems_with_overrides():
    q, M, h, f, V = nested_reference()
    system = derived("nested_scenes.yaml")
    assert compare_explicit(system, (M, h, f), 510) < TOL
    assert compare_energies(system, kinetic(M, q), V, 510) < TOL


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


def test_nested_scene_numpy_module(tmp_path):
    import importlib.util

    result = CliRunner().invoke(main, ["codegen", str(HERE / "nested_scenes.yaml"), "--scene", "quiet",
                                       "--lang", "python", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    spec = importlib.util.spec_from_file_location("sweep5_nested_quiet", tmp_path / "nested_scenes.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert not {"cp", "tm"} & set(mod.PARAMETERS), mod.PARAMETERS  # only the switched-off effects use them
    values = quiet_values()
    param = np.array([float(values[n]) for n in mod.PARAMETERS])
    fM, fh, ff, fT, fV = hand_numbers(nested_reference(hinges=False, motor=False), values)
    pairs = []
    for tt, y in nested_states(511):
        q, qd = y[:5], y[5:]
        M, h, f = (np.array(fn(tt, *y), dtype=float) for fn in (fM, fh, ff))
        pairs += [(mod.mass_matrix(q, param), M), (mod.velocity_terms(q, qd, param), h.ravel()),
                  (mod.forces(tt, q, qd, param), f.ravel()),
                  (np.asarray(mod.rhs(tt, y, param))[5:], np.linalg.solve(M, f.ravel() - h.ravel())),
                  (np.array([mod.kinetic_energy(y, param), mod.potential_energy(tt, y, param)]),
                   np.array([fT(tt, *y), fV(tt, *y)], dtype=float))]
    assert worst(pairs) < TOL


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
@pytest.mark.parametrize("which", ["driven"])  # quiet: the numpy module above
def test_nested_scene_generated_c(tmp_path, which):
    from test_sweep_outputs import header_order

    result = CliRunner().invoke(main, ["codegen", str(HERE / "nested_scenes.yaml"), "--scene", which, "--lang", "c",
                                       "--prefix", "nq", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    lib = tmp_path / "libnested.so"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC",
                    str(tmp_path / "nested_scenes.c"), "-o", str(lib), "-lm"], check=True, capture_output=True)
    names, _ = header_order((tmp_path / "nested_scenes.h").read_text(), "NQ")
    if which == "quiet":
        values, ref = quiet_values(), nested_reference(hinges=False, motor=False)
        assert not {"cp", "tm"} & set(names), names
    else:  # gravity, the coupling, the shaft and the motor: no wall springs, no hinges
        values = {**NESTED_VALUES, "k": 0, "kL": 0}
        ref = nested_reference(hinges=False, motor=True)
        assert not {"cp", "k", "kL", "L0"} & set(names), names
    c = ctypes.CDLL(str(lib))
    D = ctypes.POINTER(ctypes.c_double)
    c.nq_rhs.argtypes = [ctypes.c_double, D, D, D]
    c.nq_forces.argtypes = [ctypes.c_double, D, D, D, D]
    ptr = lambda a: a.ctypes.data_as(D)  # noqa: E731
    param = np.array([float(values[n]) for n in names])
    fM, fh, ff, _, _ = hand_numbers(ref, values)
    pairs = []
    for tt, y in nested_states(512):
        q, qd = y[:5].copy(), y[5:].copy()
        M, h, f = (np.array(fn(tt, *y), dtype=float) for fn in (fM, fh, ff))
        Mc, fc, ydot = np.zeros(25), np.zeros(5), np.zeros(10)
        c.nq_mass_matrix(ptr(q), ptr(param), ptr(Mc))
        c.nq_forces(tt, ptr(q), ptr(qd), ptr(param), ptr(fc))
        assert c.nq_rhs(tt, ptr(y), ptr(param), ptr(ydot)) == 0
        pairs += [(Mc.reshape(5, 5), M), (fc, f.ravel()), (ydot[5:], np.linalg.solve(M, f.ravel() - h.ravel()))]
    assert worst(pairs) < TOL


def test_linearize_a_closed_loop_in_space_against_the_multipliers(tmp_path):
    """`linearize --scene free` of the turntable bead: the hand accelerations (the multiplier
    solve on x, y, z, a) vanish at kronsub's operating point, and kronsub's A is their
    Jacobian in [a, z, a_dot, z_dot] by central differences.

    The turntable's angle is not fixed by the equilibrium (its column of dr/dq is round-off,
    ~1e-16, not an exact zero): Levenberg-Marquardt scaled by those column norms (scipy's
    default for 'lm') sent it to a = -9.7e13 (and from the model's initial values to
    -1.4e15, "no equilibrium found"). With unit scaling it stays where it started."""
    ref = turntable_reference(free=True)
    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(HERE / "turntable_bead.yaml"), "--scene", "free",
                                       "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["state"] == ["a", "z", "a_dot", "z_dot"] and data["equilibrium"]
    assert abs(data["operating_point"]["a"] - 0.2) < 1e-9, data["operating_point"]  # the model's initial a
    values = {p.name: float(p.value) for p in derived("turntable_bead.yaml").parameters}
    pv = [values[n] for n in ref.params]
    point = np.array([data["operating_point"][n] for n in data["state"]], dtype=float)
    guess = [point[0], 0.4, 0.1, point[1]]

    def acc(state):
        yv, ydv = ref.consistent(state[:2], state[2:], guess, pv)
        return ref.evaluate(0.0, yv, ydv, pv)[3]

    assert np.max(np.abs(acc(point))) < 1e-9
    eps, cols = 1e-6, []
    for j in range(4):
        e = np.zeros(4)
        e[j] = eps
        cols.append((acc(point + e) - acc(point - e)) / (2 * eps))
    A = np.vstack([np.hstack([np.zeros((2, 2)), np.eye(2)]), np.column_stack(cols)])
    assert np.allclose(np.array(data["A"], dtype=float), A, rtol=1e-6, atol=1e-6)


def test_linearize_finds_the_equilibrium_where_levenberg_marquardt_stalls(tmp_path, monkeypatch):
    """`linearize --scene free` of the spinning frame from the model's initial values (psi = 0.1,
    zb = 0.3): Levenberg-Marquardt stalled at zb = 0.144, where the residual turns (the largest
    acceleration 1.01: "no equilibrium found"); the trust-region reflective method from the same
    start finds the equilibrium, where the hand accelerations (the multiplier solve) vanish."""
    import scipy.optimize

    methods, real = [], scipy.optimize.least_squares

    def spy(*args, **kwargs):
        methods.append(kwargs["method"])
        return real(*args, **kwargs)

    monkeypatch.setattr(scipy.optimize, "least_squares", spy)
    ref = frame_reference(free=True)
    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(HERE / "spinning_frame_slider.yaml"), "--scene", "free",
                                       "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert methods == ["lm", "trf"], methods
    data = json.loads(out.read_text())
    assert data["state"] == ["psi", "zb", "psi_dot", "zb_dot"] and data["equilibrium"], data
    values = {p.name: float(p.value) for p in derived("spinning_frame_slider.yaml").parameters}
    pv = [values[n] for n in ref.params]
    point = [data["operating_point"][n] for n in ("psi", "zb")]
    yv, ydv = ref.consistent(point, [0.0, 0.0], [point[0], 0.2, 0.1, point[1]], pv)
    assert np.max(np.abs(ref.evaluate(0.0, yv, ydv, pv)[3])) < 1e-9


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


def test_bead_on_a_helix_constraints_through_definitions():
    pairs = walk(derived("bead_on_helix.yaml"), helix_reference(), [0.5], HELIX_GUESS, 513, step=0.4)
    assert worst(pairs) < TOL


def test_bead_on_a_helix_reactions(tmp_path):
    """`simulate --reactions`: the multipliers of the three constraints as written (``g`` = the
    expressions) against the hand solve of ``M yddot + h = f + G^T mu`` at every row."""
    ref = helix_reference()
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / "bead_on_helix.yaml"), "--t", "0.4", "--dt", "0.1",
                                       "--reactions", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    values = {p.name: float(p.value) for p in derived("bead_on_helix.yaml").parameters}
    pv = [values[n] for n in ref.params]
    pairs = []
    for row in table:
        yv, ydv = ref.consistent([row["s"]], [row["s_dot"]], HELIX_GUESS, pv)
        a = (row["t"], *yv, *ydv, *pv)
        M, h, f = (np.array(fn(*a), dtype=float) for fn in (ref.fM, ref.fh, ref.ff))
        G, Gdy = np.array(ref.fG(*a), dtype=float), np.array(ref.fGd(*a), dtype=float).ravel()
        K = np.block([[M, G.T], [G, np.zeros((3, 3))]])
        mu = -np.linalg.solve(K, np.concatenate([f.ravel() - h.ravel(), -Gdy]))[4:]
        pairs.append((np.array([row[n] for n in ("mu_cx", "mu_cy", "mu_cz")]), mu))
    assert len(pairs) == 5 and worst(pairs) < 1e-8


def test_known_system_with_overrides_in_time_placed():
    """Overrides in t of parameters that enter the known system's effects only (its wall
    spring's rest length, its hinge's damping), another of its mass, and `origin:`."""
    s, th = q = list(S("s th"))
    mc, l, k, g, x0, A, w, c0, kt, mb = S("mc l k g x0 A w c0 kt mb")
    mp = R(3, 5)
    cart = sp.Matrix([x0 + s, 0])
    tip = cart + l * down(th)
    M, h = virtual_power([(mc, sp.Matrix([s])), (mp, cart + l / 2 * down(th), th, mp * l ** 2 / 12), (mb, tip)], q)
    gap = tip - sp.Matrix([R(6, 5), -R(3, 10)])
    V = (k * (sp.sqrt(s ** 2) - (R(2, 5) + A * sp.sin(w * t))) ** 2 / 2 + kt * gap.dot(gap) / 2
         + g * (mp + mb) * tip[1] - g * mp * l / 2 * down(th)[1])
    f = gradient_force(V, q, damper_rows(c0 * (1 + t / 2), th, q))
    system = derived("override_in_time.yaml")
    assert compare_explicit(system, (M, h, f), 514) < TOL
    assert compare_energies(system, kinetic(M, q), V, 514) < TOL


def test_nested_scene_run_and_placed_points(tmp_path):
    """`simulate --scene driven` (its t_end, dt and outputs): every row against the hand
    equations integrated here (scipy, tight tolerances), and the points of the placed nested
    copies (a line point on the plane's x axis) at the row's state."""
    from scipy.integrate import solve_ivp

    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / "nested_scenes.yaml"), "--scene", "driven",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#", deletechars="")
    values = {**NESTED_VALUES, "k": 0, "kL": 0}
    fM, fh, ff, fT, fV = hand_numbers(nested_reference(hinges=False, motor=True), values)

    def rhs(tt, y):
        M = np.array(fM(tt, *y), dtype=float)
        return np.concatenate([y[5:], np.linalg.solve(M, (np.array(ff(tt, *y), dtype=float)
                                                          - np.array(fh(tt, *y), dtype=float)).ravel())])

    y0 = [0.5, 0.2, 0.4, -0.1, 0, 0, 0, 0, 0, 0]
    sol = solve_ivp(rhs, (0, 0.5), y0, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=np.linspace(0, 0.5, 6))
    names = ["s1", "th1", "s2", "th2", "f", "s1_dot", "th1_dot", "s2_dot", "th2_dot", "f_dot"]
    assert np.allclose(table["t"], sol.t)
    ours = np.column_stack([table[n] for n in names])
    assert np.allclose(ours, sol.y.T, rtol=1e-8, atol=1e-8)
    l, d = values["l"], values["d"]
    s1, th1, s2, th2 = (table[n] for n in ("s1", "th1", "s2", "th2"))
    points = {"pair.right.pole.tip": (d + s2 + l * np.sin(th2), -l * np.cos(th2)),
              "pair.left.pole.centre": (s1 + l / 2 * np.sin(th1), -l / 2 * np.cos(th1)),
              "pair.right.cart.centre": (d + s2, 0 * s2)}
    for name, (px, py) in points.items():
        assert np.allclose(table[f"{name}.x"], px, atol=1e-12) and np.allclose(table[f"{name}.y"], py, atol=1e-12), name
    energy = [(fT(tt, *y), fV(tt, *y)) for tt, y in zip(sol.t, sol.y.T)]
    ours = np.column_stack([table["kinetic_energy"], table["potential_energy"]])
    assert np.allclose(ours, energy, rtol=1e-8, atol=1e-8)


def test_names_other_tools_reserve_linearized_symbolically(tmp_path):
    """`linearize --symbolic` of the odd names (the push off: `--at oo=0`): every entry of A read
    back with those names (`Abs`, `I`, `E`... as the model's symbols) equals the hand Jacobian at
    the operating point and the parameters' values."""
    q, M, h, f, _ = odd_reference()
    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(HERE / "odd_names.yaml"), "--symbolic", "--at", "oo=0",
                                       "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["state"] == ["nan", "E", "nan_dot", "E_dot"] and data["equilibrium"]
    values = {p.name: float(p.value) for p in derived("odd_names.yaml").parameters}
    values["oo"] = 0.0
    names = {n: sp.Symbol(n) for n in values}
    point = {n: float(sp.Float(v)) for n, v in data["operating_point"].items()}
    ours = np.array([[float(sp.sympify(e, locals=names).xreplace({names[k]: v for k, v in values.items()}))
                      for e in row] for row in data["A"]])  # test code reading the output, not kronsub
    qd = dots(q)
    rhs = M.inv() * (f - h)
    sub = {s: values[s.name] for s in rhs.free_symbols if s.name in values}
    sub.update({s: point[s.name] for s in [*q, *qd]})
    sub[t] = 0.0
    J = np.array(rhs.jacobian([*q, *qd]).xreplace(sub).evalf(), dtype=float)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [J]])
    assert np.allclose(ours, A, rtol=1e-9, atol=1e-9), (ours, A)


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


def test_helix_known_system_reused_and_placed_in_space():
    system = derived("helix_pair.yaml")
    assert [s.name for s in system.coordinates] == ["s1", "s2"]
    guess = [0.5, -0.3, 0.44, 0.24, 0.075, 0.48, -0.15, -0.045]
    assert worst(walk(system, helix_pair_reference(), [0.5, -0.3], guess, 515, step=0.3)) < TOL


def test_planar_body_linearized_with_inputs_in_time(tmp_path):
    """`linearize --scene pushed --inputs F,tau --at t=0.5` at a given point that is no
    equilibrium: A and B (the columns of the force's size F sin(3t) and the torque's tau cos t)
    against the hand Jacobians there."""
    q, M, h, f, _ = plate_reference(damper=False)
    at = {"x": 0.1, "y": 0.2, "th": 0.3, "x_dot": 0.5, "y_dot": -0.2, "th_dot": 1.0}
    args = ["linearize", str(HERE / "planar_body_tethered.yaml"), "--scene", "pushed", "--inputs", "F,tau",
            "--at", "t=0.5", "--format", "json", "-o", str(tmp_path / "lin.json")]
    for name, value in at.items():
        args += ["--at", f"{name}={value}"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    data = json.loads((tmp_path / "lin.json").read_text())
    assert not data["equilibrium"] and data["inputs"] == ["F", "tau"]
    values = {p.name: float(p.value) for p in derived("planar_body_tethered.yaml").parameters}
    rhs = M.inv() * (f - h)
    F, tau = S("F tau")
    sub = {s: values[s.name] for s in rhs.free_symbols if s.name in values}
    sub.update({s: at[s.name] for s in [*q, *dots(q)]})
    sub[t] = 0.5
    J = np.array(rhs.jacobian([*q, *dots(q)]).xreplace(sub).evalf(), dtype=float)
    Bl = np.array(rhs.jacobian([F, tau]).xreplace(sub).evalf(), dtype=float)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [J]])
    B = np.vstack([np.zeros((3, 2)), Bl])
    assert np.allclose(np.array(data["A"], dtype=float), A, rtol=1e-9, atol=1e-9)
    assert np.allclose(np.array(data["B"], dtype=float), B, rtol=1e-9, atol=1e-9)


# ------------------------------------------------------------------------------------------
# Defects this sweep found (these tests fail on the code before the fixes)
# ------------------------------------------------------------------------------------------

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


@pytest.mark.parametrize("where", ["here", "known"])
def test_constraints_whose_multipliers_share_a_name_are_refused(tmp_path, where):
    """A joint `B` (equations `B.x`, `B.y`) beside a constraint `B_x`: both multipliers were
    `mu_B_x`, so `derive --reactions --format json` kept two of the three (the pin's x force
    lost) and the markdown listed `mu_B_x` twice with different expressions. Likewise a
    constraint `left_cx` beside the known system `left`'s `cx` (`mu_left_cx`). Now refused at
    the constraint, naming both."""
    if where == "here":
        text, name, both = CLASHING, "B_x", ("'B.x'", "'B_x'", "'mu_B_x'")
    else:
        (tmp_path / "bead_on_helix.yaml").write_text((HERE / "bead_on_helix.yaml").read_text())
        text = (HERE / "helix_pair.yaml").read_text()
        fly = "  fly: {type: flywheel, parameters: {inertia: 1}, coordinates: [w]}\n"
        text = text.replace("  right:\n", fly + "  right:\n")
        text = text.replace("effects:\n", "constraints:\n  left_cx: w - s1\neffects:\n")
        name, both = "left_cx", ("'left.cx'", "'left_cx'", "'mu_left_cx'")
    path = tmp_path / "clash.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["derive", str(path), "--reactions", "--format", "json"])
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.startswith(f"  {name}:"))
    assert f"clash.yaml:{line}:3:" in result.output and all(b in result.output for b in both), result.output
    assert "hint: rename one of them" in result.output and "Traceback" not in result.output
    fixed = text.replace(f"  {name}:", f"  {name}_:")
    path.write_text(fixed)
    result = CliRunner().invoke(main, ["derive", str(path), "--reactions", "--format", "json"])
    assert result.exit_code == 0, result.output
    reactions = json.loads(result.stdout)["reactions"]
    names = list(reactions["expressions"]) if "expressions" in reactions else reactions["linear_system"]["unknowns"]
    assert len(names) == len(set(names)) and f"mu_{name}_" in names, names


def test_auto_coordinates_switching_in_space_follow_the_hand_motion(tmp_path):
    """The spinning frame with `coordinates: auto` (psi and xb picked; the bead's line turns, so
    the choice switches between xb and yb): the run records its switches, keeps the energy and
    follows the hand motion (the multiplier solve integrated in psi, zb by scipy), the start
    given in full so that both begin alike."""
    from scipy.integrate import solve_ivp

    text = (HERE / "spinning_frame_slider.yaml").read_text().replace("coordinates: [psi, zb]", "coordinates: auto")
    ref = frame_reference(free=True)
    values = {p.name: float(p.value) for p in derived("spinning_frame_slider.yaml").parameters}
    pv = [values[n] for n in ref.params]
    yv, ydv = ref.consistent([0.1, 0.3], [2.0, -0.3], FRAME_GUESS, pv)
    start = ", ".join([f"{s.name}: {float(v)!r}" for s, v in zip(ref.y, yv)]
                      + [f"{s.name}_dot: {float(v)!r}" for s, v in zip(ref.y, ydv)])
    old = "initial: {psi: 0.1, zb: 0.3, xb: 0.2, yb: 0.1, psi_dot: 2.0, zb_dot: -0.3}"
    assert old in text
    auto = tmp_path / "auto.yaml"
    auto.write_text(text.replace(old, "initial: {" + start + "}"))
    out = tmp_path / "auto.csv"
    result = CliRunner().invoke(main, ["simulate", str(auto), "--scene", "free", "--t", "1.5", "-o", str(out)])
    assert result.exit_code == 0, result.output
    ours = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    switches = json.loads((tmp_path / "auto.json").read_text())["coordinate_switches"]
    assert len(switches) >= 1, switches
    guess = [list(yv)]

    def rhs(tt, state):
        y_, yd_ = ref.consistent(state[:2], state[2:], guess[0], pv)
        guess[0] = y_
        return np.concatenate([state[2:], ref.evaluate(tt, y_, yd_, pv)[3]])

    sol = solve_ivp(rhs, (0, 1.5), [0.1, 0.3, 2.0, -0.3], method="DOP853", rtol=1e-11, atol=1e-11, t_eval=ours["t"])
    hand = np.array([ref.consistent(st[:2], st[2:], yv, pv)[0] for st in sol.y.T])
    for i, s in enumerate(ref.y):
        assert np.allclose(ours[s.name], hand[:, i], rtol=1e-7, atol=1e-7), s.name
    energy = ours["total_energy"]
    assert np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))
