"""Sanity checks of the independent sympy.physics.mechanics references.

The references in ``tests/reference/mechanics.py`` are what kronsub gets checked
against, so they are checked here against hand-derived / printed results and
against physics (energy balance, consistency of M and h with T).
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy
from sympy import Matrix, Symbol, cos, sin, sqrt

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reference import mechanics as mr  # noqa: E402

S = sympy.symbols


def _zero(expr) -> bool:
    if isinstance(expr, sympy.MatrixBase):
        return all(sympy.simplify(e) == 0 for e in expr)
    return sympy.simplify(expr) == 0


# References are somewhat expensive to build: build each once per session.
@functools.cache
def ref(name: str) -> mr.Reference:
    if name == "rod_chain2":
        return mr.rod_chain(2)
    if name == "rod_chain2_lagrange":
        return mr.rod_chain(2, "lagrange")
    if name == "rod_chain3":
        return mr.rod_chain(3, simplify=False)
    if name == "rod_chain3_lagrange":
        return mr.rod_chain(3, "lagrange", simplify=False)
    return getattr(mr, name)()


ALL = [
    "system1",
    "system2",
    "double_pendulum",
    "cart_pole",
    "particle_on_sphere",
    "watt_governor",
    "three_particles",
    "rod_chain2",
    "rod_chain3",
    "rod_chain3_lagrange",
]

# Generalized non-conservative forces, f + grad_q V, by hand.
a1, a2, F, I1, I2, m1, m2, g = S("a1 a2 F I1 I2 m1 m2 g")
theta, phi, theta_dot, phi_dot = S("theta phi theta_dot phi_dot")
NONCONSERVATIVE = {
    "system1": Matrix([2 * a1 * F * cos(theta), a2 * F * cos(phi)]),
    "cart_pole": Matrix([S("u") - S("b") * S("x_dot"), 0]),
    "watt_governor": Matrix([S("tau"), 0]),
    "three_particles": Matrix([S("f1"), S("f2") + S("f3")]),
}


def random_values(r: mr.Reference, rng: np.random.Generator) -> dict[str, float]:
    """Random positive parameters and random states (valid for system2)."""
    syms = set(r.mass_matrix.free_symbols | r.velocity_terms.free_symbols | r.forces.free_symbols)
    syms |= r.kinetic_energy.free_symbols | r.potential_energy.free_symbols
    vals = {s.name: float(rng.uniform(0.5, 2.0)) for s in syms}
    for c in r.coordinates:
        vals[c] = float(rng.uniform(-np.pi, np.pi))
        vals[c + "_dot"] = float(rng.uniform(-2.0, 2.0))
    vals["t"] = float(rng.uniform(0, 10))
    if "c" in vals:  # system2: need |c - a1 sin(theta)| < a2
        vals["a1"] = float(rng.uniform(0.5, 1.0))
        vals["a2"] = float(rng.uniform(2.5, 3.0))
        vals["c"] = float(rng.uniform(-1.0, 1.0))
    for k in ("u", "tau", "F", "f1", "f2", "f3"):  # loads of either sign
        if k in vals:
            vals[k] = float(rng.uniform(-2.0, 2.0))
    return vals


# ---------------------------------------------------------------------------
# Conventions
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ALL)
def test_plain_symbols_and_shapes(name):
    r = ref(name)
    n = len(r.coordinates)
    assert r.mass_matrix.shape == (n, n)
    assert r.velocity_terms.shape == (n, 1)
    assert r.forces.shape == (n, 1)
    assert isinstance(r.mass_matrix, sympy.Matrix)
    exprs = [r.mass_matrix, r.velocity_terms, r.forces, r.kinetic_energy, r.potential_energy]
    for e in exprs:
        assert not e.atoms(sympy.Derivative)
        assert not [f for f in e.atoms(sympy.Function) if isinstance(f, sympy.core.function.AppliedUndef)]
        for s in e.free_symbols:
            assert type(s) is Symbol
            assert s == Symbol(s.name)  # no assumptions
    # mass matrix depends only on coordinates and parameters, h vanishes at rest
    vel = set(r.qdot)
    assert not (r.mass_matrix.free_symbols & vel)
    at_rest = {v: 0 for v in vel}
    assert all(e.xreplace(at_rest) == 0 or sympy.simplify(e.xreplace(at_rest)) == 0 for e in r.velocity_terms)
    assert r.mass_matrix == r.mass_matrix.T


def test_numeric_interface():
    r = ref("double_pendulum")
    vals = dict(m1=1.0, m2=2.0, l1=1.5, l2=0.5, g=9.81, q1=0.3, q2=-0.4, q1_dot=1.0, q2_dot=-2.0, t=0.0, extra=3.0)
    M, h, f = mr.numeric(r, vals)
    assert M.shape == (2, 2) and h.shape == (2,) and f.shape == (2,)
    subs = {Symbol(k): v for k, v in vals.items()}
    np.testing.assert_allclose(M, np.array(r.mass_matrix.subs(subs), dtype=float))
    np.testing.assert_allclose(h, np.array(r.velocity_terms.subs(subs), dtype=float).ravel())
    np.testing.assert_allclose(f, np.array(r.forces.subs(subs), dtype=float).ravel())
    del vals["g"]
    with pytest.raises(KeyError):
        mr.numeric(r, vals)


def test_simple_pendulum_signs():
    """m l^2 q'' + m g l sin q = 0: M = m l^2, h = 0, f = -m g l sin q."""
    m, l, g_ = S("m l g")

    def build(q, u, N, O):
        A = N.orientnew("A", "Axis", (q[0], N.z))
        P = O.locatenew("P", -l * A.y)
        P.set_vel(N, P.pos_from(O).dt(N))
        assert P.pos_from(O).to_matrix(N)[:2] == [l * sin(q[0]), -l * cos(q[0])]
        return mr._Model(bodies=[mr.Particle("p", P, m)], gravity=[(m, P)], up=N.y, g=g_)

    r = mr._kane_reference("q", build)
    q, qd = S("q q_dot")
    assert _zero(r.mass_matrix - Matrix([[m * l**2]]))
    assert _zero(r.velocity_terms)
    assert _zero(r.forces - Matrix([-m * g_ * l * sin(q)]))
    assert _zero(r.kinetic_energy - m * l**2 * qd**2 / 2)
    assert _zero(r.potential_energy + m * g_ * l * cos(q))


# ---------------------------------------------------------------------------
# Hoffmann's printed results
# ---------------------------------------------------------------------------


def test_system1_matches_paper_22_23_24():
    r = ref("system1")
    assert r.coordinates == ("theta", "phi")
    M22 = Matrix(
        [
            [I1 + m1 * a1**2 + 4 * m2 * a1**2, 2 * m2 * a1 * a2 * cos(theta - phi)],
            [2 * m2 * a1 * a2 * cos(theta - phi), I2 + m2 * a2**2],
        ]
    )
    f23 = Matrix(
        [
            -(m1 + 2 * m2) * g * a1 * sin(theta) + 2 * a1 * F * cos(theta),
            a2 * F * cos(phi) - a2 * m2 * g * sin(phi),
        ]
    )
    T24 = (
        (I1 + m1 * a1**2 + 4 * m2 * a1**2) * theta_dot**2 / 2
        + 2 * m2 * a1 * a2 * cos(theta - phi) * theta_dot * phi_dot
        + (I2 + m2 * a2**2) * phi_dot**2 / 2
    )
    # Velocity terms: expand the paper's unsimplified Lagrange equations by hand.
    h_paper = Matrix(
        [
            2 * m2 * a1 * a2 * sin(theta - phi) * phi_dot**2,
            -2 * m2 * a1 * a2 * sin(theta - phi) * theta_dot**2,
        ]
    )
    for i in range(2):
        for j in range(2):
            assert sympy.simplify(r.mass_matrix[i, j] - M22[i, j]) == 0
        assert sympy.simplify(r.forces[i] - f23[i]) == 0
        assert sympy.simplify(r.velocity_terms[i] - h_paper[i]) == 0
    assert sympy.simplify(r.kinetic_energy - T24) == 0
    assert sympy.simplify(
        r.potential_energy + g * (m1 * a1 * cos(theta) + m2 * (2 * a1 * cos(theta) + a2 * cos(phi)))
    ) == 0


def test_system1_paper_lagrange_equations_literally():
    """The paper's unsimplified equations d/dt(dT/dqdot) - dT/dq = f, via sympy."""
    r = ref("system1")
    t = Symbol("t")
    th, ph = sympy.Function("th")(t), sympy.Function("ph")(t)
    T24 = (
        (I1 + m1 * a1**2 + 4 * m2 * a1**2) * th.diff(t) ** 2 / 2
        + 2 * m2 * a1 * a2 * cos(th - ph) * th.diff(t) * ph.diff(t)
        + (I2 + m2 * a2**2) * ph.diff(t) ** 2 / 2
    )
    lhs = [T24.diff(x.diff(t)).diff(t) - T24.diff(x) for x in (th, ph)]
    thdd, phdd = S("theta_ddot phi_ddot")
    rep = {th.diff(t, 2): thdd, ph.diff(t, 2): phdd}
    rep2 = {th.diff(t): theta_dot, ph.diff(t): phi_dot}
    rep3 = {th: theta, ph: phi}
    lhs = Matrix([e.subs(rep).subs(rep2).subs(rep3) for e in lhs])
    ours = r.mass_matrix * Matrix([thdd, phdd]) + r.velocity_terms
    assert _zero(lhs - ours)


def _system2_paper(vals):
    """System II via Kron's transformation (27) applied to System I numerically."""
    s1 = ref("system1")
    th = Symbol("theta")
    a1_, a2_, c_ = S("a1 a2 c")
    phi_expr = sympy.asin((c_ - a1_ * sin(th)) / a2_)  # (26)
    lam = -a1_ * cos(th) / sqrt(a2_**2 - (c_ - a1_ * sin(th)) ** 2)  # (27)
    dlam = lam.diff(th)
    sub = {k: v for k, v in vals.items()}
    phi_v = float(phi_expr.subs({Symbol(k): v for k, v in sub.items()}))
    lam_v = float(lam.subs({Symbol(k): v for k, v in sub.items()}))
    dlam_v = float(dlam.subs({Symbol(k): v for k, v in sub.items()}))
    v1 = dict(vals, phi=phi_v, phi_dot=lam_v * vals["theta_dot"])
    M1, h1, f1 = mr.numeric(s1, v1)
    C = np.array([1.0, lam_v])
    Cdot_qd = np.array([0.0, dlam_v * vals["theta_dot"] ** 2])
    M2 = C @ M1 @ C
    h2 = C @ (h1 + M1 @ Cdot_qd)
    f2 = C @ f1
    # (29), last line, literally
    a1v, a2v, cv, thv = vals["a1"], vals["a2"], vals["c"], vals["theta"]
    root = np.sqrt(a2v**2 - (cv - a1v * np.sin(thv)) ** 2)
    f29 = (
        -(vals["m1"] + 2 * vals["m2"]) * vals["g"] * a1v * np.sin(thv)
        + a1v * vals["F"] * np.cos(thv)
        + a1v * vals["m2"] * vals["g"] * (cv - a1v * np.sin(thv)) * np.cos(thv) / root
    )
    return M2, h2, f2, f29


def test_system2_against_kron_projection_of_system1_and_paper_29():
    r = ref("system2")
    assert r.coordinates == ("theta",)
    assert {s.name for s in r.forces.free_symbols} <= {"m1", "m2", "a1", "a2", "g", "F", "c", "theta"}
    rng = np.random.default_rng(2)
    for _ in range(20):
        vals = random_values(r, rng)
        M, h, f = mr.numeric(r, vals)
        M2, h2, f2, f29 = _system2_paper(vals)
        np.testing.assert_allclose(M[0, 0], M2, rtol=1e-10)
        np.testing.assert_allclose(h[0], h2, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(f[0], f2, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(f[0], f29, rtol=1e-10, atol=1e-12)


def test_system2_f_symbolically_with_positive_a2():
    r = ref("system2")
    a2p = Symbol("a2", positive=True)
    c_ = Symbol("c")
    f29 = (
        -(m1 + 2 * m2) * g * a1 * sin(theta)
        + a1 * F * cos(theta)
        + a1 * m2 * g * (c_ - a1 * sin(theta)) * cos(theta) / sqrt(a2**2 - (c_ - a1 * sin(theta)) ** 2)
    )
    diff = (r.forces[0] - f29).xreplace({a2: a2p})
    assert sympy.simplify(diff) == 0


# ---------------------------------------------------------------------------
# Textbook results
# ---------------------------------------------------------------------------


def test_double_pendulum_textbook():
    r = ref("double_pendulum")
    assert r.coordinates == ("q1", "q2")
    l1, l2, q1, q2, q1d, q2d = S("l1 l2 q1 q2 q1_dot q2_dot")
    M = Matrix([[(m1 + m2) * l1**2, m2 * l1 * l2 * cos(q1 - q2)], [m2 * l1 * l2 * cos(q1 - q2), m2 * l2**2]])
    h = Matrix([m2 * l1 * l2 * sin(q1 - q2) * q2d**2, -m2 * l1 * l2 * sin(q1 - q2) * q1d**2])
    f = Matrix([-(m1 + m2) * g * l1 * sin(q1), -m2 * g * l2 * sin(q2)])
    assert _zero(r.mass_matrix - M)
    assert _zero(r.velocity_terms - h)
    assert _zero(r.forces - f)


def test_rod_chain2_hand_lagrangian():
    """Two uniform rods: T, V written by hand, Lagrange's equations by hand."""
    r = ref("rod_chain2")
    assert r.coordinates == ("q1", "q2")
    l1, l2, q1, q2, q1d, q2d = S("l1 l2 q1 q2 q1_dot q2_dot")
    # centre of rod 2 velocity: l1 q1d e(q1) + l2/2 q2d e(q2), e(q) = (cos q, sin q)
    T = (
        m1 * l1**2 / 3 * q1d**2 / 2
        + m2 / 2 * (l1**2 * q1d**2 + l2**2 / 4 * q2d**2 + l1 * l2 * cos(q1 - q2) * q1d * q2d)
        + m2 * l2**2 / 12 * q2d**2 / 2
    )
    V = -m1 * g * l1 / 2 * cos(q1) - m2 * g * (l1 * cos(q1) + l2 / 2 * cos(q2))
    M = Matrix([[(m1 / 3 + m2) * l1**2, m2 * l1 * l2 / 2 * cos(q1 - q2)], [m2 * l1 * l2 / 2 * cos(q1 - q2), m2 * l2**2 / 3]])
    h = Matrix([m2 * l1 * l2 / 2 * sin(q1 - q2) * q2d**2, -m2 * l1 * l2 / 2 * sin(q1 - q2) * q1d**2])
    f = Matrix([-(m1 / 2 + m2) * g * l1 * sin(q1), -m2 * g * l2 / 2 * sin(q2)])
    for rr in (r, ref("rod_chain2_lagrange")):
        assert _zero(rr.mass_matrix - M)
        assert _zero(rr.velocity_terms - h)
        assert _zero(rr.forces - f)
        assert _zero(rr.kinetic_energy - T)
        assert _zero(rr.potential_energy - V)


def test_rod_chain2_is_system1_without_F():
    r, s1 = ref("rod_chain2"), ref("system1")
    l1, l2, q1, q2, q1d, q2d = S("l1 l2 q1 q2 q1_dot q2_dot")
    rep = {
        a1: l1 / 2, a2: l2 / 2, I1: m1 * l1**2 / 12, I2: m2 * l2**2 / 12, F: 0,
        theta: q1, phi: q2, theta_dot: q1d, phi_dot: q2d,
    }
    assert _zero(s1.mass_matrix.xreplace(rep) - r.mass_matrix)
    assert _zero(s1.velocity_terms.xreplace(rep) - r.velocity_terms)
    assert _zero(s1.forces.xreplace(rep) - r.forces)


def test_rod_chain3_kane_equals_lagrange():
    rk, rl = ref("rod_chain3"), ref("rod_chain3_lagrange")
    assert rk.coordinates == rl.coordinates == ("q1", "q2", "q3")
    rng = np.random.default_rng(3)
    for _ in range(10):
        vals = random_values(rk, rng)
        for a, b in zip(mr.numeric(rk, vals), mr.numeric(rl, vals)):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)


def test_rod_chain_raw_interface():
    for method in ("kane", "lagrange"):
        raw = mr.rod_chain(2, method, raw=True)
        assert isinstance(raw, mr.RawDerivation)
        assert raw.coordinates == ("q1", "q2") and raw.method == method
        assert raw.seconds > 0
        M, forcing = raw.plain()
        r = ref("rod_chain2")
        assert _zero(M - r.mass_matrix)
        assert _zero(forcing - (r.forces - r.velocity_terms))
    with pytest.raises(ValueError):
        mr.rod_chain(2, "hamilton")


def test_cart_pole_hand():
    r = ref("cart_pole")
    assert r.coordinates == ("x", "theta")
    mc, mp, l, b, u, xd = S("mc mp l b u x_dot")
    M = Matrix([[mc + mp, mp * l / 2 * cos(theta)], [mp * l / 2 * cos(theta), mp * l**2 / 3]])
    h = Matrix([-mp * l / 2 * sin(theta) * theta_dot**2, 0])
    f = Matrix([u - b * xd, -mp * g * l / 2 * sin(theta)])
    assert _zero(r.mass_matrix - M)
    assert _zero(r.velocity_terms - h)
    assert _zero(r.forces - f)


def test_particle_on_sphere_hand():
    r = ref("particle_on_sphere")
    assert r.coordinates == ("theta", "phi")
    m, R = S("m R")
    M = Matrix([[m * R**2, 0], [0, m * R**2 * sin(theta) ** 2]])
    h = Matrix([-m * R**2 * sin(theta) * cos(theta) * phi_dot**2, 2 * m * R**2 * sin(theta) * cos(theta) * theta_dot * phi_dot])
    f = Matrix([m * g * R * sin(theta), 0])
    assert _zero(r.mass_matrix - M)
    assert _zero(r.velocity_terms - h)
    assert _zero(r.forces - f)
    assert _zero(r.potential_energy - m * g * R * cos(theta))


def test_watt_governor_hand():
    r = ref("watt_governor")
    assert r.coordinates == ("psi", "alpha")
    J, m, l, Ms, tau, al, psd, ald = S("J m l M tau alpha psi_dot alpha_dot")
    M = Matrix([[J + 2 * m * l**2 * sin(al) ** 2, 0], [0, 2 * m * l**2 + 4 * Ms * l**2 * sin(al) ** 2]])
    h = Matrix(
        [
            4 * m * l**2 * sin(al) * cos(al) * psd * ald,
            -2 * m * l**2 * sin(al) * cos(al) * psd**2 + 4 * Ms * l**2 * sin(al) * cos(al) * ald**2,
        ]
    )
    f = Matrix([tau, -2 * (m + Ms) * g * l * sin(al)])
    assert _zero(r.mass_matrix - M)
    assert _zero(r.velocity_terms - h)
    assert _zero(r.forces - f)


def test_three_particles_exact():
    r = ref("three_particles")
    assert r.coordinates == ("x1", "x2")
    m1_, m2_, m3_, f1, f2, f3 = S("m1 m2 m3 f1 f2 f3")
    assert r.mass_matrix == Matrix([[m1_, 0], [0, m2_ + m3_]])
    assert r.velocity_terms == Matrix([0, 0])
    assert _zero(r.forces - Matrix([f1, f2 + f3]))
    assert r.potential_energy == 0


# ---------------------------------------------------------------------------
# Physics: consistency with T and V, energy balance
# ---------------------------------------------------------------------------


@functools.cache
def _energy_functions(name):
    r = ref(name)
    q, qd = list(r.q), list(r.qdot)
    T, V = r.kinetic_energy, r.potential_energy
    E = T + V
    syms = sorted(
        set().union(
            *(e.free_symbols for e in (r.mass_matrix, r.velocity_terms, r.forces, T, V))
        )
        | set(q) | set(qd) | {Symbol("t")},
        key=lambda s: s.name,
    )
    hess = Matrix(len(q), len(q), lambda i, j: T.diff(qd[i]).diff(qd[j]))
    # Lagrange: d/dt dT/dqd_i - dT/dq_i = M qdd + sum_j d2T/dqd_i dq_j qd_j - dT/dq_i
    h_from_T = Matrix(
        [sum(T.diff(qd[i]).diff(q[j]) * qd[j] for j in range(len(q))) - T.diff(q[i]) for i in range(len(q))]
    )
    exprs = [
        hess,
        h_from_T,
        Matrix([E.diff(x) for x in q]),
        Matrix([E.diff(x) for x in qd]),
        Matrix([V.diff(x) for x in q]),
    ]
    return [s.name for s in syms], sympy.lambdify(syms, exprs, "numpy")


@pytest.mark.parametrize("name", ALL)
def test_consistent_with_energies_and_energy_balance(name):
    r = ref(name)
    n = len(r.coordinates)
    names, fn = _energy_functions(name)
    nc = NONCONSERVATIVE.get(name)
    nc_fn = None
    if nc is not None:
        nc_syms = sorted(nc.free_symbols, key=lambda s: s.name)
        nc_fn = sympy.lambdify(nc_syms, nc, "numpy")
    rng = np.random.default_rng(1)
    for _ in range(10):
        vals = random_values(r, rng)
        M, h, f = mr.numeric(r, vals)
        hess, h_T, dEdq, dEdqd, dVdq = (
            np.array(a, dtype=float) for a in fn(*[vals[k] for k in names])
        )
        np.testing.assert_allclose(M, hess.reshape(n, n), rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(h, h_T.ravel(), rtol=1e-9, atol=1e-10)
        qd = np.array([vals[v] for v in r.velocities])
        qdd = np.linalg.solve(M, f - h)
        dEdt = dEdq.ravel() @ qd + dEdqd.ravel() @ qdd
        f_nc = f + dVdq.ravel()  # f = -grad V + f_nc
        np.testing.assert_allclose(dEdt, qd @ f_nc, rtol=1e-8, atol=1e-9)
        expected_nc = np.zeros(n)
        if nc_fn is not None:
            expected_nc = np.array(nc_fn(*[vals[s.name] for s in nc_syms]), dtype=float).ravel()
        if name == "system2":  # F projected with (27)/(28): 2 a1 F cos - a1 F cos
            expected_nc = np.array([vals["a1"] * vals["F"] * np.cos(vals["theta"])])
        np.testing.assert_allclose(f_nc, expected_nc, rtol=1e-9, atol=1e-10)
