"""The Taylor integrator generated as C: every recurrence against the mpmath Taylor route, models
that build with warnings as errors, and the benchmark double pendulum against its 40-digit state."""
from __future__ import annotations

import mpmath
import numpy as np
import pytest

import kronsub
from conftest import MODELS, ROOT
from kronsub.simulation import reference as R
from kronsub.simulation.taylor_c import TaylorC
from kronsub.simulation.values import resolve
from test_reference import _functions_system, benchmark_problem


def test_every_rule_matches_the_mpmath_taylor_route():
    system = _functions_system()
    y0 = [0.4, -0.3]
    want = R.taylor(system, [0.3], y0, [1.0], digits=20).states[-1]
    got, status, steps, order = TaylorC(system).integrate([0.3], y0, 1.0, 1e-15)
    assert status == 0 and steps > 1 and order == 19
    assert np.allclose(got, [float(v) for v in want], rtol=0, atol=1e-13)


@pytest.mark.parametrize("path", [MODELS / "examples" / "cart_pole.yaml", MODELS / "examples" / "watt_governor.yaml",
                                  ROOT / "tests" / "models" / "polar_spring.yaml"], ids=lambda p: p.stem)
def test_models_build_and_match_the_reference(path):
    model = kronsub.load(path)
    system = model.derive()
    values = resolve(system, dict(model.initial), {"r": "1.2", "a": "0.3"} if path.stem == "polar_spring" else {})
    want = R.taylor(system, values.parameters, values.y0, [0.5], digits=18).states[-1]
    got, status, _, _ = TaylorC(system).integrate(values.parameters, values.y0, 0.5, 1e-14)
    assert status == 0
    assert np.allclose(got, [float(v) for v in want], rtol=1e-11, atol=1e-11)


def test_benchmark_double_pendulum_reaches_the_float64_end():
    """The chaotic double pendulum to t = 10: about heyoka's best float64 result (1.5e-10)."""
    system, _, _, want = benchmark_problem()
    values = resolve(system, {}, {"theta": "2*pi/3", "phi": "-pi/18"})
    got, status, _, _ = TaylorC(system).integrate(values.parameters, values.y0, 10.0, 1e-16)
    with mpmath.workdps(50):
        error = max(abs(float(g - w)) for g, w in zip(got, want))
    assert status == 0 and error < 1e-9, error
