"""The optional heyoka backend: against the 40-digit reference and against kronsub's own C."""
from __future__ import annotations

import json
import sys

import numpy as np
import pytest

import kronsub
from conftest import MODELS, ROOT
from kronsub.errors import KronsubError
from kronsub.simulation import heyoka_backend
from kronsub.simulation.run import simulate
from kronsub.simulation.values import resolve

# the 40-digit solution, recomputed independently by tests/data/double_pendulum_reference.py
REFERENCE = ROOT / "tests" / "data" / "double_pendulum_rods.json"


@pytest.fixture
def heyoka():
    return pytest.importorskip("heyoka")


def test_double_pendulum_of_rods_against_the_high_precision_reference(heyoka):
    """System I with its defaults is two uniform unit rods; 120 deg / -10 deg, rest, t = 10."""
    data = json.loads(REFERENCE.read_text())
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive()
    values = resolve(system, {}, {"theta": "2*pi/3", "phi": "-pi/18"})
    t, Y, complete, message = heyoka_backend.integrate(
        system, np.array(values.parameters), np.array(values.y0), np.array([0.0, 5.0, 10.0]), 1e-15)
    want = [float(data["state_at_t_end"][k]) for k in ("q1", "q2", "u1", "u2")]
    assert complete and message == ""
    assert list(t) == [0.0, 5.0, 10.0] and Y.shape == (3, 4)
    assert np.max(np.abs(Y[-1] - want)) < 1e-9, Y[-1] - want


def test_agrees_with_the_compiled_c_integrator(heyoka):
    model = kronsub.load(MODELS / "examples" / "double_pendulum.yaml")
    system = model.derive()
    values = resolve(system, dict(model.initial), {})
    traj = simulate(system, values, 2.0, 0.25, "dop853", rtol=1e-12, atol=1e-12, progress=False)
    t, Y, complete, _ = heyoka_backend.integrate(
        system, np.array(values.parameters), np.array(values.y0), traj.t, 1e-15)
    assert complete
    np.testing.assert_array_equal(t, traj.t)
    np.testing.assert_allclose(Y, traj.y, rtol=0, atol=1e-9)


def test_one_compiled_integrator_serves_other_parameters(heyoka):
    """Parameters are heyoka's runtime par[]: changing g changes the answer without recompiling."""
    model = kronsub.load(MODELS / "examples" / "double_pendulum.yaml")
    system = model.derive()
    values = resolve(system, dict(model.initial), {})
    integrator = heyoka_backend.HeyokaIntegrator(system, 1e-14)
    grid = np.linspace(0.0, 1.0, 5)
    for g in ("9.81", "1.62"):
        values = resolve(system, dict(model.initial), {"g": g})
        traj = simulate(system, values, 1.0, 0.25, "dop853", rtol=1e-12, atol=1e-12, progress=False)
        _, Y, complete, _ = integrator.run(values.parameters, values.y0, grid)
        assert complete
        np.testing.assert_allclose(Y, traj.y, rtol=0, atol=1e-9)


def test_missing_heyoka_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "heyoka", None)  # import heyoka now raises ImportError
    system = kronsub.load(MODELS / "examples" / "double_pendulum.yaml").derive()
    with pytest.raises(KronsubError, match=r"pip install 'kronsub\[heyoka\]'"):
        heyoka_backend.integrate(system, np.ones(5), np.zeros(4), np.array([0.0, 1.0]), 1e-12)
    assert not heyoka_backend.available()
