"""Viewpoint (alpha): reactions as unknowns (Hoffmann, R and -R at A and A').

- System I's hinge reaction at A, from ``derive --reactions``, satisfies Newton-Euler on the
  lower rod (its rotation about its centre) and on the upper rod (about O), with the
  accelerations from the independent sympy.physics.mechanics reference.
- (alpha) and (beta) give the same motion: the four-bar integrated in all its coordinates
  with Lagrange multipliers (M yddot + h = f + G^T mu, G yddot = quadratic) follows the
  projected system's trajectory, and its multipliers are the reactions kronsub prints.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from reference import mechanics as ref
from conftest import MODELS
from kronsub.cli import main
from kronsub.core.constraints import Intermediates
from kronsub.core.reactions import reactions
from kronsub.core.symbols import velocity_symbol


def test_system1_hinge_reaction_agrees_with_newton_euler():
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive()
    items = dict(reactions(system))
    reference = ref.system1()
    rng = np.random.default_rng(44)
    for _ in range(10):
        values = {n: rng.uniform(0.3, 1.7) for n in ("m1", "m2", "a1", "a2", "I1", "I2", "g", "F")}
        values.update({n: rng.uniform(-1.5, 1.5) for n in ("theta", "phi", "theta_dot", "phi_dot")})
        M, h, f = ref.numeric(reference, values)
        thdd, phdd = np.linalg.solve(M, f - h)
        values.update(theta_ddot=thdd, phi_ddot=phdd)
        sub = {s: values[s.name] for e in items.values() for s in e.free_symbols}
        Ry, Rz = (float(items[k].xreplace(sub)) for k in ("R_y", "R_z"))
        th, ph, a1, a2 = values["theta"], values["phi"], values["a1"], values["a2"]
        # lower rod about its centre: the hinge A' is a2 (-sin phi, cos phi) from it
        moment = a2 * (-np.sin(ph)) * Rz - a2 * np.cos(ph) * Ry
        assert np.isclose(values["I2"] * phdd, moment, rtol=1e-10, atol=1e-10)
        # upper rod about O: gravity and -R at A = 2 a1 (sin theta, -cos theta)
        lhs = (values["I1"] + values["m1"] * a1**2) * thdd
        rhs = -values["m1"] * values["g"] * a1 * np.sin(th) - 2 * a1 * (np.sin(th) * Rz + np.cos(th) * Ry)
        assert np.isclose(lhs, rhs, rtol=1e-10, atol=1e-10)


def test_derive_reactions_in_the_output():
    result = CliRunner().invoke(main, ["derive", str(MODELS / "hoffmann" / "system1.yaml"), "--reactions",
                                       "--format", "json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert set(data["reactions"]["expressions"]) == {"R_theta", "R_y", "R_z", "R_phi"}


def test_alpha_and_beta_give_the_same_motion():
    from scipy.integrate import solve_ivp

    model = kronsub.load(MODELS / "examples" / "four_bar.yaml")
    system = model.derive()
    imp = system.implicit
    values = {p.symbol: p.value for p in system.parameters}
    y = list(imp.independent) + list(imp.dependent)
    yd = [velocity_symbol(q) for q in y]
    # (alpha) in all of y: the projection onto y (before the constraints), untouched by them
    order = [imp.intermediate.index(q) for q in y]
    M = imp.metric.extract(order, order).xreplace(values)
    h = imp.velocity_terms.extract(order, [0]).xreplace(values)
    f = imp.forces.extract(order, [0]).xreplace(values)
    g = sympy.Matrix([c.expression for c in imp.constraints]).xreplace(values)
    G = g.jacobian(y)
    quad = -(G * sympy.Matrix(yd)).jacobian(y) * sympy.Matrix(yd)
    fM, fh, ff, fG, fq = (sympy.lambdify(y + yd + [sympy.Symbol("t", real=True)], e, "numpy")
                          for e in (M, h, f, G, quad))
    k, ny = len(imp.constraints), len(y)

    def alpha(t, state):
        args = list(state) + [t]
        A = np.zeros((ny + k, ny + k))
        Gv = np.array(fG(*args), float)
        A[:ny, :ny], A[:ny, ny:], A[ny:, :ny] = np.array(fM(*args), float), -Gv.T, Gv
        b = np.concatenate([np.array(ff(*args), float).ravel() - np.array(fh(*args), float).ravel(),
                            np.array(fq(*args), float).ravel()])
        sol = np.linalg.solve(A, b)
        return np.concatenate([state[ny:], sol[:ny]]), sol[ny:]

    ev = Intermediates(imp, values)
    q0 = np.array([float(model.initial.get(q, 0)) for q in imp.independent])
    qd0 = np.array([float(model.initial.get(velocity_symbol(q), 0)) for q in imp.independent])
    w = ev.at(q0, qd0)
    lam = np.array([[w[s] for s in row] for row in imp.sensitivities.tolist()])
    state0 = np.concatenate([q0, [w[d] for d in imp.dependent], qd0, lam @ qd0])
    times = np.linspace(0, 2, 21)
    a = solve_ivp(lambda t, s: alpha(t, s)[0], (0, 2), state0, t_eval=times, rtol=1e-11, atol=1e-11,
                  method="DOP853")
    result = CliRunner().invoke(main, ["simulate", str(MODELS / "examples" / "four_bar.yaml"), "--t", "2",
                                       "--dt", "0.1", "--reactions"])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    header = lines[0].split(",")
    beta = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    col = {n: i for i, n in enumerate(header)}
    assert np.allclose(a.y[0], beta[:, col["theta1"]], atol=1e-7)
    assert np.allclose(a.y[ny], beta[:, col["theta1_dot"]], atol=1e-7)
    # the multipliers of (alpha) are the reactions kronsub prints
    for i, t in enumerate(times[::5]):
        _, mu = alpha(t, a.y[:, i * 5])
        printed = [beta[i * 5, col[f"mu_{c.name.replace('.', '_')}"]] for c in imp.constraints]
        assert np.allclose(mu, printed, rtol=1e-6, atol=1e-6), (mu, printed)


def test_a_reaction_named_like_a_coordinate_gets_its_own_column(tmp_path):
    """A coordinate called ``R_x`` beside a primitive ``x``: the CSV keeps one column per
    quantity (the coordinate's is ``R_x``, the reaction's ``reaction_R_x``), and the reaction
    is the rod's pull on the bob, towards O: ``m (g cos R_x + L R_x_dot^2) (-sin R_x, cos R_x)``."""
    model = tmp_path / "bob.yaml"
    model.write_text(
        "name: bob on a massless rod\n"
        "parameters:\n  m: {value: 1.5, unit: kg}\n  L: {value: 0.8, unit: m}\n  g: {value: 9.81, unit: m/s^2}\n"
        "components:\n  bob: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}\n"
        "coordinates: [R_x]\n"
        "connection: {x: L*sin(R_x), y: -L*cos(R_x)}\n"
        "effects:\n  gravity: {type: gravity, g: g}\n"
        "initial: {R_x: 0.7, R_x_dot: 1.1}\n", encoding="utf-8")
    result = CliRunner().invoke(main, ["simulate", str(model), "--t", "0.2", "--dt", "0.1", "--reactions"])
    assert result.exit_code == 0, result.output
    lines = [ln for ln in result.stdout.splitlines() if not ln.startswith("#")]
    header = lines[0].split(",")
    assert len(header) == len(set(header)) and "reaction_R_x" in header and "R_y" in header, header
    col = {n: i for i, n in enumerate(header)}
    for line in lines[1:]:
        row = [float(v) for v in line.split(",")]
        angle, rate = row[col["R_x"]], row[col["R_x_dot"]]
        tension = 1.5 * (9.81 * np.cos(angle) + 0.8 * rate ** 2)  # the rod pulls the bob towards O
        assert row[col["reaction_R_x"]] == pytest.approx(-tension * np.sin(angle), rel=1e-6)
        assert row[col["R_y"]] == pytest.approx(tension * np.cos(angle), rel=1e-6)
