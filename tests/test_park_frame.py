"""A change of velocity frame (`speeds:` without `velocity_constraints:`,
core/reference_frame.py): Kron's non-holonomic reference frame without a constraint. The
synchronous machine in phase variables, carried to Park's d-q currents by ``xdot = C u`` with
``C = P(theta)^T``, against Park's equations written here from the textbook; a rigid body in
its body-frame velocities against Euler's equations in the plane; bad frames as located errors."""
from __future__ import annotations

import json

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from helpers.circuits import CIRCUITS, simulated
from helpers.located import line_column, refused
from kronsub.cli import main
from kronsub.emitters.text import emit_json


def named(system):
    """Parameters, coordinates and speeds of a system in speeds, by name."""
    return ({p.name: p.symbol for p in system.parameters} | {q.name: q for q in system.coordinates}
            | {u.name: u for u in system.speeds.speeds})


def park_power_invariant(theta):
    """Park's power-invariant transformation ``x_dq0 = P(theta) x_abc`` (P orthogonal)."""
    angles = [theta, theta - 2 * sympy.pi / 3, theta + 2 * sympy.pi / 3]
    k = sympy.sqrt(sympy.Rational(2, 3))
    return sympy.Matrix([[k * sympy.cos(a) for a in angles], [-k * sympy.sin(a) for a in angles],
                         [1 / sympy.sqrt(3)] * 3])


@pytest.fixture(scope="module")
def machine_dq():
    return kronsub.load(CIRCUITS / "synchronous_machine_dq.yaml", cache=False).derive(cache=False)


def test_machine_in_parks_frame_is_the_textbook_park_model(machine_dq):
    """``Mbar``, ``hbar``, ``fbar`` in the speeds ``(i_d, i_q, i_0, i_f, omega)`` are Park's
    equations (Kundur 3.3, power-invariant, one pole pair, motor convention): ``psi_d = Ld i_d +
    Lmd i_f``, ``psi_q = Lq i_q``, ``psi_0 = L0 i_0``, ``psi_f = Lffd i_f + Lmd i_d`` with ``Ld =
    Laa0 + Lab0 + 3/2 Laa2``, ``Lq = Laa0 + Lab0 - 3/2 Laa2``, ``L0 = Laa0 - 2 Lab0``, ``Lmd =
    sqrt(3/2) Lafd``; speed voltages ``-omega psi_q``, ``omega psi_d``; torque
    ``psi_d i_q - psi_q i_d``; ``v_dq0 = P v_abc``. Mbar exactly, and constant in theta."""
    s = named(machine_dq)
    eq = machine_dq.speeds
    assert [u.name for u in eq.speeds] == ["i_d", "i_q", "i_0", "i_f", "omega"]
    i_d, i_q, i_0, i_f, omega = eq.speeds
    theta, t = s["theta"], sympy.Symbol("t", real=True)
    Laa0, Lab0, Laa2, Lafd, Lffd, J = (s[n] for n in ("Laa0", "Lab0", "Laa2", "Lafd", "Lffd", "J"))
    Ld, Lq, L0 = Laa0 + Lab0 + 3 * Laa2 / 2, Laa0 + Lab0 - 3 * Laa2 / 2, Laa0 - 2 * Lab0
    Lmd = sympy.sqrt(sympy.Rational(3, 2)) * Lafd
    mass = sympy.Matrix([[Ld, 0, 0, Lmd, 0], [0, Lq, 0, 0, 0], [0, 0, L0, 0, 0], [Lmd, 0, 0, Lffd, 0],
                         [0, 0, 0, 0, J]])
    assert theta not in eq.mass_matrix.free_symbols  # Park: constant inductances in d-q axes
    assert (eq.mass_matrix - mass).applyfunc(sympy.simplify) == sympy.zeros(5, 5)
    psi_d, psi_q = Ld * i_d + Lmd * i_f, Lq * i_q
    hbar = sympy.Matrix([-omega * psi_q, omega * psi_d, 0, 0, -(psi_d * i_q - psi_q * i_d)])
    Vm, w = s["Vm"], s["w"]
    v_abc = sympy.Matrix([Vm * sympy.cos(w * t - k * 2 * sympy.pi / 3) for k in (0, 1, -1)])
    v_d, v_q, v_0 = park_power_invariant(theta) * v_abc
    fbar = sympy.Matrix([v_d - s["Rs"] * i_d, v_q - s["Rs"] * i_q, v_0 - s["Rs"] * i_0,
                         s["vf"] - s["Rf"] * i_f, s["Tm"] - s["D"] * omega])
    got = sympy.lambdify([t, theta, *eq.speeds, *[p.symbol for p in machine_dq.parameters]],
                         list(eq.velocity_terms) + list(eq.forces))
    want = sympy.lambdify([t, theta, *eq.speeds, *[p.symbol for p in machine_dq.parameters]],
                          list(hbar) + list(fbar))
    rng = np.random.default_rng(37)
    for _ in range(20):
        args = [rng.uniform(0, 0.1), rng.uniform(-np.pi, np.pi), *rng.uniform(-50, 50, 4),
                rng.uniform(-400, 400), *rng.uniform(0.01, 2.0, len(machine_dq.parameters))]
        a, b = np.array(got(*args), dtype=float), np.array(want(*args), dtype=float)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(b))))


def test_derive_prints_parks_equations(machine_dq):
    """The printed contract (JSON) shows Park's form: ``Mbar`` free of ``theta``, the bus voltages
    in Park's axes as one sinusoid of ``w t - theta`` each (the three phases' ``fbar`` summed)."""
    data = json.loads(emit_json(machine_dq))
    assert data["velocity_constraints"] == {} and data["speeds"] == ["i_d", "i_q", "i_0", "i_f", "omega"]
    assert not any("theta" in entry for row in data["mass_matrix"] for entry in row)
    assert data["forces"][:3] == ["-Rs*i_d + sqrt(6)*Vm*cos(t*w - theta)/2",
                                  "-Rs*i_q + sqrt(6)*Vm*sin(t*w - theta)/2", "-Rs*i_0"]


def test_parks_frame_is_the_jacobian_of_no_connection(machine_dq):
    """``C = P^T`` (P orthogonal), and ``i_d`` is the rate of no coordinate: its one-form
    ``Y_d dx`` (``Y = C^-1``) is not closed, ``d Y_d,a / d theta != d Y_d,theta / d q_a``, as
    Kron's d-q axes are non-holonomic."""
    s = named(machine_dq)
    C = machine_dq.speeds.transformation
    P = park_power_invariant(s["theta"])
    assert (C[:3, :3] - P.T).applyfunc(sympy.simplify) == sympy.zeros(3, 3)
    x = machine_dq.coordinates
    Y = sympy.Matrix([[sympy.diff(e, sympy.Symbol(f"{q.name}_dot", real=True)) for q in x]
                      for _, e in machine_dq.speeds.definitions])
    assert (Y[:3, :3] - P).applyfunc(sympy.simplify) == sympy.zeros(3, 3)
    assert (Y * C - sympy.eye(5)).applyfunc(sympy.simplify) == sympy.zeros(5, 5)
    assert sympy.simplify(sympy.diff(Y[0, 0], s["theta"]) - sympy.diff(Y[0, 4], s["q_a"])) != 0


def test_dq_run_is_the_phase_run_seen_through_park():
    """The dq model's run is the phase model's run with its currents turned by Park's
    transformation and its speed, to the run's tolerance."""
    args = ("--t", "0.02", "--dt", "0.001")
    head_abc, abc = simulated(CIRCUITS / "synchronous_machine.yaml", *args)
    head_dq, dq = simulated(CIRCUITS / "synchronous_machine_dq.yaml", *args)
    col = {n: i for i, n in enumerate(head_abc)}
    cdq = {n: i for i, n in enumerate(head_dq)}
    np.testing.assert_allclose(dq[:, cdq["t"]], abc[:, col["t"]])
    theta = sympy.Symbol("theta")
    P = sympy.lambdify(theta, park_power_invariant(theta))
    for row_abc, row_dq in zip(abc, dq):
        currents = np.array(P(row_abc[col["theta"]]), dtype=float) @ row_abc[[col["i_a"], col["i_b"],
                                                                             col["i_c"]]]
        np.testing.assert_allclose(row_dq[[cdq["i_d"], cdq["i_q"], cdq["i_0"]]], currents, rtol=0, atol=1e-6)
        np.testing.assert_allclose(row_dq[cdq["i_f"]], row_abc[col["i_f"]], rtol=0, atol=1e-6)
        np.testing.assert_allclose(row_dq[cdq["omega"]], row_abc[col["theta_dot"]], rtol=1e-9)
        np.testing.assert_allclose(row_dq[cdq["theta"]], row_abc[col["theta"]], rtol=1e-9, atol=1e-9)
    assert np.max(np.abs(dq[:, cdq["i_d"]])) > 1.0  # the bus drives real currents


BODY = """name: body
parameters:
  m: {value: 2}
  I: {value: 0.3}
components:
  body: {type: planar_body, parameters: {mass: m, inertia: I}}
coordinates: [x, y, theta]
connection: {body.x: x, body.y: y, body.angle: theta}
"""


def test_body_frame_velocities_give_eulers_equations(tmp_path):
    """A planar body in its body-frame velocities ``v``, ``w`` and rate ``r``: ``Mbar =
    diag(m, m, I)`` and ``hbar = (-m w r, m v r, 0)`` (the rotating frame's terms)."""
    path = tmp_path / "body.yaml"
    path.write_text(BODY + "speeds:\n  v: cos(theta)*x_dot + sin(theta)*y_dot\n"
                    "  w: -sin(theta)*x_dot + cos(theta)*y_dot\n  r: theta_dot\n", encoding="utf-8")
    system = kronsub.load(path, cache=False).derive(cache=False)
    s = named(system)
    v, w, r = system.speeds.speeds
    assert system.speeds.mass_matrix == sympy.diag(s["m"], s["m"], s["I"])
    want = sympy.Matrix([-s["m"] * w * r, s["m"] * v * r, 0])
    assert (system.speeds.velocity_terms - want).applyfunc(sympy.simplify) == sympy.zeros(3, 1)


BAD = [
    ("speeds:\n  v: cos(theta)*x_dot**2\n  w: y_dot\n  r: theta_dot\n",
     "speed 'v' is not linear in the velocities", "Y(x) xdot", "v:"),
    ("speeds:\n  v: x_dot + x\n  w: y_dot\n  r: theta_dot\n",
     "speed 'v' has a term without a velocity", "Y(x) xdot", "v:"),
    ("speeds:\n  v: x_dot + y_dot\n  w: 2*x_dot + 2*y_dot\n  r: theta_dot\n",
     "speed 'w' is a combination of the speeds before it at every configuration", "independent", "w:"),
    ("speeds: {}\n", "0 speed(s) for 3 velocities and no velocity constraint", "name 3 speeds", "speeds:"),
    ("speeds:\n  v: 0*x_dot\n  w: y_dot\n  r: theta_dot\n",
     "speed 'v' is zero at every configuration", "independent", "v:"),
    ("speeds:\n  v: x_dot\n  r: theta_dot\n",
     "2 speed(s) for 3 velocities and no velocity constraint", "name 3 speeds", "speeds:"),
    ("speeds:\n  v: cos(theta)*x_dot\n  w: y_dot\n  r: theta_dot\ninitial: {theta: 1.5707963267948966}\n",
     "the speeds are singular at the initial configuration (theta = 1.5707963267948966)", "start", "speeds:"),
    ("speeds:\n  v: x_dot\n  w: y_dot\n  r: theta_dot\ninitial: {x_dot: 1}\n",
     "'x_dot' is not a speed: the speeds fix it", "v, w, r", "x_dot: 1"),
    ("speeds:\n  v: x_dot\n  w: y_dot\n  r: theta_dot\nconstraints:\n  c: x - y\n",
     "`speeds:` (a change of velocity frame) together with `constraints:` is not supported yet", "closed loop",
     "speeds:"),
]


@pytest.mark.parametrize("extra, message, hint, at", BAD)
def test_bad_frames_are_located(tmp_path, extra, message, hint, at):
    text = BODY + extra
    path, out = refused(tmp_path, text)
    index = len(BODY) + extra.index(at)
    line, column = line_column(text, index)
    assert f"Error: {path}:{line}:{column}: {message}" in out
    hint_line = out.split(message, 1)[1].split("\n")[1]
    assert hint_line.startswith("  hint: ") and hint in hint_line


def test_a_speed_not_linear_under_velocity_constraints_is_placed_at_the_speed(tmp_path):
    """Under velocity constraints too, a speed that is not linear in the velocities is said of
    the speed, where it is written (not of a constraint)."""
    text = BODY + ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\n"
                   "speeds:\n  v: x_dot**2\n  w: theta_dot\n")
    path = tmp_path / "model.yaml"
    path.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["derive", str(path), "--no-cache"])
    line = text[:text.index("  v: x_dot**2")].count("\n") + 1
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"Error: {path}:{line}:3: speed 'v' is not linear in the velocities" in result.output
