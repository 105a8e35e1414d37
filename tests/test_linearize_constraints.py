"""Linearising systems with implicit constraints: the reduced equations in the independent
coordinates, checked against the same mechanism in parametric form (eq. 26) and against
finite differences of the constrained simulation's right-hand side (Newton's method for the
dependent coordinates at every perturbed state)."""
from __future__ import annotations

import numpy as np
import pytest

import kronsub
from conftest import MODELS
from kronsub.simulation.constrained import configure_module
from kronsub.simulation.fallback import numpy_module


def _system(path):
    model = kronsub.load(MODELS / path)
    return model, model.derive()


def _rhs_jacobian(system, lin, h=1e-6):
    """Central differences of the generated numpy right-hand side (the one simulate uses
    without a compiler) in the reduced state, and in the inputs."""
    module = numpy_module(system)
    params = {p: float(v) for p, v in lin.parameters}
    param = np.array([params[p.symbol] for p in system.parameters])
    y0 = np.array([float(v) for _, v in lin.point[: len(lin.state)]])
    guess = np.array([v for _, v in lin.dependent])

    def f(y, param=param):
        configure_module(module, guess, 1e-14)
        return np.asarray(module["rhs"](float(lin.time), y, param), dtype=float)

    A = np.column_stack([(f(y0 + h * e) - f(y0 - h * e)) / (2 * h) for e in np.eye(len(y0))])
    index = [p.symbol for p in system.parameters]
    B = []
    for u in lin.inputs:
        e = np.zeros(len(param))
        e[index.index(u)] = h
        B.append((f(y0, param + e) - f(y0, param - e)) / (2 * h))
    return A, (np.column_stack(B) if B else np.zeros((len(y0), 0))), f(y0)


def test_system2_implicit_equals_its_parametric_form():
    """Hoffmann's System II written with `constraints:` and with the connection (26)."""
    _, implicit = _system("hoffmann/system2_implicit.yaml")
    _, explicit = _system("hoffmann/system2.yaml")
    a = implicit.linearize(inputs=["F"])
    b = explicit.linearize(inputs=["F"])
    assert a.equilibrium and b.equilibrium
    assert float(a.point[0][1]) == pytest.approx(float(b.point[0][1]), abs=1e-10)
    np.testing.assert_allclose(a.A, b.A, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a.B, b.B, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.imag(a.eigenvalues), np.imag(b.eigenvalues), rtol=1e-9)


@pytest.mark.parametrize("path, inputs", [("examples/four_bar.yaml", ["tau"]),
                                          ("examples/slider_crank.yaml", ["P"]),
                                          ("hoffmann/system2_implicit.yaml", ["F"])])
def test_a_and_b_match_finite_differences_of_the_simulation_rhs(path, inputs):
    _, system = _system(path)
    lin = system.linearize(inputs=inputs)
    assert lin.equilibrium and lin.dependent
    A, B, ydot = _rhs_jacobian(system, lin)
    assert np.max(np.abs(ydot)) < 1e-8  # the point is at rest in the simulation too
    np.testing.assert_allclose(lin.A, A, rtol=1e-6, atol=1e-6 * max(1.0, np.max(np.abs(A))))
    np.testing.assert_allclose(lin.B, B, rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("path, at", [("examples/four_bar.yaml", {"theta1": 0.4, "theta1_dot": 1.5}),
                                      ("examples/slider_crank.yaml", {"theta": 0.9, "theta_dot": -2.0})])
def test_away_from_equilibrium_the_velocity_terms_are_linearised_too(path, at):
    """With qdot != 0 the convective terms (gamma, quadratic in qdot) enter A: checked against
    finite differences as well."""
    _, system = _system(path)
    lin = system.linearize(at=at)
    assert not lin.equilibrium
    A, _, ydot = _rhs_jacobian(system, lin)
    np.testing.assert_allclose(lin.acceleration, ydot[len(ydot) // 2:], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(lin.A, A, rtol=1e-6, atol=1e-6 * max(1.0, np.max(np.abs(A))))


def test_a_dependent_coordinate_cannot_be_fixed():
    from click.testing import CliRunner

    from kronsub.cli import main

    result = CliRunner().invoke(main, ["linearize", str(MODELS / "examples" / "four_bar.yaml"), "--at", "theta2=1"])
    assert result.exit_code == 1
    assert "'theta2' is a dependent coordinate" in result.output and "(theta1) instead" in result.output
