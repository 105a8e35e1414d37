"""The energy check after a run: when the energy of a model that conserves it changes by more
than 1 % of its largest kinetic energy over a complete run, ``simulate`` warns (heyoka, fooled by the Taylor
series with gaps of two rods released from rest level with their hinge, benchmarks/HISTORY.md);
accurate runs, and models that do not conserve energy (a damper), say nothing. Whether a model conserves energy is read off its equations: dE/dt at
states with random velocities, by central differences."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import kronsub
from conftest import MODELS
from kronsub.simulation import advice as A
from kronsub.simulation import run as R
from kronsub.simulation.values import resolve


def _system1(**settings):
    model = kronsub.load(MODELS / "hoffmann/system1.yaml")
    system = model.derive()
    return system, resolve(system, dict(model.initial), {"theta": "pi/2", "phi": "pi/2", "F": "0", **settings})


def _damped():
    cart = kronsub.load(MODELS / "examples/pendulum_on_cart.yaml")
    system = cart.derive()
    values = resolve(system, dict(cart.initial), {})
    assert len(system.coordinates) == 2
    return R._compiled(system, None), np.array(values.parameters), np.array(values.y0)


def _energy_warnings(system, values, method, t_end=3.0, rtol=1e-6):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = R.simulate(system, values, t_end, 0.01, method, rtol=rtol, atol=rtol, progress=False)
    return traj, [str(w.message) for w in caught if issubclass(w.category, R.EnergyWarning)]


def test_heyoka_fooled_by_a_series_with_gaps_is_reported():
    pytest.importorskip("heyoka")
    system, values = _system1()
    traj, found = _energy_warnings(system, values, "heyoka")
    assert traj.complete and len(found) == 1, found
    assert "heyoka's rows are not accurate" in found[0] and "--method taylor or dop853" in found[0]
    T, V = traj.energies  # the energies the warning read, from the compiled model
    assert abs((T[-1] + V[-1]) - (T[0] + V[0])) > 0.01 * np.max(T)


@pytest.mark.parametrize("method", ["dop853", "taylor", "gauss4"])
def test_accurate_runs_say_nothing(method):
    system, values = _system1()
    traj, found = _energy_warnings(system, values, method)
    assert traj.complete and not found and traj.energies is not None


def test_conservation_is_read_off_the_equations():
    system, values = _system1()
    native = R._compiled(system, None)
    y0 = np.array(values.y0)
    assert A.conserves_energy(native, np.array(values.parameters), 2, 0.0, y0)
    pushed, pushed_values = _system1(F="5")  # a steady push has a potential, -F x: E = T + V still holds
    assert A.conserves_energy(native, np.array(pushed_values.parameters), 2, 0.0, y0)
    cart_native, cart_param, cart_y0 = _damped()
    assert not A.conserves_energy(cart_native, cart_param, 2, 0.0, cart_y0)
    assert not A.conserves_energy(cart_native, cart_param, 2, 0.0, cart_y0 * 0)  # at rest too (random velocities)


def test_the_threshold_is_one_percent_of_the_energy_scale():
    system, values = _system1()
    native, param, y0 = R._compiled(system, None), np.array(values.parameters), np.array(values.y0)
    assert A.energy_advice(native, param, 2, "dop853", 0.0, y0, -2.0, 10.0, -2.0 + 0.099) == ""
    advice = A.energy_advice(native, param, 2, "dop853", 0.0, y0, -2.0, 10.0, -2.0 + 0.101)
    assert "dop853's rows are not accurate" in advice and "tighten --rtol" in advice
    cart_native, cart_param, cart_y0 = _damped()
    assert A.energy_advice(cart_native, cart_param, 2, "dop853", 0.0, cart_y0, -2.0, 10.0, -5.0) == ""
    assert A.energy_advice(native, param, 2, "dop853", 0.0, y0, 0.0, 0.0, 0.0) == ""  # at rest: no scale
    # the scale is the kinetic energy, not |E|: an offset of the potential hides nothing
    assert "dop853's rows" in A.energy_advice(native, param, 2, "dop853", 0.0, y0, -1e4, 1.0, -1e4 + 0.05)
    # a run that hardly moves: the rounding of a large potential is not a drift
    assert A.energy_advice(native, param, 2, "dop853", 0.0, y0, -17.7, 1e-16, -17.7 + 1e-14) == ""


def test_a_damped_run_that_loses_energy_says_nothing():
    cart = kronsub.load(MODELS / "examples/pendulum_on_cart.yaml")
    system = cart.derive()
    values = resolve(system, dict(cart.initial), {})
    traj, found = _energy_warnings(system, values, "dop853", t_end=10.0, rtol=1e-8)
    T, V = traj.energies
    assert traj.complete and not found and abs((T[-1] + V[-1]) - (T[0] + V[0])) > 0.01 * max(np.max(T), 1e-300)
