"""The Whipple bicycle of the benchmark (models/benchmarks/whipple_bicycle.py: four placed rigid
bodies, the front contact's height a configuration constraint, rolling velocity constraints),
derived and linearised about upright straight running (core/nonholonomic_linearize.py), against
Meijaard, Papadopoulos, Ruina & Schwab (2007): the eigenvalues of Table 2 for v = 0 .. 10 m/s,
the paper's canonical matrices M, C1, K0, K2, and the weave and capsize speeds by a root search.
The published numbers are in tests/data/whipple_benchmark.json."""
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from helpers.compare import same_roots
from kronsub.core.symbols import symbol

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "models" / "benchmarks"))
import whipple_bicycle as bicycle  # noqa: E402

PUBLISHED = json.loads((ROOT / "tests" / "data" / "whipple_benchmark.json").read_text())
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

