"""`coordinates: auto` during a run: the independent coordinates change where G_d nears singular.

System II with (25) and `coordinates: auto` picks phi independent; driven hard, the
mechanism passes theta = pi/2, where dg/dtheta = a1 cos(theta) vanishes and phi can no longer
be independent. The run switches to theta and back as often as needed and goes on.
Independent routes: the total energy is kept (no non-conservative load) and the constraint
residual, evaluated from the CSV apart from the generated code, stays at rounding level;
the run passes configurations no single choice covers; the first choice alone stops there.
"""
from __future__ import annotations

import io
import json
import shutil

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from conftest import MODELS
from helpers import constraint_residual
from kronsub.cli import main


@pytest.fixture()
def auto_model(tmp_path):
    shutil.copy(MODELS / "hoffmann" / "system1.yaml", tmp_path / "system1.yaml")
    text = (MODELS / "hoffmann" / "system2_implicit.yaml").read_text(encoding="utf-8")
    lines = ["coordinates: auto" if line.startswith("coordinates:") else line for line in text.splitlines()]
    path = tmp_path / "system2_auto.yaml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _table(stdout: str):
    lines = [ln for ln in stdout.splitlines() if not ln.startswith("#") and ln.strip()]
    return lines[0].split(","), np.loadtxt(io.StringIO("\n".join(lines[1:])), delimiter=",", ndmin=2)


@pytest.mark.parametrize("method", ["dop853", "Radau"])
def test_auto_switches_through_the_toggle_and_keeps_the_loop_closed(auto_model, method, tmp_path):
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(auto_model), "--t", "0.8", "--method", method,
                                       "--set", "phi_dot=-15", "--set", "F=0", "-o", str(out)])
    assert result.exit_code == 0, result.output
    switches = json.loads(out.with_suffix(".json").read_text())["coordinate_switches"]
    assert len(switches) >= 2, switches
    assert "independent coordinates phi -> theta (dg/d(theta) nearly singular)" in switches[0]["what"]
    assert 0 < switches[0]["t"] < switches[1]["t"] <= 0.8
    assert "note: coordinates: auto switched at t = " in result.stderr
    assert not any(line.startswith("#") for line in out.read_text().splitlines())  # the switches: in the JSON
    header, data = _table(out.read_text())
    col = {c: i for i, c in enumerate(header)}
    assert header[:3] == ["t", "phi", "phi_dot"] and "theta" in col  # the first choice's columns throughout
    assert np.all(np.isfinite(data)) and np.allclose(np.diff(data[:, 0]), 0.01)
    theta = data[:, col["theta"]]
    assert theta.max() > np.pi / 2 + 0.3  # past the toggle of the first choice
    system = kronsub.load(auto_model).derive()
    assert constraint_residual(system, header, data) <= 1e-9
    energy = data[:, col["total_energy"]]
    assert np.max(np.abs(energy - energy[0])) <= 1e-6 * abs(energy[0])


def test_given_coordinates_stop_at_the_same_toggle_with_a_clear_error(auto_model):
    text = auto_model.read_text(encoding="utf-8").replace("coordinates: auto", "coordinates: [phi]")
    auto_model.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["simulate", str(auto_model), "--t", "1.5", "--set", "phi_dot=-15",
                                       "--set", "F=0"])
    assert result.exit_code == 3, result.output
    assert "toggle position" in result.output and "'line'" in result.output and "t = " in result.output


@pytest.mark.parametrize("independent, push", [("phi", "phi_dot=-15"), ("theta", "theta_dot=15")])
def test_a_stop_at_a_toggle_blames_the_choice_not_the_mechanism(auto_model, independent, push):
    """Listed coordinates that go singular stop the run with a message that names them as what is
    singular there (Newton's method for phi independent, the closed form's asin for theta), never
    that the mechanism cannot reach the configuration, and points at `coordinates: auto`."""
    text = auto_model.read_text(encoding="utf-8").replace("coordinates: auto", f"coordinates: [{independent}]")
    auto_model.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["simulate", str(auto_model), "--t", "1.5", "--set", push, "--set", "F=0"])
    assert result.exit_code == 3, result.output
    assert f"the independent coordinates chosen ({independent})" in result.output, result.output
    assert "cannot reach" not in result.output and "cannot take" not in result.output
    assert "hint: only the independent coordinates chosen are singular there: with `coordinates: auto`" \
        in result.output


def test_a_closed_loop_naming_no_coordinates_picks_them_as_auto(auto_model):
    """Without `coordinates:`, a model with constraints derives as with `coordinates: auto`."""
    auto = CliRunner().invoke(main, ["derive", str(auto_model), "--format", "json"])
    bare = auto_model.with_name("bare.yaml")
    bare.write_text(auto_model.read_text(encoding="utf-8").replace("coordinates: auto\n", ""), encoding="utf-8")
    none = CliRunner().invoke(main, ["derive", str(bare), "--format", "json"])
    assert auto.exit_code == 0 and none.exit_code == 0, none.output
    assert json.loads(none.stdout) == json.loads(auto.stdout)


@pytest.mark.parametrize("method", ["RK45", "Radau", "LSODA"])
def test_scipy_methods_stop_at_the_toggle_and_keep_the_rows_before(auto_model, method, tmp_path):
    """scipy's solvers are stepped one step at a time: the rows before the failure are kept (not
    lost with the whole call), an implicit method creeping towards the toggle in steps of 1e-12
    stops (run.STALL_STEPS) instead of running for ever, and the configuration named is the last
    one reached, not an integrator's trial stage."""
    text = auto_model.read_text(encoding="utf-8").replace("coordinates: auto", "coordinates: [phi]")
    auto_model.write_text(text, encoding="utf-8")
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(auto_model), "--t", "1.5", "--set", "phi_dot=-15",
                                       "--set", "F=0", "--method", method, "-o", str(out)])
    assert result.exit_code == 3, result.output
    assert "toggle position" in result.output and "the run stopped at t = 0.16" in result.output
    phi = float(result.output.split("phi=")[1].split(",")[0])
    assert abs(phi) < 1.0, result.output
    header, data = _table(out.read_text())
    assert len(data) >= 15 and np.all(np.isfinite(data)) and data[-1, 0] >= 0.15
    assert json.loads(out.with_suffix(".json").read_text())["complete"] is False


def test_reactions_across_switches_match_the_multipliers_of_the_run(auto_model, tmp_path):
    """`--reactions` on a run that switches: each stretch is evaluated with the choice that
    computed it. Independent route: the multiplier of `M_y yddot + h_y = f_y + G^T mu` by least
    squares, with `yddot` from finite differences of the CSV's own rows (no generated code).
    The first choice's closed form of theta is on the wrong branch past its toggle: evaluating
    every row with it gave mu = 40.2 where the run's mechanism needs 8.8."""
    from kronsub.core.symbols import velocity_symbol

    out, h = tmp_path / "run.csv", 0.0005
    result = CliRunner().invoke(main, ["simulate", str(auto_model), "--t", "0.8", "--dt", str(h), "--reactions",
                                       "--set", "phi_dot=-15", "--set", "F=0", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert len(json.loads(out.with_suffix(".json").read_text())["coordinate_switches"]) >= 2
    header, data = _table(out.read_text())
    col = {c: i for i, c in enumerate(header)}
    system = kronsub.load(auto_model).derive()
    imp = system.implicit
    y = list(imp.intermediate)
    values = {p.symbol: p.value for p in system.parameters}
    values[next(p.symbol for p in system.parameters if p.name == "F")] = 0.0
    yd = [velocity_symbol(c) for c in y]
    t = sympy.Symbol("t", real=True)
    M = sympy.lambdify(y, imp.metric.xreplace(values))
    hv = sympy.lambdify(y + yd, imp.velocity_terms.xreplace(values))
    f = sympy.lambdify([t] + y + yd, imp.forces.xreplace(values))
    G = sympy.lambdify(y, sympy.Matrix([c.expression for c in imp.constraints]).jacobian(y).xreplace(values))
    Y = np.column_stack([data[:, col[c.name]] for c in y])
    Yd = np.gradient(Y, h, axis=0, edge_order=2)
    Ydd = np.gradient(Yd, h, axis=0, edge_order=2)
    mu, scale = col["mu_line"], np.max(np.abs(data[:, col["mu_line"]]))
    checked = 0
    for i in range(10, len(data) - 10, 20):
        r = (np.asarray(M(*Y[i]), float) @ Ydd[i] + np.ravel(np.asarray(hv(*Y[i], *Yd[i]), float))
             - np.ravel(np.asarray(f(data[i, 0], *Y[i], *Yd[i]), float)))
        expected = np.linalg.lstsq(np.asarray(G(*Y[i]), float).T, r, rcond=None)[0][0]
        assert abs(data[i, mu] - expected) <= 2e-3 * scale, (data[i, 0], data[i, mu], expected)
        checked += 1
    assert checked >= 70


@pytest.mark.parametrize("method, dt, hints", [("gauss4", "0.1", ["gauss4 takes fixed steps of --dt 0.1"]),
                                               ("dop853", "0.05", ["only the independent coordinates chosen are "
                                                                   "singular there: with `coordinates: auto`"])])
def test_a_stopped_closed_loop_run_says_what_would_go_on(auto_model, method, dt, hints, tmp_path):
    """A fixed step that jumps past what the mechanism can reach points to --dt; a toggle position
    of given coordinates points to `coordinates: auto`; a configuration that still solves is not
    called unsolvable (the step from it is)."""
    text = auto_model.read_text(encoding="utf-8").replace("coordinates: auto", "coordinates: [phi]")
    auto_model.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["simulate", str(auto_model), "--t", "1.5", "--dt", dt, "--method", method,
                                       "--set", "phi_dot=-15", "--set", "F=0", "-o", str(tmp_path / "run.csv")])
    assert result.exit_code == 3, result.output
    for hint in hints:
        assert f"hint: {hint}" in result.output
    if "could not be solved" in result.output:
        assert "where they still have a solution" in result.output
    assert "1 rows" not in result.output
