"""``kronsub simulate``: trajectories against independent references, energy, CSV, faults."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import solve_ivp

import kronsub
from reference import mechanics as ref
from conftest import MODELS, ROOT
from kronsub.cli import main
from kronsub.simulation.run import simulate
from kronsub.simulation.values import resolve

# the 40-digit solution, recomputed independently by tests/data/double_pendulum_reference.py
REFERENCE = ROOT / "tests" / "data" / "double_pendulum_rods.json"


def run_cli(*args):
    return CliRunner().invoke(main, ["simulate", *map(str, args)])


def read_csv(text: str):
    lines = text.splitlines()
    header = lines[0].split(",")
    data = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    return header, data


def _reference_trajectory(reference, values: dict[str, float], y0, t_end, t_eval):
    """Integrate mechanics' M qddot + h = f with scipy at tight tolerance."""
    n = len(reference.coordinates)

    def f(t, y):
        vals = dict(values, t=t)
        vals.update(zip(reference.coordinates, y[:n]))
        vals.update(zip(reference.velocities, y[n:]))
        M, h, fo = ref.numeric(reference, vals)
        return np.concatenate([y[n:], np.linalg.solve(M, fo - h)])

    sol = solve_ivp(f, (0, t_end), y0, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t_eval)
    return sol.y.T


@pytest.mark.parametrize("path, make_reference", [
    ("hoffmann/system1.yaml", ref.system1),
    ("examples/double_pendulum.yaml", ref.double_pendulum),
])
@pytest.mark.parametrize("method", ["dop853", "DOP853"])
def test_trajectory_matches_mechanics_and_scipy(path, make_reference, method):
    model = kronsub.load(MODELS / path)
    system = model.derive()
    values = resolve(system, dict(model.initial), {"F": "0.5"} if "system1" in path else {})
    traj = simulate(system, values, 2.0, 0.5, method, rtol=1e-12, atol=1e-12, progress=False)
    assert traj.complete
    params = {p.name: v for p, v in zip(system.parameters, values.parameters)}
    expected = _reference_trajectory(make_reference(), params, np.array(values.y0), 2.0, traj.t)
    assert np.allclose(traj.y, expected, rtol=1e-8, atol=1e-8)


def test_double_pendulum_of_rods_against_the_high_precision_reference():
    """System I with uniform unit rods is the reference problem (40-digit solution in tests/data)."""
    data = json.loads(REFERENCE.read_text())
    model = kronsub.load(MODELS / "hoffmann" / "system1.yaml")
    system = model.derive()
    values = resolve(system, {}, {"theta": "2*pi/3", "phi": "-pi/18", "F": "0"})
    traj = simulate(system, values, 10.0, 10.0, "dop853", rtol=1e-13, atol=1e-13, progress=False)
    final = traj.y[-1]
    want = [float(data["state_at_t_end"][k]) for k in ("q1", "q2", "u1", "u2")]
    assert traj.t[-1] == 10.0
    assert np.max(np.abs(final - want)) < 1e-7, final - want


CONSERVATIVE = ["hoffmann/system1.yaml", "examples/double_pendulum.yaml", "examples/particle_on_sphere.yaml",
                "examples/watt_governor.yaml", "chain/chain5.yaml", "hoffmann/system2.yaml"]


@pytest.mark.parametrize("path", CONSERVATIVE)
def test_energy_drift_of_conservative_models(path):
    model = kronsub.load(MODELS / path)
    system = model.derive()
    values = resolve(system, dict(model.initial), {})
    traj = simulate(system, values, 10.0, 0.1, "dop853", rtol=1e-13, atol=1e-13, progress=False)
    assert traj.complete, traj.message
    header, data = read_csv(_csv(system, path, traj, values))
    E = data[:, header.index("total_energy")]
    scale = max(abs(E[0]), float(np.max(np.abs(data[:, header.index("kinetic_energy")]))), 1e-300)
    assert np.max(np.abs(E - E[0])) / scale <= 1e-9


def _csv(system, path, traj, values):
    from kronsub.simulation.table import trajectory_csv

    return trajectory_csv(system, path, traj, values, 1e-13, 1e-13)[0]


def test_csv_columns_are_as_documented(tmp_path):
    out = tmp_path / "traj.csv"
    result = run_cli(MODELS / "hoffmann" / "system1.yaml", "--t", "1", "--dt", "0.1", "--output", out, "--points")
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert text.startswith("t,theta,phi,") and "#" not in text
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["model"]["name"] == "System I" and meta["status"] == "complete" and meta["rows"] == 11
    header, data = read_csv(text)
    assert meta["columns"] == header
    assert header[:5] == ["t", "theta", "phi", "theta_dot", "phi_dot"]
    assert header[5:8] == ["kinetic_energy", "potential_energy", "total_energy"]
    assert "lower.centre.x" in header and "upper.tip.y" in header
    assert data.shape == (11, len(header))
    assert np.allclose(data[:, 0], np.linspace(0, 1, 11))
    assert np.allclose(data[:, 7], data[:, 5] + data[:, 6])


def test_set_overrides_parameters_and_initial_state(tmp_path):
    meta = tmp_path / "run.json"
    result = run_cli(MODELS / "hoffmann" / "system1.yaml", "--t", "0.1", "--dt", "0.1",
                     "--set", "theta=0", "--set", "phi=0", "--set", "m2=3", "--meta", meta)
    assert result.exit_code == 0, result.output
    info = json.loads(meta.read_text())
    assert info["parameters"]["m2"] == 3.0 and info["initial_state"]["theta"] == 0.0
    header, data = read_csv(result.stdout)
    assert np.allclose(data[:, 1:5], 0.0)  # hanging at rest stays at rest


def test_missing_parameter_values_are_named(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text("name: x\nparameters:\n  m: {unit: kg}\n  k: 2\ncomponents:\n  p: {type: particle1d, "
                    "parameters: {mass: m}, coordinates: [x]}\ncoordinates: [x]\neffects:\n"
                    "  s: {type: spring, between: [p.centre, [0]], stiffness: k}\n")
    result = run_cli(path, "--t", "1")
    assert result.exit_code == 1
    assert "no value for parameter m" in result.output and "--set m=" in result.output
    assert run_cli(path, "--t", "1", "--set", "m=2").exit_code == 0


def test_unknown_set_name_and_bad_output_fail_before_integrating(tmp_path):
    result = run_cli(MODELS / "hoffmann" / "system1.yaml", "--set", "mm1=2")
    assert result.exit_code == 1 and "mm1" in result.output and "did you mean" in result.output
    result = run_cli(MODELS / "hoffmann" / "system1.yaml", "--output", tmp_path / "missing" / "t.csv")
    assert result.exit_code == 1 and "does not exist" in result.output
    assert "Traceback" not in result.output


def test_nan_stops_the_run_and_keeps_the_rows(tmp_path):
    """A force that blows up at t = 0.5 (1/(t - 1/2)) gives a non-finite state."""
    path = tmp_path / "blowup.yaml"
    path.write_text("name: blow-up\nparameters: {m: 1}\ncomponents:\n  p: {type: particle1d, parameters: {mass: m},"
                    " coordinates: [x]}\ncoordinates: [x]\neffects:\n"
                    "  kick: {type: generalized_force, coordinate: x, value: 1/(t - 1/2)**3}\n")
    out = tmp_path / "t.csv"
    result = run_cli(path, "--t", "1", "--dt", "0.1", "--output", out)
    assert result.exit_code == 3  # numerical failure, rows kept
    assert "stopped at t" in result.output and "Traceback" not in result.output
    text = out.read_text()
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "stopped" and not meta["complete"] and 0.4 < meta["stopped_at"] <= 0.5
    assert meta["stop_reason"] and meta["rows"] == text.count("\n") - 1
    header, data = read_csv(text)
    assert 1 <= len(data) <= 6 and np.all(np.isfinite(data))


def test_gauss4_keeps_energy_bounded_over_a_long_run():
    model = kronsub.load(MODELS / "examples" / "double_pendulum.yaml")
    system = model.derive()
    values = resolve(system, {}, {"q1": "0.5", "q2": "-0.3"})
    traj = simulate(system, values, 200.0, 0.01, "gauss4", progress=False)
    assert traj.complete, traj.message
    from kronsub.simulation.table import energies

    T, V = energies(system, traj, np.array(values.parameters))
    E = T + V
    drift = np.abs(E - E[0]) / np.max(np.abs(T))
    # bounded, not growing: the error over the last quarter is no larger than over the first
    quarter = len(E) // 4
    assert np.max(drift) < 1e-6
    assert np.max(drift[-quarter:]) < 3 * np.max(drift[:quarter]) + 1e-12


def test_singular_mass_matrix_reports_the_configuration(tmp_path):
    """A particle whose mass vanishes: Mbar is not positive definite."""
    path = tmp_path / "singular.yaml"
    path.write_text("name: singular\nparameters: {m: 0}\ncomponents:\n  p: {type: particle1d, parameters: {mass: m},"
                    " coordinates: [x]}\ncoordinates: [x]\ninitial: {x: 0.25}\n")
    for method in ("dop853", "RK45"):
        result = run_cli(path, "--t", "1", "--method", method)
        assert result.exit_code == 3, result.output  # numerical failure
        assert "positive definite" in result.output and "x=0.25" in result.output
        assert "Traceback" not in result.output


def test_without_a_compiler_the_numpy_module_is_used(monkeypatch, tmp_path):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    result = run_cli(MODELS / "examples" / "double_pendulum.yaml", "--t", "0.2", "--dt", "0.1",
                     "--meta", tmp_path / "run.json")
    assert result.exit_code == 0, result.output
    assert "no C compiler" in result.output
    assert json.loads((tmp_path / "run.json").read_text())["right_hand_side"] == "numpy"


def test_plot_writes_a_png(tmp_path):
    pytest.importorskip("matplotlib")
    png = tmp_path / "traj.png"
    result = run_cli(MODELS / "hoffmann" / "system1.yaml", "--t", "1", "--dt", "0.05", "--plot", png,
                     "--output", tmp_path / "t.csv")
    assert result.exit_code == 0, result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_title_is_text_not_mathtext(tmp_path):
    """A model named like broken mathtext is printed as it is: no parse error, no lost plot."""
    pytest.importorskip("matplotlib")
    text = (MODELS / "hoffmann" / "system1.yaml").read_text()
    model = tmp_path / "dollars.yaml"
    model.write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith("name:"))
                     + "\nname: '$\\frac{a}{ cost 5$ ^_'\n")
    png = tmp_path / "traj.png"
    result = run_cli(model, "--t", "0.2", "--dt", "0.05", "--plot", png, "--output", tmp_path / "t.csv")
    assert result.exit_code == 0, result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_heyoka_method_agrees_with_dop853():
    pytest.importorskip("heyoka")
    a = run_cli(MODELS / "hoffmann" / "system1.yaml", "--t", "1", "--dt", "0.5", "--method", "heyoka",
                "--rtol", "1e-14")
    b = run_cli(MODELS / "hoffmann" / "system1.yaml", "--t", "1", "--dt", "0.5", "--rtol", "1e-13", "--atol", "1e-13")
    assert a.exit_code == 0 and b.exit_code == 0, a.output + b.output
    ha, da = read_csv(a.stdout)
    hb, db = read_csv(b.stdout)
    assert ha == hb and np.allclose(da, db, rtol=1e-9, atol=1e-9)


def test_a_start_outside_the_connections_domain_is_named(tmp_path):
    """System II's (26) takes asin((c - a1 sin theta)/a2): with c = 0.9 it has no real value at the
    start. The run says so, not "mass matrix singular" (its entries are NaN, not a singular matrix)."""
    import shutil

    for name in ("system1.yaml", "system2.yaml"):
        shutil.copy(MODELS / "hoffmann" / name, tmp_path / name)
    result = CliRunner().invoke(main, ["simulate", str(tmp_path / "system2.yaml"), "--set", "c=0.9", "--t", "0.1",
                                       "-o", str(tmp_path / "run.csv")])
    assert result.exit_code == 3, result.output
    assert "no real value at this state" in result.output and "mass matrix singular" not in result.output
    assert "theta=0.3" in result.output
