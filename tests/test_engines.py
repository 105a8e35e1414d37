"""Every method of the method table (kronsub.simulation.methods) runs through its engine's one
interface (kronsub.simulation.engines) in both commands: ``simulate`` (rows on a grid) and
``accuracy`` (the state at the end), each checked against the exact solution of the spring
chain (a linear system: ``y(t) = expm(A t) y0``, tests/reference/exact.py); a method the table
gives a new engine reaches both commands through the engines' table alone."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import ROOT
from helpers.systems import loaded
from reference.exact import spring_chain_exact
from kronsub.simulation import accuracy, engines, methods, run
from kronsub.simulation.methods import METHODS, SIMULATE
from kronsub.simulation.reference import Reference

CHAIN = ROOT / "tests" / "models" / "spring_chain.yaml"
T_END, DT = 1.0, 0.05


def _needs(method: str) -> None:
    if METHODS[method].engine == "heyoka":
        pytest.importorskip("heyoka", reason="method 'heyoka' needs the optional heyoka (kronsub[heyoka])")


@pytest.fixture(scope="module")
def chain():
    system, values = loaded(CHAIN)
    times = [DT * i for i in range(int(round(T_END / DT)) + 1)]
    exact = np.array([[float(v) for v in row] for row in spring_chain_exact(values, times)])
    return system, values, np.array(times), exact, Reference([T_END], spring_chain_exact(values, [T_END]), 1e-25, 30,
                                                          ("exact solution",))


@pytest.mark.parametrize("method", SIMULATE)
def test_every_simulate_method_runs_through_its_engine(chain, method):
    _needs(method)
    system, values, times, exact, _ = chain
    trajectory = run.simulate(system, values, T_END, DT, method, rtol=1e-8, atol=1e-8)
    assert trajectory.complete, trajectory.message
    assert trajectory.method == method
    assert trajectory.backend == ("heyoka" if method == "heyoka" else "C")
    assert np.allclose(trajectory.t, times, rtol=0, atol=1e-12)
    tolerance = 1e-4 if METHODS[method].fixed_step else 1e-6  # rk4, gauss4: C h^4 at h = 0.05, about 2e-5
    assert np.max(np.abs(trajectory.y - exact)) < tolerance


@pytest.mark.parametrize("method", methods.MEASURED)
def test_every_method_runs_through_its_engine_in_accuracy(chain, method):
    _needs(method)
    system, values, _, _, ref = chain
    wp = accuracy.measure(system, values, T_END, (method,), (1e-8,), ref=ref, progress=False, budget=0.0,
                          max_repeats=1)
    assert not wp.skipped, wp.skipped
    (point,) = wp.points
    assert point.ok, point.status
    assert point.error < 1e-5
    assert point.setting == ("h 0.01" if METHODS[method].fixed_step else "tol 1e-08")


def test_methods_of_accuracy_only_are_refused_by_simulate(chain):
    system, values, _, _, _ = chain
    for name, m in METHODS.items():
        if not m.simulate:
            with pytest.raises(run.SimulationError, match=f"unknown method '{name}'"):
                run.simulate(system, values, T_END, DT, name)


class _Spy:
    """An engine that is scipy's under another name, counting the runners it makes."""

    COMPILED_RHS, EVENTS = engines.scipy.COMPILED_RHS, engines.scipy.EVENTS

    def __init__(self):
        self.made = []

    def runner(self, problem, method):
        self.made.append(method.name)
        return engines.scipy.runner(problem, dataclasses.replace(method, name="RK45"))


def test_a_new_engine_reaches_both_commands_through_the_tables(chain, monkeypatch):
    """A method registered with an engine of its own runs in simulate and in accuracy with no
    other change: neither command names an engine."""
    system, values, _, exact, ref = chain
    spy = _Spy()
    new = methods.Method(name="spy45", engine="spy", order=5, fixed_step=False, closed_loops=True,
                         precision="double", summary="scipy's RK45 under another name")
    monkeypatch.setitem(engines.ENGINES, "spy", spy)
    monkeypatch.setitem(METHODS, "spy45", new)
    monkeypatch.setitem(run.METHODS, "spy45", new)
    trajectory = run.simulate(system, values, T_END, DT, "spy45", rtol=1e-9, atol=1e-9)
    assert trajectory.complete and np.max(np.abs(trajectory.y - exact)) < 1e-6
    wp = accuracy.measure(system, values, T_END, ("spy45",), (1e-8,), ref=ref, progress=False, budget=0.0,
                          max_repeats=1)
    assert [p.method for p in wp.points] == ["spy45"] and wp.points[0].error < 1e-6
    assert spy.made == ["spy45", "spy45"]
