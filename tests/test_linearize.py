"""Linearisation: A, B about an operating point, checked against sympy.physics.mechanics'
``KanesMethod.linearize`` (tests/reference/mechanics.py) and known eigenvalues."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from reference import mechanics as mr
from conftest import MODELS, ROOT
from helpers import COMPOUND, by_name
from kronsub.cli import main
from kronsub.errors import KronsubError

CART_POLE = MODELS / "examples" / "cart_pole.yaml"
DOUBLE_PENDULUM = MODELS / "examples" / "double_pendulum.yaml"



@pytest.fixture(scope="module")
def cart_pole():
    return kronsub.load(CART_POLE).derive()


@pytest.fixture(scope="module")
def double_pendulum():
    return kronsub.load(DOUBLE_PENDULUM).derive()


def _zero(matrix) -> bool:
    return matrix.applyfunc(lambda e: sympy.simplify(e)).is_zero_matrix


def _values(system, **overrides) -> dict:
    values = {p.name: float(p.value) for p in system.parameters}
    values.update(overrides)
    return values


def _number(matrix, values: dict) -> np.ndarray:
    subs = {sympy.Symbol(k): v for k, v in values.items()}
    return np.array(by_name(matrix).xreplace(subs).evalf(), dtype=float)


def test_cart_pole_symbolic_matches_kanes_method(cart_pole):
    """The equilibrium found from theta = 3 is the upright pole; A and B as expressions."""
    lin = cart_pole.linearize(inputs=["u"], symbolic=True)
    assert lin.equilibrium
    point = {s.name: v for s, v in lin.point}
    assert point["theta"] == sympy.pi and point["x_dot"] == 0
    A_ref, B_ref = mr.linearized("cart_pole", {"x": point["x"], "theta": sympy.pi}, ["u"])
    assert _zero(by_name(lin.A) - A_ref)
    assert _zero(by_name(lin.B) - B_ref)


@pytest.mark.parametrize("theta", [0.0, math.pi])
def test_cart_pole_numeric_matches_kanes_method(cart_pole, theta):
    lin = cart_pole.linearize(at={"theta": theta, "x": 0.25}, inputs=["u"])
    assert lin.equilibrium
    A_ref, B_ref = mr.linearized("cart_pole", {"x": 0.25, "theta": theta}, ["u"])
    values = _values(cart_pole)
    np.testing.assert_allclose(lin.A, _number(A_ref, values), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(lin.B, _number(B_ref, values), rtol=1e-12, atol=1e-12)


def test_double_pendulum_at_rest_matches_kanes_method(double_pendulum):
    lin = double_pendulum.linearize(at={"q1": 0, "q2": 0}, symbolic=True)
    A_ref, _ = mr.linearized("double_pendulum", {})
    assert lin.equilibrium
    assert _zero(by_name(lin.A) - A_ref)


def test_double_pendulum_away_from_equilibrium_matches_kanes_method(double_pendulum):
    """Moving and accelerating: the velocity terms and the dMbar/dq a* term count."""
    at = {"q1": 0.3, "q2": -0.7, "q1_dot": 0.5, "q2_dot": -1.1, "m2": 1.7, "l1": 0.8}
    lin = double_pendulum.linearize(at=at)
    assert not lin.equilibrium
    A_ref, _ = mr.linearized("double_pendulum", {k: v for k, v in at.items() if k[0] == "q"})
    values = _values(double_pendulum, m2=1.7, l1=0.8)
    np.testing.assert_allclose(lin.A, _number(A_ref, values), rtol=1e-11, atol=1e-11)
    assert max(abs(a) for a in lin.acceleration) > 0.1


def test_double_pendulum_equilibrium_found_from_the_initial_values(double_pendulum):
    """From q1 = 2 pi/3, q2 = -pi/18 the search lands on an equilibrium: sin q1 = sin q2 = 0."""
    lin = double_pendulum.linearize()
    assert lin.equilibrium and set(lin.found) == set(double_pendulum.coordinates)
    point = {s.name: float(v) for s, v in lin.point}
    assert abs(math.sin(point["q1"])) < 1e-9 and abs(math.sin(point["q2"])) < 1e-9
    A_ref, _ = mr.linearized("double_pendulum", {"q1": point["q1"], "q2": point["q2"]})
    np.testing.assert_allclose(lin.A, _number(A_ref, _values(double_pendulum)), rtol=1e-10, atol=1e-10)


def test_compound_pendulum_eigenvalues(tmp_path):
    """+-i sqrt(m g d / (I + m d^2)), d = L/2, about the hanging equilibrium."""
    path = tmp_path / "compound.yaml"
    path.write_text(COMPOUND)
    system = kronsub.load(path).derive()
    lin = system.linearize()
    assert lin.equilibrium and abs(float(dict(lin.point)[system.symbol("theta")])) < 1e-12
    m, L, I, g = 2.0, 1.5, 0.3, 9.81
    d = L / 2
    omega = math.sqrt(m * g * d / (I + m * d * d))
    assert [e.real for e in lin.eigenvalues] == [0.0, 0.0]
    np.testing.assert_allclose(sorted(e.imag for e in lin.eigenvalues), [-omega, omega], rtol=1e-12)
    symbolic = system.linearize(symbolic=True)
    m_, L_, I_, g_ = (system.symbol(n) for n in ("m", "L", "I", "g"))
    expected = -m_ * g_ * (L_ / 2) / (I_ + m_ * L_**2 / 4)
    assert sympy.simplify(symbolic.A[1, 0] - expected) == 0
    assert sympy.simplify(symbolic.A - sympy.Matrix([[0, 1], [expected, 0]])) == sympy.zeros(2, 2)


def test_inverted_pendulum_on_a_cart_has_one_positive_real_eigenvalue(cart_pole):
    """Undamped (b = 0), upright: eigenvalues 0, 0, +-lambda with the hand-derived
    lambda^2 = mp g d (mc + mp) / ((mc + mp)(I + mp d^2) - mp^2 d^2), d = l/2, I = mp l^2/12."""
    lin = cart_pole.linearize(at={"theta": "pi", "b": 0})
    mc, mp, l, g = 1.0, 0.1, 1.0, 9.81
    d, I = l / 2, mp * l * l / 12
    lam = math.sqrt(mp * g * d * (mc + mp) / ((mc + mp) * (I + mp * d * d) - mp**2 * d * d))
    eig = lin.eigenvalues
    assert [e for e in eig if e.real > 1e-9] == [pytest.approx(lam, rel=1e-12)]
    assert all(e.imag == 0 for e in eig)
    np.testing.assert_allclose([e.real for e in eig], [-lam, 0, 0, lam], atol=1e-7)
    # with the damper too: still exactly one eigenvalue in the right half plane, and real
    damped = cart_pole.linearize(at={"theta": "pi"})
    right = [e for e in damped.eigenvalues if e.real > 1e-9]
    assert len(right) == 1 and right[0].imag == 0
    assert damped.stable is False


def test_hanging_damped_cart_pole_has_no_unstable_eigenvalue(cart_pole):
    lin = cart_pole.linearize(at={"theta": 0})
    assert all(e.real <= 1e-12 for e in lin.eigenvalues)
    # the damper is fbar's velocity dependence: it is what puts -b/(mc + ...) into A
    undamped = cart_pole.linearize(at={"theta": 0, "b": 0})
    assert undamped.A[2, 2] == 0 and lin.A[2, 2] < 0


def test_velocity_terms_vanish_at_an_equilibrium(double_pendulum):
    """hbar is quadratic in qdot: at rest its derivative in qdot is zero, so without
    dampers the lower right block of A is zero."""
    lin = double_pendulum.linearize(at={"q1": 0, "q2": 0})
    assert np.all(lin.A[2:, 2:] == 0)


def test_no_equilibrium_is_an_error(tmp_path):
    path = tmp_path / "pushed.yaml"
    path.write_text("parameters: {m: 1, F: 2}\ncomponents:\n  p: {type: particle1d, parameters: {mass: m}, "
                    "coordinates: [x]}\ncoordinates: [x]\neffects:\n  push: {type: force, point: p.centre, "
                    "vector: [F]}\n")
    result = CliRunner().invoke(main, ["linearize", str(path)])
    assert result.exit_code == 1
    assert "no equilibrium found" in result.output and "--at" in result.output
    given = CliRunner().invoke(main, ["linearize", str(path), "--at", "x=0", "--format", "json"])
    assert given.exit_code == 0, given.output
    assert "not an equilibrium" in given.output and json.loads(given.stdout)["equilibrium"] is False


def test_cli_formats():
    runner = CliRunner()
    md = runner.invoke(main, ["linearize", str(CART_POLE), "--inputs", "u"])
    assert md.exit_code == 0, md.output
    assert "## A" in md.output and "## Eigenvalues of A" in md.output and "unstable" in md.output
    js = runner.invoke(main, ["linearize", str(CART_POLE), "--inputs", "u", "--format", "json"])
    data = json.loads(js.stdout)
    assert data["state"] == ["x", "theta", "x_dot", "theta_dot"] and data["inputs"] == ["u"]
    assert data["equilibrium"] is True and len(data["A"]) == 4 and len(data["B"][0]) == 1
    assert sum(e["re"] > 0 for e in data["eigenvalues"]) == 1
    tex = runner.invoke(main, ["linearize", str(CART_POLE), "--symbolic", "--format", "latex"])
    assert tex.exit_code == 0 and tex.stdout.startswith("\\documentclass") and "\\end{document}" in tex.stdout
    assert "Cart-pole" not in tex.stdout  # no free text of the model in LaTeX
    assert "values of u and depends on them" in tex.stderr  # u kept a symbol, the equilibrium needs u = 0


def test_cli_reports_every_bad_name_at_once():
    result = CliRunner().invoke(main, ["linearize", str(DOUBLE_PENDULUM), "--at", "qq=1", "--inputs", "z"])
    assert result.exit_code == 1
    assert "'qq' is not a coordinate" in result.output and "input 'z'" in result.output
    assert "2 problems found." in result.output
    assert "Traceback" not in result.output


def test_cli_warns_away_from_equilibrium():
    result = CliRunner().invoke(main, ["linearize", str(DOUBLE_PENDULUM), "--at", "q1=1", "--at", "q2=0"])
    assert result.exit_code == 0, result.output
    assert "not an equilibrium" in result.output


def test_json_output_is_byte_identical_under_different_hash_seeds():
    outputs = []
    for seed in ("0", "4242"):
        env = dict(os.environ, PYTHONHASHSEED=seed)  # the tests' private derive cache
        proc = subprocess.run([sys.executable, "-m", "kronsub", "linearize", str(CART_POLE), "--inputs", "u",
                               "--symbolic", "--format", "json"], capture_output=True, env=env, cwd=ROOT)
        assert proc.returncode == 0, proc.stderr.decode()
        outputs.append(proc.stdout)
    assert outputs[0] == outputs[1]


def test_symbolic_equilibrium_that_depends_on_the_parameters_is_flagged(tmp_path):
    """A hanging spring-mass rests at x* = -m g / k: found with the values, so the
    symbolic A holds at those values only, and says so; the frequency is sqrt(k/m)."""
    path = tmp_path / "hanging.yaml"
    path.write_text("parameters: {m: 2, k: 50, g: 9.81}\ncomponents:\n  p: {type: particle1d, parameters: "
                    "{mass: m}, coordinates: [x]}\ncoordinates: [x]\neffects:\n  gravity: {type: gravity}\n"
                    "  spring: {type: spring, between: [p.centre, [0]], stiffness: k}\n")
    system = kronsub.load(path).derive()
    lin = system.linearize()
    assert float(dict(lin.point)[system.symbol("x")]) == pytest.approx(-2 * 9.81 / 50, rel=1e-12)
    np.testing.assert_allclose(sorted(e.imag for e in lin.eigenvalues), [-5.0, 5.0], rtol=1e-12)
    assert lin.notes == ()
    symbolic = system.linearize(symbolic=True)
    assert symbolic.notes and "values of g, k, m and depends on them" in symbolic.notes[0]
    assert sympy.simplify(symbolic.A[1, 0] + system.symbol("k") / system.symbol("m")) == 0


def test_parameters_without_values(tmp_path):
    """Numeric linearisation names them; symbolic needs the point, checks it exactly."""
    path = tmp_path / "compound.yaml"
    path.write_text(COMPOUND.replace("g: {value: 9.81}", "g:"))
    system = kronsub.load(path).derive()
    with pytest.raises(KronsubError, match="no value for parameter g"):
        system.linearize(at={"theta": 0})
    with pytest.raises(KronsubError, match="cannot find an equilibrium without values for g"):
        system.linearize(symbolic=True)
    lin = system.linearize(at={"theta": "pi"}, symbolic=True)
    assert lin.equilibrium and lin.eigenvalues is None
    m, L, I, g = (system.symbol(n) for n in ("m", "L", "I", "g"))
    assert sympy.simplify(lin.A[1, 0] - m * g * (L / 2) / (I + m * L**2 / 4)) == 0  # upright: unstable sign
    moving = system.linearize(at={"theta": "pi/2"}, symbolic=True)
    assert not moving.equilibrium


def test_cli_scene_leaves_the_damper_out():
    """The cart-pole's scene `undamped`: eigenvalues 0, 0, +-lambda (as with b = 0 above)."""
    result = CliRunner().invoke(main, ["linearize", str(CART_POLE), "--scene", "undamped", "--format", "json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert "b" not in data["parameters"]
    real = sorted(e["re"] for e in data["eigenvalues"])
    assert real[0] == pytest.approx(-real[-1]) and real[-1] > 3 and real[1] == real[2] == 0


def test_implicit_constraints_linearise_numerically_but_not_symbolically():
    path = str(MODELS / "hoffmann" / "system2_implicit.yaml")
    result = CliRunner().invoke(main, ["linearize", path, "--format", "json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["state"] == ["theta", "theta_dot"] and set(data["dependent"]) == {"phi"}
    symbolic = CliRunner().invoke(main, ["linearize", path, "--symbolic"])
    assert symbolic.exit_code == 1
    assert "implicit constraints" in symbolic.output and "numeric only" in symbolic.output
    assert "internal error" not in symbolic.output


def test_the_equilibrium_search_runs_one_method_where_it_converges(monkeypatch):
    """The fallback of a stalled search (trust-region reflective after Levenberg-Marquardt) is
    not run where Levenberg-Marquardt finds the equilibrium: those results stay as they were."""
    import scipy.optimize

    methods, real = [], scipy.optimize.least_squares

    def spy(*args, **kwargs):
        methods.append(kwargs["method"])
        return real(*args, **kwargs)

    monkeypatch.setattr(scipy.optimize, "least_squares", spy)
    for model in (DOUBLE_PENDULUM, MODELS / "examples" / "four_bar.yaml"):
        methods.clear()
        result = CliRunner().invoke(main, ["linearize", str(model)])
        assert result.exit_code == 0 and methods == ["lm"], (model, methods, result.output)


def test_a_mass_matrix_singular_at_the_equilibrium_is_an_error_not_an_internal_one():
    """The ball-joint body's equilibrium is at Euler angles 0, where two of its axes line up:
    Cholesky passed the round-off of a singular Mbar, then numpy's solve raised (an internal
    error, exit 4)."""
    model = ROOT / "tests" / "models" / "sweep5" / "ball_joint_body.yaml"
    result = CliRunner().invoke(main, ["linearize", str(model)])
    assert result.exit_code == 1, result.output
    assert "Error: the mass matrix is singular at psi=" in result.output and "hint: give another operating point" \
        in result.output and "internal error" not in result.output
