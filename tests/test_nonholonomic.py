"""Non-holonomic constraints (core/nonholonomic.py): the rolling disc and the Chaplygin sleigh
against sympy's KanesMethod with the same velocity constraints, the sleigh's asymptotic motion
and the disc's energy in simulation, and the refusals of bad constraints and speeds."""
import numpy as np
import pytest
import sympy
from scipy.integrate import solve_ivp
from sympy.physics import mechanics as me

from kronsub.core.nonholonomic import (VelocityConstraintError, integrable, linear_form, project_nonholonomic,
                                       velocity_transformation)
from kronsub.core.primitive import christoffel_terms
from kronsub.core.symbols import symbol, velocity_symbol

m, g, r, a, I = (symbol(n) for n in ("m", "g", "r", "a", "I"))


def _ours(q, qs, T, V):
    """``M``, ``h``, ``f`` of the unconstrained system from ``T(q, qdot)`` and ``V(q)``."""
    qd = [velocity_symbol(s) for s in qs]
    M = sympy.hessian(T, qd).applyfunc(sympy.expand)
    return M, christoffel_terms(M, qs, qd), sympy.Matrix([-sympy.diff(V, s) for s in qs])


def _to_symbols(expr, q, qs):
    t = me.dynamicsymbols._t
    return sympy.sympify(expr).subs({sympy.Derivative(a_, t): velocity_symbol(b) for a_, b in zip(q, qs)}).subs(
        dict(zip(q, qs)))


def _kane_udot(kane, q, u, state_q, state_u, values):
    at = {**dict(zip(q, state_q)), **dict(zip(u, state_u)), **values}
    M = np.array(kane.mass_matrix.subs(at).evalf(), dtype=float)
    F = np.array(kane.forcing.subs(at).evalf(), dtype=float)
    return np.linalg.solve(M, F).ravel()


def _rolling_disc():
    q = me.dynamicsymbols("q1:6")  # yaw, lean, spin, contact x, contact y
    u = me.dynamicsymbols("u1:6")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q[0], N.z])
    L = Y.orientnew("L", "Axis", [q[1], Y.x])
    R = L.orientnew("R", "Axis", [q[2], L.y])
    O = me.Point("O")
    O.set_vel(N, 0)
    C = O.locatenew("C", q[3] * N.x + q[4] * N.y)  # the contact point, where it is on the plane
    centre = C.locatenew("Dmc", r * L.z)
    centre.set_vel(N, centre.pos_from(O).dt(N))
    contact = centre.locatenew("P", -r * L.z)
    slip = centre.vel(N) + R.ang_vel_in(N).cross(contact.pos_from(centre))
    constraints = [slip.dot(N.x), slip.dot(N.y)]
    inertia = me.inertia(L, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4)
    disc = me.RigidBody("disc", centre, R, m, (inertia, centre))
    T = disc.kinetic_energy(N)
    V = m * g * centre.pos_from(C).dot(N.z)
    # Kane: u = qdot, the contact point's speeds dependent
    to_u = {qi.diff(): ui for qi, ui in zip(q, u)}
    kane = me.KanesMethod(N, q_ind=q, u_ind=u[:3], u_dependent=u[3:], kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u)],
                          velocity_constraints=[c.subs(to_u) for c in constraints])
    kane.kanes_equations([disc], [(centre, -m * g * N.z)])
    return q, u, T, V, constraints, kane


def test_rolling_disc_against_kanes_method():
    q, u, T, V, constraints, kane = _rolling_disc()
    qs = tuple(symbol(n) for n in ("yaw", "lean", "spin", "x", "y"))
    M, h, f = _ours(q, qs, _to_symbols(T, q, qs), _to_symbols(V, q, qs))
    velocity = velocity_transformation([_to_symbols(c, q, qs) for c in constraints], qs)
    assert velocity.speeds == tuple(velocity_symbol(s) for s in qs[:3])  # the contact's velocities dependent
    assert velocity.constraint_matrix * velocity.transformation == sympy.zeros(2, 3) or \
        (velocity.constraint_matrix * velocity.transformation).applyfunc(sympy.simplify) == sympy.zeros(2, 3)
    p = project_nonholonomic(M, h, f, velocity)
    rng = np.random.default_rng(11)
    values = {m: 1.7, g: 9.81, r: 0.35}
    for _ in range(4):
        state_q = rng.uniform(-1.2, 1.2, 5)
        speeds = rng.uniform(-3, 3, 3)
        at = {**dict(zip(qs, state_q)), **dict(zip(velocity.speeds, speeds)), **values}
        xdot = np.array(velocity.kinematics.subs(at).evalf(), dtype=float).ravel()
        ours = np.linalg.solve(np.array(p.mass_matrix.subs(at).evalf(), dtype=float),
                               np.array((p.forcing - p.velocity_terms).subs(at).evalf(), dtype=float)).ravel()
        theirs = _kane_udot(kane, q, u, state_q, xdot, values)
        assert np.allclose(ours, theirs[:3], rtol=1e-10, atol=1e-10)


def test_rolling_disc_keeps_its_energy_and_rolls():
    q, u, T, V, constraints, _ = _rolling_disc()
    qs = tuple(symbol(n) for n in ("yaw", "lean", "spin", "x", "y"))
    Ts, Vs = _to_symbols(T, q, qs), _to_symbols(V, q, qs)
    M, h, f = _ours(q, qs, Ts, Vs)
    velocity = velocity_transformation([_to_symbols(c, q, qs) for c in constraints], qs)
    p = project_nonholonomic(M, h, f, velocity)
    values = {m: 1.0, g: 9.81, r: 0.3}
    args = (*qs, *velocity.speeds)
    accel = sympy.lambdify(args, p.mass_matrix.LUsolve(p.forcing - p.velocity_terms).subs(values), "numpy")
    kin = sympy.lambdify(args, velocity.kinematics.subs(values), "numpy")
    speeds_of = {velocity_symbol(s): e for s, e in zip(qs, velocity.kinematics)}
    energy = sympy.lambdify(args, (Ts.xreplace(speeds_of) + Vs).subs(values), "numpy")

    def rates(t, z):
        return np.concatenate([np.ravel(kin(*z)), np.ravel(accel(*z))])

    z0 = [0.0, 0.2, 0.0, 0.0, 0.0, 0.5, 0.0, 8.0]
    run = solve_ivp(rates, (0.0, 3.0), z0, method="DOP853", rtol=1e-11, atol=1e-12)
    E = np.array([energy(*z) for z in run.y.T])
    assert np.max(np.abs(E - E[0])) < 1e-8 * abs(E[0])
    assert np.hypot(run.y[3, -1], run.y[4, -1]) > 1.0  # it rolled away


def _sleigh():
    """Chaplygin sleigh: centre of mass (x, y), heading phi, a knife edge at distance ``a``
    behind the centre allowing no sideways slip."""
    x, y, phi = (symbol(n) for n in ("x", "y", "phi"))
    xd, yd, phid = (velocity_symbol(s) for s in (x, y, phi))
    T = m * (xd**2 + yd**2) / 2 + I * phid**2 / 2
    constraint = -sympy.sin(phi) * xd + sympy.cos(phi) * yd - a * phid
    return (x, y, phi), T, constraint


def test_chaplygin_sleigh_against_kanes_method_and_its_straight_end():
    qs, T, constraint = _sleigh()
    M, h, f = _ours(None, qs, T, 0)
    v, w = symbol("v"), symbol("w")
    x, y, phi = qs
    speeds = {v: sympy.cos(phi) * velocity_symbol(x) + sympy.sin(phi) * velocity_symbol(y), w: velocity_symbol(phi)}
    velocity = velocity_transformation([constraint], qs, speeds)
    p = project_nonholonomic(M, h, f, velocity)
    # the sleigh's equations (Bloch): m v' = m a w^2, (I + m a^2) w' = -m a v w
    assert sympy.simplify(p.mass_matrix - sympy.diag(m, I + m * a**2)) == sympy.zeros(2, 2)
    assert sympy.simplify(p.forcing - p.velocity_terms - sympy.Matrix([m * a * w**2, -m * a * v * w])) == \
        sympy.zeros(2, 1)
    # Kane, with the same constraint and the generalized speeds v, w, sideways speed dependent
    q = me.dynamicsymbols("q1:4")
    uk = me.dynamicsymbols("u1:4")  # v, w, sideways velocity of the centre
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [q[2], N.z])
    B.set_ang_vel(N, uk[1] * N.z)
    G = me.Point("G")
    G.set_vel(N, uk[0] * B.x + uk[2] * B.y)
    kd = [uk[0] - (sympy.cos(q[2]) * q[0].diff() + sympy.sin(q[2]) * q[1].diff()), uk[1] - q[2].diff(),
          uk[2] - (-sympy.sin(q[2]) * q[0].diff() + sympy.cos(q[2]) * q[1].diff())]
    body = me.RigidBody("sleigh", G, B, m, (me.inertia(B, 0, 0, I), G))
    kane = me.KanesMethod(N, q_ind=q, u_ind=uk[:2], u_dependent=uk[2:], kd_eqs=kd,
                          velocity_constraints=[uk[2] - a * uk[1]])
    kane.kanes_equations([body], [])
    rng = np.random.default_rng(3)
    values = {m: 2.0, I: 0.3, a: 0.4}
    for _ in range(3):
        sq, (sv, sw) = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 2)
        at = {**dict(zip(qs, sq)), v: sv, w: sw, **values}
        ours = np.linalg.solve(np.array(p.mass_matrix.subs(at), dtype=float),
                               np.array((p.forcing - p.velocity_terms).subs(at), dtype=float)).ravel()
        theirs = _kane_udot(kane, q, uk, sq, (sv, sw, values[a] * sw), values)
        assert np.allclose(ours, theirs[:2], rtol=1e-10, atol=1e-12)
    # in time: it ends moving straight along its knife edge, at the speed its energy allows
    args = (*qs, v, w)
    rates_of = sympy.lambdify(args, velocity.kinematics.col_join(
        p.mass_matrix.LUsolve(p.forcing - p.velocity_terms)).subs(values), "numpy")
    v0, w0 = -0.5, 2.0
    run = solve_ivp(lambda t, z: np.ravel(rates_of(*z)), (0.0, 60.0), [0, 0, 0, v0, w0], rtol=1e-10, atol=1e-12)
    v_end, w_end = run.y[3, -1], run.y[4, -1]
    energy = values[m] * v0**2 / 2 + (values[I] + values[m] * values[a]**2) * w0**2 / 2
    assert abs(w_end) < 1e-3
    assert v_end == pytest.approx(np.sqrt(2 * energy / values[m]), rel=1e-6)
    heading = run.y[2, -1]
    velocity_dir = np.ravel(rates_of(*run.y[:, -1]))[:2]
    assert abs(-np.sin(heading) * velocity_dir[0] + np.cos(heading) * velocity_dir[1]) < 1e-3


def test_linear_form_and_refusals():
    x, y, phi = (symbol(n) for n in ("x", "y", "phi"))
    xd, yd, phid = (velocity_symbol(s) for s in (x, y, phi))
    A, b = linear_form([xd * sympy.cos(phi) + 3 * yd + sympy.sin(phi)], (x, y, phi))
    assert A == sympy.Matrix([[sympy.cos(phi), 3, 0]]) and b == sympy.Matrix([sympy.sin(phi)])
    with pytest.raises(VelocityConstraintError, match="not linear in the velocities") as e:
        velocity_transformation([xd**2 + yd], (x, y, phi))
    assert e.value.index == 0
    with pytest.raises(VelocityConstraintError, match="has no velocity"):
        velocity_transformation([x - y], (x, y, phi))
    # d(x y) = 0 in disguise: integrable
    with pytest.raises(VelocityConstraintError, match="integrable") as e:
        velocity_transformation([y * xd + x * yd], (x, y, phi))
    assert "configuration constraint" in e.value.hint
    knife = -sympy.sin(phi) * xd + sympy.cos(phi) * yd
    assert integrable(*linear_form([knife], (x, y, phi)), (x, y, phi)) == []
    with pytest.raises(VelocityConstraintError, match="do not span") as e:
        velocity_transformation([knife], (x, y, phi), {symbol("u1"): 2 * knife, symbol("u2"): phid})
    assert e.value.kind == "speeds"
    scaled = velocity_transformation([knife], (x, y, phi), {symbol("u1"): a * (sympy.cos(phi) * xd + sympy.sin(phi) * yd),
                                                              symbol("u2"): phid})
    assert sympy.simplify(scaled.constraint_matrix * scaled.transformation) == sympy.zeros(1, 2)
    with pytest.raises(VelocityConstraintError, match="1 speed"):
        velocity_transformation([knife], (x, y, phi), {symbol("u1"): phid})
    with pytest.raises(VelocityConstraintError, match="not independent"):
        velocity_transformation([knife, 2 * knife], (x, y, phi))
