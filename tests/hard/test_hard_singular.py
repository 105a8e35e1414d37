"""Hard case 5: near-singular configurations.

What could go wrong: at a configuration where the coordinates stop being independent, ``Mbar``
blows up or becomes singular, and the run returns NaN or garbage silently. Criteria: a clear,
early stop naming the configuration, every row kept finite, and the rows before the stop correct
(energy conserved). Cases: System II as the lower rod reaches the vertical line (the square root
in (27) goes to 0), a ``rigid_body3d`` at gimbal lock of its Z-Y-X angles, and a four-bar that
reaches its toggle position (``tests/hard/models/triple_rocker.yaml``: a non-Grashof linkage whose
coupler and rocker come into one line at ``sin(theta1) = -1/4``, where ``dg/d(theta2, theta3)``
is singular and ``theta1`` cannot go on): the run stops there, says "toggle position" and
names the configuration, its rows before are finite, keep the constraints to 1e-9 and keep
the energy; a run that does not reach the toggle goes on undisturbed.
"""
from __future__ import annotations

import io
import math

import numpy as np
from click.testing import CliRunner

import kronsub
from conftest import MODELS, ROOT
from helpers import constraint_residual
from kronsub.cli import main
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
    assert "in Mbar[theta, theta] is outside its domain" in traj.message  # the square root of (27) at 0
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


TRIPLE_ROCKER = ROOT / "tests/hard/models/triple_rocker.yaml"


def _simulate_cli(*extra):
    result = CliRunner().invoke(main, ["simulate", str(TRIPLE_ROCKER), "--t", "2", *extra])
    lines = [ln for ln in result.stdout.splitlines() if not ln.startswith("#") and ln.strip()]
    header = lines[0].split(",")
    return result, header, np.loadtxt(io.StringIO("\n".join(lines[1:])), delimiter=",", ndmin=2)


def test_four_bar_stops_at_its_toggle_naming_the_configuration():
    result, header, data = _simulate_cli("--set", "theta1_dot=-6")
    assert result.exit_code == 3, result.output  # a numerical stop, rows kept
    assert "toggle position" in result.output and "'B.x', 'B.y'" in result.output
    toggle = math.asin(-0.25)  # |A - D| = l2 + l3: 0.6^2 + 0.9^2 - 2 0.6 0.9 sin(theta1) = 1.2^2
    theta1_at_stop = float(result.output.split("theta1=")[1].split(",")[0])
    assert abs(theta1_at_stop - toggle) < 1e-4
    assert np.all(np.isfinite(data)) and len(data) > 5
    col = {name: i for i, name in enumerate(header)}
    assert np.all(data[:, col["theta1"]] >= toggle - 1e-9)  # never beyond the reach
    assert constraint_residual(kronsub.load(TRIPLE_ROCKER).derive(), header, data) <= 1e-9
    energy = data[:, col["total_energy"]]
    assert np.ptp(energy) <= 1e-7 * abs(energy[0])


def test_four_bar_that_does_not_reach_its_toggle_runs_on():
    result, header, data = _simulate_cli()  # theta1_dot = -2: it turns back at theta1 = -0.06
    assert result.exit_code == 0, result.output
    col = {name: i for i, name in enumerate(header)}
    assert data[:, col["theta1"]].min() > math.asin(-0.25) + 0.1
    energy = data[:, col["total_energy"]]
    assert np.ptp(energy) <= 1e-7 * abs(energy[0])
