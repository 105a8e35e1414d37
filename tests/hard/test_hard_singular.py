"""Hard case 5: near-singular configurations.

What could go wrong: at a configuration where the coordinates stop being independent, ``Mbar``
blows up or becomes singular, and the run returns NaN or garbage silently. Criteria: a clear,
early stop naming the configuration, every row kept finite, and the rows before the stop correct
(energy conserved). Cases: System II as the lower rod reaches the vertical line (the square root
in (27) goes to 0), a ``rigid_body3d`` at gimbal lock of its Z-Y-X angles.
"""
from __future__ import annotations

import math

import numpy as np

import kronsub
from conftest import MODELS, ROOT
from kronsub.simulation.run import simulate
from kronsub.simulation.values import resolve


def _run(path, settings, t_end, dt=0.01):
    model = kronsub.load(path)
    system = model.derive()
    values = resolve(system, dict(model.initial), settings)
    return simulate(system, values, t_end, dt, "dop853", progress=False)


def test_system2_stops_where_the_lower_rod_reaches_the_line():
    # c = 0.6, a1 = a2 = 0.5: (c - a1 sin theta) / a2 reaches 1 at sin theta = 0.2
    traj = _run(MODELS / "hoffmann/system2.yaml", {"theta": "1.0"}, 5.0)
    assert not traj.complete
    reach = math.asin(0.2)
    assert "theta=" in traj.message and "singular" in traj.message
    theta_at_stop = float(traj.message.split("theta=")[1].split()[0].rstrip(",;"))
    assert abs(theta_at_stop - reach) < 1e-3
    assert np.all(np.isfinite(traj.y)) and len(traj.t) > 10
    T, V = traj.energies
    assert np.ptp(T + V) < 1e-7 * abs(V[0])


def test_rigid_body_at_gimbal_lock_stops_at_once_naming_the_configuration():
    traj = _run(ROOT / "tests/models/top_3d.yaml", {"theta": "1.5707963", "phi_dot": "5"}, 1.0)
    assert not traj.complete
    assert traj.t_fail == 0.0
    assert "theta=1.5708" in traj.message and "singular" in traj.message
    assert np.all(np.isfinite(traj.y))


def test_rigid_body_away_from_gimbal_lock_runs():
    traj = _run(ROOT / "tests/models/top_3d.yaml", {"theta": "1.2", "phi_dot": "5", "k": "0"}, 1.0)
    assert traj.complete, traj.message
    assert np.all(np.isfinite(traj.y))
