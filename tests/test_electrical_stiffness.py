"""Stiffness advice names the electrical mode: the coordinates that carry the fastest mode, a
circuit's loop charges among them, and its time constant, checked against ``L/R`` of the DC
motor's armature."""
from __future__ import annotations

import numpy as np
from click.testing import CliRunner

import kronsub
from conftest import MODELS
from kronsub.cli import main
from kronsub.simulation.advice import mode_coordinates
from kronsub.simulation.power import charge_coordinates


def test_the_charges_are_the_coordinates_that_move_a_branch_charge():
    electrical = MODELS / "electrical"
    assert charge_coordinates(kronsub.load(electrical / "dc_motor.yaml").derive()) == {"q"}
    assert charge_coordinates(kronsub.load(electrical / "loudspeaker.yaml").derive()) == {"q"}
    assert charge_coordinates(kronsub.load(electrical / "rlc_ladder.yaml").derive()) == {"q1", "q2"}
    assert charge_coordinates(kronsub.load(MODELS / "examples" / "double_pendulum.yaml").derive()) == frozenset()


def test_a_mode_is_carried_by_the_coordinates_of_its_largest_rates():
    lam = -10.0
    vector = np.array([1.0, 0.01, lam * 1.0, lam * 0.01])  # q moves, theta hardly
    assert mode_coordinates(lam, vector, ["q", "theta"]) == ["q"]
    assert mode_coordinates(lam, np.array([1.0, 1.0, -10.0, -10.0]), ["q", "theta"]) == ["q", "theta"]


def test_a_stiff_armature_is_named_with_its_time_constant():
    """A 1 uH armature: the current's mode ``-R/L = -5e5`` holds dop853's step; the warning
    names the loop charge q and ``L/R = 2e-6`` s."""
    result = CliRunner().invoke(main, ["simulate", str(MODELS / "electrical" / "dc_motor.yaml"), "--t", "3",
                                       "--dt", "1", "--set", "L=1e-6", "--rtol", "1e-6", "--atol", "1e-8"])
    assert result.exit_code == 0, result.output
    assert "the problem is stiff" in result.output
    assert "it is an electrical mode, the currents of q, time constant 2e-06" in result.output
    assert "use --method Radau (with --jacobian exact)" in result.output
