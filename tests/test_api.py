"""The notebook API: system.simulate, system.numeric, system.symbol, Jupyter display."""
from __future__ import annotations

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
    assert out.strip() == "['kronsub.api']"


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
