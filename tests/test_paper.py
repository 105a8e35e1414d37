"""The paper's examples against its printed equations, term by term (Hoffmann 1944)."""
from __future__ import annotations

import sympy
from sympy import asin, cos, sin, sqrt

import kronsub
from conftest import MODELS
from helpers import S, assert_same

HOFFMANN = MODELS / "hoffmann"


def test_three_particles_eqs_8_and_9():
    system = kronsub.load(HOFFMANN / "three_particles.yaml").derive()
    m1, m2, m3, f1, f2, f3 = S("m1 m2 m3 f1 f2 f3")
    assert [q.name for q in system.coordinates] == ["x1", "x2"]
    # (9): Mbar = C^t M C = diag(m1, m2 + m3)
    assert system.mass_matrix == sympy.Matrix([[m1, 0], [0, m2 + m3]])
    # (8): fbar = C^t F = (f1, f2 + f3)
    assert system.forces == sympy.Matrix([f1, f2 + f3])
    assert system.velocity_terms == sympy.zeros(2, 1)
    # (7): C
    assert system.transition.transformation == sympy.Matrix([[1, 0], [0, 1], [0, 1]])


def test_system1_metric_eq_22():
    system = kronsub.load(HOFFMANN / "system1.yaml").derive()
    m1, m2, a1, a2, I1, I2, th, ph = S("m1 m2 a1 a2 I1 I2 theta phi")
    M = system.mass_matrix
    assert_same(M[0, 0], I1 + m1 * a1**2 + 4 * m2 * a1**2)
    assert_same(M[0, 1], 2 * m2 * a1 * a2 * cos(th - ph))
    assert_same(M[1, 0], 2 * m2 * a1 * a2 * cos(th - ph))
    assert_same(M[1, 1], I2 + m2 * a2**2)
    # the compact closed form itself, not merely an equivalent one
    assert M[0, 1] == 2 * a1 * a2 * m2 * cos(th - ph)


def test_system1_primitive_eqs_16_17_21():
    system = kronsub.load(HOFFMANN / "system1.yaml").derive()
    m1, m2, a1, a2, I1, I2, g, F, th, ph = S("m1 m2 a1 a2 I1 I2 g F theta phi")
    tr = system.transition
    names = [x.name for x in tr.primitive_coordinates]
    order = [names.index(n) for n in ("theta", "phi", "y", "z")]
    M = tr.primitive_metric.extract(order, order)
    assert_same(M - sympy.diag(I1 + m1 * a1**2, I2, m2, m2), sympy.zeros(4, 4))
    f = sum(tr.primitive_forces.values(), sympy.zeros(4, 1)).extract(order, [0])
    # (17), with z up and y horizontal
    for got, want in zip(f, [-m1 * g * a1 * sin(th), 0, F, -m2 * g]):
        assert_same(got, want)
    # (21): C^t rows theta, phi over columns theta, phi, y, z
    Ct = tr.transformation.extract(order, [0, 1]).T
    want = sympy.Matrix([[1, 0, 2 * a1 * cos(th), 2 * a1 * sin(th)], [0, 1, a2 * cos(ph), a2 * sin(ph)]])
    assert_same(Ct - want, sympy.zeros(2, 4))


def test_system1_forces_eq_23():
    system = kronsub.load(HOFFMANN / "system1.yaml").derive()
    m1, m2, a1, a2, g, F, th, ph = S("m1 m2 a1 a2 g F theta phi")
    f = system.forces
    assert_same(f[0], -(m1 + 2 * m2) * g * a1 * sin(th) + 2 * a1 * F * cos(th))
    assert_same(f[1], a2 * F * cos(ph) - a2 * m2 * g * sin(ph))


def test_system1_kinetic_energy_eq_24_and_lagrange_equations():
    system = kronsub.load(HOFFMANN / "system1.yaml").derive()
    m1, m2, a1, a2, I1, I2, th, ph, thd, phd = S("m1 m2 a1 a2 I1 I2 theta phi theta_dot phi_dot")
    T = (I1 + m1 * a1**2 + 4 * m2 * a1**2) * thd**2 / 2 + 2 * m2 * a1 * a2 * cos(th - ph) * thd * phd \
        + (I2 + m2 * a2**2) * phd**2 / 2
    assert_same(system.kinetic_energy, T)
    # the paper's Lagrange equations (after (24)): the velocity terms are
    # d/dt of the momenta minus the accelerations, minus dT/dq
    assert_same(system.velocity_terms[0], 2 * m2 * a1 * a2 * sin(th - ph) * phd**2)
    assert_same(system.velocity_terms[1], -2 * m2 * a1 * a2 * sin(th - ph) * thd**2)


def test_system2_force_eq_29():
    system = kronsub.load(HOFFMANN / "system2.yaml").derive()
    m1, m2, a1, a2, g, F, c, th = S("m1 m2 a1 a2 g F c theta")
    assert [q.name for q in system.coordinates] == ["theta"]
    want = (-(m1 + 2 * m2) * g * a1 * sin(th) + a1 * F * cos(th)
            + a1 * m2 * g * (c - a1 * sin(th)) * cos(th) / sqrt(a2**2 - (c - a1 * sin(th)) ** 2))
    got = system.forces[0]
    # equal for a2 > 0 (the paper's sqrt(a2^2 - u^2) is a2 sqrt(1 - u^2/a2^2))
    positive = {s: sympy.Symbol(s.name, positive=True) for s in (m1, m2, a1, a2, g)}
    diff = sympy.simplify((got - want).xreplace(positive))
    assert diff == 0, diff


def test_system2_metric_is_system1_metric_on_the_subspace():
    """(26), (27): Mbar = [1 lambda] M_I [1 lambda]^t with lambda = dphi/dtheta."""
    sys1 = kronsub.load(HOFFMANN / "system1.yaml").derive()
    sys2 = kronsub.load(HOFFMANN / "system2.yaml").derive()
    a1, a2, c, th, ph = S("a1 a2 c theta phi")
    phi_of = asin((c - a1 * sin(th)) / a2)
    lam = sympy.diff(phi_of, th)
    M1 = sys1.mass_matrix.xreplace({ph: phi_of})
    want = (sympy.Matrix([[1, lam]]) * M1 * sympy.Matrix([1, lam]))[0, 0]
    import random

    rng = random.Random(4)
    for _ in range(5):
        vals = {s: rng.uniform(0.5, 1.5) for s in want.free_symbols | sys2.mass_matrix[0, 0].free_symbols}
        vals[c] = 0.2
        vals[th] = rng.uniform(-0.3, 0.3)
        a = float(sys2.mass_matrix[0, 0].xreplace(vals).evalf(30))
        b = float(want.xreplace(vals).evalf(30))
        assert abs(a - b) <= 1e-12 * abs(b)
