"""Electromechanical systems by the same projection: a known system from its textbook
equations (model/textbook.py) and the DC machine's gyrator (effects/electrical.py), against
the equations published for them and the exact solution of a linear model."""
from __future__ import annotations

import numpy as np
import pytest
import sympy
from click.testing import CliRunner
from scipy.linalg import expm

import kronsub
from helpers.circuits import CIRCUITS, simulated
from helpers.circuits import symbols as named
from kronsub.cli import main


def accelerations(system):
    return system.mass_matrix.LUsolve(system.forces - system.velocity_terms)


def test_magnetic_force_comes_from_the_metric():
    """``hbar_y = -i^2/2 dL/dy``: the force ``i^2/2 dL/dy`` of the magnet on the ball is a
    velocity term of the projection, and the coil sees the motional EMF ``i ydot dL/dy``."""
    system = kronsub.load(CIRCUITS / "magnetic_suspension.yaml", cache=False).derive(cache=False)
    s = named(system)
    y, i, ydot = s["y"], s["q_dot"], s["y_dot"]
    L = s["L1"] + s["L0"] * s["a"] / (s["a"] + y)
    assert sympy.simplify(system.mass_matrix - sympy.diag(s["m"], L)) == sympy.zeros(2, 2)
    assert sympy.simplify(system.velocity_terms[0] + i**2 / 2 * sympy.diff(L, y)) == 0
    assert sympy.simplify(system.velocity_terms[1] - i * ydot * sympy.diff(L, y)) == 0


def test_magnetic_suspension_is_khalils_model_at_random_states():
    """Khalil, Nonlinear Systems, exercise 1.18: ``m yddot = -k ydot + m g + F``,
    ``F = -L0 i^2/(2 a (1 + y/a)^2)``, and ``d(L(y) i)/dt = -R i + v``."""
    system = kronsub.load(CIRCUITS / "magnetic_suspension.yaml", cache=False).derive(cache=False)
    s = named(system)
    derived = sympy.lambdify([s[n] for n in ("y", "y_dot", "q_dot", "v")], list(accelerations(system).xreplace(
        {p.symbol: p.value for p in system.parameters if p.name != "v"})))
    m, a, L0, L1, R, k, g = 0.1, 0.05, 0.01, 0.02, 1.0, 0.001, 9.81
    rng = np.random.default_rng(1944)
    for _ in range(20):
        y, ydot, i, v = rng.uniform(0, 0.2), rng.uniform(-1, 1), rng.uniform(-10, 10), rng.uniform(-20, 20)
        F = -L0 * i**2 / (2 * a * (1 + y / a) ** 2)
        Ly = L1 + L0 / (1 + y / a)
        dLdy = -L0 / (a * (1 + y / a) ** 2)
        expected = [g - k / m * ydot + F / m, (v - R * i - dLdy * ydot * i) / Ly]
        np.testing.assert_allclose(derived(y, ydot, i, v), expected, rtol=1e-12, atol=1e-12)


def test_balanced_ball_stays_at_its_equilibrium_for_a_while():
    header, rows = simulated(CIRCUITS / "magnetic_suspension.yaml", "--scene", "balanced")
    assert np.max(np.abs(rows[:, header.index("y")] - 0.05)) < 1e-5
    assert np.max(np.abs(rows[:, header.index("i")] - 6.264184)) < 1e-4


DC = dict(R=0.5, L=4.5e-3, k=0.5, J=0.02, f=0.01, V=1.0, tau_L=0.25, t_load=1.0)


def dc_motor_exact(times):
    """``[q, theta, i, omega]`` of ``L i' = V - R i - k omega``, ``J omega' = k i - f omega - tau``
    from rest, ``tau`` stepping from 0 to ``tau_L`` at ``t_load``: each piece is affine with
    constant input, solved by the exponential of its augmented matrix."""
    R, L, k, J, f, V = (DC[n] for n in ("R", "L", "k", "J", "f", "V"))

    def flow(y0, tau, t):
        big = np.zeros((5, 5))
        big[0, 2] = big[1, 3] = 1
        big[2, 2:4] = [-R / L, -k / L]
        big[3, 2:4] = [k / J, -f / J]
        big[2, 4], big[3, 4] = V / L, -tau / J
        return (expm(big * t) @ np.append(y0, 1.0))[:4]

    at_load = flow(np.zeros(4), 0.0, DC["t_load"])
    return np.array([flow(np.zeros(4), 0.0, t) if t <= DC["t_load"] else
                     flow(at_load, DC["tau_L"], t - DC["t_load"]) for t in times])


def test_dc_motor_with_a_load_step_is_the_exact_solution():
    header, rows = simulated(CIRCUITS / "dc_motor.yaml", "--dt", "0.01")
    exact = dc_motor_exact(rows[:, 0])
    got = rows[:, [header.index(c) for c in ("q", "theta", "i", "theta_dot")]]
    scale = np.max(np.abs(exact), axis=0)
    np.testing.assert_allclose(got / scale, exact / scale, rtol=0, atol=1e-7)
    # the speed before and after the step: omega = k V/(R f + k^2), then less by the load's share
    R, k, f, V, tau = DC["R"], DC["k"], DC["f"], DC["V"], DC["tau_L"]
    assert got[rows[:, 0] == 1.0, 3][0] == pytest.approx(k * V / (R * f + k**2), rel=1e-6)
    assert got[-1, 3] == pytest.approx((k * V - R * tau) / (R * f + k**2), rel=1e-6)


def test_dc_motor_energy_balance():
    """Supplied ``V q`` = stored ``T`` + heat ``integral (R i^2 + f omega^2) dt`` + the load's
    work ``integral tau omega dt``: the gyrator itself neither makes nor loses energy."""
    header, rows = simulated(CIRCUITS / "dc_motor.yaml", "--dt", "0.0005")
    t, q, i, w = (rows[:, header.index(c)] for c in ("t", "q", "i", "theta_dot"))
    theta = rows[:, header.index("theta")]
    power = DC["R"] * i**2 + DC["f"] * w**2
    heat = np.concatenate([[0], np.cumsum(np.diff(t) * (power[1:] + power[:-1]) / 2)])
    loaded = np.flatnonzero(t == DC["t_load"])[0]
    spent = heat + DC["tau_L"] * np.maximum(theta - theta[loaded], 0) * (t > DC["t_load"])  # tau (theta - theta_1)
    stored = rows[:, header.index("kinetic_energy")]
    np.testing.assert_allclose(stored + spent, DC["V"] * q, rtol=0, atol=1e-5 * np.max(DC["V"] * q))


def test_a_textbook_component_is_the_library_component_it_writes():
    """Mechanics too: a point mass in polar coordinates given by its metric and potential
    derives the same equations as the library's ``particle_polar`` under a spring to the origin."""
    textbook = """
name: polar by its textbook equations
parameters: {m: 2, k: 3}
components:
  bob: {coordinates: [r, th], metric: [[m, 0], [0, m*r**2]], potential: k*r**2/2}
coordinates: [r, th]
connection: {r: r, th: th}
"""
    library = """
name: polar from the library
parameters: {m: 2, k: 3}
components:
  bob: {type: particle_polar, parameters: {mass: m}, coordinates: [r, th]}
coordinates: [r, th]
connection: {r: r, th: th}
effects:
  spring: {type: spring, between: [bob.centre, [0, 0]], stiffness: k}
"""
    a = kronsub.load("textbook.yaml", text=textbook, cache=False).derive(cache=False)
    b = kronsub.load("library.yaml", text=library, cache=False).derive(cache=False)
    assert sympy.simplify(a.mass_matrix - b.mass_matrix) == sympy.zeros(2, 2)
    assert sympy.simplify(accelerations(a) - accelerations(b)) == sympy.zeros(2, 1)
    assert sympy.simplify(a.potential_energy - b.potential_energy) == 0


BAD = """
name: bad
parameters: {m: 1, L: 1}
components:
  c: {coordinates: [y, q], metric: METRIC, potential: POTENTIAL}
coordinates: [y, q]
connection: {y: y, q: q}
"""


@pytest.mark.parametrize("metric, potential, message", [
    ("[[m, 0], [1, L]]", "0", "`metric:` of 'c' is not symmetric: entry (2, 1) is not entry (1, 2)"),
    ("[[m, 0]]", "0", "`metric:` of 'c' must be 2 rows of 2 entries"),
    ("[[m, 0], [0, L]]", "m*t", "in potential of 'c' 'm*t': unknown name 't'"),
    ("[[m, 0], [0, L*y_dot]]", "0", "unknown name 'y_dot'"),
])
def test_bad_textbook_components_are_located_errors(tmp_path, metric, potential, message):
    path = tmp_path / "bad.yaml"
    path.write_text(BAD.replace("METRIC", metric).replace("POTENTIAL", potential), encoding="utf-8")
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1, result.output
    assert message in result.output and "bad.yaml:5:" in result.output
    assert "Traceback" not in result.output


def park(theta):
    """Park's transformation ``x_dq0 = P(theta) x_abc`` (Kundur, 3.3)."""
    angles = np.array([theta, theta - 2 * np.pi / 3, theta + 2 * np.pi / 3])
    return 2 / 3 * np.array([np.cos(angles), -np.sin(angles), [0.5, 0.5, 0.5]])


def test_synchronous_machine_in_phase_variables_is_parks_dq0_model_at_random_states():
    """The machine's phase-variable equations, derived by the projection, turned into Park's
    axes at random states, are Park's equations written here by hand (motor convention,
    ``v = R i + dpsi/dt``): ``psi_d = Ld i_d + Lafd i_f``, ``psi_q = Lq i_q``, ``psi_0 = L0 i_0``,
    ``psi_f = Lffd i_f + 3/2 Lafd i_d``; ``v_d = R i_d + psi_d' - omega psi_q``,
    ``v_q = R i_q + psi_q' + omega psi_d``, ``v_0 = R i_0 + psi_0'``, ``v_f = R_f i_f + psi_f'``;
    ``J omega' = 3/2 (psi_d i_q - psi_q i_d) + Tm - D omega``, with the constant
    ``Ld = Laa0 + Lab0 + 3/2 Laa2``, ``Lq = Laa0 + Lab0 - 3/2 Laa2``, ``L0 = Laa0 - 2 Lab0``."""
    system = kronsub.load(CIRCUITS / "synchronous_machine.yaml", cache=False).derive(cache=False)
    p = {info.name: float(info.value) for info in system.parameters}
    s = named(system)
    state = [s[n] for n in ("q_a", "q_b", "q_c", "q_f", "theta", "q_a_dot", "q_b_dot", "q_c_dot", "q_f_dot",
                            "theta_dot")]
    t = sympy.Symbol("t", real=True)
    derived = sympy.lambdify([t, *state], list(accelerations(system).xreplace(
        {info.symbol: info.value for info in system.parameters})))
    Ld = p["Laa0"] + p["Lab0"] + 1.5 * p["Laa2"]
    Lq = p["Laa0"] + p["Lab0"] - 1.5 * p["Laa2"]
    L0 = p["Laa0"] - 2 * p["Lab0"]
    flux = np.array([[Ld, 0, 0, p["Lafd"]], [0, Lq, 0, 0], [0, 0, L0, 0], [1.5 * p["Lafd"], 0, 0, p["Lffd"]]])
    rng = np.random.default_rng(36)
    for _ in range(25):
        tt, theta, omega = rng.uniform(0, 0.1), rng.uniform(-np.pi, np.pi), rng.uniform(-400, 400)
        i_abc, i_f = rng.uniform(-50, 50, 3), rng.uniform(-20, 20)
        got = np.array(derived(tt, 0, 0, 0, 0, theta, *i_abc, i_f, omega), dtype=float)
        # Park's side
        P = park(theta)
        i_d, i_q, i_0 = P @ i_abc
        v_abc = p["Vm"] * np.cos(p["w"] * tt - np.array([0, 2 * np.pi / 3, -2 * np.pi / 3]))
        v_d, v_q, v_0 = P @ v_abc
        psi_d, psi_q = Ld * i_d + p["Lafd"] * i_f, Lq * i_q
        rates = np.linalg.solve(flux, [v_d - p["Rs"] * i_d + omega * psi_q, v_q - p["Rs"] * i_q - omega * psi_d,
                                       v_0 - p["Rs"] * i_0, p["vf"] - p["Rf"] * i_f])
        torque = 1.5 * (psi_d * i_q - psi_q * i_d)
        omega_rate = (torque + p["Tm"] - p["D"] * omega) / p["J"]
        # the projection's phase currents' rates, in Park's axes: d(P i)/dt = P i' + omega dP/dtheta i
        dP = (park(theta + 1e-6) - park(theta - 1e-6)) / 2e-6
        dq0_rates = P @ got[:3] + omega * dP @ i_abc
        scale = np.max(np.abs(rates))
        np.testing.assert_allclose(dq0_rates, rates[:3], rtol=0, atol=1e-7 * scale)
        np.testing.assert_allclose(got[3], rates[3], rtol=0, atol=1e-7 * scale)
        np.testing.assert_allclose(got[4], omega_rate, rtol=1e-9, atol=1e-9 * abs(omega_rate))


def test_machines_in_parallel_add_their_stator_inductances():
    """Kron's ``Zbar = Cᵀ Z C`` for two machines in one loop per phase: the loop inductances
    are the sum of the machines' stator inductances, each field couples with its own sign, and
    the rotors keep their inertia."""
    machine = kronsub.load(CIRCUITS / "machine.yaml", cache=False).derive(cache=False)
    pair = kronsub.load(CIRCUITS / "machine_pair.yaml", cache=False).derive(cache=False)
    m, s = named(machine), named(pair)
    L = machine.mass_matrix
    left, right = (L.xreplace({m["theta"]: s[name]}) for name in ("th1", "th2"))
    M = pair.mass_matrix
    assert [q.name for q in pair.coordinates] == ["qa", "qb", "qc", "qf1", "qf2", "th1", "th2"]
    assert sympy.simplify(M[:3, :3] - (left[:3, :3] + right[:3, :3])) == sympy.zeros(3, 3)
    assert sympy.simplify(M[:3, 3] - left[:3, 3]) == sympy.zeros(3, 1)
    assert sympy.simplify(M[:3, 4] + right[:3, 3]) == sympy.zeros(3, 1)
    assert M[3:, 3:] == sympy.diag(L[3, 3], L[3, 3], L[4, 4], L[4, 4])


def test_machines_in_parallel_stay_in_step():
    """The left machine drives the right one through the phases: after the swing the angle
    between the rotors stays bounded (they are synchronized), and the driven one turns with it."""
    header, rows = simulated(CIRCUITS / "machine_pair.yaml", "--t", "2", "--dt", "0.01")
    delta = rows[:, header.index("th1")] - rows[:, header.index("th2")]
    assert np.all(np.abs(delta) < 1.0)
    speeds = rows[:, [header.index("th1_dot"), header.index("th2_dot")]]
    assert np.max(np.abs(speeds[:, 0] - speeds[:, 1])) < 2.0  # rad/s, against about 300


def test_loudspeaker_draws_the_current_of_its_textbook_impedance():
    """In the steady state the coil's current is ``E/Z(jw)`` with the loudspeaker's input
    impedance ``Z = Re + jw Le + Bl^2/(Rms + jw Mms + 1/(jw Cms))`` (the cone's motional
    impedance seen through the gyrator): amplitude and phase fitted over the last periods."""
    header, rows = simulated(CIRCUITS / "loudspeaker.yaml", "--t", "0.2", "--dt", "0.0001")
    Le, Re, Bl, Mms, Cms, Rms, E, w = 0.5e-3, 6.0, 7.0, 0.015, 0.8e-3, 1.5, 2.0, 400.0
    Z = Re + 1j * w * Le + Bl**2 / (Rms + 1j * w * Mms + 1 / (1j * w * Cms))
    current = E / Z  # phasor of i against sin(w t): i = Im(current exp(j w t))
    late = rows[:, 0] > 0.1
    t, i = rows[late, 0], rows[late, header.index("i")]
    basis = np.column_stack([np.sin(w * t), np.cos(w * t)])
    (a, b), *_ = np.linalg.lstsq(basis, i, rcond=None)  # i = a sin + b cos = Im((a + j b) exp(j w t))
    assert a + 1j * b == pytest.approx(current, rel=1e-6)
    np.testing.assert_allclose(basis @ [a, b], i, rtol=0, atol=1e-6 * abs(current))
