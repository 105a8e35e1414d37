"""Hard case 8: lengths and masses from 1e-6 to 1e6.

What could go wrong: absolute tolerances, thresholds or constants tuned to unit-sized systems
(a step-size floor, a singularity test, an ``atol`` on the state) break at extreme scales, and
the results stop scaling as dimensional analysis says they must. Criteria (System I, two rods):
with every length times ``L`` and every mass times ``m`` (inertias times ``m L^2``), the angles
are the same functions of ``t / sqrt(L)`` and the angular velocities scale as ``1 / sqrt(L)``
(gravity fixed), independent of ``m``; the kinetic energy scales as ``m L`` (to 1e-8 relative).
"""
from __future__ import annotations

import numpy as np
import pytest

import kronsub
from conftest import MODELS
from kronsub.simulation.run import simulate
from kronsub.simulation.values import resolve

T_END, DT = 2.0, 0.25


def _run(L: float, m: float):
    model = kronsub.load(MODELS / "hoffmann/system1.yaml")
    system = model.derive()
    settings = {"theta": "1.2", "phi": "-0.7", "F": "0",
                "a1": repr(0.5 * L), "a2": repr(0.4 * L), "m1": repr(1.0 * m), "m2": repr(2.0 * m),
                "I1": repr(m * L * L / 12), "I2": repr(2 * m * (0.8 * L) ** 2 / 12)}
    values = resolve(system, dict(model.initial), settings)
    s = np.sqrt(L)
    # atol in the units of the smaller of the angles (1) and the angular velocities (1/sqrt(L))
    traj = simulate(system, values, T_END * s, DT * s, "dop853", rtol=1e-12, atol=1e-12 * min(1.0, 1.0 / s),
                    progress=False)
    assert traj.complete, traj.message
    return traj


@pytest.fixture(scope="module")
def base():
    return _run(1.0, 1.0)


@pytest.mark.parametrize("L, m", [(1e-6, 1.0), (1e6, 1.0), (1.0, 1e-6), (1.0, 1e6), (1e-6, 1e6), (1e6, 1e-6)])
def test_motion_scales_as_dimensional_analysis_says(base, L, m):
    traj = _run(L, m)
    s = np.sqrt(L)
    assert np.allclose(traj.t / s, base.t, rtol=1e-12)
    assert np.allclose(traj.y[:, :2], base.y[:, :2], rtol=0, atol=1e-8)
    assert np.allclose(traj.y[:, 2:] * s, base.y[:, 2:], rtol=0, atol=1e-8)
    T, _ = traj.energies
    T0, _ = base.energies
    assert np.allclose(T / (m * L), T0, rtol=1e-8, atol=1e-12)
