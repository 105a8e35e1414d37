"""Robustness sweep of kronsub's OUTPUTS (not the derived equations, see tests/test_models_*.py):
the trajectory CSV (``simulate``, CLI and API), the generated C and numpy code, ``linearize``,
``derive --format latex|json``, each checked against an independent route written here in
plain sympy/numpy/scipy (Lagrange's equations of a hand-written T and V, scipy's solve_ivp at
tight tolerances, a finite-difference Jacobian), never with kronsub's own functions.

Tests marked ``xfail(strict=True)`` reproduce bugs found by this sweep (SWEEP2_REPORT.md).
"""
from __future__ import annotations

import ctypes
import json
import re
import shutil
import subprocess
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

import kronsub
from helpers.generated import header_order
from kronsub.cli import main

ROOT = Path(__file__).resolve().parent.parent
SWEEP = ROOT / "tests" / "models" / "sweep"
SYSTEM1 = ROOT / "models" / "hoffmann" / "system1.yaml"
SPRING = SWEEP / "spring_pendulum.yaml"
COUPLED = SWEEP / "coupled_spring_pendulums.yaml"
t = sp.Symbol("t")


def run_cli(*args):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result


def read_csv(path):
    return np.genfromtxt(path, names=True, delimiter=",", deletechars="")


# ------------------------------------------------------------------------------------------
# Independent references: Lagrange's equations of T and V written by hand
# ------------------------------------------------------------------------------------------

def dots(q):
    return [sp.Symbol(f"{s.name}_dot") for s in q]


class Reference:
    """``M qddot + h = f`` from ``T(q, qdot, t)``, ``V(q, t)`` and generalized forces ``Q``,
    evaluated at numeric parameter values."""

    def __init__(self, q, T, V, Q, values, points=None):
        self.q, self.qd = list(q), dots(q)
        n = len(q)
        M = sp.Matrix(n, n, lambda i, j: sp.diff(T, self.qd[i], self.qd[j]))
        h = sp.Matrix([sum(sp.diff(T, self.qd[i], q[j]) * self.qd[j] for j in range(n))
                       + sp.diff(T, self.qd[i], t) - sp.diff(T, q[i]) for i in range(n)])
        f = sp.Matrix([-sp.diff(V, q[i]) + Q[i] for i in range(n)])
        self.symbolic = (M, h, f)
        self.values = values
        sub = {sp.Symbol(k): v for k, v in values.items()}
        args = [t, *self.q, *self.qd]
        fn = lambda e: sp.lambdify(args, sp.sympify(e).subs(sub), "numpy")  # noqa: E731
        dTdq = sp.Matrix([T.diff(a) for a in q])
        self.fM, self.fh, self.ff, self.fT, self.fV, self.fTq = map(fn, (M, h, f, T, V, dTdq))
        self.points = {name: fn(sp.Matrix(p)) for name, p in (points or {}).items()}

    def M(self, tt, y):
        return np.array(self.fM(tt, *y), dtype=float)

    def h(self, tt, y):
        return np.array(self.fh(tt, *y), dtype=float).ravel()

    def f(self, tt, y):
        return np.array(self.ff(tt, *y), dtype=float).ravel()

    def dTdq(self, tt, y):
        return np.array(self.fTq(tt, *y), dtype=float).ravel()

    def rhs(self, tt, y):
        n = len(self.q)
        acc = np.linalg.solve(self.M(tt, y), self.f(tt, y) - self.h(tt, y))
        return np.concatenate([y[n:], acc])

    def trajectory(self, y0, times):
        sol = solve_ivp(self.rhs, (0.0, float(times[-1])), y0, t_eval=times, method="DOP853",
                        rtol=1e-13, atol=1e-13)
        assert sol.success
        return sol.y.T

    def energies(self, times, Y):
        T = np.array([float(self.fT(tt, *y)) for tt, y in zip(times, Y)])
        V = np.array([float(self.fV(tt, *y)) for tt, y in zip(times, Y)])
        return T, V


SYSTEM1_VALUES = {"m1": 1, "m2": 1, "a1": 0.5, "a2": 0.5, "I1": 1 / 12, "I2": 1 / 12, "g": 9.81, "F": 0}


def system1_geometry():
    """Hoffmann's System I (his Fig. 1): rod 1 (length 2 a1) pinned at O, rod 2 hinged to its tip."""
    th, ph = sp.symbols("theta phi")
    a1, a2 = sp.symbols("a1 a2")
    down = lambda a: sp.Matrix([sp.sin(a), -sp.cos(a)])  # noqa: E731
    tip = 2 * a1 * down(th)
    points = {"upper.centre": a1 * down(th), "upper.tip": tip, "upper.pivot": sp.Matrix([0, 0]),
              "lower.centre": tip + a2 * down(ph), "lower.a": tip, "lower.b": tip + 2 * a2 * down(ph)}
    return th, ph, points


@lru_cache(maxsize=None)
def system1_reference(F=0.0):
    th, ph, pts = system1_geometry()
    q = [th, ph]
    m1, m2, a1, I1, I2, g, Fs = sp.symbols("m1 m2 a1 I1 I2 g F")
    thd, phd = dots(q)
    c2 = pts["lower.centre"]
    v2 = c2.jacobian(q) * sp.Matrix([thd, phd])
    T = (I1 + m1 * a1 ** 2) * thd ** 2 / 2 + m2 * v2.dot(v2) / 2 + I2 * phd ** 2 / 2
    V = g * (m1 * pts["upper.centre"][1] + m2 * c2[1])
    Q = [Fs * c2[0].diff(a) for a in q]  # the horizontal push on the lower rod's centre
    return Reference(q, T, V, Q, {**SYSTEM1_VALUES, "F": F}, pts)


SPRING_VALUES = {"m": 0.7, "k": 35, "L0": 0.9, "c": 0.3, "cd": 0.05, "F0": 0.4, "w": 2.3, "g": 9.81}


@lru_cache(maxsize=None)
def spring_reference(**overrides):
    """tests/models/sweep/spring_pendulum.yaml: a bob on an elastic, damped rod, drag and a push in t."""
    r, q = sp.symbols("r q")
    rd, qd = dots([r, q])
    m, k, L0, c, cd, F0, w, g = sp.symbols("m k L0 c cd F0 w g")
    bob = sp.Matrix([r * sp.sin(q), -r * sp.cos(q)])
    v = bob.jacobian([r, q]) * sp.Matrix([rd, qd])
    T = m * v.dot(v) / 2
    V = m * g * bob[1] + k * (r - L0) ** 2 / 2
    force = -cd * v + sp.Matrix([F0 * sp.sin(w * t), 0])
    Q = [force.dot(bob.diff(a)) - c * rd * int(a == r) for a in (r, q)]
    return Reference([r, q], T, V, Q, {**SPRING_VALUES, **overrides}, {"bob.centre": bob})


# ------------------------------------------------------------------------------------------
# 1. simulate: the trajectory, energies, points and reactions against solve_ivp
# ------------------------------------------------------------------------------------------

STATE1 = ["theta", "phi", "theta_dot", "phi_dot"]


def system1_reactions(ref, times, Y):
    """``R = M xddot + h - f`` on the primitive (theta, y, z, phi) of System I: the upper rod about
    O, the lower rod's centre and angle; ``xddot`` from the reference's accelerations."""
    v = ref.values
    rows = []
    for tt, y in zip(times, Y):
        th, ph, thd, phd = y
        thdd, phdd = ref.rhs(tt, y)[2:]
        ydd = (2 * v["a1"] * (np.cos(th) * thdd - np.sin(th) * thd ** 2)
               + v["a2"] * (np.cos(ph) * phdd - np.sin(ph) * phd ** 2))
        zdd = (2 * v["a1"] * (np.sin(th) * thdd + np.cos(th) * thd ** 2)
               + v["a2"] * (np.sin(ph) * phdd + np.cos(ph) * phd ** 2))
        rows.append([(v["I1"] + v["m1"] * v["a1"] ** 2) * thdd + v["m1"] * v["g"] * v["a1"] * np.sin(th),
                     v["m2"] * ydd - v["F"], v["m2"] * zdd + v["m2"] * v["g"], v["I2"] * phdd])
    return np.array(rows)


HEYOKA = pytest.param("heyoka", 1e-8, marks=pytest.mark.skipif(
    __import__("importlib").util.find_spec("heyoka") is None, reason="needs heyoka"))


@pytest.mark.parametrize("method, tol", [("dop853", 1e-8), ("RK45", 1e-7), ("Radau", 1e-7), ("LSODA", 1e-7), HEYOKA])
def test_system1_pushed_scene_csv(tmp_path, method, tol):
    """`--scene pushed` (F = 2 from the scene), `--set` an expression and a velocity, `--dt` that
    does not divide `--t`: rows at the grid and at t_end, state, energies, points, reactions."""
    out = tmp_path / "run.csv"
    run_cli("simulate", SYSTEM1, "--t", "0.73", "--dt", "0.2", "--scene", "pushed", "--set", "theta=2*pi/3",
            "--set", "phi_dot=-1", "--method", method, "--points", "--reactions", "-o", out)
    tab = read_csv(out)
    assert np.allclose(tab["t"], [0, 0.2, 0.4, 0.6, 0.73], rtol=0, atol=1e-15)
    ref = system1_reference(2.0)
    Y = ref.trajectory([2 * np.pi / 3, -0.2, 0.0, -1.0], tab["t"])
    got = np.column_stack([tab[n] for n in STATE1])
    assert np.max(np.abs(got - Y)) < tol
    T, V = ref.energies(tab["t"], Y)
    assert np.max(np.abs(tab["kinetic_energy"] - T)) < 10 * tol
    assert np.max(np.abs(tab["potential_energy"] - V)) < 10 * tol
    assert np.max(np.abs(tab["total_energy"] - tab["kinetic_energy"] - tab["potential_energy"])) < 1e-12
    for name, fn in ref.points.items():
        want = np.array([np.array(fn(tt, *y), dtype=float).ravel() for tt, y in zip(tab["t"], got)])
        assert np.max(np.abs(np.column_stack([tab[f"{name}.x"], tab[f"{name}.y"]]) - want)) < 1e-12, name
    R = system1_reactions(ref, tab["t"], got)
    assert np.max(np.abs(np.column_stack([tab[n] for n in ("R_theta", "R_y", "R_z", "R_phi")]) - R)) < 1e-8
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "complete" and meta["parameters"]["F"] == 2 and meta["rows"] == 5


def test_spring_pendulum_api_time_dependent_forcing():
    """The Python API with `set` overrides (a parameter and an initial velocity as text)."""
    system = kronsub.load(SPRING).derive()
    run = system.simulate(t=1.3, dt=0.25, set={"F0": 1.5, "q_dot": "-1/2"}, dataframe=False)
    ref = spring_reference(F0=1.5)
    assert np.allclose(run.t, [0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.3], rtol=0, atol=1e-15)
    Y = ref.trajectory([1.1, 0.6, 0.0, -0.5], run.t)
    got = np.column_stack([run[n] for n in ("r", "q", "r_dot", "q_dot")])
    assert np.max(np.abs(got - Y)) < 1e-8
    T, V = ref.energies(run.t, Y)
    assert np.max(np.abs(run["kinetic_energy"] - T)) < 1e-8
    assert np.max(np.abs(run["potential_energy"] - V)) < 1e-8


def test_spring_pendulum_taylor_and_gauss4_converge(tmp_path):
    """`--method taylor` at its tolerance, and gauss4's fourth order (error / 16 when dt / 2)."""
    ref = spring_reference()
    y0 = [1.1, 0.6, 0.0, -0.4]
    out = tmp_path / "taylor.csv"
    run_cli("simulate", SPRING, "--t", "1", "--dt", "0.25", "--method", "taylor", "--rtol", "1e-12",
            "--atol", "1e-12", "-o", out)
    tab = read_csv(out)
    Y = ref.trajectory(y0, tab["t"])
    assert np.max(np.abs(np.column_stack([tab[n] for n in ("r", "q", "r_dot", "q_dot")]) - Y)) < 1e-9
    errors = []
    for dt in ("0.05", "0.025"):
        out = tmp_path / f"g{dt}.csv"
        run_cli("simulate", SPRING, "--t", "1", "--dt", dt, "--method", "gauss4", "-o", out)
        tab = read_csv(out)
        assert tab["t"][-1] == 1.0
        Y = ref.trajectory(y0, tab["t"])
        errors.append(np.max(np.abs(np.column_stack([tab[n] for n in ("r", "q", "r_dot", "q_dot")]) - Y)))
    assert 10 < errors[0] / errors[1] < 25, errors


def test_gauss4_rows_on_the_dt_grid(tmp_path):
    out = tmp_path / "g.csv"
    run_cli("simulate", SYSTEM1, "--t", "0.35", "--dt", "0.1", "--method", "gauss4", "-o", out)
    tab = read_csv(out)
    assert np.allclose(tab["t"], [0, 0.1, 0.2, 0.3, 0.35], rtol=0, atol=1e-12), tab["t"]


# ------------------------------------------------------------------------------------------
# 2. codegen: the generated C (gcc -std=c99 -Wall -Wextra -Werror -O2) and numpy module
# ------------------------------------------------------------------------------------------

CODEGEN = [(SYSTEM1, system1_reference, {"F": 0.8}), (SPRING, spring_reference, {"c": 0.45})]


def random_states(n, seed, spread=2.0):
    rng = np.random.default_rng(seed)
    return [(rng.uniform(0, 3), rng.uniform(-spread, spread, 2 * n)) for _ in range(6)]


def fix_state(y, name):
    """Keep the spring pendulum's rod length positive."""
    if name == "spring_pendulum":
        y = y.copy()
        y[0] = 0.5 + abs(y[0])
    return y


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
@pytest.mark.parametrize("model, make_ref, overrides", CODEGEN, ids=["system1", "spring_pendulum"])
def test_generated_c(tmp_path, model, make_ref, overrides):
    run_cli("codegen", model, "--lang", "c", "--prefix", "sw", "-o", tmp_path)
    stem = model.stem
    lib = tmp_path / f"lib{stem}.so"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC",
                    str(tmp_path / f"{stem}.c"), "-o", str(lib), "-lm"], check=True, capture_output=True)
    names, point_names = header_order((tmp_path / f"{stem}.h").read_text(), "SW")
    ref = make_ref(**overrides)
    c = ctypes.CDLL(str(lib))
    D = ctypes.POINTER(ctypes.c_double)
    for fn in ("sw_kinetic_energy", "sw_potential_energy"):
        getattr(c, fn).restype = ctypes.c_double
    c.sw_potential_energy.argtypes = [ctypes.c_double, D, D]
    c.sw_forces.argtypes = [ctypes.c_double, D, D, D, D]
    c.sw_rhs.argtypes = c.sw_rhs_canonical.argtypes = c.sw_rhs_pre.argtypes = [ctypes.c_double, D, D, D]
    param = np.array([float(ref.values[name]) for name in names])
    pre = np.zeros(c.sw_npre())
    ptr = lambda a: a.ctypes.data_as(D)  # noqa: E731
    c.sw_prepare(ptr(param), ptr(pre))
    n = len(ref.q)
    for tt, y in random_states(n, 3):
        y = fix_state(y, stem)
        q, qd = y[:n].copy(), y[n:].copy()
        M, h, f = np.zeros(n * n), np.zeros(n), np.zeros(n)
        c.sw_mass_matrix(ptr(q), ptr(param), ptr(M))
        c.sw_velocity_terms(ptr(q), ptr(qd), ptr(param), ptr(h))
        c.sw_forces(tt, ptr(q), ptr(qd), ptr(param), ptr(f))
        assert np.allclose(M.reshape(n, n), ref.M(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose(h, ref.h(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose(f, ref.f(tt, y), rtol=1e-12, atol=1e-12)
        for fn, args in (("sw_rhs", param), ("sw_rhs_pre", pre)):
            ydot = np.zeros(2 * n)
            assert getattr(c, fn)(tt, ptr(y), ptr(args), ptr(ydot)) == 0
            assert np.allclose(ydot, ref.rhs(tt, y), rtol=1e-11, atol=1e-11), fn
        z, zdot = np.zeros(2 * n), np.zeros(2 * n)
        c.sw_momentum(ptr(y), ptr(param), ptr(z))
        assert np.allclose(z[n:], ref.M(tt, y) @ qd, rtol=1e-12, atol=1e-12)
        assert c.sw_rhs_canonical(tt, ptr(z), ptr(param), ptr(zdot)) == 0
        assert np.allclose(zdot, np.concatenate([qd, ref.dTdq(tt, y) + ref.f(tt, y)]), rtol=1e-11, atol=1e-11)
        T, V = ref.energies([tt], [y])
        assert np.isclose(c.sw_kinetic_energy(ptr(y), ptr(param)), T[0], rtol=1e-12, atol=1e-12)
        assert np.isclose(c.sw_potential_energy(tt, ptr(y), ptr(param)), V[0], rtol=1e-12, atol=1e-12)
        out = np.zeros(2 * len(point_names))
        c.sw_points(ptr(y), ptr(param), ptr(out))
        for i, name in enumerate(point_names):
            if name in ref.points:
                want = np.array(ref.points[name](tt, *y), dtype=float).ravel()
                assert np.allclose(out[2 * i:2 * i + 2], want, rtol=1e-12, atol=1e-12), name


@pytest.mark.parametrize("model, make_ref, overrides", CODEGEN, ids=["system1", "spring_pendulum"])
def test_generated_numpy_module(tmp_path, model, make_ref, overrides):
    import importlib.util

    run_cli("codegen", model, "--lang", "python", "-o", tmp_path)
    spec = importlib.util.spec_from_file_location(f"sweep_{model.stem}", tmp_path / f"{model.stem}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ref = make_ref(**overrides)
    assert mod.STATE == [s.name for s in ref.q + ref.qd]
    param = np.array([float(ref.values[name]) for name in mod.PARAMETERS])
    n = len(ref.q)
    slots = {name: 2 * i for i, (name, _) in enumerate(mod.POINTS)}
    for tt, y in random_states(n, 4):
        y = fix_state(y, model.stem)
        q, qd = y[:n], y[n:]
        assert np.allclose(mod.mass_matrix(q, param), ref.M(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose(mod.velocity_terms(q, qd, param), ref.h(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose(mod.forces(tt, q, qd, param), ref.f(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose(mod.rhs(tt, y, param), ref.rhs(tt, y), rtol=1e-11, atol=1e-11)
        z = mod.momentum(y, param)
        assert np.allclose(mod.rhs_canonical(tt, z, param), np.concatenate([qd, ref.dTdq(tt, y) + ref.f(tt, y)]),
                           rtol=1e-11, atol=1e-11)
        T, V = ref.energies([tt], [y])
        assert np.isclose(mod.kinetic_energy(y, param), T[0], rtol=1e-12, atol=1e-12)
        assert np.isclose(mod.potential_energy(tt, y, param), V[0], rtol=1e-12, atol=1e-12)
        out = np.asarray(mod.points(y, param)).ravel()
        for name, fn in ref.points.items():
            want = np.array(fn(tt, *y), dtype=float).ravel()
            assert np.allclose(out[slots[name]:slots[name] + 2], want, rtol=1e-12, atol=1e-12), name


# ------------------------------------------------------------------------------------------
# 3. linearize: the equilibrium, A, B and eigenvalues against finite differences of our own
# ------------------------------------------------------------------------------------------

def jacobian(fn, x, eps=1e-6):
    x = np.asarray(x, dtype=float)
    cols = []
    for i in range(len(x)):
        d = np.zeros(len(x))
        d[i] = eps * max(1.0, abs(x[i]))
        cols.append((fn(x + d) - fn(x - d)) / (2 * d[i]))
    return np.column_stack(cols)


def evaluate_text(entry, values):
    """A linearisation entry: a number, or (``--symbolic``) an expression in the model's language."""
    if isinstance(entry, (int, float)):
        return float(entry)
    expr = sp.parse_expr(entry, local_dict={name: sp.Symbol(name) for name in values})
    return float(expr.subs({sp.Symbol(k): v for k, v in values.items()}))


def test_linearize_system1_pushed_equilibrium_and_input(tmp_path):
    """Scene `pushed` (F = 2): the tilted equilibrium of f(q) = 0, A and the input column B of F."""
    out = tmp_path / "lin.json"
    run_cli("linearize", SYSTEM1, "--scene", "pushed", "--inputs", "F", "--format", "json", "-o", out)
    lin = json.loads(out.read_text())
    ref = system1_reference(2.0)
    q_star = fsolve(lambda q: ref.f(0.0, [*q, 0, 0]), [0.1, 0.1], xtol=1e-14)
    assert lin["equilibrium"] and lin["state"] == STATE1
    point = [lin["operating_point"][name] for name in STATE1]
    assert np.allclose(point, [*q_star, 0, 0], rtol=0, atol=1e-10)
    y_star = np.array([*q_star, 0.0, 0.0])
    A = jacobian(lambda y: ref.rhs(0.0, y), y_star)
    assert np.allclose(np.array(lin["A"], dtype=float), A, rtol=1e-6, atol=1e-6)
    B = (system1_reference(2.0 + 1e-3).rhs(0.0, y_star) - system1_reference(2.0 - 1e-3).rhs(0.0, y_star)) / 2e-3
    assert np.allclose(np.array(lin["B"], dtype=float).ravel(), B, rtol=1e-6, atol=1e-6)
    key = lambda z: (round(z.real, 6), round(z.imag, 6))  # noqa: E731
    eig = sorted((complex(e["re"], e["im"]) for e in lin["eigenvalues"]), key=key)
    assert np.allclose(eig, sorted(np.linalg.eigvals(A), key=key), atol=1e-5)


def test_linearize_system1_inverted_symbolic(tmp_path):
    """`--at theta=pi --at phi=pi --symbolic`: A in the parameters' symbols, evaluated at their
    values, is the finite-difference Jacobian there; the eigenvalues are real, two positive."""
    out = tmp_path / "lin.json"
    run_cli("linearize", SYSTEM1, "--scene", "free", "--at", "theta=pi", "--at", "phi=pi", "--symbolic",
            "--format", "json", "-o", out)
    lin = json.loads(out.read_text())
    ref = system1_reference(0.0)
    y_star = np.array([np.pi, np.pi, 0.0, 0.0])
    values = {k: v for k, v in SYSTEM1_VALUES.items()}
    A = np.array([[evaluate_text(e, values) for e in row] for row in lin["A"]])
    assert np.allclose(A, jacobian(lambda y: ref.rhs(0.0, y), y_star), rtol=1e-6, atol=1e-6)
    eig = np.array([complex(e["re"], e["im"]) for e in lin["eigenvalues"]])
    assert np.allclose(sorted(eig.real), sorted(np.linalg.eigvals(A).real), atol=1e-6)
    assert sum(e.real > 0 for e in eig) == 2


def test_linearize_spring_pendulum_damped(tmp_path):
    """The spring pendulum hangs at r = L0 + m g / k; its damping enters A's velocity columns."""
    out = tmp_path / "lin.json"
    run_cli("linearize", SPRING, "--format", "json", "-o", out)
    lin = json.loads(out.read_text())
    ref = spring_reference()
    v = SPRING_VALUES
    y_star = np.array([v["L0"] + v["m"] * v["g"] / v["k"], 0.0, 0.0, 0.0])
    assert np.allclose([lin["operating_point"][n] for n in ("r", "q", "r_dot", "q_dot")], y_star, atol=1e-10)
    A = jacobian(lambda y: ref.rhs(0.0, y), y_star)
    assert np.allclose(np.array(lin["A"], dtype=float), A, rtol=1e-6, atol=1e-6)


# ------------------------------------------------------------------------------------------
# 4. derive --format json (its expressions evaluated) and --format latex (built by pdflatex)
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("model, make_ref", [(SYSTEM1, system1_reference), (SPRING, spring_reference)],
                         ids=["system1", "spring_pendulum"])
def test_derive_json_evaluates_to_the_reference(model, make_ref):
    data = json.loads(run_cli("derive", model, "--format", "json").output)
    ref = make_ref()
    names = [*data["coordinates"], *data["velocities"], *data["parameters"], "t"]
    assert data["coordinates"] == [s.name for s in ref.q] and data["velocities"] == [s.name for s in ref.qd]
    local = {name: sp.Symbol(name) for name in names}
    for name, entry in data["parameters"].items():
        assert float(sp.Rational(entry["value"])) == pytest.approx(ref.values[name], rel=1e-15)

    def value(text, tt, y):
        expr = sp.parse_expr(text, local_dict=local)
        sub = {local[k]: v for k, v in ref.values.items()}
        sub.update({local[s.name]: v for s, v in zip(ref.q + ref.qd, y)})
        sub[local["t"]] = tt
        return float(expr.subs(sub))

    n = len(ref.q)
    for tt, y in random_states(n, 5)[:3]:
        y = fix_state(y, model.stem)
        M = np.array([[value(e, tt, y) for e in row] for row in data["mass_matrix"]])
        h = np.array([value(e, tt, y) for e in data["velocity_terms"]])
        f = np.array([value(e, tt, y) for e in data["forces"]])
        assert np.allclose(M, ref.M(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose(h, ref.h(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose(f, ref.f(tt, y), rtol=1e-12, atol=1e-12)
        effects = sum(np.array([value(e, tt, y) for e in column]) for column in data["effects"].values())
        assert np.allclose(effects, f, rtol=1e-12, atol=1e-12)
        T, V = ref.energies([tt], [y])
        assert value(data["kinetic_energy"], tt, y) == pytest.approx(T[0], rel=1e-12, abs=1e-12)
        assert value(data["potential_energy"], tt, y) == pytest.approx(V[0], rel=1e-12, abs=1e-12)


def pdflatex(tmp_path, tex):
    path = tmp_path / "doc.tex"
    path.write_text(tex, encoding="utf-8")
    result = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", path.name], cwd=tmp_path,
                            capture_output=True, text=True, timeout=120)
    return result.returncode, result.stdout


needs_pdflatex = pytest.mark.skipif(shutil.which("pdflatex") is None, reason="needs pdflatex")


@needs_pdflatex
@pytest.mark.parametrize("args", [(SYSTEM1, "--reactions"), (SPRING,)], ids=["system1", "spring"])
def test_derive_latex_builds(tmp_path, args):
    tex = run_cli("derive", *args, "--format", "latex").output
    code, log = pdflatex(tmp_path, tex)
    assert code == 0, log[-2000:]
    assert (tmp_path / "doc.pdf").is_file()


def overfull_lines(log):
    """Source lines of the overfull boxes pdflatex reports."""
    pattern = r"Overfull \\hbox \(.*?too wide\) (?:detected at line|in paragraph at lines) (\d+)"
    return [int(m) for m in re.findall(pattern, log)]


@needs_pdflatex
def test_derive_latex_reactions_stay_on_the_page(tmp_path):
    tex = run_cli("derive", COUPLED, "--format", "latex", "--reactions").output
    code, _ = pdflatex(tmp_path, tex)
    assert code == 0
    start = next(i for i, line in enumerate(tex.splitlines(), 1) if line.startswith("\\section*{Reactions}"))
    log = (tmp_path / "doc.log").read_text(errors="replace")
    assert [n for n in overfull_lines(log) if n > start] == []


def test_derive_latex_reactions_note_has_no_raw_angle_brackets():
    tex = run_cli("derive", SYSTEM1, "--format", "latex", "--reactions").output
    section = tex[tex.index("\\section*{Reactions}"):]
    prose = section[:section.index("\\begin{align*}")]
    assert "<" not in prose and ">" not in prose, prose


# ------------------------------------------------------------------------------------------
# 5. The README's other first-hour commands
# ------------------------------------------------------------------------------------------

def gif_seconds(path):
    from PIL import Image

    image, total = Image.open(path), 0
    try:
        while True:
            total += image.info["duration"]
            image.seek(image.tell() + 1)
    except EOFError:
        pass
    return total / 1000


def test_animate_model_plays_in_real_time(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "motion.gif"
    run_cli("animate", ROOT / "models" / "examples" / "cart_pole.yaml", "--t", "0.25", "--output", out)
    assert gif_seconds(out) == pytest.approx(0.25, rel=0.1)


def test_accuracy_reference_state(tmp_path):
    """`kronsub accuracy`: its 30-digit reference at t_end is our solve_ivp's state to ~1e-11."""
    out = tmp_path / "wp.csv"
    run_cli("accuracy", SPRING, "--t", "1", "--methods", "dop853", "--tolerances", "1e-8", "--quick", "-o", out)
    meta = json.loads(out.with_suffix(".json").read_text())
    names = ("r", "q", "r_dot", "q_dot")
    got = [float(meta["reference"]["state_at_t_end"][n]) for n in names]
    want = spring_reference().trajectory([1.1, 0.6, 0.0, -0.4], np.array([0.0, 1.0]))[-1]
    assert np.max(np.abs(np.array(got) - want)) < 1e-10
    table = read_csv(out)
    assert float(np.atleast_1d(table["error"])[0]) < 1e-6


def test_simulate_to_a_closed_pipe_keeps_its_metadata(tmp_path):
    import os
    import sys

    meta = tmp_path / "run.json"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "kronsub", "simulate", str(SYSTEM1), "--t", "100", "--dt", "0.001",
                             "--meta", str(meta)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    proc.stdout.readline()
    proc.stdout.close()
    proc.wait(timeout=120)
    proc.stderr.close()
    assert meta.is_file()
    assert json.loads(meta.read_text())["status"] in ("stopped", "interrupted")


def test_linearize_closed_loop_against_multipliers(tmp_path):
    """A closed loop (tests/models/sweep/offset_slider_crank.yaml, five dependent coordinates):
    the equilibrium, A and B (input tau) against finite differences of the accelerations of the
    Lagrange-multiplier reference of tests/reference/sweep.py (which never forms C)."""
    from reference.sweep import slider_crank_reference

    out = tmp_path / "lin.json"
    run_cli("linearize", SWEEP / "offset_slider_crank.yaml", "--inputs", "tau", "--format", "json", "-o", out)
    lin = json.loads(out.read_text())
    ref = slider_crank_reference()
    pv = np.array([0.8, 0.5, 0.3, 0.2, 0.7, -0.1, 20, 0.3, 0.4, 0.5, 9.81])  # the model's values, ref.params order
    guess = [0.5, 0.44, -0.14, 0.11, 0.79, -0.1]

    def acc(state, params=pv):
        yv, ydv = ref.consistent([state[0]], [state[1]], guess, params)
        return ref.evaluate(0.0, yv, ydv, params)[3][0]

    theta = fsolve(lambda x: [acc([x[0], 0.0])], [0.5], xtol=1e-14)[0]
    assert lin["equilibrium"] and lin["operating_point"]["theta"] == pytest.approx(theta, abs=1e-9)
    yv, _ = ref.consistent([theta], [0.0], guess, pv)
    dependent = dict(zip(["rx", "ry", "ra", "px", "py"], yv[1:]))
    assert all(lin["dependent"][k] == pytest.approx(v, abs=1e-9) for k, v in dependent.items())
    row = jacobian(lambda s: np.array([acc(s)]), [theta, 0.0])[0]
    assert np.allclose(lin["A"], [[0, 1], row], rtol=1e-6, atol=1e-6)
    tau = list(ref.params).index("tau")
    up, down = pv.copy(), pv.copy()
    up[tau] += 1e-4
    down[tau] -= 1e-4
    b = (acc([theta, 0.0], up) - acc([theta, 0.0], down)) / 2e-4
    assert np.allclose(np.array(lin["B"], dtype=float).ravel(), [0, b], rtol=1e-6, atol=1e-6)


@lru_cache(maxsize=None)
def slider_crank_trajectory(times):
    from reference.sweep import slider_crank_reference

    ref = slider_crank_reference()
    pv = np.array([0.8, 0.5, 0.3, 0.2, 0.7, -0.1, 20, 0.3, 0.4, 0.5, 9.81])
    guess = [[0.5, 0.44, -0.14, 0.11, 0.79, -0.1]]

    def rhs(tt, s):
        yv, ydv = ref.consistent([s[0]], [s[1]], guess[0], pv)
        guess[0] = yv
        return [s[1], ref.evaluate(tt, yv, ydv, pv)[3][0]]

    sol = solve_ivp(rhs, (0, times[-1]), [0.5, 1.5], t_eval=list(times), method="DOP853", rtol=1e-12, atol=1e-12)
    dependent = [ref.consistent([q], [0.0], [0.5, 0.44, -0.14, 0.11, 0.79, -0.1], pv)[0][1:] for q in sol.y[0]]
    return sol.y.T, np.array(dependent)


@pytest.mark.parametrize("method, tol", [("dop853", 1e-8), ("Radau", 1e-7)])
def test_closed_loop_trajectory(tmp_path, method, tol):
    """offset_slider_crank.yaml simulated: the independent state, the dependent coordinates written
    after the energies, and the pinned points, against the multiplier reference integrated here."""
    out = tmp_path / "run.csv"
    run_cli("simulate", SWEEP / "offset_slider_crank.yaml", "--t", "0.5", "--dt", "0.125", "--method", method,
            "--points", "-o", out)
    tab = read_csv(out)
    assert np.allclose(tab["t"], [0, 0.125, 0.25, 0.375, 0.5], rtol=0, atol=1e-12)
    Y, dep = slider_crank_trajectory(tuple(tab["t"]))
    assert np.max(np.abs(np.column_stack([tab["theta"], tab["theta_dot"]]) - Y)) < tol
    got = np.column_stack([tab[n] for n in ("rx", "ry", "ra", "px", "py")])
    assert np.max(np.abs(got - dep)) < tol
    assert np.allclose(tab["crank.tip.x"], tab["rod.a.x"], atol=1e-9)
    assert np.allclose(tab["rod.b.y"], tab["piston.centre.y"], atol=1e-9)
    assert np.allclose(tab["piston.centre.y"], -0.1, atol=1e-9)


def test_closed_loop_gauss4_fourth_order(tmp_path):
    """gauss4 on a closed loop, in (q, qdot) with Newton's method in every stage: order 4."""
    errors = []
    Y, _ = slider_crank_trajectory((0.0, 0.5))
    for dt in ("0.0625", "0.03125"):
        out = tmp_path / f"g{dt}.csv"
        run_cli("simulate", SWEEP / "offset_slider_crank.yaml", "--t", "0.5", "--dt", dt, "--method", "gauss4",
                "-o", out)
        tab = read_csv(out)
        errors.append(np.max(np.abs([tab["theta"][-1] - Y[-1][0], tab["theta_dot"][-1] - Y[-1][1]])))
    assert 10 < errors[0] / errors[1] < 25, errors


def test_generated_numpy_module_of_a_closed_loop(tmp_path):
    """`codegen --lang python` of offset_slider_crank.yaml: its rhs (Newton for the dependent
    coordinates inside), potential energy and points along a walk of the crank angle."""
    import importlib.util

    from reference.sweep import slider_crank_reference

    run_cli("codegen", SWEEP / "offset_slider_crank.yaml", "--lang", "python", "-o", tmp_path)
    spec = importlib.util.spec_from_file_location("sweep_osc", tmp_path / "offset_slider_crank.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ref = slider_crank_reference()
    param = np.array([mod.DEFAULTS[name] for name in mod.PARAMETERS])
    pv = np.array([mod.DEFAULTS[name] for name in ref.params])
    slots = {name: 2 * i for i, (name, _) in enumerate(mod.POINTS)}
    rng = np.random.default_rng(6)
    q, guess = 0.5, [0.5, 0.44, -0.14, 0.11, 0.79, -0.1]
    r, e, m1, m2, mp, g, k, l0 = (mod.DEFAULTS[n] for n in ("r", "e", "m1", "m2", "mp", "g", "k", "l0"))
    for _ in range(8):
        q += rng.uniform(-0.2, 0.2)
        u, tt = rng.uniform(-2, 2), rng.uniform(0, 2)
        yv, ydv = ref.consistent([q], [u], guess, pv)
        guess = yv
        acc = ref.evaluate(tt, yv, ydv, pv)[3]
        assert np.allclose(mod.rhs(tt, np.array([q, u]), param), [u, acc[0]], rtol=1e-9, atol=1e-9)
        _, rx, ry, ra, px, py = yv
        V = g * (-m1 * r / 2 * np.cos(q) + m2 * ry + mp * py) + k * (np.hypot(px - 1.3, py - e) - l0) ** 2 / 2
        assert mod.potential_energy(tt, np.array([q, u]), param) == pytest.approx(V, abs=1e-9)
        out = np.asarray(mod.points(np.array([q, u]), param)).ravel()
        assert np.allclose(out[slots["piston.centre"]:slots["piston.centre"] + 2], [px, py], atol=1e-9)
        assert np.allclose(out[slots["rod.centre"]:slots["rod.centre"] + 2], [rx, ry], atol=1e-9)


def test_coordinate_named_like_a_column(tmp_path):
    """Either the name is refused with a model error, or every output keeps the angle apart."""
    from kronsub.errors import ModelError

    path = SWEEP / "pendulum_named_like_columns.yaml"
    try:
        system = kronsub.load(path).derive()
    except ModelError:
        return
    out = tmp_path / "run.csv"
    run_cli("simulate", path, "--t", "0.2", "--dt", "0.1", "-o", out)
    header = out.read_text().splitlines()[0].split(",")
    assert len(header) == len(set(header)), header
    frame = system.simulate(t=0.2, dt=0.1, dataframe=False)
    angle = frame["total_energy"]
    assert angle[0] == 0.5
    pd = pytest.importorskip("pandas")
    table = system.simulate(t=0.2, dt=0.1)
    assert isinstance(table, pd.DataFrame)
    assert any(np.allclose(table[c].to_numpy(), angle) for c in table.columns), table


# ------------------------------------------------------------------------------------------
# derive's Markdown read back: the named subexpressions (w1, ...) put back, every entry evaluated
# ------------------------------------------------------------------------------------------

def markdown_entries(text):
    """``{"where": {w: expr}, "Mbar": rows, "fbar": rows, "hbar": rows, "T": expr, "V": expr}`` of
    ``derive``'s Markdown, all as text."""
    lines = text.splitlines()
    out = {"where": {}}

    def table_after(prefix):
        start = next(i for i, line in enumerate(lines) if line.startswith(prefix))
        rows, i = [], start + 1
        while not lines[i].startswith("| **"):
            i += 1
        while i < len(lines) and lines[i].startswith("| **"):
            rows.append(re.findall(r"`([^`]*)`", lines[i]))
            i += 1
        return rows

    for line in lines:
        m = re.match(r"- `(w\d+) = (.*)`$", line)
        if m:
            out["where"][m.group(1)] = m.group(2)
    out["Mbar"] = table_after("Metric `Mbar")
    out["fbar"] = [row[0] for row in table_after("Forces `fbar")]
    out["hbar"] = [row[0] for row in table_after("Velocity terms `hbar")]
    out["T"] = re.search(r"Kinetic energy \(24\): `T = (.*)`", text).group(1)
    out["V"] = re.search(r"Potential energy: `V = (.*)`", text).group(1)
    return out


@lru_cache(maxsize=None)
def coupled_reference():
    """tests/models/sweep/coupled_spring_pendulums.yaml written by hand (as tests/reference/sweep.py does)."""
    r1, q1, r2, q2 = q = list(sp.symbols("r1 q1 r2 q2"))
    m, m2, d, e, kc, k, L0, c, cd, F0, w, g = sp.symbols("m m2 d e kc k L0 c cd F0 w g")
    b1 = sp.Matrix([r1 * sp.sin(q1), -r1 * sp.cos(q1)])
    b2 = sp.Matrix([d + r2 * sp.sin(q2), e - r2 * sp.cos(q2)])
    qd = sp.Matrix(dots(q))
    v1, v2 = b1.jacobian(q) * qd, b2.jacobian(q) * qd
    T = m * v1.dot(v1) / 2 + m2 * v2.dot(v2) / 2
    gap = b2 - b1
    V = (g * (m * b1[1] + m2 * b2[1]) + k * (r1 - L0) ** 2 / 2 + (2 * k + 1) * (r2 - L0) ** 2 / 2
         + kc * (sp.sqrt(gap.dot(gap)) - d) ** 2 / 2)
    F1 = -cd * v1 + sp.Matrix([F0 * sp.sin(w * t), 0])
    F2 = -cd * v2  # the right one's push is overridden to F0 = 0
    Q = [F1.dot(b1.diff(a)) + F2.dot(b2.diff(a)) - c * qd[0] * int(a == r1) - c * qd[2] * int(a == r2) for a in q]
    values = {**yaml_values(SPRING), **yaml_values(COUPLED)}  # `left` and `right` take spring_pendulum.yaml's
    return Reference(q, T, V, Q, values)


def yaml_values(path):
    import yaml

    data = yaml.safe_load(path.read_text())
    return {name: float(sp.Rational(str(spec["value"]))) for name, spec in data["parameters"].items()}


def test_derive_markdown_reads_back(tmp_path):
    """Every printed entry, with its named subexpressions substituted, is the hand-derived one."""
    text = run_cli("derive", COUPLED).output
    md = markdown_entries(text)
    assert md["where"], "expected named subexpressions in this model's Markdown"
    ref = coupled_reference()
    local = {s.name: s for s in ref.q + ref.qd}
    local.update({name: sp.Symbol(name) for name in ref.values})
    local["t"] = t
    where = {}
    for name, body in md["where"].items():
        where[sp.Symbol(name)] = sp.parse_expr(body, local_dict={**local, **{k.name: k for k in where}})
    local.update({k.name: k for k in where})

    params = [sp.Symbol(k) for k in ref.values]
    compiled = {}

    def value(body, tt, y):
        if body not in compiled:
            expr = sp.parse_expr(body, local_dict=local)
            for _ in range(len(where) + 1):
                expr = expr.xreplace(where)
            compiled[body] = sp.lambdify([t, *ref.q, *ref.qd, *params], expr, "math")
        return float(compiled[body](tt, *y, *ref.values.values()))

    rng = np.random.default_rng(7)
    offsets = []
    for _ in range(3):
        y = rng.uniform(-2, 2, 8)
        y[0], y[2] = rng.uniform(0.3, 2, 2)
        tt = rng.uniform(0, 3)
        assert np.allclose([[value(e, tt, y) for e in row] for row in md["Mbar"]], ref.M(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose([value(e, tt, y) for e in md["fbar"]], ref.f(tt, y), rtol=1e-12, atol=1e-12)
        assert np.allclose([value(e, tt, y) for e in md["hbar"]], ref.h(tt, y), rtol=1e-12, atol=1e-12)
        T, V = ref.energies([tt], [y])
        assert value(md["T"], tt, y) == pytest.approx(T[0], rel=1e-12, abs=1e-12)
        offsets.append(value(md["V"], tt, y) - V[0])
    assert np.max(np.abs(offsets)) < 1e-10  # V itself, with the placed known system's weight at its origin


def test_potential_of_a_placed_known_system():
    """The printed V (derive's Markdown) at the initial state against the world's gravity and springs:
    a known system placed with `origin: [d, e]` brings its own gravity's potential moved with it
    (it missed m2 g e, 0.7848 J here, when only its points and bodies moved)."""
    md = markdown_entries(run_cli("derive", COUPLED).output)
    ref = coupled_reference()
    local = {s.name: s for s in ref.q + ref.qd}
    local.update({name: sp.Symbol(name) for name in ref.values})
    V = sp.parse_expr(md["V"], local_dict=local).subs({sp.Symbol(k): v for k, v in ref.values.items()})
    y = [1.0, 0.3, 1.0, -0.2, 0.0, 0.0, 0.0, 0.0]  # the model's initial state
    printed = float(V.subs(dict(zip(ref.q + ref.qd, y))))
    assert printed == pytest.approx(ref.energies([0.0], [y])[1][0], abs=1e-9)

@needs_pdflatex
def test_derive_latex_builds_with_unicode_free_text(tmp_path):
    model = tmp_path / "pendel.yaml"
    model.write_text(
        'name: "Pendel, Winkel θ ≥ 0"\n'
        "description: the angle θ from the downward vertical, ½ m L² ω²\n"
        "parameters:\n"
        "  m: {value: 1, unit: kg}\n"
        "  L: {value: 1, unit: m}\n"
        "  g: {value: 9.81, unit: m/s²}\n"
        "components:\n"
        "  rod: {type: pinned_rod, parameters: {mass: m, length: L}, coordinates: [theta]}\n"
        "coordinates: [theta]\n"
        "effects:\n"
        "  gravity: {type: gravity, g: g}\n", encoding="utf-8")
    tex = run_cli("derive", model, "--format", "latex").output
    code, log = pdflatex(tmp_path, tex)
    assert code == 0, log[-1500:]


@pytest.mark.skipif(__import__("importlib").util.find_spec("heyoka") is None, reason="needs heyoka")
def test_heyoka_on_the_spring_pendulum(tmp_path):
    out = tmp_path / "run.csv"
    run_cli("simulate", SPRING, "--t", "0.5", "--dt", "0.25", "--method", "heyoka", "-o", out)
    tab = read_csv(out)
    Y = spring_reference().trajectory([1.1, 0.6, 0.0, -0.4], tab["t"])
    assert np.max(np.abs(np.column_stack([tab[n] for n in ("r", "q", "r_dot", "q_dot")]) - Y)) < 1e-8
