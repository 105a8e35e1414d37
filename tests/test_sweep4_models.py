"""Fourth robustness sweep: models of kinds the first three sweeps did not cover
(tests/models/sweep4/): two-loop linkages (a Stephenson six-bar, a V-twin sharing one
crank), a known closed loop renamed with a second loop around it, a four-bar whose coupler
carries a pendulum, implicit constraints mixing lengths and angles, a closed loop in space
(a rod on a ball joint, its tip on a tilted plane), a gyroscope on gimbals in Z-X-Y angles
with an offset mass centre, a free body in X-Z-X angles, forces in the velocities (quadratic
drag, abs) and in time, central potentials in polar and spherical coordinates, component
parameters given by expressions of shared ones, zero coefficients and zero-length springs,
and scenes over a known system.

Each is checked against a derivation written here in plain sympy (never with kronsub), with
the reference helpers of the earlier sweeps: Lagrange's equations of a hand ``T`` and ``V``,
virtual power over the bodies, Lagrange multipliers on the full coordinates for closed
loops (and the reactions of `simulate --reactions` against them).
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
from helpers import Rx, Ry, Rz, generated_numpy_module, sweep_models
from kronsub.cli import main
from test_sweep3_models import accelerations_agree, kinetic, walk_independent
from test_sweep_models import (Constrained, compare_explicit, dots, lagrange, largest_difference, rate_of,
                               virtual_power, walk_constrained, world_angular_velocity, worst)

HERE = Path(__file__).resolve().parent / "models" / "sweep4"
t = sp.Symbol("t")
S = sp.symbols
TOL = 1e-10

loaded, derived = sweep_models(HERE)


def down(a):
    return sp.Matrix([sp.sin(a), -sp.cos(a)])


def across(a):
    """A pinned rod's body y axis (its x axis, ``down(a)``, turned a quarter counter-clockwise)."""
    return sp.Matrix([sp.cos(a), sp.sin(a)])


def compare_energies(system, T, V, seed, *, spread=3.0, states=6, fixed=None):
    return largest_difference(system, [system.kinetic_energy, system.potential_energy], [sp.sympify(T), sp.sympify(V)],
                              seed, spread=spread, states=states, fixed=fixed)


def gradient_force(V, q, extra=None):
    return sp.Matrix([-V.diff(a) + (extra[i] if extra is not None else 0) for i, a in enumerate(q)])


def damper_rows(c, length, q):
    return [-c * rate_of(length, q) * length.diff(a) for a in q]


def norm(v):
    return sp.sqrt(v.dot(v))


# ------------------------------------------------------------------------------------------
# Space: gimbals in Z-X-Y angles, a free body in X-Z-X angles
# ------------------------------------------------------------------------------------------

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


def test_gyroscope_on_gimbals_zxy_offset_centre(tmp_path):
    q, M, h, f, V = gimbal_reference()
    system = derived("gimbal_gyro.yaml")
    fixed = lambda rng: {"theta": rng.uniform(-1.2, 1.2)}  # noqa: E731  (off gimbal lock)
    assert compare_explicit(system, (M, h, f), 51, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 51, fixed=fixed) < TOL
    module = numpy_module(tmp_path, "gimbal_gyro.yaml")
    assert accelerations_agree(system, M, h, f, 51, spread=1.0, numpy_module=module) < TOL


def numpy_module(tmp_path, name):
    return generated_numpy_module(tmp_path, HERE / name)


def test_free_box_xzx_products_of_inertia():
    x, y, z, a, b, c3 = q = list(S("x y z a b c3"))
    m, Ix, Iy, Iz, Pxy, Pyz, k, F, w, g = S("m Ix Iy Iz Pxy Pyz k F w g")
    R = Rx(a) * Rz(b) * Rx(c3)
    centre = sp.Matrix([x, y, z])
    I3 = sp.Matrix([[Ix, Pxy, 0], [Pxy, Iy, Pyz], [0, Pyz, Iz]])
    M, h = virtual_power([(m, centre, R, I3)], q)
    hook = centre + R * sp.Matrix([sp.Rational(1, 10), sp.Rational(1, 5), sp.Rational(3, 20)])
    side = centre + R * sp.Matrix([sp.Rational(1, 5), 0, sp.Rational(1, 20)])
    gap = hook - sp.Matrix([sp.Rational(1, 10), 0, 1])
    V = m * g * z + k * gap.dot(gap) / 2
    shake = sp.Matrix([0, F * sp.sin(w * t), F * sp.cos(w * t)])
    f = gradient_force(V, q, [shake.dot(side.diff(v)) for v in q])
    system = derived("tumbling_box_xzx.yaml")
    fixed = lambda rng: {"b": rng.uniform(0.2, 2.9)}  # noqa: E731  (X-Z-X: singular at b = 0, pi)
    assert compare_explicit(system, (M, h, f), 52, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 52, fixed=fixed) < TOL


# ------------------------------------------------------------------------------------------
# Forces in the velocities and in time; central potentials
# ------------------------------------------------------------------------------------------

def test_particle_on_three_springs_with_quadratic_drag(tmp_path):
    x, y, z = q = list(S("x y z"))
    m, k1, k2, k3, L1, L2, cq, A, w, g = S("m k1 k2 k3 L1 L2 cq A w g")
    p = sp.Matrix(q)
    a1, a2, a3 = (sp.Matrix(v) for v in ([1, 0, 1], [-sp.Rational(1, 2), sp.Rational(4, 5), 1],
                                          [-sp.Rational(1, 2), -sp.Rational(4, 5), 1]))
    V = (m * g * z + k1 * (norm(p - a1) - L1) ** 2 / 2 + k2 * (norm(a2 - p) - L2) ** 2 / 2
         + k3 * (p - a3).dot(p - a3) / 2)
    v = sp.Matrix(dots(q))
    drag = -cq * norm(v) * v
    T = m * v.dot(v) / 2
    M, hh, f = lagrange(T, V, q, [drag[i] + (A * sp.sin(w * t) * sp.exp(-t / 2) if i == 2 else 0) for i in range(3)])
    system = derived("drag_particle3d.yaml")
    assert compare_explicit(system, (M, hh, f), 53) < TOL
    assert compare_energies(system, T, V, 53) < TOL
    assert accelerations_agree(system, M, hh, f, 53, numpy_module=numpy_module(tmp_path, "drag_particle3d.yaml")) < TOL


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


def test_kepler_polar_thrust_and_abs_drag():
    """The full model (every effect): ``derive()`` of the model, not of its one scene."""
    q, T, V, Q = kepler_reference()
    system = derived("kepler_polar.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.3, 2)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, Q), 54, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 54, fixed=fixed) < TOL


def test_kepler_scene_keeps_energy_and_angular_momentum():
    from kronsub.model.scenes import derive_scene, select_scene

    q, T, V, _ = kepler_reference()
    model = loaded("kepler_polar.yaml")
    system = derive_scene(model, select_scene(model, "kepler"))
    fixed = lambda rng: {"r": rng.uniform(0.3, 2)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, [0, 0]), 55, fixed=fixed) < TOL
    run = dataclasses.replace(system, initial=dict(model.initial)).simulate(t=10.0, dt=0.5, dataframe=False)
    assert run.complete
    energy = run["total_energy"]
    assert np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))
    momentum = run["r"] ** 2 * run["a_dot"]  # m = 1
    assert np.ptp(momentum) < 1e-8


def test_particle_around_an_oblate_body_spherical():
    r, th, ph = q = list(S("r th ph"))
    m, mu, J2, R, c, ca, zero = S("m mu J2 R c ca zero")
    p = r * sp.Matrix([sp.sin(th) * sp.cos(ph), sp.sin(th) * sp.sin(ph), sp.cos(th)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    V = -mu * m / r * (1 - J2 * (R / r) ** 2 * (3 * sp.cos(th) ** 2 - 1) / 2)
    rd, thd, phd = dots(q)
    Q = [-c * rd, -zero * thd, -ca * phd]  # the dashpot to O is along r (r > 0)
    system = derived("spherical_oblate.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.3, 2)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, Q), 56, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 56, fixed=fixed) < TOL


# ------------------------------------------------------------------------------------------
# Parameters by expressions, zero coefficients, a known system under scenes
# ------------------------------------------------------------------------------------------

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


def test_rod_stock_torsion_springs_on_expressions():
    th1, th2 = q = list(S("th1 th2"))
    bodies, V, rows = torsion_parts(th1, th2, S("rho"))
    M, h = virtual_power(bodies, q)
    system = derived("torsion_pendulum.yaml")
    assert compare_explicit(system, (M, h, gradient_force(V, q, rows)), 57) < TOL
    assert compare_energies(system, kinetic(M, q), V, 57) < TOL


@lru_cache(maxsize=None)
def scene_reference():
    u, v, fw = q = list(S("u v f"))
    Jf, ks, tm = S("Jf ks tm")
    bodies, V, rows = torsion_parts(u, v, sp.Rational(3, 2))
    M, h = virtual_power(bodies + [(0, sp.Matrix([0]), fw, Jf)], q)
    V = V + ks * (fw - u) ** 2 / 2
    motor = [0, 0, tm * sp.cos(t)]
    return q, M, h, V, [*rows, 0], motor


def test_known_system_under_scenes():
    from kronsub.model.scenes import derive_scene, select_scene

    q, M, h, V, knee, motor = scene_reference()
    model = loaded("scene_with_known.yaml")
    full = derived("scene_with_known.yaml")
    assert "rho" not in {p.name for p in full.parameters}
    assert compare_explicit(full, (M, h, gradient_force(V, q, [a + b for a, b in zip(knee, motor)])), 58) < TOL
    assert compare_energies(full, kinetic(M, q), V, 58) < TOL
    cons = derive_scene(model, select_scene(model, "conservative"))
    names = {p.name for p in cons.parameters}
    assert not names & {"cr", "tm"}, names
    assert next(p for p in cons.parameters if p.name == "kt").value == sp.Rational(5, 2)
    assert compare_explicit(cons, (M, h, gradient_force(V, q)), 59) < TOL
    run = dataclasses.replace(cons, initial=dict(model.initial)).simulate(t=3.0, dt=0.5, dataframe=False)
    energy = run["total_energy"]
    assert run.complete and np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))
    bare = derive_scene(model, select_scene(model, "bare"))  # the shaft and the known system's gravity
    kt, k0 = S("kt k0")
    assert compare_explicit(bare, (M, h, gradient_force(V.subs({kt: 0, k0: 0}), q)), 60) < TOL


def test_parameter_value_in_other_parameters_is_a_clear_error(tmp_path):
    """A parameter's value may not use other parameters (docs/model-format.md): said at its
    place with a hint, never a traceback."""
    text = (HERE / "torsion_pendulum.yaml").read_text().replace("c0: {value: 0,", "c0: {value: cr/2,")
    path = tmp_path / "p.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if "c0: {value: cr/2" in ln)
    assert f"p.yaml:{line}:" in result.output and "hint:" in result.output
    assert "Traceback" not in result.output


# ------------------------------------------------------------------------------------------
# Closed loops
# ------------------------------------------------------------------------------------------

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


def test_stephenson_six_bar_two_loops():
    rows = walk_constrained(derived("stephenson_six_bar.yaml"), six_bar_reference(), 2.0,
                            [2.0, 0.344, -0.251, 0.977, 0.026], 61, step=0.08)
    assert worst(pair for row in rows for pair in row) < TOL


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


def test_v_twin_two_loops_sharing_a_crank():
    rows = walk_constrained(derived("v_twin.yaml"), v_twin_reference(), 0.3, V_TWIN_GUESS, 62, step=0.1)
    assert worst(pair for row in rows for pair in row) < TOL


def test_v_twin_reactions(tmp_path):
    """Pin forces and bore normal forces of `simulate --reactions`: the multipliers of
    ``M yddot + h = f + G^T mu`` in every row against the hand ones at the row's state (the
    bores as ``d x (P - Q)``, kronsub's sign of a line joint)."""
    ref = v_twin_reference()
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / "v_twin.yaml"), "--t", "0.2", "--dt", "0.1",
                                       "--reactions", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    values = {p.name: float(p.value) for p in derived("v_twin.yaml").parameters}
    pv = [values[n] for n in ref.params]
    labels = ["mu_A1_x", "mu_A1_y", "mu_A2_x", "mu_A2_y", "mu_bore1", "mu_bore2"]
    pairs = []
    for row in table:
        yv, ydv = ref.consistent([row["th"]], [row["th_dot"]], V_TWIN_GUESS, pv)
        a = (row["t"], *yv, *ydv, *pv)
        M, h, f = (np.array(fn(*a), dtype=float) for fn in (ref.fM, ref.fh, ref.ff))
        G, Gdy = np.array(ref.fG(*a), dtype=float), np.array(ref.fGd(*a), dtype=float).ravel()
        K = np.block([[M, G.T], [G, np.zeros((6, 6))]])
        mu = -np.linalg.solve(K, np.concatenate([f.ravel() - h.ravel(), -Gdy]))[len(yv):]
        pairs.append((np.array([row[n] for n in labels]), mu))
    assert len(pairs) == 3 and worst(pairs) < 1e-8


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


def test_four_bar_known_renamed_with_a_slider_loop():
    y = list(S("a b c e s"))
    a, b, c, e, s = y
    bodies, V, g_ = four_bar_parts(a, b, c)
    m4, l4, ms, ks, s0, cs, tau, g = S("m4 l4 ms ks s0 cs tau g")
    pivot = bodies[2][1]  # the rocker's centre
    c4 = pivot + l4 / 2 * down(e)
    tip = pivot + l4 * down(e)
    M, h = virtual_power([*bodies, (m4, c4, e, m4 * l4 ** 2 / 12), (ms, sp.Matrix([s]))], y)
    V = V + g * m4 * c4[1] + ks * (s - s0) ** 2 / 2  # the slider stays right of O
    f = gradient_force(V, y, [x + tau * int(q == a) for q, x in zip(y, damper_rows(cs, s, y))])  # |s| = s
    params = (*S("m1 m2 m3 l1 l2 l3 d g tau"), m4, l4, ms, ks, s0, cs)
    ref = Constrained(y, M, h, f, [*g_, *(tip - sp.Matrix([s, 0]))], [a], params)
    system = derived("four_bar_slider_renamed.yaml")
    assert [x.name for x in system.coordinates] == ["a"]
    rows = walk_constrained(system, ref, 2.0, [2.0, 0.344, -0.251, 2.273, 1.259], 63, step=0.06)
    assert worst(pair for row in rows for pair in row) < TOL


def test_four_bar_coupler_carries_a_pendulum():
    th1, ps, th2, th3 = y = list(S("theta1 psi theta2 theta3"))
    bodies, V, g_ = four_bar_parts(th1, th2, th3)
    mp, lp, kp, T0, g = S("mp lp kp T0 g")
    cb = bodies[1][1] + lp / 2 * down(ps)
    M, h = virtual_power([*bodies, (mp, cb, ps, mp * lp ** 2 / 12)], y)
    V = V + g * mp * cb[1] + kp * (ps - th2 - sp.Rational(3, 10)) ** 2 / 2
    f = gradient_force(V, y, [T0 * sp.cos(t) * int(a == th1) for a in y])
    ref = Constrained(y, M, h, f, g_, [th1, ps], (*S("m1 m2 m3 l1 l2 l3 d g"), mp, lp, kp, T0))
    system = derived("coupler_pendulum.yaml")
    pairs = walk_independent(system, ref, [2.0, 0.2], [2.0, 0.2, 0.344, -0.251], 64, step=0.05)
    assert worst(pairs) < TOL


def test_bead_on_a_turning_arm_held_by_a_spiral():
    y = list(S("a x y"))
    a, x, yy = y
    m, L, mb, b0, b1, k, l0, A, c, g = params = S("m L mb b0 b1 k l0 A c g")
    p = sp.Matrix([x, yy])
    M, h = virtual_power([(m, L / 2 * down(a), a, m * L ** 2 / 12), (mb, p)], y)
    anchor = sp.Matrix([sp.Rational(2, 5), sp.Rational(3, 10)])
    V = g * (m * (-L / 2 * sp.cos(a)) + mb * yy) + k * (norm(p - anchor) - l0) ** 2 / 2
    f = gradient_force(V, y, [(A * sp.sin(2 * t) - c * dots(y)[0]) * int(q == a) for q in y])
    g_ = [x * sp.cos(a) + yy * sp.sin(a), x ** 2 + yy ** 2 - (b0 + b1 * a) ** 2]
    ref = Constrained(y, M, h, f, g_, [a], params)
    rows = walk_constrained(derived("spiral_arm.yaml"), ref, 0.5, [0.5, 0.2876, -0.5266], 65, step=0.2)
    assert worst(pair for row in rows for pair in row) < TOL


def test_rod_on_a_ball_joint_tip_on_a_tilted_plane():
    psi, phi, th, xp, yp, zp = y = list(S("psi phi theta xp yp zp"))
    m, L, It, Ia, mp, s, hh, cs, Fp, g = params = S("m L It Ia mp s h cs Fp g")
    R = Rz(psi) * Ry(th) * Rx(phi)
    centre = R * sp.Matrix([L / 2, 0, 0])
    p = sp.Matrix([xp, yp, zp])
    M, h = virtual_power([(m, centre, R, sp.diag(Ia, It, It)), (mp, p)], y)
    V = g * (m * centre[2] + mp * zp)
    f = gradient_force(V, y, [Fp * int(q == yp) - cs * dots(y)[1] * int(q == phi) for q in y])
    g_ = [*(R * sp.Matrix([L, 0, 0]) - p), zp - s * xp + hh]
    ref = Constrained(y, M, h, f, g_, [psi, phi], params)
    system = derived("rod_on_tilted_plane.yaml")
    pairs = walk_independent(system, ref, [0.3, 0.0], [0.3, 0.0, 0.222, 0.932, 0.288, -0.220], 66, step=0.1)
    assert worst(pairs) < TOL


# ------------------------------------------------------------------------------------------
# Defects this sweep found (these tests fail on the code before the fixes)
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("model, old, new, what", [
    ("kepler_polar.yaml", "value: -mu*m/r + m*eps/r**2", "value: -mu*m/r + m*eps*r_dot**2", "the potential of 'well'"),
    ("torsion_pendulum.yaml", "angle: th1 + th2/2 - sin(th1)/3", "angle: th1 + th2_dot/2", "the angle of 'twist'"),
    ("torsion_pendulum.yaml", "stiffness: k0}", "stiffness: k0*(1 + th1_dot**2)}", "the stiffness of 'tie'"),
    ("torsion_pendulum.yaml", "angle: th2 - th1, coefficient: cr", "angle: th2 - th1_dot, coefficient: cr",
     "the angle of 'knee'"),
    ("drag_particle3d.yaml", "stiffness: k1, length: L1", "stiffness: k1, length: L1 + x_dot",
     "the rest length of 's1'"),
])
def test_conservative_effects_in_the_velocities_are_refused(tmp_path, model, old, new, what):
    """A potential in a velocity (``m eps r_dot^2``) derived without it, silently: the radial
    equation was ``-m mu/r^2`` alone (``-dV/dr``, no ``d/dt dV/dr_dot = 2 m eps r_ddot``).
    Likewise a spring's or a torsional spring's terms and a torsional damper's angle. Now an
    error at the expression; a velocity stays allowed in a damper's coefficient."""
    text = (HERE / model).read_text()
    assert old in text
    path = tmp_path / model
    path.write_text(text.replace(old, new))
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if new in ln)
    assert f"{model}:{line}:" in result.output and f"{what} depends on the velocity" in result.output
    assert "hint:" in result.output and "Traceback" not in result.output


def test_a_damper_coefficient_in_the_velocities_stays_allowed(tmp_path):
    text = (HERE / "torsion_pendulum.yaml").read_text()
    path = tmp_path / "p.yaml"
    path.write_text(text.replace("angle: th2 - th1, coefficient: cr", "angle: th2 - th1, coefficient: cr*abs(th1_dot)"))
    system = kronsub.load(path, cache=False).derive()
    th1, th2 = q = list(S("th1 th2"))
    bodies, V, _ = torsion_parts(th1, th2, S("rho"))
    cr, c0 = S("cr c0")
    rows = [x + y for x, y in zip(damper_rows(cr * sp.Abs(dots(q)[0]), th2 - th1, q),
                                  damper_rows(c0, th1 - 2 * th2, q))]
    M, h = virtual_power(bodies, q)
    assert compare_explicit(system, (M, h, gradient_force(V, q, rows)), 67) < TOL


def test_hint_lists_each_valid_name_once(tmp_path):
    """A generalized force on a velocity: the hint listed 'a, a, r, r' (a coordinate that is
    both primitive and generalized came twice)."""
    path = tmp_path / "k.yaml"
    text = (HERE / "kepler_polar.yaml").read_text()
    path.write_text(text.replace("coordinate: r, value", "coordinate: a_dot, value"))
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1 and "'a_dot' is not a primitive or generalized coordinate" in result.output
    hint = next(ln for ln in result.output.splitlines() if "hint:" in ln)
    names = hint.split("valid names:")[1].split(",")
    assert sorted(n.strip() for n in names) == ["a", "r", "sat.a", "sat.angle", "sat.r"], hint


@pytest.mark.parametrize("name, quiet", [("stephenson_six_bar.yaml", ["tm=0", "cm=0"]),
                                         ("rod_on_tilted_plane.yaml", ["cs=0", "Fp=0"])])
def test_closed_loops_keep_energy_without_their_drives(tmp_path, name, quiet):
    """`simulate` (dop853 at its tight tolerance): the total energy of the two-loop linkage and
    of the loop in space (gravity and a spring only) is kept, and the constraints hold in
    every row (evaluated here from the CSV's coordinates)."""
    out = tmp_path / "run.csv"
    args = ["simulate", str(HERE / name), "--t", "2", "--dt", "0.25", "-o", str(out)]
    for item in quiet:
        args += ["--set", item]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    energy = table["total_energy"]
    assert len(energy) == 9 and np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))
    system = derived(name)
    imp = system.implicit
    values = {p.symbol: p.value for p in system.parameters}
    y = [*imp.independent, *imp.dependent]
    g = sp.lambdify(y, [c.expression.xreplace(values) for c in imp.constraints])
    residual = np.array(g(*[table[s.name] for s in y]), dtype=float)
    assert np.max(np.abs(residual)) < 1e-9
