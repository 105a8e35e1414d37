"""Odd expressions that derive also build and agree (issue 31, section 5).

``sign`` where it is differentiated (a connection), ``abs(sign(q))``, and products of powers
whose integer coefficients pass 64 bits (no C or numpy integer holds them): every such model
checks, derives without ``DiracDelta``, builds under ``gcc -std=c99 -Wall -Wextra -Werror -O2``,
and its C and numpy code agree with the symbolic equations; ``simulate`` runs on the C, on
the numpy fallback, on the Taylor integrator and on heyoka.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from helpers.generated import c_agrees_with_symbolic, python_agrees_with_symbolic
from kronsub.cli import main
from kronsub.core.derivative import derivative, jacobian

ODD = {
    "sign_in_connection": """\
parameters:
  m: {value: 1.5}
  k: {value: 2}
components:
  bob: {type: particle1d, parameters: {mass: m}, coordinates: [x]}
coordinates: [q]
connection: {x: "q + q*sign(q)/10 + sin(sign(q))*q/7"}
effects:
  spring: {type: potential, value: "k*(abs(x) - 1/3)**2/2"}
initial: {q: 0.3}
""",
    "abs_of_sign": """\
parameters:
  m: {value: 1}
  k: {value: 2}
components:
  bob: {type: particle1d, parameters: {mass: m}, coordinates: [x]}
coordinates: [q]
connection: {x: q}
effects:
  push: {type: force, point: bob.centre, vector: ["-k*q*abs(sign(q)) - abs(sign(q_dot))*q_dot"]}
initial: {q: 0.3}
""",
    "big_coefficients": """\
parameters:
  m: {value: 1}
components:
  bob: {type: particle1d, parameters: {mass: m}, coordinates: [x]}
coordinates: [q]
connection: {x: q}
effects:
  stiff: {type: force, point: bob.centre, vector: ["-(2*q)**40*(3*q)**30*q - (2*q/3)**45*q_dot - q"]}
  well: {type: potential, value: "(5*q)**29*(7*q)**23/11**30"}
initial: {q: 0.1}
""",
}


@pytest.fixture(params=sorted(ODD))
def odd(request, tmp_path):
    path = tmp_path / f"{request.param}.yaml"
    path.write_text(f"name: {request.param}\n" + ODD[request.param], encoding="utf-8")
    return path


def test_an_odd_model_checks_and_derives_without_impulses(odd):
    result = CliRunner().invoke(main, ["check", str(odd)])
    assert result.exit_code == 0, result.output
    system = kronsub.load(odd).derive()
    for matrix in (system.mass_matrix, system.velocity_terms, system.forces):
        assert not matrix.has(sympy.DiracDelta)
    if odd.stem == "big_coefficients":  # the coefficients that no 64-bit integer holds are there
        assert any(abs(int(n)) > 2 ** 64 for n in system.forces.atoms(sympy.Integer))


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
def test_an_odd_model_builds_under_werror_and_agrees_with_the_symbolic_equations(odd, tmp_path):
    (tmp_path / "c").mkdir()
    c_agrees_with_symbolic(str(odd), tmp_path / "c")


def test_the_numpy_code_of_an_odd_model_agrees_with_the_symbolic_equations(odd, tmp_path):
    python_agrees_with_symbolic(str(odd), tmp_path)


@pytest.mark.parametrize("env, method", [({}, "dop853"), ({"CC": "kronsub-no-such-compiler"}, "DOP853"),
                                         ({}, "taylor"), ({}, "heyoka")])
def test_an_odd_model_simulates_on_every_backend(odd, env, method, tmp_path, monkeypatch):
    """Every backend, heyoka's ``sign(0)`` included (``abs_of_sign`` starts at rest: it was NaN)."""
    if method in ("dop853", "taylor") and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    if method == "heyoka":
        pytest.importorskip("heyoka")
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    result = CliRunner().invoke(main, ["simulate", str(odd), "--t", "0.2", "--dt", "0.1", "--method", method])
    assert result.exit_code == 0, result.output
    assert "failed" not in result.stderr, result.stderr
    rows = [list(map(float, line.split(","))) for line in result.stdout.splitlines()[1:]]
    assert len(rows) == 3 and np.all(np.isfinite(rows))


def test_sign_and_abs_are_differentiated_where_they_have_a_derivative():
    q = sympy.Symbol("q", real=True)
    assert derivative(q * sympy.sign(q), q) == sympy.sign(q)
    assert derivative(sympy.Abs(q), q) == sympy.sign(q)
    assert derivative(sympy.sin(sympy.sign(q)) * q, q) == sympy.sin(sympy.sign(q))
    assert derivative(sympy.sign(q), q) == 0
    J = jacobian(sympy.Matrix([q * sympy.sign(q), sympy.sin(sympy.Abs(q))]), [q])
    assert J == sympy.Matrix([sympy.sign(q), sympy.cos(sympy.Abs(q)) * sympy.sign(q)])


def test_heyoka_runs_a_model_whose_parameters_cancel(tmp_path, monkeypatch):
    """``m*sign(q)**2*qddot = 0`` and a free particle: no parameter is left in the equations
    (heyoka refused the parameter values it did not see: an internal error), in simulate and
    accuracy."""
    pytest.importorskip("heyoka")
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    free = tmp_path / "free.yaml"
    free.write_text("name: free\nparameters:\n  m: {value: 1}\n  k: {value: 3}\ncomponents:\n"
                    "  bob: {type: particle1d, parameters: {mass: m}, coordinates: [x]}\ncoordinates: [q]\n"
                    "connection: {x: q}\ninitial: {q: 0.3, q_dot: 1}\n", encoding="utf-8")
    result = CliRunner().invoke(main, ["simulate", str(free), "--t", "0.2", "--dt", "0.1", "--method", "heyoka"])
    assert result.exit_code == 0, result.output
    assert [float(v) for v in result.stdout.splitlines()[-1].split(",")[:3]] == pytest.approx([0.2, 0.5, 1.0])
    result = CliRunner().invoke(main, ["accuracy", str(free), "--t", "0.1", "--quick", "--methods", "heyoka",
                                       "--tolerances", "1e-6"])
    assert result.exit_code == 0, result.output
    assert "| heyoka | tol 1e-06 |" in result.stdout
