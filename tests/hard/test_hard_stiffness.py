"""Hard case 3: stiffness, two masses coupled by springs with stiffness ratio 1e8.

What could go wrong: the explicit default (dop853) grinds through hundreds of thousands of
steps held by stability, silently, or blows up; an implicit method gets the slow motion wrong.
Criteria: dop853 finishes without blow-up; when the fast mode is damped (real eigenvalues,
Hairer's test) it says the problem is stiff and recommends Radau, and Radau's trajectory agrees
with the exact solution (matrix exponential); when it is undamped (imaginary eigenvalues: an
implicit method must resolve the fast mode too, and scipy's Radau is then far slower, so
recommending it would be wrong) it says a fast mode holds the step and its slow motion is
right; a smooth non-stiff run says nothing.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from scipy.linalg import expm

import kronsub
from kronsub.simulation.run import StiffnessWarning, simulate
from kronsub.simulation.values import resolve

HERE = Path(__file__).resolve().parent


def _run(settings: dict, method: str, t_end=4.0, dt=0.5):
    model = kronsub.load(HERE / "models/stiff_pair.yaml")
    system = model.derive()
    values = resolve(system, dict(model.initial), settings)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = simulate(system, values, t_end, dt, method, rtol=1e-8, atol=1e-8, progress=False)
    stiff = [w for w in caught if issubclass(w.category, StiffnessWarning)]
    return values, traj, stiff


def _exact(values, t: np.ndarray, c: float) -> np.ndarray:
    """y(t) = expm(A t) y0 for M x'' + C x' + K x = 0."""
    m1, m2, k1, k2 = 1.0, 1.0, 1.0, 1e8
    M = np.diag([m1, m2])
    K = np.array([[k1 + k2, -k2], [-k2, k2]])
    C = np.array([[c, -c], [-c, c]])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    y0 = np.array(values.y0)
    return np.array([expm(A * ti) @ y0 for ti in t])


def test_damped_stiff_problem_is_reported_with_an_implicit_method_to_use():
    values, traj, stiff = _run({"c": "1e5"}, "dop853", t_end=1.0)
    assert traj.complete and np.all(np.isfinite(traj.y))
    assert len(stiff) == 1 and "stiff" in str(stiff[0].message)
    assert "--method Radau" in str(stiff[0].message)
    assert np.allclose(traj.y[:, :2], _exact(values, traj.t, 1e5)[:, :2], atol=1e-6)


def test_undamped_fast_mode_is_reported_and_resolved():
    values, traj, stiff = _run({"c": "0"}, "dop853", t_end=1.0)
    assert traj.complete and np.all(np.isfinite(traj.y))
    assert len(stiff) == 1 and "fast oscillation" in str(stiff[0].message)
    assert "undamped" in str(stiff[0].message)
    assert np.allclose(traj.y[:, :2], _exact(values, traj.t, 0.0)[:, :2], atol=1e-6)


def test_non_stiff_run_says_nothing():
    _, traj, stiff = _run({"k_stiff": "4", "c": "0.1", "x2": "0"}, "dop853")
    assert traj.complete
    assert not stiff


def test_implicit_method_gets_the_slow_dynamics_right():
    values, traj, _ = _run({"c": "1e5"}, "Radau")
    assert traj.complete
    exact = _exact(values, traj.t, 1e5)
    # the slow mode (x1 = x2, period 2 pi sqrt(2)) carries the motion: positions to 1e-6
    assert np.allclose(traj.y[:, :2], exact[:, :2], atol=1e-6), np.abs(traj.y - exact).max(axis=0)
    assert np.allclose(traj.y[:, 0], np.cos(np.sqrt(0.5) * traj.t), atol=1e-6)
