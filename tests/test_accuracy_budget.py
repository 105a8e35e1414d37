"""``accuracy`` and ``simulate`` from a state that changes far too fast stop within seconds:
the reference's steps are bounded (simulation/reference.py, ``REFERENCE_STEPS``), estimated
from the first step; a SciPy run that stalls or takes too many steps is a failed point
(simulation/accuracy.py). Subprocesses with a generous timeout guard against a hang; no
timing is asserted."""
from __future__ import annotations

import subprocess
import sys

from conftest import MODELS

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"

SLIDER = """\
name: slider
parameters: {m: 1, k: 2}
components:
  s: {type: particle1d, parameters: {mass: m}, coordinates: [x]}
coordinates: [x]
effects:
  spring: {type: spring, between: [s.centre, [0]], stiffness: k}
initial: {x: 10}
"""


def _kronsub(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "kronsub", *map(str, args)], capture_output=True, text=True,
                          timeout=60, cwd=cwd)


def test_accuracy_from_a_huge_velocity_stops_at_the_reference():
    done = _kronsub("accuracy", SYSTEM1, "--quick", "--set", "theta_dot=1e154")
    assert done.returncode == 1, done.stderr
    assert "Error: the reference would take more than 10,000 steps to t = 10" in done.stderr
    assert "hint: a shorter --t" in done.stderr and "Traceback" not in done.stderr


def test_a_stalled_scipy_run_is_a_failed_point(tmp_path):
    """LSODA's step is 0 at a state of 1e154 (its first step's estimate overflows): the run
    stops after 100 steps that do not advance, and every point failed (exit 1)."""
    (tmp_path / "slider.yaml").write_text(SLIDER)
    done = _kronsub("accuracy", "slider.yaml", "--t", "1", "--set", "x_dot=1e154", "--methods", "LSODA",
                    "--tolerances", "1e-6", cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    assert "stopped at t = 0: 100 steps in a row that did not advance" in done.stdout
    assert "Error: every point failed" in done.stderr


def test_simulate_from_a_huge_velocity_is_a_numerical_failure(tmp_path):
    done = _kronsub("simulate", SYSTEM1, "--set", "theta_dot=1e154", "--output", tmp_path / "run.csv")
    assert done.returncode == 3, done.stderr
    assert "Error: the run stopped at t = " in done.stderr and "Traceback" not in done.stderr


def test_reference_budget_unit():
    """The estimate refuses a step that would need too many more, and a step of 0."""
    import pytest

    from kronsub.simulation.reference import REFERENCE_STEPS, ReferenceFailure, _within_budget

    bits = 64
    one = 1 << bits
    _within_budget(0, 0, one // 100, 10 * one, bits)  # 1000 steps to t = 10
    with pytest.raises(ReferenceFailure, match="its step at t = 0 is 1e-06"):
        _within_budget(0, 0, one // 10**6, one, bits)
    with pytest.raises(ReferenceFailure, match="below the reference's resolution"):
        _within_budget(0, 0, 0, one, bits)
    with pytest.raises(ReferenceFailure):
        _within_budget(REFERENCE_STEPS, 0, one, one * 2, bits)
