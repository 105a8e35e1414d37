"""The Whipple bicycle of the benchmark (models/benchmarks/whipple_bicycle.py: four placed rigid
bodies, the front contact's height a configuration constraint, rolling velocity constraints),
derived and linearised about upright straight running (core/nonholonomic_linearize.py), against
Meijaard, Papadopoulos, Ruina & Schwab (2007): the eigenvalues of Table 2 for v = 0 .. 10 m/s,
the paper's canonical matrices M, C1, K0, K2, and the weave and capsize speeds by a root search.
The published numbers are in tests/data/whipple_benchmark.json.

And a run of the nonlinear rates: the state [x; u], the pitch held by the front contact's height
and solved from it by Newton's method at every evaluation (as the generated right-hand side of a
model file does, core/held.py). From upright running at 5 m/s (stable: between the weave and
capsize speeds) with a small roll, the roll and steer follow the linearised motion ``exp(A t)``
to second order in the perturbation; the energy balance ``T(t) - int_0^t f . xdot = T(0)``
(gravity's work, the rolling contacts' none) holds and the front contact stays on the ground."""
import json
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.optimize import brentq

from helpers.compare import same_roots
from kronsub.core.symbols import symbol

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "models" / "benchmarks"))
import whipple_bicycle as bicycle  # noqa: E402

PUBLISHED = json.loads((ROOT / "tests" / "data" / "whipple_benchmark.json").read_text())
SPEED, ROLL, SPAN = 5.0, 1e-3, 2.0  # the run: upright at 5 m/s, rolled by ROLL rad, for SPAN s
FREE = (0.0, 0.0)  # the roll and steer torques of the run
STEER_SIGN = np.diag([1.0, -1.0, 1.0, -1.0])  # our steer turns left, the paper's right: A = S A_paper S


@pytest.fixture(scope="module")
def rates():
    """The real route: the bodies and constraints built, their rates compiled (a few seconds)."""
    return bicycle.rates_of()


def _lateral(lin):
    """Roll and steer with their rates: the forward speed (the rear wheel's rate, last) is decoupled."""
    assert np.max(np.abs(lin.A[:4, 4])) <= 1e-12 and np.max(np.abs(lin.A[4])) <= 1e-12
    return lin.A[:4, :4]


def _canonical(v):
    """``A`` of the paper's ``M q'' + v C1 q' + (g K0 + v^2 K2) q = 0`` in ``[q; q']``."""
    M, C1, K0, K2 = (np.array(PUBLISHED[k]) for k in ("M", "C1", "K0", "K2"))
    stiffness = np.linalg.solve(M, PUBLISHED["g"] * K0 + v**2 * K2)
    return np.block([[np.zeros((2, 2)), np.eye(2)], [-stiffness, -np.linalg.solve(M, v * C1)]])


def _abscissa(rates, v):
    return float(np.max(np.linalg.eigvals(_lateral(bicycle.linearized(rates, v))).real))


def test_eigenvalues_of_table_2(rates):
    for speed, published in PUBLISHED["eigenvalues"].items():
        lin = bicycle.linearized(rates, float(speed))
        assert lin.equilibrium and lin.state == tuple(symbol(n) for n in ("roll", "steer")) + tuple(
            rates.speeds)
        assert lin.dependent == ((symbol("pitch"), 0.0),)  # the paper's reference configuration
        expected = [complex(re, im) for re, im in published]
        assert same_roots(np.linalg.eigvals(_lateral(lin)), expected, 1e-10), speed
        assert same_roots(lin.eigenvalues, expected + [0.0], 1e-10), speed
        # the paper's own matrices give the table too (an independent reading of it)
        assert same_roots(np.linalg.eigvals(_canonical(float(speed))), expected, 1e-10), speed


def test_linearised_matrix_is_the_canonical_form(rates):
    """``A`` and, for the roll and steer torques, ``B = [0; M^-1]`` of the paper's equations."""
    torque_input = np.vstack([np.zeros((2, 2)), np.linalg.inv(np.array(PUBLISHED["M"]))])
    for v in (0.0, 1.0, 4.6, 10.0):
        lin = bicycle.linearized(rates, v)
        assert np.allclose(_lateral(lin), STEER_SIGN @ _canonical(v) @ STEER_SIGN, rtol=0, atol=1e-10)
        assert lin.inputs == bicycle.TORQUES
        assert np.allclose(lin.B[:4], STEER_SIGN @ torque_input @ STEER_SIGN[:2, :2], rtol=0, atol=1e-10)
        assert np.max(np.abs(lin.B[4])) <= 1e-12
    # the ignorable coordinates found alone: the position, heading and the wheels' turns
    found = rates.linearize(bicycle.upright(4.6), dependent=(symbol("pitch"),))
    assert found.state == bicycle.linearized(rates, 4.6).state
    assert np.array_equal(found.A, bicycle.linearized(rates, 4.6).A)


def test_weave_and_capsize_speeds(rates):
    weave = brentq(lambda v: _abscissa(rates, v), 4.0, 5.0, xtol=1e-14, rtol=1e-15)
    capsize = brentq(lambda v: _abscissa(rates, v), 6.0, 7.0, xtol=1e-14, rtol=1e-15)
    assert weave == pytest.approx(PUBLISHED["weave_speed"], abs=1e-10)
    assert capsize == pytest.approx(PUBLISHED["capsize_speed"], abs=1e-10)
    at_weave = np.linalg.eigvals(_lateral(bicycle.linearized(rates, PUBLISHED["weave_speed"])))
    assert max(abs(e.imag) for e in at_weave) == pytest.approx(PUBLISHED["weave_frequency_at_weave_speed"], abs=1e-10)
    assert _abscissa(rates, 5.0) < 0 < min(_abscissa(rates, 4.0), _abscissa(rates, 7.0))



@pytest.fixture(scope="module")
def run(rates):
    """The run from upright at SPEED rolled by ROLL (DOP853), the work of the forces integrated
    beside it, and the kinetic energy ``1/2 (J xdot)^T W (J xdot)`` of a state."""
    built = rates.motion
    numbers = {**bicycle.benchmark_values(), **{s: 0.0 for s in bicycle.TORQUES}}
    x = list(built.coordinates)
    W = sympy.lambdify([x], built.metric.weights.xreplace(numbers), "numpy", cse=True)
    J = sympy.lambdify([x], built.metric.projection.xreplace(numbers), "numpy", cse=True)
    force = sympy.lambdify([x], list(built.force.xreplace(numbers)), "numpy", cse=True)
    pitch, n = x.index(symbol("pitch")), len(x)

    def held(z):
        return rates.on_constraints(z[:n], [pitch], 0.0, FREE)

    def field(t, z):  # z = [x; u; work of the forces]
        q = held(z)
        out = rates.rates(q, z[n:-1], 0.0, FREE).real
        return [*out, float(np.dot(force(q), out[:n]))]

    def kinetic(z):
        q = held(z)
        v = np.asarray(J(q), dtype=float) @ rates.rates(q, z[n:-1], 0.0, FREE).real[:n]
        return 0.5 * v @ np.asarray(W(q), dtype=float) @ v

    start = np.zeros(n + len(rates.speeds) + 1)
    start[x.index(symbol("roll"))] = ROLL
    start[:n] = held(start)
    rear = n + rates.speeds.index(bicycle.velocity_symbol(symbol("rear")))
    start[rear] = SPEED / bicycle.benchmark_values()[symbol("rR")]
    result = solve_ivp(field, (0.0, SPAN), start, t_eval=np.linspace(0.0, SPAN, 41), method="DOP853", rtol=1e-10,
                       atol=1e-12)
    assert result.success
    return x, result, held, kinetic


def test_a_run_follows_the_linearised_motion(rates, run):
    x, result, _, _ = run
    lin = bicycle.linearized(rates, SPEED)
    assert [s.name for s in lin.state] == ["roll", "steer", "roll_dot", "steer_dot", "rear_dot"]
    linear = np.array([expm(lin.A * t) @ [ROLL, 0.0, 0.0, 0.0, 0.0] for t in result.t])
    n = len(x)
    ours = [result.y[x.index(symbol("roll"))], result.y[x.index(symbol("steer"))], result.y[n], result.y[n + 1]]
    for k in range(4):
        assert np.max(np.abs(ours[k] - linear[:, k])) < 1e-4 * ROLL, k  # second order in ROLL (1e-5 ROLL here)
    assert np.max(np.abs(ours[1])) > 0.1 * ROLL  # the steer answers the roll


def test_a_run_keeps_the_energy_balance_and_the_front_contact(rates, run):
    x, result, held, kinetic = run
    balance = np.array([kinetic(z) - z[-1] for z in result.y.T])
    work = np.ptp(result.y[-1])  # gravity's work: of the size of the perturbation's energy
    assert work > 0.1 * 85 * 9.81 * ROLL ** 2
    assert np.max(np.abs(balance - balance[0])) < 1e-6 * work
    assert max(abs(rates.constraint(held(z), 0.0, FREE)[0][0]) for z in result.y.T) < 1e-13
