"""Sixth robustness sweep: models of kinds the first five sweeps did not cover
(tests/models/sweep6/): a double pendulum of particles on massless rods (and two of them as
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
the reference helpers of the earlier sweeps: Lagrange's equations of a hand ``T`` and ``V``,
virtual power over the bodies, virtual work for the non-conservative loads, Lagrange
multipliers on the full coordinates for closed loops. The defects this sweep found have their
tests at the end: an effect in a pivoted rod's angle acted in the subspace only (so the
reactions were refused), and a pivoted rod's angle left out of `coordinates:` was a frozen
symbol (the rod's swing missing from ``Mbar``).
"""
from __future__ import annotations

import ctypes
import shutil
import subprocess
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

from helpers import Rx, Rz, generated_numpy_module, scene_of, sweep_models
from kronsub.cli import main
from test_sweep3_models import accelerations_agree, kinetic
from test_sweep5_models import add, damper_rows, down, gradient_force, norm, spring_V, work_rows
from test_sweep_models import (Constrained, compare_explicit, dots, lagrange, largest_difference, rate_of,
                               virtual_power, world_angular_velocity, worst)

HERE = Path(__file__).resolve().parent / "models" / "sweep6"
t = sp.Symbol("t")
S = sp.symbols
R = sp.Rational
TOL = 1e-10

loaded, derived = sweep_models(HERE)
scene = scene_of(loaded)


def compare_energies(system, T, V, seed, *, fixed=None):
    return largest_difference(system, [system.kinetic_energy, system.potential_energy], [sp.sympify(T), sp.sympify(V)],
                              seed, states=6, fixed=fixed)


# ------------------------------------------------------------------------------------------
# The plane: particles on massless rods, two pendulums on one cart
# ------------------------------------------------------------------------------------------

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


def test_double_pendulum_of_particles_on_massless_rods():
    """Massless pinned_rods carry only geometry: ``T`` is the bobs' alone, the spring hangs from
    the middle of the upper (massless) rod."""
    q = list(S("q1 q2"))
    T, V, Q, _ = particle_pendulum_parts(*q, q)
    system = derived("particle_double_pendulum.yaml")
    assert compare_explicit(system, lagrange(T, V, q, Q), 601) < TOL
    assert compare_energies(system, T, V, 601) < TOL


@lru_cache(maxsize=None)
def twin_reference(quiet=False):
    q = list(S("a1 a2 b1 b2"))
    d, kc = S("d kc")
    TL, VL, QL, left = particle_pendulum_parts(q[0], q[1], q, push=not quiet, damper=not quiet)
    TR, VR, QR, right = particle_pendulum_parts(q[2], q[3], q, origin=(d, 0), heavier=2, push=False,
                                                damper=not quiet)
    V = VL + VR + spring_V(kc, left, right, d)
    return q, TL + TR, V, add(QL, QR)


@pytest.mark.parametrize("which", [None, "quiet"])
def test_two_particle_pendulums_as_known_systems_placed_and_tied(which):
    """particle_double_pendulum.yaml twice (one placed, overridden), and its scene without the
    nested dampers and push: equal to the hand equations with those loads left out."""
    q, T, V, Q = twin_reference(quiet=which == "quiet")
    system = scene("twin_particle_pendulums.yaml", which) if which else derived("twin_particle_pendulums.yaml")
    assert compare_explicit(system, lagrange(T, V, q, Q), 615) < TOL
    assert compare_energies(system, T, V, 615) < TOL


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


def test_elastic_spherical_pendulum():
    q, T, V, Q = elastic_reference()
    system = derived("elastic_spherical_pendulum.yaml")
    assert compare_explicit(system, lagrange(T, V, q, Q), 602, fixed=positive_r) < TOL
    assert compare_energies(system, T, V, 602, fixed=positive_r) < TOL


@pytest.mark.parametrize("which, damper, swirl", [("undamped", False, True), ("free", False, False)])
def test_elastic_spherical_pendulum_scenes(which, damper, swirl):
    """A scene's equations are the full ones with its switched-off effects' parameters at zero
    (the hand ones with c = 0, and P = 0 for `free`), and they no longer contain them."""
    q, T, V, Q = elastic_reference(damper, swirl)
    system = scene("elastic_spherical_pendulum.yaml", which)
    gone = {"c"} if swirl else {"c", "P", "w"}
    used = {s.name for e in (system.mass_matrix, system.velocity_terms, system.forces) for s in e.free_symbols}
    assert not gone & used and not gone & {p.name for p in system.parameters}
    assert compare_explicit(system, lagrange(T, V, q, Q), 603, fixed=positive_r) < TOL
    full = derived("elastic_spherical_pendulum.yaml")
    zero = {p.symbol: 0 for p in full.parameters if p.name in ({"c"} if swirl else {"c", "P"})}
    for ours, theirs in ((system.mass_matrix, full.mass_matrix), (system.velocity_terms, full.velocity_terms),
                         (system.forces, full.forces.xreplace(zero))):
        assert sp.expand(ours - theirs) == sp.zeros(*ours.shape)


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_elastic_spherical_pendulum_scene_generated_c(tmp_path):
    """`codegen --scene undamped --lang c`, compiled with warnings as errors: no slot for the
    damper's ``c``; mass matrix, forces and accelerations against the hand equations."""
    from test_sweep_outputs import header_order

    result = CliRunner().invoke(main, ["codegen", str(HERE / "elastic_spherical_pendulum.yaml"), "--scene",
                                       "undamped", "--lang", "c", "--prefix", "esp", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    lib = tmp_path / "libesp.so"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC",
                    str(tmp_path / "elastic_spherical_pendulum.c"), "-o", str(lib), "-lm"], check=True,
                   capture_output=True)
    names, _ = header_order((tmp_path / "elastic_spherical_pendulum.h").read_text(), "ESP")
    assert "c" not in names and {"P", "w"} <= set(names)
    q, T, V, Q = elastic_reference(damper=False)
    M, h, f = lagrange(T, V, q, Q)
    values = {"m": 0.7, "k": 30, "l0": 0.9, "P": 0.5, "w": 1.7, "g": 9.81}  # the model's values
    sub = {s: values[s.name] for e in (M, h, f) for s in e.free_symbols if s.name in values}
    fM, fh, ff = (sp.lambdify([t, *q, *dots(q)], e.xreplace(sub), "numpy") for e in (M, h, f))
    lib = ctypes.CDLL(str(lib))
    D = ctypes.POINTER(ctypes.c_double)
    lib.esp_rhs.argtypes = [ctypes.c_double, D, D, D]
    lib.esp_forces.argtypes = [ctypes.c_double, D, D, D, D]
    ptr = lambda a: a.ctypes.data_as(D)  # noqa: E731
    param = np.array([float(values[n]) for n in names])
    rng = np.random.default_rng(621)
    pairs = []
    for _ in range(6):
        tt, y = rng.uniform(0, 3), rng.uniform(-2, 2, 6)
        y[0], y[1] = rng.uniform(0.3, 2), rng.uniform(0.2, 2.9)
        qv, qdv = y[:3].copy(), y[3:].copy()
        Mr, hr, fr = (np.array(fn(tt, *y), dtype=float) for fn in (fM, fh, ff))
        Mc, fc, ydot = np.zeros(9), np.zeros(3), np.zeros(6)
        lib.esp_mass_matrix(ptr(qv), ptr(param), ptr(Mc))
        lib.esp_forces(tt, ptr(qv), ptr(qdv), ptr(param), ptr(fc))
        assert lib.esp_rhs(tt, ptr(y), ptr(param), ptr(ydot)) == 0
        pairs += [(Mc.reshape(3, 3), Mr), (fc, fr.ravel()), (ydot[3:], np.linalg.solve(Mr, fr.ravel() - hr.ravel()))]
    assert worst(pairs) < TOL


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


def test_cart_with_two_pendulums_on_points_of_its_own():
    q, M, h, f, V = cart_twin_reference()
    system = derived("cart_twin_pendulums.yaml")
    fixed = lambda rng: {"s": rng.uniform(-1, 1)}  # noqa: E731  (the wall spring stays stretched one way)
    assert compare_explicit(system, (M, h, f), 604, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 604, fixed=fixed) < TOL


def test_cart_with_two_pendulums_linearized_at_its_equilibrium(tmp_path):
    """`linearize` finds the equilibrium from the initial values (the tie between tips of unequal
    rods tilts both pendulums: p1, p2 != 0); there the hand accelerations vanish, and ``A`` is
    their Jacobian ``[[0, I], [M^-1 d(f - h)/dq, M^-1 d(f - h)/dqdot]]`` (at t = 0, the drive off)."""
    import json

    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(HERE / "cart_twin_pendulums.yaml"), "--format", "json",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["equilibrium"] and data["found"] == ["s", "p1", "p2"] and data["time"] == 0
    q, M, h, f, _ = cart_twin_reference()
    y = [*q, *dots(q)]
    acc = M.LUsolve(f - h)
    given = data["parameters"]
    point = {**{v: data["operating_point"][v.name] for v in y}, t: 0}
    values = {s: float(given[s.name]) for s in (M.free_symbols | f.free_symbols) if s.name in given}
    at = lambda e: np.array(e.xreplace(values).xreplace(point).evalf(), dtype=float)  # noqa: E731
    assert abs(data["operating_point"]["p1"]) > 0.01 and np.max(np.abs(at(acc))) < 1e-9
    A = np.vstack([np.hstack([np.zeros((3, 3)), np.eye(3)]), at(acc.jacobian(y))])
    assert worst([(np.array(data["A"]), A)]) < 1e-8


# ------------------------------------------------------------------------------------------
# Space: a Furuta pendulum of two rigid_body3d's placed by the connection
# ------------------------------------------------------------------------------------------

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


def test_furuta_pendulum():
    q, M, h, f, V = furuta_reference()
    system = derived("furuta.yaml")
    assert compare_explicit(system, (M, h, f), 605) < TOL
    assert compare_energies(system, kinetic(M, q), V, 605) < TOL


def test_furuta_pendulum_generated_c_and_numpy(tmp_path):
    """The accelerations of the compiled C right-hand side and of `codegen --lang python`."""
    _, M, h, f, _ = furuta_reference()
    mod = generated_numpy_module(tmp_path, HERE / "furuta.yaml")
    assert accelerations_agree(derived("furuta.yaml"), M, h, f, 606, numpy_module=mod) < TOL


def test_furuta_pendulum_linearized_upright(tmp_path):
    """`linearize --scene balance` at the upright (th = pi, u = 0, t = 0) with the motor's ``u``
    as input: ``A = [[0, I], [M^-1 d(f - h)/dq, M^-1 d(f - h)/dqdot]]`` and ``B = M^-1 df/du`` of
    the hand equations (without the tether), their accelerations zero there."""
    import json

    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(HERE / "furuta.yaml"), "--scene", "balance", "--at",
                                       f"th={np.pi!r}", "--at", "al=0", "--at", "t=0", "--at", "u=0",
                                       "--inputs", "u", "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["equilibrium"] and data["state"] == ["al", "th", "al_dot", "th_dot"]
    q, M, h, f, _ = furuta_reference(tether=False)
    u = S("u")
    y = [*q, *dots(q)]
    acc = M.LUsolve(f - h)
    given = data["parameters"]
    values = {s: float(given[s.name]) for s in (M.free_symbols | f.free_symbols) if s.name in given}
    point = {**dict(zip(y, [0.0, sp.pi, 0, 0])), t: 0}
    jac = acc.jacobian(y).xreplace({**values, **point})
    A = np.vstack([np.hstack([np.zeros((2, 2)), np.eye(2)]), np.array(jac.evalf(), dtype=float)])
    B = np.vstack([np.zeros((2, 1)), np.array(acc.diff(u).xreplace({**values, **point}).evalf(), dtype=float)])
    assert np.max(np.abs(np.array(acc.xreplace({**values, **point}).evalf(), dtype=float))) < 1e-12
    assert worst([(np.array(data["A"]), A), (np.array(data["B"]), B)]) < 1e-9


def test_elastic_pendulum_carrying_a_rod_and_the_pin_between_them():
    """A rod hung from a bob in polar coordinates; `derive --reactions` (the hinge damper is
    written in the rod's pivoted angle) at the hand accelerations: the pin pushes the rod with
    ``F = (R_rod_x, R_rod_y)`` and the bob with ``-F``, so ``R_r = -F . e_r`` and
    ``R_a = -r F . e_a`` (Newton's third law)."""
    from kronsub.core.reactions import reactions

    r, a, th = q = list(S("r a th"))
    m, mr, L, k, l0, c, g = S("m mr L k l0 c g")
    bob = r * sp.Matrix([sp.cos(a), sp.sin(a)])
    centre = bob + L / 2 * down(th)
    M, h = virtual_power([(m, bob), (mr, centre, th, mr * L ** 2 / 12)], q)
    V = g * (m * bob[1] + mr * centre[1]) + k * (r - l0) ** 2 / 2  # r > 0: the spring's length
    f = gradient_force(V, q, damper_rows(c, th - a, q))
    system = derived("elastic_double_pendulum.yaml")
    positive = lambda rng: {"r": rng.uniform(0.3, 2)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 623, fixed=positive) < TOL
    assert compare_energies(system, kinetic(M, q), V, 623, fixed=positive) < TOL
    items = dict(reactions(system))
    assert list(items) == ["R_r", "R_a", "R_rod_x", "R_rod_y", "R_rod_axis"]
    plain = lambda e: e.xreplace({s: sp.Symbol(s.name) for s in e.free_symbols})  # noqa: E731
    F = sp.Matrix([plain(items["R_rod_x"]), plain(items["R_rod_y"])])
    laws = sp.Matrix([plain(items["R_r"]) + F.dot(bob.diff(r)), plain(items["R_a"]) + F.dot(bob.diff(a))])
    qd, qdd = dots(q), [sp.Symbol(f"{v.name}_ddot") for v in q]
    values = {s: float(p.value) for p in system.parameters for s in (M.free_symbols | f.free_symbols)
              if s.name == p.name}
    fM, frhs = (sp.lambdify([*q, *qd], e.xreplace(values), "numpy") for e in (M, f - h))
    flaw = sp.lambdify([*q, *qd, *qdd], laws.xreplace({sp.Symbol(s.name): v for s, v in values.items()}), "numpy")
    rng = np.random.default_rng(624)
    pairs = []
    for _ in range(6):
        qv, qdv = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        qv[0] = rng.uniform(0.3, 2)
        acc = np.linalg.solve(np.array(fM(*qv, *qdv), dtype=float), np.array(frhs(*qv, *qdv), dtype=float).ravel())
        pairs.append((np.array(flaw(*qv, *qdv, *acc), dtype=float).ravel(), np.zeros(2)))
    assert worst(pairs) < 1e-9


# ------------------------------------------------------------------------------------------
# One pendulum in two sets of coordinates: absolute and relative angles
# ------------------------------------------------------------------------------------------

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


def test_triple_pendulum_in_absolute_and_in_relative_angles():
    """Each against the hand equations, and the two against each other through the change of
    variables ``a = J q`` (``J`` constant): ``Mbar_q = J^T Mbar_a J``, ``hbar_q = J^T hbar_a``,
    ``fbar_q = J^T fbar_a``, the group property (13) of two subspaces of one primitive."""
    a = list(S("a1 a2 a3"))
    q = list(S("q1 q2 q3"))
    absolute, relative = derived("triple_absolute.yaml"), derived("triple_relative.yaml")
    M, h, f, V = triple_parts(*a, a)
    assert compare_explicit(absolute, (M, h, f), 607) < TOL
    assert compare_energies(absolute, kinetic(M, a), V, 607) < TOL
    M, h, f, V = triple_parts(q[0], q[0] + q[1], q[0] + q[1] + q[2], q)
    assert compare_explicit(relative, (M, h, f), 608) < TOL
    assert compare_energies(relative, kinetic(M, q), V, 608) < TOL
    # kronsub's absolute equations carried to the relative angles
    J = sp.Matrix([[1, 0, 0], [1, 1, 0], [1, 1, 1]])
    by_name = {s.name: s for e in (absolute.mass_matrix, absolute.velocity_terms, absolute.forces)
               for s in e.free_symbols}
    qs = {n: sp.Symbol(n) for n in ("q1", "q2", "q3", "q1_dot", "q2_dot", "q3_dot")}
    rel = J * sp.Matrix([qs["q1"], qs["q2"], qs["q3"]])
    reld = J * sp.Matrix([qs["q1_dot"], qs["q2_dot"], qs["q3_dot"]])
    change = {by_name[n]: rel[i] for i, n in enumerate(("a1", "a2", "a3")) if n in by_name}
    change.update({by_name[n]: reld[i] for i, n in enumerate(("a1_dot", "a2_dot", "a3_dot")) if n in by_name})
    carried = [J.T * absolute.mass_matrix.xreplace(change) * J, J.T * absolute.velocity_terms.xreplace(change),
               J.T * absolute.forces.xreplace(change)]
    ours = [relative.mass_matrix, relative.velocity_terms, relative.forces]
    plain = lambda e: e.xreplace({s: sp.Symbol(s.name) for s in e.free_symbols})  # noqa: E731
    assert largest_difference(relative, [plain(e) for e in ours], [plain(e) for e in carried], 609) < TOL


# ------------------------------------------------------------------------------------------
# Coupled oscillators in a ring: beads on a hoop
# ------------------------------------------------------------------------------------------

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


def test_beads_on_a_hoop_in_a_ring_of_springs():
    def apart(rng):  # the beads in their order round the hoop
        return {n: a + rng.uniform(-0.4, 0.4) for n, a in zip(("u1", "u2", "u3", "u4"), (0, 1.6, 3.1, 4.7))}

    u, T, V, Q = ring_reference()
    system = derived("bead_ring.yaml")
    assert compare_explicit(system, lagrange(T, V, u, Q), 610, fixed=apart) < TOL
    assert compare_energies(system, T, V, 610, fixed=apart) < TOL


def test_ring_free_scene_keeps_energy_and_angular_momentum(tmp_path):
    """`simulate --scene free`: the energies in the CSV are the hand ``T`` and ``V`` of each row,
    and the total energy and ``sum m_i R^2 u_i_dot`` (the springs are central in the ring's
    plane) stay constant."""
    out = tmp_path / "ring.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / "bead_ring.yaml"), "--scene", "free", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    assert len(table) == 7  # the scene's t_end and dt
    u, T, V, _ = ring_reference(damper=False)
    values = {s: RING[s.name] for s in (T + V).free_symbols if s.name in RING}
    fT, fV = (sp.lambdify([*u, *dots(u)], e.xreplace(values), "numpy") for e in (T, V))
    state = [table[n] for n in ("u1", "u2", "u3", "u4", "u1_dot", "u2_dot", "u3_dot", "u4_dot")]
    assert np.allclose(table["kinetic_energy"], fT(*state), rtol=1e-12, atol=1e-12)
    assert np.allclose(table["potential_energy"], fV(*state), rtol=1e-12, atol=1e-12)
    energy = table["total_energy"]
    momentum = sum(RING[f"m{i}"] * RING["R"] ** 2 * table[f"u{i}_dot"] for i in range(1, 5))
    assert np.max(np.abs(energy - energy[0])) < 1e-7 and np.max(np.abs(momentum - momentum[0])) < 1e-7
    assert abs(momentum[0] - (1.0 * 2.0 - 0.8) * 0.25) < 1e-12  # the initial velocities


# ------------------------------------------------------------------------------------------
# A rope over a peg: the swinging Atwood machine, across a line and the plane
# ------------------------------------------------------------------------------------------

@lru_cache(maxsize=None)
def atwood_reference(rope=True):
    r, a = q = list(S("r a"))
    m, M, L, b, g = S("m M L b g")
    bob = r * sp.Matrix([sp.cos(a), sp.sin(a)])
    T = m * rate_of(bob, q).dot(rate_of(bob, q)) / 2 + M * rate_of(r - L, q) ** 2 / 2
    V = m * g * bob[1] + M * g * (r - L)
    return q, T, V, [-b * dots(q)[0] if rope else 0, 0]


def test_swinging_atwood_machine():
    """Two gravities, one per world (the counterweight's line is vertical: its direction ``[-1]``)."""
    q, T, V, Q = atwood_reference()
    system = derived("swinging_atwood.yaml")
    positive = lambda rng: {"r": rng.uniform(0.2, 2.5)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, Q), 611, fixed=positive) < TOL
    assert compare_energies(system, T, V, 611, fixed=positive) < TOL


def free_run(tmp_path, model, q, energy, values):
    """`simulate --scene free` of ``model``: its rows, and the hand ``energy`` (at the model's
    parameter ``values``) at each row's state."""
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / model), "--scene", "free", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    f = sp.lambdify([*q, *dots(q)], energy.xreplace(values), "numpy")
    return table, f(*(table[s.name] for s in q), *(table[s.name + "_dot"] for s in q))


def test_swinging_atwood_free_scene_keeps_energy(tmp_path):
    """`simulate --scene free` (gauss4, fixed step 0.01): the hand energy of every row is the first's."""
    q, T, V, _ = atwood_reference(rope=False)
    values = {s: v for s, v in zip(S("m M L g"), (1.0, 1.3, 3, 9.81))}  # the model's values
    table, energy = free_run(tmp_path, "swinging_atwood.yaml", q, T + V, values)
    assert len(table) == 201 and np.min(table["r"]) > 0.3
    assert np.allclose(table["total_energy"], energy, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(energy - energy[0])) < 1e-6


# ------------------------------------------------------------------------------------------
# A rolling wheel and a body driven against each other: the segway
# ------------------------------------------------------------------------------------------

def test_segway_motor_torques_act_and_react():
    """One motor torque (a definition in the state and t) on the wheel and minus it on the body:
    by virtual work ``tau (d wheel_angle - d th)``, ``wheel_angle = -x/Rw`` (rolling)."""
    x, th = q = list(S("x th"))
    Mw, Rw, mb, L, Ib, kp, kd, u0, cb, g = S("Mw Rw mb L Ib kp kd u0 cb g")
    wheel_angle = -x / Rw
    centre = sp.Matrix([x, Rw])
    body = centre + L / 2 * down(th)
    M, h = virtual_power([(Mw, centre, wheel_angle, Mw * Rw ** 2 / 2), (mb, body, th, Ib)], q)
    V = g * (Mw * Rw + mb * body[1])
    tau = kp * sp.sin(th) - kd * dots(q)[1] + u0 * sp.cos(3 * t)
    rows = add([tau * (wheel_angle - th).diff(v) for v in q], damper_rows(cb, wheel_angle - th, q))
    system = derived("segway.yaml")
    f = gradient_force(V, q, rows)
    assert compare_explicit(system, (M, h, f), 612) < TOL
    assert compare_energies(system, kinetic(M, q), V, 612) < TOL
    assert accelerations_agree(system, M, h, f, 612) < TOL


# ------------------------------------------------------------------------------------------
# A closed loop across worlds: a slider-crank whose piston is a particle on a line
# ------------------------------------------------------------------------------------------

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


def test_slider_crank_with_the_piston_on_a_line():
    from test_sweep_models import walk_constrained

    rows = walk_constrained(derived("slider_crank_line.yaml"), slider_crank_reference(), 0.5, SLIDER_GUESS, 613,
                            step=0.4)
    assert worst(p for row in rows for p in row) < TOL


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


def test_slider_crank_derive_reactions_against_the_multipliers():
    """Four dependent coordinates: the printed linear system ``G_d^T mu = r``."""
    pv = [0.6, 0.4, 0.5, 0.25, 0.8, 0.1, 15, 0.4, 0.6, 2, 9.81]  # the model's values, in ref.params order
    pairs = printed_multipliers("slider_crank_line.yaml", slider_crank_reference(), SLIDER_GUESS, pv, 614)
    assert worst(pairs) < 1e-9


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


def test_four_bar_with_a_sprung_coupler():
    from test_sweep_models import walk_constrained

    rows = walk_constrained(derived("four_bar_reactions.yaml"), four_bar_reference(), 2.0, FOUR_BAR_GUESS, 619,
                            step=0.3)
    assert worst(p for row in rows for p in row) < TOL


def test_four_bar_derive_reactions_in_closed_form_against_the_multipliers():
    """Two dependent coordinates: ``mu_B`` printed in closed form."""
    pv = [0.5, 1.0, 0.8, 0.4, 1.0, 0.8, 0.9, 2, 5, 0.1, 0.5, 9.81]  # the model's values, in ref.params order
    pairs = printed_multipliers("four_bar_reactions.yaml", four_bar_reference(), FOUR_BAR_GUESS, pv, 620, step=0.3)
    assert worst(pairs) < 1e-9


# ------------------------------------------------------------------------------------------
# A top on a moving support: a cart on a line carrying a top in space
# ------------------------------------------------------------------------------------------

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


def test_heavy_top_on_a_sliding_base():
    """The top's support moves with a coordinate (no prescribed motion): ``M`` couples ``s`` to
    the angles; a torque vector in the angles by ``tau . d omega/d qdot``."""
    q, M, h, f, V, _, _ = top_reference()
    system = derived("top_on_sliding_base.yaml")
    fixed = lambda rng: {"th": rng.uniform(0.2, 2.9)}  # noqa: E731  (Z-X-Z: singular at th = 0, pi)
    assert compare_explicit(system, (M, h, f), 616, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 616, fixed=fixed) < TOL


def test_heavy_top_on_a_sliding_base_reactions_at_the_cup():
    """`derive --reactions`: on the top's centre coordinates the cup's force on the top,
    ``m a_c + m g e_z - F`` (Newton, the flick's force ``F`` at the rim); on the cart's ``s`` minus
    its x component (Newton's third law at the cup); ``C^T R = 0``. At the hand accelerations."""
    import json

    q, M, h, f, _, centre, flick = top_reference()
    m, g = S("m g")
    result = CliRunner().invoke(main, ["derive", str(HERE / "top_on_sliding_base.yaml"), "--reactions",
                                       "--format", "json"])
    assert result.exit_code == 0, result.output
    expressions = json.loads(result.stdout)["reactions"]["expressions"]
    prim = ["s", "x", "y", "z", "psi", "th", "phi"]
    assert list(expressions) == [f"R_{n}" for n in prim]
    qd, qdd = dots(q), [sp.Symbol(f"{v.name}_ddot") for v in q]
    names = {v.name: v for v in [*q, *qd, *qdd, t, *S("mc m h A C k l0 c u F g")]}
    ours = sp.Matrix([sp.sympify(expressions[f"R_{n}"], locals=names) for n in prim])  # test code, not kronsub
    Cm = sp.Matrix([q[0], *centre, *q[1:]]).jacobian(q)
    rate = rate_of(centre, q)
    accel = rate.jacobian(qd) * sp.Matrix(qdd) + rate.jacobian(q) * sp.Matrix(qd)
    joint = m * accel + sp.Matrix([0, 0, m * g]) - flick
    values = {names[p.name]: float(p.value) for p in derived("top_on_sliding_base.yaml").parameters}
    args = [t, *q, *qd, *qdd]
    checks = [sp.lambdify(args, e.xreplace(values), "numpy")
              for e in (ours[1:4, :], joint, sp.Matrix([ours[0] + ours[1]]), Cm.T * ours)]
    fM, frhs = (sp.lambdify([t, *q, *qd], e.xreplace(values), "numpy") for e in (M, f - h))
    rng = np.random.default_rng(622)
    pairs = []
    for _ in range(6):
        tt, qv, qdv = rng.uniform(0, 3), rng.uniform(-2, 2, 4), rng.uniform(-2, 2, 4)
        qv[2] = rng.uniform(0.2, 2.9)
        acc = np.linalg.solve(np.array(fM(tt, *qv, *qdv), dtype=float),
                              np.array(frhs(tt, *qv, *qdv), dtype=float).ravel())
        mine, hand, third, work = (np.array(fn(tt, *qv, *qdv, *acc), dtype=float).ravel() for fn in checks)
        pairs += [(mine, hand), (third, np.zeros(1)), (work, np.zeros(4))]
    assert worst(pairs) < 1e-9


# ------------------------------------------------------------------------------------------
# A particle in space under a central potential and a magnetic field
# ------------------------------------------------------------------------------------------

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


def test_charge_in_a_central_and_a_magnetic_field():
    """A potential in the generalized ``r`` beside one in the primitive ``z``, forces in the
    primitive velocities (the Lorentz force's rows are gyroscopic: ``Q . qdot = 0``)."""
    q, T, V, Q = charge_reference()
    system = derived("charge_in_central_field.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.3, 2), "th": rng.uniform(0.2, 2.9)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, Q), 617, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 617, fixed=fixed) < TOL
    _, _, _, lorentz = charge_reference(drag=False)
    assert sp.simplify(sum(row * v for row, v in zip(lorentz, dots(q)))) == 0  # the hand force does no work


def test_charge_free_scene_keeps_energy_and_canonical_angular_momentum(tmp_path):
    q, T, V, _ = charge_reference(drag=False)
    values = dict(zip(S("m mu eps b"), (1.0, 4, 0.5, 0.7)))  # the model's values
    table, energy = free_run(tmp_path, "charge_in_central_field.yaml", q, T + V, values)
    rho2 = (table["r"] * np.sin(table["th"])) ** 2
    momentum = 1.0 * rho2 * table["ph_dot"] + 0.7 * rho2 / 2
    assert len(table) == 9 and np.allclose(table["total_energy"], energy, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(energy - energy[0])) < 1e-7 and np.max(np.abs(momentum - momentum[0])) < 1e-7


# ------------------------------------------------------------------------------------------
# Defects this sweep found
# ------------------------------------------------------------------------------------------

def test_segway_reactions_with_an_effect_on_the_pivoted_rods_angle():
    """`derive --reactions` of the segway, whose bearing damper is written in the body's angle
    ``th`` (a pivoted rod's angle, not a primitive coordinate: the primitive has
    ``body_axis = th - pi/2``). Such an effect once acted in the subspace only and the reactions
    were refused; ``th`` is ``body_axis + pi/2`` exactly, so the damper now acts on the primitive.
    ``R = M xddot + h - f`` on the six primitive coordinates from a hand primitive (two free
    bodies, the motor's and the bearing's torques on their angles), at the hand accelerations;
    ``C^T R = 0``."""
    import json

    x, th = q = list(S("x th"))
    Mw, Rw, mb, L, Ib, kp, kd, u0, cb, g = S("Mw Rw mb L Ib kp kd u0 cb g")
    prim = list(S("wx wy wa body_x body_y body_axis"))
    qd, qdd = dots(q), [sp.Symbol(f"{s.name}_ddot") for s in q]
    wa_d, axis_d = sp.Symbol("wa_dot"), sp.Symbol("body_axis_dot")
    tau = kp * sp.sin(th) - kd * qd[1] + u0 * sp.cos(3 * t)
    bearing = -cb * (wa_d - axis_d)  # on wa, minus it on body_axis
    Mx = sp.diag(Mw, Mw, Mw * Rw ** 2 / 2, mb, mb, Ib)
    fx = sp.Matrix([0, -Mw * g, tau + bearing, 0, -mb * g, -tau - bearing])
    image = sp.Matrix([x, Rw, -x / Rw, x + L / 2 * sp.sin(th), Rw - L / 2 * sp.cos(th), th - sp.pi / 2])
    C = image.jacobian(q)
    xdot = C * sp.Matrix(qd)
    xddot = C * sp.Matrix(qdd) + xdot.jacobian(q) * sp.Matrix(qd)
    r_hand = (Mx * xddot - fx).xreplace({wa_d: xdot[2], axis_d: xdot[5]})
    result = CliRunner().invoke(main, ["derive", str(HERE / "segway.yaml"), "--reactions", "--format", "json"])
    assert result.exit_code == 0, result.output
    expressions = json.loads(result.stdout)["reactions"]["expressions"]
    assert list(expressions) == [f"R_{a.name}" for a in prim]
    names = {s.name: s for s in [*q, *qd, *qdd, t, Mw, Rw, mb, L, Ib, kp, kd, u0, cb, g]}
    ours = sp.Matrix([sp.sympify(expressions[f"R_{a.name}"], locals=names) for a in prim])  # test code
    values = {names[p.name]: float(p.value) for p in derived("segway.yaml").parameters}
    M, h = virtual_power([(Mw, image[:2, :], image[2], Mw * Rw ** 2 / 2), (mb, image[3:5, :], th, Ib)], q)
    f = C.T * fx.xreplace({wa_d: xdot[2], axis_d: xdot[5]})
    fns = [sp.lambdify([t, *q, *qd], e.xreplace(values), "numpy") for e in (M, f - h)]
    args = [t, *q, *qd, *qdd]
    f_ours, f_hand, f_work = (sp.lambdify(args, e.xreplace(values), "numpy") for e in (ours, r_hand, C.T * ours))
    rng = np.random.default_rng(618)
    pairs = []
    for _ in range(6):
        tt, qv, qdv = rng.uniform(0, 3), rng.uniform(-3, 3, 2), rng.uniform(-2, 2, 2)
        acc = np.linalg.solve(np.array(fns[0](tt, *qv, *qdv), dtype=float),
                              np.array(fns[1](tt, *qv, *qdv), dtype=float).ravel())
        a = (tt, *qv, *qdv, *acc)
        pairs += [(np.array(f_ours(*a), dtype=float).ravel(), np.array(f_hand(*a), dtype=float).ravel()),
                  (np.array(f_work(*a), dtype=float).ravel(), np.zeros(2))]
    assert worst(pairs) < 1e-9


def test_a_generalized_force_on_a_pivoted_rods_angle_acts_on_its_axis(tmp_path):
    """`generalized_force` on ``th`` (``body_axis + pi/2``) is the force on ``body_axis``: the row
    ``th`` of ``fbar`` gains the value, and the reaction on the axis loses it (``R = ... - f``)."""
    import kronsub
    from kronsub.core.reactions import reactions
    from kronsub.core.symbols import symbol

    text = (HERE / "segway.yaml").read_text().replace(
        "  bearing:", "  nudge: {type: generalized_force, coordinate: th, value: 0.3*th_dot + 0.2}\n  bearing:")
    path = tmp_path / "segway_nudged.yaml"
    path.write_text(text)
    nudged, plain = kronsub.load(path).derive(), derived("segway.yaml")
    assert not nudged.transition.direct_effects
    extra = R(3, 10) * symbol("th_dot") + R(1, 5)
    assert sp.expand(nudged.forces - plain.forces - sp.Matrix([0, extra])) == sp.zeros(2, 1)
    ours, theirs = dict(reactions(nudged)), dict(reactions(plain))
    assert sp.expand(ours["R_body_axis"] - theirs["R_body_axis"] + extra) == 0
    assert all(sp.expand(ours[k] - theirs[k]) == 0 for k in ours if k != "R_body_axis")


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


@pytest.mark.parametrize("coordinates, connected, line, message", [
    ("[q1]", "", 5, "the angle 'b2' of 'r2' (hung from `pivot: r1.tip`) is not a generalized coordinate"),
    ("[q1, q2]", "  b2: q1 + q2", 9, "'b2' is the angle of 'r2', which hangs from `pivot: r1.tip`"),
])
def test_a_pivoted_rods_angle_must_be_a_generalized_coordinate(tmp_path, coordinates, connected, line, message):
    """Left out of `coordinates:`, a pivoted rod's angle was a frozen symbol: the model derived
    with ``b2`` a constant in ``V`` and the rod's swing missing from ``Mbar``. Connected (a
    relative angle), it was "not a coordinate of the primitive system" with a hint naming the
    other rod's angle. Both are now one error at its place, with the way to relative angles."""
    path = tmp_path / "relative.yaml"
    path.write_text(RELATIVE_PIVOT.replace("COORDINATES", coordinates).replace("CONNECTED", connected))
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"relative.yaml:{line}:" in result.output and message in result.output
    assert "`rod` with `axis: down`" in result.output and "problems found" not in result.output
