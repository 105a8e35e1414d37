"""The notebook API: system.simulate, system.numeric, system.symbol, Jupyter display."""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
import sympy

import kronsub
from reference import mechanics as mr
from conftest import MODELS, ROOT
from helpers import COMPOUND
from kronsub.errors import KronsubError, ModelError

DOUBLE_PENDULUM = MODELS / "examples" / "double_pendulum.yaml"



@pytest.fixture(scope="module")
def double_pendulum():
    return kronsub.load(DOUBLE_PENDULUM).derive()


@pytest.fixture()
def compound(tmp_path):
    path = tmp_path / "compound.yaml"
    path.write_text(COMPOUND)
    return kronsub.load(path).derive()


def test_simulate_starts_from_the_model_initial_values(double_pendulum):
    run = double_pendulum.simulate(t=1.0, dt=0.1, dataframe=False)
    assert run.columns == ("q1", "q2", "q1_dot", "q2_dot")
    assert run.t[0] == 0 and run.t[-1] == 1.0 and run.y.shape == (11, 4)
    assert run["q1"][0] == pytest.approx(2 * math.pi / 3) and run["q2"][0] == pytest.approx(-math.pi / 18)
    energy = run["total_energy"]
    assert np.ptp(energy) < 1e-7 * abs(energy[0])  # conservation, an invariant of the motion
    assert run.complete


def test_simulate_small_oscillation_is_the_linear_solution(compound):
    """theta(t) = theta0 cos(omega t), omega^2 = m g d / (I + m d^2), for a small theta0."""
    theta0 = 1e-4
    run = compound.simulate(t=3.0, dt=0.05, set={"theta": theta0}, atol=1e-15, rtol=1e-12, dataframe=False)
    m, L, I, g = 2.0, 1.5, 0.3, 9.81
    omega = math.sqrt(m * g * (L / 2) / (I + m * (L / 2) ** 2))
    np.testing.assert_allclose(run["theta"], theta0 * np.cos(omega * run.t), atol=theta0 * 1e-6)
    heavier = compound.simulate(t=3.0, dt=0.05, set={"theta": theta0, "I": "1/2"}, dataframe=False)
    assert heavier.parameters["I"] == 0.5 and not np.allclose(heavier["theta"], run["theta"])


def test_simulate_reports_bad_settings_at_once(double_pendulum):
    with pytest.raises(ModelError) as info:
        double_pendulum.simulate(t=1.0, set={"qq": 1, "m9": 2})
    assert len(info.value.problems) == 2


def test_simulate_gives_a_dataframe_with_pandas(double_pendulum):
    pandas = pytest.importorskip("pandas")
    frame = double_pendulum.simulate(t=0.5, dt=0.1)
    assert isinstance(frame, pandas.DataFrame) and frame.index.name == "t"
    assert list(frame.columns[:4]) == ["q1", "q2", "q1_dot", "q2_dot"] and len(frame) == 6


def test_simulate_gives_arrays_without_pandas(double_pendulum, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas now raises ImportError
    run = double_pendulum.simulate(t=0.5, dt=0.1)
    assert isinstance(run, kronsub.api.Run)
    with pytest.raises(ImportError):
        run.to_dataframe()


def test_numeric_functions_match_the_mechanics_reference(double_pendulum):
    """rhs, mass matrix, energies against sympy.physics.mechanics' own derivation."""
    ref = mr.double_pendulum()
    f = double_pendulum.numeric(set={"m2": 1.3, "l2": 0.7})
    values = {"m1": 1.0, "m2": 1.3, "l1": 1.0, "l2": 0.7, "g": 9.81, "t": 0.0}
    rng = np.random.default_rng(12)
    for _ in range(3):
        y = rng.uniform(-2, 2, 4)
        state = dict(zip(("q1", "q2", "q1_dot", "q2_dot"), y))
        M, h, force = mr.numeric(ref, {**values, **state})
        np.testing.assert_allclose(f.mass_matrix(y[:2]), M, rtol=1e-12)
        np.testing.assert_allclose(f.rhs(0.0, y), np.concatenate([y[2:], np.linalg.solve(M, force - h)]),
                                   rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(f.forces(0.0, y) - f.velocity_terms(y), force - h, rtol=1e-10, atol=1e-12)
        subs = {sympy.Symbol(k): v for k, v in {**values, **state}.items()}
        assert f.kinetic_energy(y) == pytest.approx(float(ref.kinetic_energy.xreplace(subs)), rel=1e-12)
        assert f.potential_energy(0.0, y) == pytest.approx(float(ref.potential_energy.xreplace(subs)), rel=1e-12)
    assert f.parameters["m2"] == 1.3 and f.state == ("q1", "q2", "q1_dot", "q2_dot")


def test_numeric_makes_the_numpy_module_only_when_asked_and_within_the_budget(double_pendulum, monkeypatch):
    """rhs and the energies come from the C; the numpy module (mass matrix, forces, velocity
    terms) is made at the first call that needs it, once, under the work budget: a system whose
    symbolic projection is beyond it (the bicycle's model file) stops there with a hint instead
    of running without end."""
    import shutil

    import kronsub.simulation.fallback as fallback
    from kronsub import budget

    if not (shutil.which("gcc") or shutil.which("cc")):
        pytest.skip("no C compiler")
    made = []
    real = fallback.numpy_module
    monkeypatch.setattr(fallback, "numpy_module", lambda *a, **k: made.append(budget.active()) or real(*a, **k))
    f = double_pendulum.numeric()
    y = np.array([0.3, -0.2, 0.1, 0.4])
    f.rhs(0.0, y), f.kinetic_energy(y)
    assert made == []
    f.mass_matrix(y[:2]), f.forces(0.0, y), f.velocity_terms(y)
    assert len(made) == 1 and made[0] is not None


def test_symbol_by_name_is_the_systems_own(double_pendulum):
    g = double_pendulum.symbol("g")
    assert g in double_pendulum.forces.free_symbols
    assert sympy.Symbol("g") not in double_pendulum.forces.free_symbols  # why symbol() exists
    q1_dot = double_pendulum.symbol("q1_dot")
    assert q1_dot in double_pendulum.velocities
    with pytest.raises(KronsubError, match="did you mean 'g'"):
        double_pendulum.symbol("gg")


def test_jupyter_display(double_pendulum):
    md = double_pendulum._repr_markdown_()
    assert md.startswith("# Double pendulum") and "## Equations of motion" in md
    tex = double_pendulum._repr_latex_()
    assert tex.startswith("$$\\begin{aligned}") and tex.endswith("$$") and "\\ddot{q_{1}}" in tex
    assert tex.count("&=") == 2


def test_the_core_does_not_import_the_simulation():
    """Loading and deriving import the notebook face (kronsub.api), whose System imports the
    simulation only when one of its conveniences needs it."""
    code = ("import sys, kronsub; s = kronsub.load(sys.argv[1]).derive(); s.symbol('g'); "
            "print(sorted(m for m in sys.modules if m.startswith(('kronsub.simulation', 'kronsub.api'))))")
    out = subprocess.run([sys.executable, "-c", code, str(DOUBLE_PENDULUM)], capture_output=True, text=True,
                         cwd=ROOT, check=True).stdout
    assert out.strip() == "['kronsub.api', 'kronsub.api.naming', 'kronsub.api.outputs', 'kronsub.api.runs', " \
                          "'kronsub.api.sweeps', 'kronsub.api.system', 'kronsub.simulation', " \
                          "'kronsub.simulation.span']"  # the run's defaults (no engine); no other simulation module  # the notebook face, its rooms; no kronsub.simulation


def test_the_notebook_system_is_the_known_system_with_conveniences(double_pendulum):
    """KnownSystem is pure data; api.System adds the conveniences and goes wherever it does."""
    import dataclasses

    from kronsub.core.known_system import KnownSystem

    assert isinstance(double_pendulum, kronsub.api.System) and isinstance(double_pendulum, KnownSystem)
    for name in ("symbol", "simulate", "numeric", "linearize", "_repr_markdown_", "_repr_latex_"):
        assert not hasattr(KnownSystem, name) and callable(getattr(double_pendulum, name))
    known = KnownSystem(**{f.name: getattr(double_pendulum, f.name) for f in dataclasses.fields(KnownSystem)})
    again = kronsub.api.System.of(known)
    assert again == dataclasses.replace(double_pendulum) and again.mass_matrix == double_pendulum.mass_matrix
    assert again.symbol("g") is double_pendulum.symbol("g")


def test_simulate_a_model_with_implicit_constraints():
    """System II written with its constraint (25): the run keeps its energy (F = 0)."""
    system = kronsub.load(MODELS / "hoffmann" / "system2_implicit.yaml").derive()
    run = system.simulate(t=1.0, dt=0.1, dataframe=False)
    assert run.columns == ("theta", "theta_dot") and run.complete
    assert run["theta"][0] == pytest.approx(0.3)
    energy = run["total_energy"]
    assert np.ptp(energy) < 1e-7 * max(1.0, abs(energy[0]))


FOUR_BAR = MODELS / "examples" / "four_bar.yaml"


def test_every_name_of_the_printed_equations_is_reachable():
    """A closed loop's dependent coordinates and named intermediates (26)-(29) by name."""
    system = kronsub.load(FOUR_BAR).derive()
    printed = set().union(system.mass_matrix.free_symbols, system.velocity_terms.free_symbols,
                          *(f.free_symbols for f in system.effect_forces.values()))
    assert {"theta2", "theta3", "lambda_theta2_theta1", "gamma_theta3"} <= {s.name for s in printed}
    for s in printed:  # the same symbol: name and assumptions (one object unless sympy's cache was cleared)
        assert system.symbol(s.name) == s
    for name, value in system.implicit.definitions:  # the closed forms printed under the equations
        assert system.symbol(name.name) == name and value.free_symbols <= set(kronsub.api.names(system).values())


def test_a_closed_loop_run_has_the_columns_and_numbers_of_the_command_line(tmp_path):
    """``system.simulate()`` and ``kronsub simulate`` from the same model: the same CSV columns
    (the dependent coordinates among them), the same numbers, the same metadata."""
    from click.testing import CliRunner

    from kronsub.cli import main
    from kronsub.errors import KronsubError

    meta = tmp_path / "run.json"
    result = CliRunner().invoke(main, ["simulate", str(FOUR_BAR), "--t", "0.3", "--dt", "0.05", "--set", "tau=0.5",
                                       "--reactions", "--meta", str(meta)])
    assert result.exit_code == 0, result.output
    header, *rows = result.stdout.splitlines()
    run = kronsub.load(FOUR_BAR).derive().simulate(t=0.3, dt=0.05, set={"tau": 0.5}, reactions=True,
                                                    dataframe=False)
    assert run.table_columns == tuple(header.split(",")) and {"theta2", "theta3"} <= set(run.table_columns)
    assert np.array_equal(run.table, np.array([[float(x) for x in r.split(",")] for r in rows]))
    assert run["theta2"].shape == (7,) and run.notes  # the projection's corrections, as the CLI's notes
    expected = json.loads(meta.read_text())
    for key in ("model", "scene", "method", "parameters", "initial_state", "dependent_coordinates", "columns",
                "status", "rows"):
        assert run.metadata[key] == expected[key], key
    pandas = pytest.importorskip("pandas")
    frame = kronsub.load(FOUR_BAR).derive().simulate(t=0.3, dt=0.05, set={"tau": 0.5}, reactions=True)
    assert isinstance(frame, pandas.DataFrame) and list(frame.columns) == header.split(",")[1:]
    assert np.array_equal(frame.to_numpy(), run.table[:, 1:]) and np.array_equal(frame.index, run.t)
    assert frame.attrs["metadata"]["dependent_coordinates"] == expected["dependent_coordinates"]


def test_codegen_writes_the_files_of_the_command_line(tmp_path):
    from click.testing import CliRunner

    from kronsub.cli import main
    from kronsub.errors import KronsubError

    model = MODELS / "hoffmann" / "system1.yaml"
    result = CliRunner().invoke(main, ["codegen", str(model), "-o", str(tmp_path / "cli"), "--scene", "pushed"])
    assert result.exit_code == 0, result.output
    written = kronsub.load(model).derive(scene="pushed").codegen(tmp_path / "api")
    assert sorted(p.name for p in written) == sorted(p.name for p in (tmp_path / "cli").iterdir())
    for path in written:
        assert path.read_text() == (tmp_path / "cli" / path.name).read_text()


def test_reactions_are_the_text_of_derive_reactions():
    from click.testing import CliRunner

    from kronsub.cli import main
    from kronsub.errors import KronsubError

    model = MODELS / "hoffmann" / "system2_implicit.yaml"
    result = CliRunner().invoke(main, ["derive", str(model), "--reactions"])
    assert result.exit_code == 0, result.output
    assert kronsub.load(model).derive().reactions() == result.stdout


def test_accuracy_and_animate_from_the_notebook(tmp_path):
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive(scene="free")
    result = system.accuracy(t=0.2, methods="dop853,RK45", tolerances="1e-5,1e-7", quick=True)
    assert sorted((p.method, p.setting) for p in result.measurement.points) == \
        [("RK45", "tol 1e-05"), ("RK45", "tol 1e-07"), ("dop853", "tol 1e-05"), ("dop853", "tol 1e-07")]
    assert all(p.error < 1e-3 for p in result.measurement.points)  # against the reference
    assert result.to_csv().startswith("method,") and result.metadata()["scene"] == "free"
    pytest.importorskip("matplotlib")
    frames = system.animate(tmp_path / "free.gif", t=0.2, fps=10)
    assert frames == 3 and (tmp_path / "free.gif").stat().st_size > 0


def test_errors_name_the_keyword_arguments_the_command_line_its_options():
    """A wrong value given to the API is named as it was given there (``t``, ``set['m1']``,
    ``scene='nope'``), the same wrong value on the command line by its option (``--t``,
    ``--set m1``, ``--scene nope``); a command run in the same process leaves the API's spelling
    as it was."""
    from click.testing import CliRunner

    from kronsub.cli import main
    from kronsub.errors import KronsubError

    path = str(MODELS / "hoffmann" / "system1.yaml")
    system = kronsub.load(path).derive()
    wrong = [({"t": -1}, "t must be a positive finite time", ["--t", "-1"], "--t must be"),
             ({"t": 1, "dt": 0}, "dt must be a positive finite interval", ["--t", "1", "--dt", "0"], "--dt must be"),
             ({"t": 1, "set": {"m1": -1}}, "set['m1']: mass of component 'upper' must not be negative",
              ["--set", "m1=-1"], "--set m1: mass of component"),
             ({"t": 1, "rtol": -1}, "rtol must be a finite tolerance", ["--rtol", "-1"], "--rtol must be"),
             ({"t": 1, "set": {"nope": 1}}, "set['nope']: no parameter", ["--set", "nope=1"], "--set nope: no param")]
    for kwargs, said, args, told in wrong:
        with pytest.raises(KronsubError) as caught:
            system.simulate(**kwargs)
        assert said in str(caught.value) and "--" not in str(caught.value), str(caught.value)
        result = CliRunner().invoke(main, ["simulate", path, *args])
        assert result.exit_code in (1, 2) and told in result.output, result.output
    with pytest.raises(KronsubError) as caught:
        kronsub.load(path).derive(scene="nope")
    assert "scene='nope': " in str(caught.value) and "--scene" not in str(caught.value)
    assert "--scene nope: " in CliRunner().invoke(main, ["derive", path, "--scene", "nope"]).output
    for kwargs, said in [({"sample": {"m1": "uniform(1, 2)"}}, "sample needs runs=N"),
                         ({"grid": {"m1": "2:1:3"}}, "grid['m1']=2:1:3: the grid of m1 is inverted")]:
        with pytest.raises(KronsubError) as caught:
            system.sweep(t=0.1, **kwargs)
        assert said in str(caught.value) and "--" not in str(caught.value), str(caught.value)
