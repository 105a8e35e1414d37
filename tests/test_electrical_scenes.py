"""The open-circuit and short-circuit scenes of the bundled circuits, against closed forms.

In Kron's mesh transformation an element switched off by a scene is a short circuit (no
voltage across it); an open circuit is a loop that carries no current: no source in it, and
no current at the start. The scenes are added to models that already have several scenes, so
their default run (the whole model) is unchanged.
"""
from __future__ import annotations

import numpy as np

import kronsub
from helpers.circuits import CIRCUITS, simulated
from kronsub.model.scenes import select_scene


def test_the_scenes_leave_the_default_runs_as_they_were():
    for name in ("series_rlc.yaml", "magnetic_suspension.yaml"):
        model = kronsub.load(CIRCUITS / name)
        assert len(model.scenes) > 2 and select_scene(model, None) is None


def test_the_open_coil_lets_the_ball_fall():
    """No current: ``m y'' = m g - k y'`` from rest at ``y = a``:
    ``y = a + (m g/k) (t - (m/k) (1 - exp(-k t/m)))``."""
    header, rows = simulated(CIRCUITS / "magnetic_suspension.yaml", "--scene", "open_circuit")
    m, k, g, a = 0.1, 0.001, 9.81, 0.05
    t = rows[:, header.index("t")]
    exact = a + m * g / k * (t - m / k * (-np.expm1(-k * t / m)))
    np.testing.assert_allclose(rows[:, header.index("y")], exact, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rows[:, header.index("y_dot")], m * g / k * -np.expm1(-k * t / m), rtol=0, atol=1e-8)
    assert np.all(rows[:, header.index("i")] == 0) and np.all(rows[:, header.index("magnetic_energy")] == 0)


def test_the_shorted_capacitor_leaves_the_rl_step():
    """``L i' = E - R i``: ``i = (E/R) (1 - exp(-R t/L))``, ``q`` its integral."""
    header, rows = simulated(CIRCUITS / "series_rlc.yaml", "--scene", "shorted_capacitor")
    L, R, E = 0.5, 1.0, 10.0
    t = rows[:, header.index("t")]
    tau = L / R
    np.testing.assert_allclose(rows[:, header.index("i")], E / R * -np.expm1(-t / tau), rtol=0, atol=1e-8)
    np.testing.assert_allclose(rows[:, header.index("q")], E / R * (t + tau * np.expm1(-t / tau)), rtol=0, atol=1e-8)
    assert np.all(rows[:, header.index("electric_energy")] == 0)
