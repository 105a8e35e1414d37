"""``linearize`` about a steady motion: where no equilibrium has ``qdot = 0``, the cyclic
coordinates (in none of ``Mbar``, ``hbar``, ``fbar``) move at constant velocities found with the
other coordinates: the DC motor's steady speed and current, the magnet's holding current.
``A`` against the matrices of the equations written by hand (the motor's ``L i' = V - R i - k w``,
``J w' = k i - f w``; Khalil's magnetic suspension)."""
from __future__ import annotations

import numpy as np

import kronsub
from conftest import MODELS
from kronsub.core.linearize import linearize


def values(system):
    return {p.name: float(p.value) for p in system.parameters}


def test_dc_motor_at_its_steady_speed():
    system = kronsub.load(MODELS / "electrical" / "dc_motor.yaml").derive()
    lin = linearize(system)
    p = values(system)
    R, L, k, J, f, V = (p[name] for name in ("R", "L", "k", "J", "f", "V"))
    w = k * V / (R * f + k * k)
    point = {s.name: float(v) for s, v in lin.point}
    assert lin.equilibrium and np.isclose(point["theta_dot"], w, rtol=1e-10)
    assert np.isclose(point["q_dot"], f * w / k, rtol=1e-10)
    expected = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [0, 0, -R / L, -k / L], [0, 0, k / J, -f / J]])
    assert np.allclose(np.asarray(lin.A, dtype=float), expected, rtol=1e-10, atol=1e-12)
    assert any("steady motion" in note and "q, theta" in note for note in lin.notes)


def test_magnet_holding_the_ball():
    """At ``v = R i``, ``i^2 = 2 m g (a + y)^2/(L0 a)``: Khalil's linearisation in ``(y, ydot, i)``,
    ``yddot = g - k/m ydot - L0 a i^2/(2 m (a + y)^2)``, ``L(y) i' = v - R i + L0 a i ydot/(a + y)^2``."""
    system = kronsub.load(MODELS / "electrical" / "magnetic_suspension.yaml").derive(scene="balanced")
    lin = linearize(system, initial={s: 0.05 for s in system.coordinates if s.name == "y"})
    p = values(system) | {"v": 6.264184}
    m, a, L0, L1, R, k = (p[name] for name in ("m", "a", "L0", "L1", "R", "k"))
    i = p["v"] / R
    point = {s.name: float(v) for s, v in lin.point}
    y = point["y"]
    assert np.isclose(i * i, 2 * m * p["g"] * (a + y) ** 2 / (L0 * a), rtol=1e-8)
    assert np.isclose(point["q_dot"], i, rtol=1e-10)
    Ly = L1 + L0 * a / (a + y)
    expected = np.array([[0, 0, 1, 0], [0, 0, 0, 1],
                         [L0 * a * i * i / (m * (a + y) ** 3), 0, -k / m, -L0 * a * i / (m * (a + y) ** 2)],
                         [0, 0, L0 * a * i / ((a + y) ** 2 * Ly), -R / Ly]])
    # the q_dot row's dependence on y: (v - R i)/L(y) is zero at the steady current
    assert np.allclose(np.asarray(lin.A, dtype=float), expected, rtol=1e-7, atol=1e-9)
