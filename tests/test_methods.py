"""The method table (kronsub.simulation.methods) is the one list of integration methods: the
schema's enum, simulate's and accuracy's lists and both help texts follow it; rk4 is a
method of simulate, checked against the exact solution of a linear system."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.linalg import expm

from conftest import ROOT
from kronsub.cli import main
from kronsub.simulation import accuracy, run
from kronsub.simulation.methods import ENGINES, MEASURED, METHODS, SIMULATE, by_engine

SCHEMA = ROOT / "kronsub" / "model" / "schema.json"
CHAIN = ROOT / "tests" / "models" / "spring_chain.yaml"


def test_schema_enum_is_the_methods_of_simulate():
    schema = json.loads(SCHEMA.read_text(encoding="utf-8"))
    assert schema["$defs"]["scene"]["properties"]["method"]["enum"] == list(SIMULATE)


def test_every_method_is_well_formed():
    for name, m in METHODS.items():
        assert m.name == name and m.engine in ENGINES and m.summary.strip()
        assert m.precision in ("double", "long", "quad")
        assert m.order is None or m.order >= 1
        assert not (m.fixed_step and m.order is None), f"{name}: a fixed-step method has an order"
        assert m.simulate or m.engine == "extended"
    assert sorted(MEASURED) == sorted(METHODS)


def test_simulate_and_accuracy_read_the_table():
    assert list(run.METHODS) == list(SIMULATE)
    assert run.FIXED_STEP == ("gauss4", "rk4")
    assert accuracy.NATIVE == by_engine("c") == ("dop853", "gauss4", "rk4")
    assert accuracy.ALL_METHODS == ("dop853", "gauss4", "rk4", "taylor", "RK45", "DOP853", "Radau", "LSODA", "heyoka")
    assert accuracy.KNOWN_METHODS == accuracy.ALL_METHODS + ("gbs-long", "gbs-quad")
    assert accuracy.CLOSED_LOOP == accuracy.NATIVE + accuracy.SCIPY
    assert accuracy.FIXED_STEP_ORDER == {"gauss4": 4, "rk4": 4}
    assert accuracy.EXTENDED == {"gbs-long": "long", "gbs-quad": "quad"}


@pytest.mark.parametrize("command, names", [("simulate", SIMULATE), ("accuracy", MEASURED)])
def test_help_texts_name_every_method(command, names):
    result = CliRunner().invoke(main, [command, "--help"], terminal_width=10_000)
    assert result.exit_code == 0
    for name in names:
        assert f"{name} (" in result.output, name


def test_unknown_method_lists_the_table():
    result = CliRunner().invoke(main, ["simulate", str(CHAIN), "--method", "euler"])
    assert result.exit_code == 2
    assert f"choose one of {', '.join(SIMULATE)}" in result.output


def _chain_exact(t: np.ndarray) -> np.ndarray:
    """[x; xdot] of the spring chain, x'' = -M^-1 K x, by the matrix exponential."""
    m, (k1, k2, k3, k4) = np.array([1.0, 2.0, 0.5]), (3.0, 1.5, 2.0, 4.0)
    K = np.array([[k1 + k2, -k2, 0.0], [-k2, k2 + k3, -k3], [0.0, -k3, k3 + k4]])
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-K / m[:, None], np.zeros((3, 3))]])
    y0 = np.array([0.3, -0.1, 0.2, 0.0, 0.5, 0.0])
    return np.array([expm(A * ti) @ y0 for ti in t])


def _rk4_error(dt: float) -> float:
    result = CliRunner().invoke(main, ["simulate", str(CHAIN), "--method", "rk4", "--t", "2", "--dt", str(dt)])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.output.splitlines() if line and line[0] not in "#"]
    header, rows = lines[0].split(","), np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    t = rows[:, header.index("t")]
    assert np.allclose(np.diff(t), dt)
    state = [f"x{i}" for i in (1, 2, 3)] + [f"x{i}_dot" for i in (1, 2, 3)]
    Y = rows[:, [header.index(name) for name in state]]
    return float(np.max(np.abs(Y - _chain_exact(t))))


def test_rk4_in_simulate_is_fourth_order_against_the_exact_solution():
    coarse, fine = _rk4_error(0.02), _rk4_error(0.01)
    assert coarse < 2e-6  # C h^4, h = 0.02, C of the fastest mode
    assert 12 < coarse / fine < 20  # halving the step divides the error by 2^4


def test_every_engine_has_its_module():
    """A method's engine runs it for both commands: ``blocks`` (simulate's streamed rows, for an
    engine of a simulate method) and ``final_state`` (accuracy's timed run)."""
    import importlib

    for engine in ENGINES:
        module = importlib.import_module(f"kronsub.simulation.engines.{engine}")
        assert callable(module.final_state), engine
        if any(m.simulate for m in METHODS.values() if m.engine == engine):
            assert callable(module.blocks), engine
