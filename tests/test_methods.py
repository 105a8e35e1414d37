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
from kronsub.simulation import accuracy, native, run
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
    assert by_engine("c") == ("dop853", "gauss4", "rk4")
    assert native.METHODS == by_engine("c")  # the integrators in the compiled C are the c engine's methods
    assert accuracy.ALL_METHODS == ("dop853", "gauss4", "rk4", "taylor", "RK45", "DOP853", "Radau", "LSODA", "heyoka")
    assert accuracy.KNOWN_METHODS == accuracy.ALL_METHODS + ("gbs-long", "gbs-quad")
    assert accuracy.CLOSED_LOOP == by_engine("c") + by_engine("scipy")
    assert {m: accuracy.fixed_step(m, 1e-8, 1.0) for m in MEASURED if METHODS[m].fixed_step} == \
        {"gauss4": pytest.approx(1e-2), "rk4": pytest.approx(1e-2)}  # tol^(1/4)
    assert [m for m in MEASURED if METHODS[m].precision != "double"] == ["gbs-long", "gbs-quad"]


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
    """A method's engine (its module in ``simulation/engines``, one interface) runs it for both
    commands: the engines' table names exactly the engines of the method table, and each has
    the interface's flags and its ``runner``."""
    import importlib

    from kronsub.simulation import engines

    assert tuple(engines.ENGINES) == ENGINES
    for name, engine in engines.ENGINES.items():
        assert engine is importlib.import_module(f"kronsub.simulation.engines.{name}")
        assert isinstance(engine.COMPILED_RHS, bool) and isinstance(engine.EVENTS, bool), name
        assert callable(engine.runner), name
    for m in METHODS.values():
        assert engines.engine_of(m) is engines.ENGINES[m.engine]
        assert m.fallback is None or (METHODS[m.fallback].simulate and engines.engine_of(METHODS[m.fallback]).EVENTS
                                      and engines.engine_of(METHODS[m.fallback]).COMPILED_RHS), m.name


@pytest.mark.parametrize("command, names", [("simulate", SIMULATE), ("accuracy", MEASURED)])
def test_help_texts_are_the_table(command, names):
    """The help of ``--method`` / ``--methods`` is the table's description of its methods, whole."""
    from kronsub.simulation.methods import help_text

    result = CliRunner().invoke(main, [command, "--help"], terminal_width=10_000)
    assert result.exit_code == 0
    assert " ".join(help_text(names).split()) in " ".join(result.output.split())
