"""Equations without a finite value: an overflow of doubles is told apart from a function outside
its domain (kronsub/core/finite.py), in the messages of simulate, linearize and accuracy."""
from __future__ import annotations

import shutil

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

from conftest import MODELS
from kronsub.cli import main
from kronsub.core.finite import nonfinite_cause
from kronsub.core.symbols import symbol

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"
a, b = symbol("a"), symbol("b")


def test_an_overflow_names_the_subexpression_and_the_huge_value():
    cause = nonfinite_cause([("fine", a + b), ("the force", 10 * a * b)], {a: 1e300, b: 1e10})
    assert cause.overflow and cause.what == ("the force overflows the range of doubles: 10*a*b is 1.0e+311 "
                                             "(beyond 1.8e+308) with a=1e+300, b=1e+10")
    assert "smaller values" in cause.hint


def test_an_overflow_on_the_way_to_a_value_in_range_is_found():
    """``huge * sin(0)`` is 0 exactly but NaN in doubles (``inf * 0``); so is ``huge + huge - huge``."""
    c = symbol("c")
    cause = nonfinite_cause([("f", a * b * sympy.sin(c))], {a: 1e300, b: 1e10, c: 0.0})
    assert cause.overflow and "the nonzero factors of a*b*sin(c) multiply to 1.0e+310" in cause.what
    cause = nonfinite_cause([("f", a + b - c)], {a: 1e308, b: 1e308, c: 1e308})
    assert cause.overflow and "the terms of one sign" in cause.what
    assert nonfinite_cause([("f", a * b * sympy.sin(c))], {a: 1e300, b: 1e7, c: 0.0}) is None


def test_a_domain_problem_names_the_function():
    cause = nonfinite_cause([("Mbar[x, x]", 1 + sympy.sqrt(a - 2))], {a: 1.0})
    assert not cause.overflow and str(cause) == ("sqrt(a - 2) in Mbar[x, x] is outside its domain "
                                                 "(check the initial values and the parameters)")
    assert not nonfinite_cause([("y", sympy.asin(a) + 1e300 * b)], {a: 2.0, b: 1.0}).overflow
    assert "division by zero" in nonfinite_cause([("z", 1 / (a - 1))], {a: 1.0}).what


def test_finite_values_and_unknown_symbols_give_no_verdict():
    assert nonfinite_cause([("x", a ** 2 * 1e150 + sympy.sqrt(b))], {a: 1e4, b: 0.0}) is None
    assert nonfinite_cause([("x", a * b)], {a: 1e300}) is None  # b has no value
    # a product that a division brings back into range still overflows in doubles
    assert nonfinite_cause([("x", (a * a) / b)], {a: 1e200, b: 1e200}).overflow


def _simulate(*args):
    return CliRunner().invoke(main, ["simulate", *map(str, args)])


@pytest.mark.parametrize("method", ["dop853", "gauss4", "Radau", "RK45"])
def test_simulate_names_an_overflow_not_a_square_root(tmp_path, method):
    out = tmp_path / "run.csv"
    result = _simulate(SYSTEM1, "--set", "m1=1e308", "--t", "1", "--method", method, "-o", out)
    assert result.exit_code == 3, result.output
    assert "overflows the range of doubles" in result.output and "m1=1e+308" in result.output
    assert "square root" not in result.output and "domain" not in result.output
    rows = np.genfromtxt(out, delimiter=",", skip_header=1, ndmin=2)
    assert np.all(np.isfinite(rows[:, :5]))  # t and the state: no NaN row was written


def test_taylor_writes_no_nan_rows_after_an_overflow(tmp_path):
    out = tmp_path / "run.csv"
    result = _simulate(SYSTEM1, "--set", "m1=1e308", "--t", "1", "--method", "taylor", "--rtol", "1e-6", "-o", out)
    assert result.exit_code == 3, result.output
    assert "overflows the range of doubles" in result.output
    assert len(out.read_text().splitlines()) == 2  # the header and the initial row


def test_a_huge_velocity_is_named(tmp_path):
    result = _simulate(SYSTEM1, "--set", "theta_dot=1e200", "--t", "1", "-o", tmp_path / "run.csv")
    assert result.exit_code == 3 and "theta_dot=1e+200" in result.output, result.output


def test_simulate_still_names_a_domain_problem(tmp_path):
    for name in ("system1.yaml", "system2.yaml"):
        shutil.copy(MODELS / "hoffmann" / name, tmp_path / name)
    result = _simulate(tmp_path / "system2.yaml", "--set", "c=0.9", "--t", "0.1", "--method", "Radau",
                       "-o", tmp_path / "run.csv")
    assert result.exit_code == 3, result.output
    assert "no real value at this state" in result.output and "is outside its domain" in result.output
    assert "asin" in result.output or "sqrt" in result.output


def test_linearize_and_accuracy_name_an_overflow():
    result = CliRunner().invoke(main, ["linearize", str(SYSTEM1), "--at", "m1=1e308"])
    assert result.exit_code == 1 and "overflows the range of doubles" in result.output, result.output
    assert "--at NAME=VALUE" not in result.output  # another operating point would not help
    # at theta = 0 the force -a1 g (m1 + 2 m2) sin(theta) is 0 exactly, NaN in doubles
    result = CliRunner().invoke(main, ["linearize", str(SYSTEM1), "--at", "m1=1e308", "--at", "theta=0",
                                       "--at", "phi=0"])
    assert result.exit_code == 1 and "the nonzero factors of" in result.output, result.output
    result = CliRunner().invoke(main, ["accuracy", str(SYSTEM1), "--set", "m1=1e308", "--t", "1",
                                       "--methods", "dop853", "--quick"])
    assert result.exit_code == 1 and "overflows the range of doubles" in result.output, result.output


def test_linearize_names_a_domain_problem_instead_of_failing(tmp_path):
    """A potential k sqrt(x - 1) at x = 0: numpy's NaN, not Python's complex power (an internal
    error before)."""
    model = tmp_path / "model.yaml"
    model.write_text("name: slider\nparameters: {m: 1, k: 2}\ncomponents:\n"
                     "  s: {type: particle1d, parameters: {mass: m}, coordinates: [x]}\ncoordinates: [x]\n"
                     "effects:\n  well: {type: potential, value: k*sqrt(x - 1)}\n")
    result = CliRunner().invoke(main, ["linearize", str(model)])
    assert result.exit_code == 1, result.output
    assert "1/sqrt(x - 1) in (fbar - hbar)[x] is outside its domain" in result.output
    assert "--at NAME=VALUE" in result.output


def test_a_singular_mass_matrix_is_described_by_the_motion_it_loses():
    from kronsub.core.finite import describe_rank_loss

    assert describe_rank_loss(np.diag([2.0, 1.0]), ["a", "b"]) is None
    lost = describe_rank_loss(np.array([[1.0, 1.0], [1.0, 1.0]]), ["a", "b"])
    assert "a motion along (a +1, b -1) has no inertia" in lost
    assert "negative eigenvalue" in describe_rank_loss(np.diag([1.0, -0.5]), ["a", "b"])


@pytest.mark.parametrize("method", ["dop853", "RK45"])
def test_simulate_at_a_pole_of_spherical_coordinates_names_the_lost_direction(tmp_path, method):
    """The polar angle 0 of a spherical pendulum: the azimuth moves nothing (Mbar = diag(m R^2, 0))."""
    result = CliRunner().invoke(main, ["simulate", str(MODELS / "examples" / "particle_on_sphere.yaml"), "--t", "1",
                                       "--set", "theta=0", "--method", method, "-o", str(tmp_path / "run.csv")])
    assert result.exit_code == 3, result.output
    assert "Mbar loses rank here: a motion along (phi +1) has no inertia" in result.output
    assert "the 1 row computed so far is kept" in result.output


def test_linearize_at_a_pole_names_the_lost_direction():
    result = CliRunner().invoke(main, ["linearize", str(MODELS / "examples" / "particle_on_sphere.yaml"),
                                       "--at", "theta=0", "--at", "phi=0"])
    assert result.exit_code != 0 and "a motion along (phi +1) has no inertia" in result.output
COINCIDENT = """name: tether
parameters: {m: 1, k: 10, L: 0.5, c: 0.3}
components:
  a: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}
coordinates: [x, y]
effects:
  tether: {type: spring, between: [[0, 0], a.centre], stiffness: k, length: L}
  drag: {type: damper, between: [[0, 0], a.centre], coefficient: c}
initial: {x: 0, y: 0, x_dot: 0.1}
"""


@pytest.mark.parametrize("method", ["dop853", "gauss4", "taylor", "RK45", "Radau", "LSODA"])
def test_simulate_names_the_spring_whose_ends_coincide(tmp_path, method):
    """A spring with a rest length (or a damper) pulls along (p_b - p_a)/|p_b - p_a|, which is
    0/0 where its ends meet: named with its entry and the state, not a bare NaN."""
    model = tmp_path / "model.yaml"
    model.write_text(COINCIDENT)
    result = _simulate(model, "--t", "0.1", "--method", method, "--rtol", "1e-6", "-o", tmp_path / "run.csv")
    assert result.exit_code == 3, result.output
    assert f"Error: {model}:7:3: the run stopped at t = 0: the ends of spring 'tether' coincide at t = 0 " \
           "(x=0, y=0)" in result.output
    assert "hint: move one end" in result.output and "leave out `length:`" in result.output
    assert "NaN" not in result.output and "Traceback" not in result.output


def test_a_damper_whose_ends_coincide_is_named(tmp_path):
    model = tmp_path / "model.yaml"
    model.write_text(COINCIDENT.replace("  tether:", "  # tether:"))
    result = _simulate(model, "--t", "0.1", "-o", tmp_path / "run.csv")
    assert result.exit_code == 3 and f"{model}:8:3:" in result.output, result.output
    assert "the ends of damper 'drag' coincide at t = 0 (x=0, y=0)" in result.output


def test_linearize_and_accuracy_name_the_spring_whose_ends_coincide(tmp_path):
    model = tmp_path / "model.yaml"
    model.write_text(COINCIDENT)
    for args in (["linearize", str(model)], ["accuracy", str(model), "--t", "0.1", "--quick", "--methods", "dop853"]):
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 1, result.output
        assert f"Error: {model}:7:3: the ends of spring 'tether' coincide at t = 0 (x=0, y=0)" in result.output
    # elsewhere the same model linearises: about x = L (the damper's ends apart)
    result = CliRunner().invoke(main, ["linearize", str(model), "--at", "x=0.5", "--at", "y=0"])
    assert result.exit_code == 0, result.output


def test_a_spring_of_zero_rest_length_through_its_anchor_runs(tmp_path):
    """Its force k (p_b - p_a) has a value where the ends meet: nothing to report."""
    model = tmp_path / "model.yaml"
    model.write_text(COINCIDENT.replace(", length: L", "").replace("  drag:", "  # drag:"))
    result = _simulate(model, "--t", "1", "-o", tmp_path / "run.csv")
    assert result.exit_code == 0, result.output
    rows = np.genfromtxt(tmp_path / "run.csv", delimiter=",", skip_header=1, ndmin=2)
    assert np.allclose(rows[-1, 1], 0.1 * np.sin(np.sqrt(10)) / np.sqrt(10), atol=1e-8)


def test_the_force_of_a_named_effect_without_a_value_names_the_effect(tmp_path):
    model = tmp_path / "model.yaml"
    model.write_text("name: slider\nparameters: {m: 1, k: 2}\ncomponents:\n"
                     "  s: {type: particle1d, parameters: {mass: m}, coordinates: [x]}\ncoordinates: [x]\n"
                     "effects:\n  well: {type: potential, value: k*sqrt(x - 1)}\n")
    result = _simulate(model, "--t", "0.1", "--method", "Radau", "-o", tmp_path / "run.csv")
    assert result.exit_code == 3 and "1/sqrt(x - 1) in fbar[x] of effect 'well' is outside its domain" \
        in result.output, result.output


@pytest.mark.parametrize("kind, key", [("spring", "stiffness"), ("damper", "coefficient")])
def test_a_spring_or_damper_from_a_point_to_itself_is_refused(tmp_path, kind, key):
    model = tmp_path / "model.yaml"
    model.write_text(COINCIDENT.replace("effects:\n", f"effects:\n  same: {{type: {kind}, between: "
                                                     f"[a.centre, a.centre], {key}: k}}\n"))
    result = _simulate(model, "--t", "0.1")
    assert result.exit_code == 1, result.output
    assert f"Error: {model}:7:33: the two ends of {kind} 'same' are the same point, whatever the motion" \
        in result.output and "hint:" in result.output


FOUR_BAR = MODELS / "examples" / "four_bar.yaml"


def test_a_closed_loop_names_an_overflow_not_the_constraints(tmp_path):
    """With implicit constraints the quantities are in the dependent coordinates too: they are
    solved at the state, then the overflow is named as without constraints (it was 'the
    constraints could not be solved ... where they still have a solution' from simulate, 'every
    point failed' from accuracy, 'cannot be evaluated' without a cause from linearize)."""
    big = ["m1=1e308", "g=100"]
    result = _simulate(FOUR_BAR, *[a for v in big for a in ("--set", v)], "--t", "0.1", "-o", tmp_path / "run.csv")
    assert result.exit_code == 3, result.output
    assert "fbar[theta1] of effect 'gravity' overflows the range of doubles" in result.output
    assert "with m1=1e+308" in result.output and "could not be solved" not in result.output
    result = CliRunner().invoke(main, ["linearize", str(FOUR_BAR), "--at", big[0], "--at", big[1]])
    assert result.exit_code == 1 and "(fbar - hbar)[theta1] overflows the range of doubles" in result.output, \
        result.output
    result = CliRunner().invoke(main, ["accuracy", str(FOUR_BAR), "--set", big[0], "--set", big[1], "--t", "0.1",
                                       "--quick", "--methods", "dop853"])
    assert result.exit_code == 1, result.output
    assert "no finite value at the initial state: fbar[theta1] of effect 'gravity' overflows" in result.output


def test_a_closed_loop_names_a_function_outside_its_domain_partway(tmp_path):
    """A potential sqrt(theta2 - 0.34) in the dependent coordinate theta2, which falls below 0.34
    as the crank turns: the run stops there naming it, with the dependent coordinates solved."""
    model = tmp_path / "model.yaml"
    model.write_text(FOUR_BAR.read_text().replace(
        "  drive: {type: torque, component: crank, value: tau}\n",
        "  drive: {type: torque, component: crank, value: tau}\n  well: {type: potential, value: "
        "0.01*sqrt(theta2 - 0.34)}\n"))
    result = _simulate(model, "--t", "1", "-o", tmp_path / "run.csv")
    assert result.exit_code == 3, result.output
    assert "no real value at this state: 1/sqrt(theta2 - 17/50) in fbar[theta1] of effect 'well' is outside its " \
           "domain" in result.output and "theta2=0.3396" in result.output, result.output


def test_a_closed_form_outside_its_domain_is_named(tmp_path):
    """System II with the constraint (25): phi = asin((c - a1 sin(theta))/a2) has no value where
    the lower rod cannot reach the line (theta = 0.1): the closed form's asin is named."""
    for name in ("system1.yaml", "system2_implicit.yaml"):
        shutil.copy(MODELS / "hoffmann" / name, tmp_path / name)
    result = _simulate(tmp_path / "system2_implicit.yaml", "--set", "theta=0.1", "--t", "0.1")
    assert result.exit_code == 1, result.output
    assert "asin((-a1*sin(theta) + c)/a2) in phi is outside its domain" in result.output, result.output


def test_a_spring_from_a_point_to_itself_is_reported_with_its_other_problems(tmp_path):
    """The whole model is validated at once: the spring's stiffness in a velocity is told too."""
    model = tmp_path / "model.yaml"
    model.write_text(COINCIDENT.replace("effects:\n", "effects:\n  same: {type: spring, between: "
                                                     "[a.centre, a.centre], stiffness: x_dot}\n"))
    result = _simulate(model, "--t", "0.1")
    assert result.exit_code == 1, result.output
    assert "the two ends of spring 'same' are the same point" in result.output
    assert "the stiffness of 'same' depends on the velocity 'x_dot'" in result.output and "2 problems found" \
        in result.output


def test_linearize_next_to_a_pole_notes_the_lost_direction():
    """At theta = pi in floating point, Mbar[phi, phi] = sin(theta)**2 is 1.5e-32, not 0: Cholesky
    passes, and A's row for phi would be taken at its word."""
    result = CliRunner().invoke(main, ["linearize", str(MODELS / "examples" / "particle_on_sphere.yaml"),
                                       "--at", "theta=3.141592653589793", "--at", "phi=0"])
    assert result.exit_code == 0, result.output
    assert "a motion along (phi +1) has no inertia" in result.output and "not to be trusted" in result.output
    away = CliRunner().invoke(main, ["linearize", str(MODELS / "examples" / "particle_on_sphere.yaml"),
                                     "--at", "theta=2.5", "--at", "phi=0"])
    assert away.exit_code == 0 and "no inertia" not in away.output
