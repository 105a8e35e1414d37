"""The high-precision reference: its tape against lambdify, its routes against exact solutions
and against an independent 40-digit solution of the double pendulum (``tests/data``)."""
from __future__ import annotations

import mpmath
import numpy as np
import pytest
import sympy

from conftest import MODELS
# closed_loop, loaded, pendulum_exact, spring_chain_exact are also imported from here by
# test_accuracy.py until it takes them from helpers.systems and reference.exact (issue 33)
from helpers.systems import TEST_MODELS, benchmark_problem, closed_loop, functions_system, loaded
from kronsub.core.symbols import TIME
from kronsub.simulation import reference as R
from reference.exact import pendulum_exact, spring_chain_exact


def lambdified_rhs(system, param):
    """``[qdot; Mbar^-1 (fbar - hbar)]`` by sympy.lambdify and numpy: the independent evaluation."""
    n = len(system.coordinates)
    args = [list(system.coordinates), list(system.velocities), TIME, [p.symbol for p in system.parameters]]
    M = sympy.lambdify(args, system.mass_matrix, "numpy")
    r = sympy.lambdify(args, system.forces - system.velocity_terms, "numpy")

    def f(t, y):
        q, u = list(y[:n]), list(y[n:])
        return np.concatenate([y[n:], np.linalg.solve(np.array(M(q, u, t, param), dtype=float),
                                                      np.ravel(np.array(r(q, u, t, param), dtype=float)))])

    return f


@pytest.mark.parametrize("path", [
    MODELS / "hoffmann" / "system1.yaml", MODELS / "hoffmann" / "system2.yaml",
    MODELS / "examples" / "double_pendulum.yaml", MODELS / "examples" / "cart_pole.yaml",
    MODELS / "examples" / "watt_governor.yaml", MODELS / "examples" / "particle_on_sphere.yaml",
    TEST_MODELS / "polar_spring.yaml", TEST_MODELS / "body_on_springs.yaml",
    TEST_MODELS / "spring_chain.yaml", TEST_MODELS / "pendulum.yaml",
], ids=lambda p: p.stem)
def test_tape_right_hand_side_matches_lambdify(path):
    system, values = loaded(path)
    param = np.array(values.parameters)
    bits = 200
    with mpmath.workdps(60):
        series = R._series_of(system, values.parameters, bits)
    expected = lambdified_rhs(system, param)
    rng = np.random.default_rng(3)
    n = len(system.coordinates)
    for _ in range(5):
        y = np.array(values.y0) + np.concatenate([rng.uniform(-0.05, 0.05, n), rng.uniform(-2, 2, n)])
        t = float(rng.uniform(0, 2))
        with mpmath.workdps(60):
            coeff = series.coefficients(R._fixed(mpmath.mpf(t), bits), [R._fixed(mpmath.mpf(v), bits) for v in y], 1)
            got = np.array([float(R._real(c[1], bits)) for c in coeff])
        want = expected(t, y)
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12), (got, want)


def test_taylor_and_extrapolation_agree_on_every_function_rule():
    system = functions_system()
    y0 = [0.4, -0.3]
    taylor = R.taylor(system, [0.3], y0, [0.5, 1.0], digits=16)
    gbs = R.extrapolation(system, [0.3], y0, [0.5, 1.0], digits=16)
    assert R._difference(taylor.states, gbs.states) < 1e-14
    # and both against scipy at float64 on the lambdified equations
    from scipy.integrate import solve_ivp

    sol = solve_ivp(lambdified_rhs(system, np.array([0.3])), (0, 1.0), y0, method="DOP853", rtol=1e-13,
                    atol=1e-13, t_eval=[0.5, 1.0])
    assert np.allclose(sol.y.T, [[float(v) for v in s] for s in taylor.states], rtol=0, atol=1e-10)


@pytest.mark.parametrize("name, exact", [("spring_chain", spring_chain_exact), ("pendulum", pendulum_exact)])
def test_reference_matches_exact_solution(name, exact):
    system, values = loaded(TEST_MODELS / f"{name}.yaml")
    times = [1.0, 3.0]
    ref = R.reference(system, values.parameters, values.y0, times, digits=16)
    want = exact(values, times)
    actual = R._difference(ref.states, want)
    assert actual < 1e-20
    assert ref.error < 1e-12  # the estimate: the 16-digit run against the 24-digit one


def test_reference_matches_independent_40_digit_double_pendulum():
    """The benchmark problem from the exact inputs against ``tests/data/double_pendulum_rods.json``
    (hand Lagrangian, the data script's own extrapolation in mpmath at 55 digits)."""
    system, param, y0, want = benchmark_problem()
    ref = R.reference(system, param, y0, [1.0, 10.0], digits=16)
    with mpmath.workdps(40):
        actual = float(max(abs(a - b) for a, b in zip(ref.states[-1], want)))
    assert actual <= max(ref.error, 1e-22), (actual, ref.error)
    assert actual < 1e-16


# ---------------------------------------------------------------------------------------------
# extended precision: the generated C in long double and _Float128
# ---------------------------------------------------------------------------------------------

def test_taylor_route_sees_a_series_with_gaps():
    """Both rods released from rest level with the hinge: every third and fourth coefficient of the
    solution's series is zero, and at 20 digits the route's order is 28, so orders 27 and 28
    alone read a radius 10x too long (an error of 3e-7 at t = 1). With the last four orders it
    agrees with 30 digits and with the extrapolation route."""
    system, param, _, _ = benchmark_problem()
    y0 = [sympy.pi / 2, sympy.pi / 2, 0, 0]
    fine = R.taylor(system, param, y0, [1.0], digits=30)
    route = R.taylor(system, param, y0, [1.0], digits=20)
    assert route.route == "Taylor series, order 28"
    assert max(abs(a - b) for a, b in zip(route.states[0], fine.states[0])) < mpmath.mpf("1e-19")
    other = R.extrapolation(system, param, y0, [1.0], digits=20)
    assert max(abs(a - b) for a, b in zip(other.states[0], fine.states[0])) < mpmath.mpf("1e-17")


def test_quad_precision_reaches_1e15_on_the_benchmark_problem():
    """Section 3 of issue 9: error <= 1e-15 at t = 10 against the 40-digit reference."""
    from kronsub.simulation.extended import ExtendedError, ExtendedModel

    system, param, y0, want = benchmark_problem()
    try:
        model = ExtendedModel(system, "quad")
    except ExtendedError as exc:
        pytest.skip(f"no _Float128 here: {exc}")
    result = model.integrate(param, y0, 10, tol=1e-24, stages=10)
    assert result.status == 0
    with mpmath.workdps(50):
        error = float(max(abs(a - b) for a, b in zip(result.state, want)))
    assert error <= 1e-15, error


@pytest.mark.parametrize("precision, floor", [("long", 1e-16), ("quad", 1e-26)])
def test_extended_precision_beats_float64_on_the_pendulum(precision, floor):
    """Against Jacobi's elliptic functions, where float64 cannot go below ~1e-15."""
    from kronsub.simulation.extended import ExtendedError, ExtendedModel

    system, values = loaded(TEST_MODELS / "pendulum.yaml")
    try:
        model = ExtendedModel(system, precision)
    except ExtendedError as exc:
        pytest.skip(f"no {precision} here: {exc}")
    exact = [sympy.Integer(1), sympy.Rational(4, 5), sympy.Rational(981, 100)]
    with mpmath.workdps(50):
        want = pendulum_exact(type(values)(tuple(mpmath.mpf(str(v)) for v in exact), (mpmath.mpf("2.5"), 0)),
                              [2.0], digits=40)[0]
    result = model.integrate(exact, [sympy.Rational(5, 2), 0], 2)
    with mpmath.workdps(50):
        error = float(max(abs(a - b) for a, b in zip(result.state, want)))
    assert result.status == 0 and error < floor, error


@pytest.mark.parametrize("precision", ["long", "quad"])
def test_retyped_c_builds_with_warnings_as_errors(tmp_path, precision):
    import subprocess

    from kronsub.simulation.extended import sources
    from kronsub.simulation.native import compiler_command

    system, _ = loaded(MODELS / "examples" / "watt_governor.yaml")
    for name, text in sources(system, precision):
        (tmp_path / name).write_text(text)
    text = (tmp_path / "model.c").read_text()
    # every real is ks_real: double only in the typedef of long double
    assert [line for line in text.splitlines() if "double" in line and "typedef" not in line] == []
    proc = subprocess.run([*compiler_command(), "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-c",
                           "model.c", "extended.c"], cwd=tmp_path, capture_output=True, text=True)
    if proc.returncode and precision == "quad" and "_Float128" in proc.stderr:
        pytest.skip("no _Float128 in this compiler")
    assert proc.returncode == 0, proc.stderr


# ---------------------------------------------------------------------------------------------
# closed loops: the dependent coordinates as series (y_d' = Lambda qdot) and by Newton's method
# ---------------------------------------------------------------------------------------------

def test_closed_loop_reference_equals_its_explicit_twin():
    """System II written with the constraint (25) against System II in the parametric form (26):
    the same motion from two derivations; phi against its closed form asin((c - a1 sin theta)/a2)."""
    settings = {"theta": "0.55", "theta_dot": "0.5"}  # an oscillation clear of the toggle at theta = 0.2
    implicit, values, dependent = closed_loop(MODELS / "hoffmann" / "system2_implicit.yaml", settings)
    explicit, twin = loaded(MODELS / "hoffmann" / "system2.yaml", settings)
    assert twin.y0 == values.y0 and twin.parameters == values.parameters
    times = [0.5, 1.0]
    ref = R.reference(implicit, values.parameters, values.y0, times, digits=12, dependent=dependent)
    want = R.reference(explicit, twin.parameters, twin.y0, times, digits=12)
    assert ref.error < 1e-11 and want.error < 1e-11
    assert R._difference(ref.states, want.states) < 1e-17
    names = [p.name for p in implicit.parameters]
    c, a1, a2 = (mpmath.mpf(values.parameters[names.index(k)]) for k in ("c", "a1", "a2"))
    with mpmath.workdps(40):
        for state, (phi,) in zip(want.states, ref.dependent):
            assert abs(phi - mpmath.asin((c - a1 * mpmath.sin(state[0])) / a2)) < 1e-17


def test_closed_loop_series_matches_kane_and_the_newton_route():
    """The four-bar (two dependent coordinates): the tape's accelerations at consistent states
    against sympy.physics.mechanics' KanesMethod with configuration constraints; then the Taylor
    route (all orders of y_d, Lambda, gamma) against Gragg-Bulirsch-Stoer with Newton's method in
    every evaluation."""
    from reference import closed_loops as loops

    system, values, dependent = closed_loop(MODELS / "examples" / "four_bar.yaml", {"tau": "0.7"})
    kane = loops.four_bar()
    params = {p.name: v for p, v in zip(system.parameters, values.parameters)}
    bits, n = 200, len(system.coordinates)
    rng = np.random.default_rng(11)
    with mpmath.workdps(60):
        series = R._series_of(system, values.parameters, bits)
        closure = R._Closure(system, values.parameters, bits, dependent)
        for _ in range(4):
            y = np.array(values.y0) + np.concatenate([rng.uniform(-0.05, 0.05, n), rng.uniform(-2, 2, n)])
            fixed = [R._fixed(mpmath.mpf(v), bits) for v in y]
            yd = closure.dependent(fixed[:n])
            coeff = series.coefficients(0, fixed + yd, 1)
            got = np.array([float(R._real(coeff[n + a][1], bits)) for a in range(n)])
            ours = dict(zip((d.name for d in system.implicit.dependent), (float(R._real(v, bits)) for v in yd)))
            q, u = kane.state(y[:n], y[n:], [ours[name] for name in kane.dependent], params)
            assert np.allclose([ours[name] for name in kane.dependent], q[n:], atol=1e-12)
            _, _, want = kane.evaluate(q, u, params)
            assert np.allclose(got, want, rtol=1e-10, atol=1e-10), (got, want)
    taylor = R.taylor(system, values.parameters, values.y0, [0.25], digits=12, dependent=dependent)
    gbs = R.extrapolation(system, values.parameters, values.y0, [0.25], digits=12, dependent=dependent)
    assert R._difference(taylor.states, gbs.states) < 1e-12
    assert R._difference(taylor.dependent, gbs.dependent) < 1e-12
