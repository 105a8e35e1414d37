"""The energies of a run with circuit parts split by kind, and the dissipated power
(simulation/power.py): each column at every row against the formula written here from the
CSV's state and the parameters, and the energy balance
``d/dt (magnetic + electric + mechanical) = P_source - P_dissipated - P_load`` integrated with
the trapezoid rule over the run."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from conftest import MODELS
from kronsub.cli import main

CIRCUITS = MODELS / "electrical"
TEST_MODELS = Path(__file__).parent / "models" / "electrical"
SPLIT = ["magnetic_energy", "electric_energy", "mechanical_energy", "dissipated_power"]


def simulated(tmp_path, path, *args):
    """The CSV as a dict of columns, and the sidecar's metadata."""
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(path), "--rtol", "1e-11", "--atol", "1e-12",
                                       "-o", str(out), *args])
    assert result.exit_code == 0, result.output
    header = out.read_text().splitlines()[0].split(",")
    data = np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)
    return {name: data[:, k] for k, name in enumerate(header)}, json.loads(out.with_suffix(".json").read_text())


def trapezoid(t, power):
    """The work of ``power`` from the first row to each row, by the trapezoid rule."""
    return np.concatenate([[0.0], np.cumsum((power[1:] + power[:-1]) / 2 * np.diff(t))])


def work(t, power):
    """The work to every other row: the trapezoid rule over the rows, extrapolated with the
    rule over every other row (Romberg's first step, ``(4 T_h - T_2h)/3``), so the quadrature
    error is fourth order in the row spacing and the balance is checked near the run's own
    accuracy."""
    fine, coarse = trapezoid(t, power)[::2], trapezoid(t[::2], power[::2])
    return fine + (fine - coarse) / 3


def assert_balance(c, supplied, load, jumps=()):
    """``E(t) - E(0) = int (P_source - P_dissipated - P_load) dt`` at every other row (but those
    at ``jumps``, where a power steps and the rule is exact over whole intervals only)."""
    stored = c["magnetic_energy"] + c["electric_energy"] + c["mechanical_energy"]
    net = work(c["t"], supplied - c["dissipated_power"] - load)
    scale = np.max(np.abs(stored)) + np.max(np.abs(trapezoid(c["t"], c["dissipated_power"])))
    rows = ~np.isin(c["t"][::2], jumps)
    assert np.max(np.abs(stored[::2] - stored[0] - net)[rows]) < 1e-5 * scale
    np.testing.assert_allclose(stored, c["total_energy"], rtol=1e-12, atol=1e-12 * scale)


def test_dc_motor_columns_and_energy_balance(tmp_path):
    """Armature: magnetic ``L i^2/2``, heat ``R i^2``; rotor: ``J omega^2/2``, friction
    ``f omega^2``; the supply gives ``V i``, the load takes ``tau_L omega`` after ``t_load``;
    the gyrator moves power between them and adds none."""
    c, meta = simulated(tmp_path, CIRCUITS / "dc_motor.yaml")
    R, L, J, f, V, tau, t_load = 0.5, 4.5e-3, 0.02, 0.01, 1.0, 0.25, 1.0
    i, omega = c["i"], c["theta_dot"]
    np.testing.assert_allclose(c["magnetic_energy"], L * i**2 / 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(c["electric_energy"], 0.0)
    np.testing.assert_allclose(c["mechanical_energy"], J * omega**2 / 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(c["dissipated_power"], R * i**2 + f * omega**2, rtol=1e-12, atol=1e-15)
    assert meta["columns"][-4:] == SPLIT
    assert np.max(c["magnetic_energy"]) > 0 and np.max(c["mechanical_energy"]) > 0
    load = tau * (1 + np.sign(c["t"] - t_load)) / 2 * omega
    assert_balance(c, V * i, load, jumps=[t_load])
    with pytest.raises(AssertionError):  # the balance notices a power left out: the load's
        assert_balance(c, V * i, 0 * load, jumps=[t_load])


@pytest.mark.parametrize("scene, E", [("step", 10.0), ("discharge", 0.0)])
def test_series_rlc_columns_and_energy_balance(tmp_path, scene, E):
    """``L i^2/2`` in the coil, ``q^2/(2 C)`` in the capacitor, nothing mechanical, ``R i^2``
    in the resistor; the source (switched off in ``discharge``) gives ``E i``."""
    c, _ = simulated(tmp_path, CIRCUITS / "series_rlc.yaml", "--scene", scene)
    L, R, C = 0.5, 1.0, 0.02
    q, i = c["q"], c["i"]
    np.testing.assert_allclose(c["magnetic_energy"], L * i**2 / 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(c["electric_energy"], q**2 / (2 * C), rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(c["mechanical_energy"], 0.0)
    np.testing.assert_allclose(c["dissipated_power"], R * i**2, rtol=1e-12, atol=1e-15)
    assert_balance(c, E * i, 0 * i)


def test_ladder_shared_capacitor_takes_the_difference_of_the_loop_charges(tmp_path):
    """Two meshes: the shunt capacitor holds ``(q1 - q2)^2/(2 C1)``, the currents of the
    branches are the loop currents carried by the mesh transformation."""
    c, _ = simulated(tmp_path, CIRCUITS / "rlc_ladder.yaml", "--t", "0.5", "--dt", "0.0005")
    L1, L2, R1, R2, C1, C2, E = 0.1, 0.2, 2.0, 5.0, 0.01, 0.005, 12.0
    q1, q2, i1, i2 = c["q1"], c["q2"], c["i_1"], c["i_2"]
    np.testing.assert_allclose(c["magnetic_energy"], L1 * i1**2 / 2 + L2 * i2**2 / 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(c["electric_energy"], (q1 - q2) ** 2 / (2 * C1) + q2**2 / (2 * C2),
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(c["dissipated_power"], R1 * i1**2 + R2 * i2**2, rtol=1e-12, atol=1e-15)
    assert_balance(c, E * i1, 0 * i1)


def test_node_equations_split_as_the_meshes_do(tmp_path):
    """The ladder by node equations (a closed loop whose dependent charges have closed forms):
    the same formulas in the coil charges, and the columns of the mesh form at every row."""
    c, _ = simulated(tmp_path, CIRCUITS / "rlc_ladder_nodes.yaml", "--t", "0.5", "--dt", "0.0005")
    mesh, _ = simulated(tmp_path, CIRCUITS / "rlc_ladder.yaml", "--t", "0.5", "--dt", "0.0005")
    L1, L2, R1, R2, C1, C2, E = 0.1, 0.2, 2.0, 5.0, 0.01, 0.005, 12.0
    q1, q2, i1, i2 = c["q_L1"], c["q_L2"], c["i_L1"], c["i_L2"]
    np.testing.assert_allclose(c["magnetic_energy"], L1 * i1**2 / 2 + L2 * i2**2 / 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(c["electric_energy"], (q1 - q2) ** 2 / (2 * C1) + q2**2 / (2 * C2),
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(c["dissipated_power"], R1 * i1**2 + R2 * i2**2, rtol=1e-12, atol=1e-15)
    for name in SPLIT:
        np.testing.assert_allclose(c[name], mesh[name], rtol=1e-7, atol=1e-9)
    assert_balance(c, E * i1, 0 * i1)


def test_textbook_charges_split_the_magnet_energy(tmp_path):
    """``charges: [q]`` of the magnet's textbook equations: ``L(y) i^2/2`` magnetic, ``m ydot^2/2
    - m g y`` mechanical, ``k ydot^2 + R i^2`` dissipated; the balance with the source's ``v i``."""
    c, _ = simulated(tmp_path, CIRCUITS / "magnetic_suspension.yaml", "--scene", "falling", "--t", "0.1",
                     "--dt", "0.0002")
    system = kronsub.load(CIRCUITS / "magnetic_suspension.yaml").derive(scene="falling")
    p = {s.name: float(s.value) for s in system.parameters}
    y, ydot, i = c["y"], c["y_dot"], c["i"]
    L = p["L1"] + p["L0"] * p["a"] / (p["a"] + y)
    np.testing.assert_allclose(c["magnetic_energy"], L * i**2 / 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(c["mechanical_energy"], p["m"] * ydot**2 / 2 - p["m"] * p["g"] * y,
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(c["dissipated_power"], p["k"] * ydot**2 + p["R"] * i**2, rtol=1e-12, atol=1e-15)
    assert_balance(c, p["v"] * i, 0 * i)


def test_textbook_charges_split_the_machine_energy(tmp_path):
    """The synchronous machine's phases and field are its charges: the mechanical energy is the
    rotor's ``J omega^2/2``, the rest of ``T`` magnetic; the field's source feeds the balance."""
    c, _ = simulated(tmp_path, CIRCUITS / "machine.yaml", "--scene", "short_circuit", "--t", "0.02",
                     "--dt", "0.0001")
    J, vf = 0.5, 5.0
    np.testing.assert_allclose(c["mechanical_energy"], J * c["theta_dot"] ** 2 / 2, rtol=1e-9)
    np.testing.assert_allclose(c["magnetic_energy"] + c["mechanical_energy"], c["kinetic_energy"], rtol=1e-12)
    assert_balance(c, vf * c["i_f"], 0 * c["t"])


@pytest.mark.parametrize("path", [CIRCUITS / "loudspeaker.yaml", TEST_MODELS / "loudspeaker_textbook.yaml"])
def test_loudspeaker_dampers_and_springs_are_mechanical(tmp_path, path):
    """The cone's suspension (a spring and a damper, or the cone's own textbook potential and
    dissipation) is mechanical; the voice coil's resistance and the cone's losses both dissipate."""
    c, _ = simulated(tmp_path, path, "--t", "0.02", "--dt", "0.00002")
    Le, Re, Mms, Cms, Rms, E, w = 0.5e-3, 6.0, 0.015, 0.8e-3, 1.5, 2.0, 400.0
    x, i, v = c["x"], c["i"], c["x_dot"]
    np.testing.assert_allclose(c["magnetic_energy"], Le * i**2 / 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(c["electric_energy"], 0.0)
    np.testing.assert_allclose(c["mechanical_energy"], Mms * v**2 / 2 + x**2 / (2 * Cms), rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(c["dissipated_power"], Re * i**2 + Rms * v**2, rtol=1e-12, atol=1e-15)
    assert np.max(c["mechanical_energy"]) > 0.1 * np.max(c["magnetic_energy"]) > 0
    assert_balance(c, E * np.sin(w * c["t"]) * i, 0 * i)


def test_api_run_has_the_columns_of_the_csv(tmp_path):
    """The notebook's Run table is the CSV's: the same columns, the same numbers."""
    run = kronsub.load(CIRCUITS / "series_rlc.yaml").derive(scene="step").simulate(
        t=0.1, dt=0.01, rtol=1e-11, atol=1e-12, dataframe=False)
    c, _ = simulated(tmp_path, CIRCUITS / "series_rlc.yaml", "--scene", "step", "--t", "0.1", "--dt", "0.01")
    assert list(run.table_columns) == list(c) and run.metadata["columns"] == list(c)
    for name in SPLIT:
        np.testing.assert_array_equal(run[name], c[name])


@pytest.mark.parametrize("path", ["hoffmann/system1.yaml", "examples/four_bar.yaml"])
def test_models_without_circuit_parts_keep_their_columns(tmp_path, path):
    c, meta = simulated(tmp_path, MODELS / path, "--t", "0.02", "--dt", "0.01")
    assert not set(SPLIT) & set(c) and not set(SPLIT) & set(meta["columns"])
    assert "dissipated_power" not in meta["units"]


def test_a_machine_used_as_a_known_system_splits_as_the_machine(tmp_path):
    """The machine of machine.yaml on an infinite bus: its own dissipation (a known system's
    effect) is ``Rs (i_a^2 + i_b^2 + i_c^2) + Rf i_f^2 + D omega^2``, its rotor's ``J omega^2/2``
    is the mechanical energy, and the bus and the exciter supply what is stored and lost."""
    c, _ = simulated(tmp_path, CIRCUITS / "synchronous_machine.yaml", "--t", "0.02", "--dt", "0.0001")
    J, D, Rs, Rf, vf, Vm, w = 0.5, 0.02, 0.05, 0.5, 5.0, 100.0, 314.159
    ia, ib, ic, i_f, omega, t = c["i_a"], c["i_b"], c["i_c"], c["i_f"], c["theta_dot"], c["t"]
    np.testing.assert_allclose(c["mechanical_energy"], J * omega**2 / 2, rtol=1e-9)
    np.testing.assert_allclose(c["magnetic_energy"] + c["mechanical_energy"], c["kinetic_energy"], rtol=1e-12)
    np.testing.assert_allclose(c["dissipated_power"], Rs * (ia**2 + ib**2 + ic**2) + Rf * i_f**2 + D * omega**2,
                               rtol=1e-12)
    np.testing.assert_array_equal(c["electric_energy"], 0.0)
    bus = Vm * (np.cos(w * t) * ia + np.cos(w * t - 2 * np.pi / 3) * ib + np.cos(w * t + 2 * np.pi / 3) * ic)
    assert_balance(c, bus + vf * i_f, 0 * t)


def test_the_machine_pair_splits_each_machine(tmp_path):
    """Two machines through one loop charge per phase: each phase current flows in both
    stators (``Rs`` twice), each field and rotor its own; the shafts' torques do the work."""
    c, _ = simulated(tmp_path, CIRCUITS / "machine_pair.yaml", "--t", "0.02", "--dt", "0.0001")
    J, D, Rs, Rf, vf, Tm1, Tm2 = 0.5, 0.02, 0.05, 0.5, 5.0, 3.0, -3.0
    w1, w2 = c["th1_dot"], c["th2_dot"]
    phases = c["i_a"] ** 2 + c["i_b"] ** 2 + c["i_c"] ** 2
    np.testing.assert_allclose(c["mechanical_energy"], J * (w1**2 + w2**2) / 2, rtol=1e-9)
    np.testing.assert_allclose(c["dissipated_power"], 2 * Rs * phases + Rf * (c["i_f1"] ** 2 + c["i_f2"] ** 2)
                               + D * (w1**2 + w2**2), rtol=1e-12)
    assert_balance(c, vf * (c["i_f1"] + c["i_f2"]) + Tm1 * w1 + Tm2 * w2, 0 * c["t"])


def test_a_split_with_no_value_at_a_row_is_nan_and_the_run_says_why(tmp_path):
    """A capacitance C t through zero at the start: the electric energy q^2/(2 C t) has no value
    there (a division by zero in Python's floats): that row's columns are NaN, the rows are kept
    and the run stops with a located reason, never an internal error."""
    text = (CIRCUITS / "series_rlc.yaml").read_text()
    model = tmp_path / "rlc.yaml"
    model.write_text(text.replace("charge: q_C, capacitance: C}", "charge: q_C, capacitance: C*t}"))
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(model), "--t", "1", "-o", str(out)])
    assert result.exit_code == 3, result.output
    assert "internal error" not in result.output and "division by zero" in result.output
    header = out.read_text().splitlines()[0].split(",")
    row = np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)[0]
    assert all(np.isnan(row[header.index(name)]) for name in SPLIT[1:3])
