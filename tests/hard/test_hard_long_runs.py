"""Hard case 2: long conservative runs with ``gauss4`` (10^5 steps).

What could go wrong: the implicit stage iteration of the Gauss-Legendre method may fail to
converge (it once stalled just above a fixed 1e-12 limit when a momentum passed near zero, and
the run stopped at t = 927.93), and a non-symplectic drift would make the energy error grow
secularly. Criteria: the run completes; the energy error is bounded (its largest excursion over
the last tenth of the run is no larger than twice that over the first tenth); on the pendulum
the phase error against the exact elliptic-function solution is reported and falls as h^4.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipj, ellipk

import kronsub
from conftest import MODELS
from kronsub.simulation.run import simulate
from kronsub.simulation.values import resolve

HERE = Path(__file__).resolve().parent


def _run(path, settings, t_end, h):
    model = kronsub.load(path)
    system = model.derive()
    values = resolve(system, dict(model.initial), settings)
    traj = simulate(system, values, t_end, h, "gauss4", progress=False)
    return system, values, traj


def _bounded(energy: np.ndarray) -> tuple[float, float]:
    err = np.abs(energy - energy[0])
    tenth = len(err) // 10
    return float(err[1:tenth].max()), float(err[-tenth:].max())


def test_double_pendulum_of_rods_completes_and_keeps_its_energy():
    _, _, traj = _run(MODELS / "hoffmann/system1.yaml",
                      {"theta": "2*pi/3", "phi": "-pi/18", "F": "0"}, 1000.0, 0.01)
    assert traj.complete, traj.message
    assert traj.stats["steps"] == 100_000
    T, V = traj.energies
    E = T + V
    first, last = _bounded(E)
    assert last <= 2 * first + 1e-12, f"energy error grew from {first:.3g} to {last:.3g}"
    assert np.max(np.abs(E - E[0])) <= 1e-3 * abs(E[0])


def _exact_pendulum(theta0: float, omega0: float, t: np.ndarray) -> np.ndarray:
    """theta(t) = 2 asin(k sn(K - omega0 t | k^2)), k = sin(theta0 / 2), from rest at theta0."""
    k = np.sin(theta0 / 2)
    m = k * k
    sn, _, _, _ = ellipj(ellipk(m) - omega0 * t, m)
    return 2 * np.arcsin(k * sn)


@pytest.mark.parametrize("theta0", [2.0, 3.0])
def test_pendulum_phase_error_falls_as_h4_and_energy_stays_bounded(theta0):
    g, L = 9.81, 1.0
    omega0 = np.sqrt(g * (L / 2) / (L * L / 12 + (L / 2) ** 2))   # m g d / (I + m d^2)
    errors = {}
    for h in (0.02, 0.01):
        _, _, traj = _run(HERE / "models/pendulum.yaml", {"theta": str(theta0)}, 1000.0 if h == 0.01 else 500.0, h)
        assert traj.complete, traj.message
        T, V = traj.energies
        first, last = _bounded(T + V)
        assert last <= 2 * first + 1e-12, f"h = {h}: energy error grew from {first:.3g} to {last:.3g}"
        exact = _exact_pendulum(theta0, omega0, traj.t)
        # phase error at t = 500, measured as the largest angle error over the last period
        window = (traj.t > 500 - 2 * np.pi / omega0) & (traj.t <= 500 + 1e-9)
        errors[h] = float(np.max(np.abs(traj.y[window, 0] - exact[window])))
    ratio = errors[0.02] / errors[0.01]
    print(f"phase error at t = 500, theta0 = {theta0}: h = 0.02: {errors[0.02]:.3g}, "
          f"h = 0.01: {errors[0.01]:.3g} (ratio {ratio:.1f}; order 4 gives 16)")
    assert 12 < ratio < 20, errors
    assert errors[0.01] < 1e-3
