"""Circuits as primitive systems (components/electrical.py, effects/electrical.py): branch
charges as coordinates, inductance as the metric, Kirchhoff's voltage law as the connection.
Each bundled network against an answer found without kronsub: the closed-form step response
of the series RLC circuit, and the exact solution (a matrix exponential) of the loop
equations written here from the circuit diagram for the ladder and the transformer."""
from __future__ import annotations

import numpy as np
import pytest
import sympy
from scipy.linalg import expm

import kronsub
from helpers.circuits import CIRCUITS, simulated, symbols


def affine_solution(A, b, y0, times):
    """``y(t)`` of ``ydot = A y + b`` exactly: the augmented matrix ``[[A, b], [0, 0]]``'s exponential."""
    n = len(y0)
    big = np.zeros((n + 1, n + 1))
    big[:n, :n], big[:n, n] = A, b
    start = np.append(y0, 1.0)
    return np.array([(expm(big * t) @ start)[:n] for t in times])


def test_series_rlc_is_the_loop_equation():
    system = kronsub.load(CIRCUITS / "series_rlc.yaml", cache=False).derive(cache=False)
    s = symbols(system)
    L, R, C, E, q, i = (s[n] for n in ("L", "R", "C", "E", "q", "q_dot"))
    assert system.mass_matrix == sympy.Matrix([[L]])  # the loop inductance
    assert sympy.simplify(system.forces[0] - (E - R * i - q / C)) == 0  # the loop voltage
    assert sympy.simplify(system.potential_energy - q**2 / (2 * C)) == 0


def test_series_rlc_step_response_is_the_closed_form():
    header, rows = simulated(CIRCUITS / "series_rlc.yaml", "--scene", "step")
    assert header[:3] == ["t", "q", "i"]
    L, R, C, E = 0.5, 1.0, 0.02, 10.0
    alpha, w0 = R / (2 * L), 1 / np.sqrt(L * C)
    wd = np.sqrt(w0**2 - alpha**2)
    assert alpha < w0  # underdamped
    t = rows[:, 0]
    decay = np.exp(-alpha * t)
    q = C * E * (1 - decay * (np.cos(wd * t) + alpha / wd * np.sin(wd * t)))
    i = C * E * decay * (w0**2 / wd) * np.sin(wd * t)
    assert t[-1] == pytest.approx(1.0)
    np.testing.assert_allclose(rows[:, 1], q, rtol=0, atol=1e-9 * C * E)
    np.testing.assert_allclose(rows[:, 2], i, rtol=0, atol=1e-8 * np.max(np.abs(i)))


def test_series_rlc_discharge_loses_its_energy_in_the_resistor():
    """Without the source, ``T + V`` falls by ``integral R i^2 dt`` (trapezoids on a fine grid)."""
    header, rows = simulated(CIRCUITS / "series_rlc.yaml", "--scene", "discharge", "--dt", "0.0001")
    t, i = rows[:, 0], rows[:, header.index("i")]
    total = rows[:, header.index("total_energy")]
    heat = np.concatenate([[0], np.cumsum(np.diff(t) * (i[1:] ** 2 + i[:-1] ** 2) / 2)])  # R = 1
    assert total[0] == pytest.approx(0.2**2 / (2 * 0.02))
    np.testing.assert_allclose(total + heat, total[0], rtol=1e-5)


def test_ladder_loop_inductance_and_loop_voltages():
    system = kronsub.load(CIRCUITS / "rlc_ladder.yaml", cache=False).derive(cache=False)
    s = symbols(system)
    L1, L2, R1, R2, C1, C2, E = (s[n] for n in ("L1", "L2", "R1", "R2", "C1", "C2", "E"))
    q1, q2, i1, i2 = (s[n] for n in ("q1", "q2", "q1_dot", "q2_dot"))
    assert system.mass_matrix == sympy.diag(L1, L2)
    loop_voltages = sympy.Matrix([E - R1 * i1 - (q1 - q2) / C1, -R2 * i2 + (q1 - q2) / C1 - q2 / C2])
    assert sympy.simplify(system.forces - loop_voltages) == sympy.zeros(2, 1)
    assert system.velocity_terms == sympy.zeros(2, 1)


@pytest.mark.parametrize("path, columns", [
    ("rlc_ladder.yaml", ("q1", "q2", "i_1", "i_2")),  # the mesh transformation under `connection:`
    ("rlc_ladder_nodes.yaml", ("q_L1", "q_L2", "i_L1", "i_L2")),  # the current law under `constraints:`
])
def test_ladder_step_response_is_exact(path, columns):
    header, rows = simulated(CIRCUITS / path, "--scene", "step")
    L1, L2, R1, R2, C1, C2, E = 0.1, 0.2, 2.0, 5.0, 0.01, 0.005, 12.0
    # y = [q1, q2, i1, i2], written from the diagram: L1 i1' = E - R1 i1 - (q1 - q2)/C1, ...
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1],
                  [-1 / (C1 * L1), 1 / (C1 * L1), -R1 / L1, 0],
                  [1 / (C1 * L2), -(1 / C1 + 1 / C2) / L2, 0, -R2 / L2]])
    b = np.array([0, 0, E / L1, 0])
    exact = affine_solution(A, b, np.zeros(4), rows[:, 0])
    got = rows[:, [header.index(c) for c in columns]]
    scale = np.max(np.abs(exact), axis=0)
    np.testing.assert_allclose(got / scale, exact / scale, rtol=0, atol=1e-8)


def test_ladder_energy_balance():
    """The source's work ``E q1`` is the stored ``T + V`` plus the heat ``integral R i^2 dt``."""
    header, rows = simulated(CIRCUITS / "rlc_ladder.yaml", "--scene", "step", "--dt", "0.0001")
    t, q1, i1, i2 = (rows[:, header.index(c)] for c in ("t", "q1", "i_1", "i_2"))
    power = 2.0 * i1**2 + 5.0 * i2**2
    heat = np.concatenate([[0], np.cumsum(np.diff(t) * (power[1:] + power[:-1]) / 2)])
    stored = rows[:, header.index("total_energy")]
    assert np.max(heat) > 0.1 * np.max(stored)  # the resistors matter
    np.testing.assert_allclose(stored + heat, 12.0 * q1, rtol=0, atol=1e-6 * np.max(12.0 * q1))


def test_transformer_metric_holds_the_mutual_inductance_and_its_response_is_exact():
    system = kronsub.load(CIRCUITS / "transformer.yaml", cache=False).derive(cache=False)
    s = symbols(system)
    assert system.mass_matrix == sympy.Matrix([[s["L1"], s["M"]], [s["M"], s["L2"]]])
    header, rows = simulated(CIRCUITS / "transformer.yaml", "--scene", "switched_on")
    L1, L2, M, R1, R2, E, w = 0.2, 0.05, 0.09, 1.0, 10.0, 100.0, 314.159
    # [L1 M; M L2] i' = [E sin(wt) - R1 i1, -R2 i2]; sin and cos as two more states of the linear system
    Minv = np.linalg.inv(np.array([[L1, M], [M, L2]]))
    A = np.zeros((6, 6))
    A[0, 2] = A[1, 3] = 1
    A[2:4, 2:4] = Minv @ np.diag([-R1, -R2])
    A[2:4, 4] = Minv @ np.array([E, 0])
    A[4, 5], A[5, 4] = w, -w  # s' = w c, c' = -w s
    exact = affine_solution(A, np.zeros(6), np.array([0, 0, 0, 0, 0, 1.0]), rows[:, 0])[:, :4]
    got = rows[:, [header.index(c) for c in ("q1", "q2", "i_1", "i_2")]]
    scale = np.max(np.abs(exact), axis=0)
    np.testing.assert_allclose(got / scale, exact / scale, rtol=0, atol=1e-8)



def test_parallel_rlc_natural_response_is_the_closed_form():
    """The node voltage ``v = q_C / C`` of ``v'' + v'/(R C) + v/(L C) = 0`` from ``v(0) = V0``,
    ``i_L(0) = 0`` (so ``C v'(0) = -V0/R``), and the coil's current ``L i_L' = -v``:
    ``v = V0 e^(-a t) (cos wd t - a/wd sin wd t)``, ``i_L = -V0/(L wd) e^(-a t) sin wd t``,
    ``a = 1/(2 R C)``; the resistor's current is ``v / R``."""
    header, rows = simulated(CIRCUITS / "parallel_rlc.yaml", "--t", "1", "--dt", "0.001")
    assert header[:5] == ["t", "q1", "q2", "i_1", "i_2"]
    L, C, R, V0 = 0.5, 0.02, 10.0, 5.0
    a, w0 = 1 / (2 * R * C), 1 / np.sqrt(L * C)
    wd = np.sqrt(w0**2 - a**2)
    t = rows[:, 0]
    v = V0 * np.exp(-a * t) * (np.cos(wd * t) - a / wd * np.sin(wd * t))
    i_L = -V0 / (L * wd) * np.exp(-a * t) * np.sin(wd * t)
    np.testing.assert_allclose((rows[:, 1] - rows[:, 2]) / C, v, rtol=0, atol=1e-8 * V0)
    np.testing.assert_allclose(rows[:, 3], i_L, rtol=0, atol=1e-8 * V0 / (L * wd))
    np.testing.assert_allclose(rows[:, 4], v / R, rtol=0, atol=1e-8 * V0 / R)


BALANCE = {"dc_motor.yaml": ("--set", "t_load=5")}  # its load step has an exact balance of its own
"""Extra options per model: the trapezoid rule below wants smooth powers."""


@pytest.mark.parametrize("path", sorted(p.name for p in CIRCUITS.glob("*.yaml") if p.name != "rlc_ladder_nodes.yaml"))
def test_energy_balance_on_every_bundled_circuit(path):
    """``T + V`` changes by the work of the effects without a potential (sources, resistors,
    gyrators, a textbook component's dissipation): ``d(T + V)/dt = sum fbar_e . qdot``, the
    power integrated by trapezoids over a run of 2000 rows. (The ladder by node equations has
    the trajectory of the ladder by meshes, checked above.)"""
    system = kronsub.load(CIRCUITS / path, cache=False).derive(cache=False)
    t_end = {"synchronous_machine.yaml": 0.02, "synchronous_machine_dq.yaml": 0.02, "transformer.yaml": 0.05,
             "loudspeaker.yaml": 0.01}.get(path, 0.2)
    # (rows finer than the fastest mode: the loudspeaker's Le/Re is 0.08 ms)
    header, rows = simulated(CIRCUITS / path, "--t", str(t_end), "--dt", str(t_end / 2000), *BALANCE.get(path, ()))
    values = {p.symbol: sympy.Float(float(p.value)) for p in system.parameters}
    if path in BALANCE:
        values[symbols(system)[BALANCE[path][1].split("=")[0]]] = sympy.Float(BALANCE[path][1].split("=")[1])
    working = [label for label in system.effect_forces if system.effect_potentials.get(label, 0) == 0]
    assert working  # every circuit has a source or a resistor
    # in a change of velocity frame (Park's axes) the power is fbar . u in the speeds
    forces, moving = ((system.speeds.effect_forces, system.speeds.speeds) if system.speeds is not None
                      else (system.effect_forces, system.velocities))
    power = sum((forces[label].T * sympy.Matrix(moving))[0] for label in working)
    t = sympy.Symbol("t", real=True)
    state = [*system.coordinates, *moving]
    P = sympy.lambdify([t, *state], power.xreplace(values))
    columns = [header.index(system.name_of(q)) for q in state]
    p = np.array([P(row[0], *row[columns]) for row in rows], dtype=float)
    work = np.concatenate([[0], np.cumsum(np.diff(rows[:, 0]) * (p[1:] + p[:-1]) / 2)])
    energy = rows[:, header.index("total_energy")]
    scale = max(np.max(np.abs(energy)), np.max(np.abs(work)))
    assert np.max(np.abs(work)) > 1e-3 * scale  # the effects do work
    np.testing.assert_allclose(energy - energy[0], work, rtol=0, atol=1e-5 * scale)


def test_series_rlc_linearised_has_the_circuits_natural_frequencies():
    """``linearize``: the equilibrium is the charged capacitor ``q = C E``, the eigenvalues
    ``-R/(2L) +- j sqrt(1/(L C) - (R/(2L))^2)``, and ``B`` the source's ``1/L``."""
    system = kronsub.load(CIRCUITS / "series_rlc.yaml", cache=False).derive(cache=False)
    lin = system.linearize(inputs=["E"])
    L, R, C, E = 0.5, 1.0, 0.02, 10.0
    assert lin.equilibrium and float(dict(lin.point)[symbols(system)["q"]]) == pytest.approx(C * E)
    alpha, wd = R / (2 * L), np.sqrt(1 / (L * C) - (R / (2 * L)) ** 2)
    assert sorted(lin.eigenvalues, key=lambda z: z.imag) == pytest.approx([-alpha - 1j * wd, -alpha + 1j * wd])
    np.testing.assert_allclose(np.asarray(lin.B, dtype=float).ravel(), [0, 1 / L])


def test_elements_written_on_loop_charges_give_the_same_loop_voltages():
    """An element's ``charge:`` may name the loop charges themselves (applied in the subspace,
    ``Effect.direct_force``): the ladder's loop voltages are the same."""
    text = (CIRCUITS / "rlc_ladder.yaml").read_text(encoding="utf-8")
    for branch, loop in (("q_E", "q1"), ("q_R1", "q1"), ("q_C1", "q1 - q2"), ("q_R2", "q2"), ("q_C2", "q2")):
        text = text.replace(f"charge: {branch},", f"charge: {loop},")
    assert "charge: q_" not in text
    by_loops = kronsub.load("loops.yaml", text=text, cache=False).derive(cache=False)
    by_branches = kronsub.load(CIRCUITS / "rlc_ladder.yaml", cache=False).derive(cache=False)
    assert set(by_loops.effect_forces) == set(by_branches.effect_forces)
    for label, force in by_branches.effect_forces.items():
        assert sympy.simplify(by_loops.effect_forces[label] - force) == sympy.zeros(2, 1), label
    assert sympy.simplify(by_loops.potential_energy - by_branches.potential_energy) == 0
