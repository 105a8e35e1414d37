"""Prescribed motions (core/rheonomic.py): a time-dependent connection against Lagrange's
equations of the same time-dependent kinematics (sympy.physics.mechanics), the bead on a turning
hoop's equilibria, Kapitza's inverted pendulum, the drive's power, inverse dynamics."""
import numpy as np
import pytest
import sympy
from scipy.integrate import solve_ivp
from sympy.physics import mechanics as me

from kronsub.core.rheonomic import depends_on_time, driving_force, prescribe, project_rheonomic
from kronsub.core.symbols import TIME, acceleration_symbol, symbol, velocity_symbol

m, m2, g, l, l2, R, w, A = (symbol(n) for n in ("m", "m2", "g", "l", "l2", "R", "w", "A"))


def _particles(n, dim):
    """``n`` point masses in ``dim`` dimensions: coordinates, M, h = 0, gravity along the last axis."""
    x = [symbol(f"p{i}_{axis}") for i in range(n) for axis in "xyz"[:dim]]
    masses = [m, m2][:n]
    M = sympy.diag(*[masses[i] for i in range(n) for _ in range(dim)])
    f = sympy.Matrix([-masses[i] * g if k == dim - 1 else 0 for i in range(n) for k in range(dim)])
    return x, M, sympy.zeros(len(x), 1), f


def _accelerations(projection):
    return projection.mass_matrix.LUsolve(projection.forcing - projection.velocity_terms)


def _random_point(rng, symbols):
    return {s: sympy.Float(rng.uniform(0.3, 1.7)) for s in symbols}


def test_time_in_the_connection_is_seen():
    th = symbol("th")
    assert depends_on_time({symbol("p0_x"): l * sympy.sin(th) + A * sympy.sin(w * TIME)})
    assert not depends_on_time({symbol("p0_x"): l * sympy.sin(th)})


def test_bead_on_turning_hoop_against_lagranges_method():
    th = symbol("th")
    x, M, h, f = _particles(1, 3)
    connection = dict(zip(x, (R * sympy.sin(th) * sympy.cos(w * TIME), R * sympy.sin(th) * sympy.sin(w * TIME),
                              -R * sympy.cos(th))))
    p = project_rheonomic(x, M, h, f, connection, (th,))
    # sympy.physics.mechanics: the same particle, the same turning hoop
    q = me.dynamicsymbols("q")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", R * sympy.sin(q) * sympy.cos(w * me.dynamicsymbols._t) * N.x
                    + R * sympy.sin(q) * sympy.sin(w * me.dynamicsymbols._t) * N.y - R * sympy.cos(q) * N.z)
    P.set_vel(N, P.pos_from(O).dt(N))
    bead = me.Particle("bead", P, m)
    bead.potential_energy = m * g * P.pos_from(O).dot(N.z)
    lm = me.LagrangesMethod(me.Lagrangian(N, bead), [q])
    lm.form_lagranges_equations()
    rhs = lm.rhs()[1]
    tt = me.dynamicsymbols._t
    ours = _accelerations(p)[0]
    rng = np.random.default_rng(5)
    for _ in range(5):
        values = _random_point(rng, (m, g, R, w))
        state = {th: rng.uniform(-3, 3), velocity_symbol(th): rng.uniform(-2, 2), TIME: rng.uniform(0, 10)}
        theirs = rhs.subs({sympy.Derivative(q, tt): state[velocity_symbol(th)]}).subs(
            {q: state[th], tt: state[TIME]}).subs(values)
        assert float(ours.subs({**values, **state})) == pytest.approx(float(theirs), rel=1e-10, abs=1e-12)
    # the drive's extra terms: the centrifugal -m R^2 w^2 sin cos
    assert sympy.simplify(p.drive_terms[0] + m * R**2 * w**2 * sympy.sin(th) * sympy.cos(th)) == 0
    # relative equilibria cos th = g / (w^2 R), stable where they exist; the bottom unstable then
    qdd = _accelerations(p)[0].subs(velocity_symbol(th), 0)
    values = {m: 1.0, g: 9.81, R: 0.5, w: 7.0}
    th0 = float(sympy.acos(g / (w**2 * R)).subs(values))
    assert abs(float(qdd.subs({**values, th: th0}))) < 1e-12
    stiffness = sympy.diff(qdd, th)
    assert float(stiffness.subs({**values, th: th0})) < 0
    assert float(stiffness.subs({**values, th: 0})) > 0
    slow = {**values, w: 3.0}  # w^2 R < g: only the bottom
    assert float(stiffness.subs({**slow, th: 0})) < 0


def test_driven_double_pendulum_against_lagranges_method():
    a, b = symbol("a"), symbol("b")
    x, M, h, f = _particles(2, 2)
    support = A * sympy.sin(w * TIME)
    connection = dict(zip(x, (support + l * sympy.sin(a), -l * sympy.cos(a),
                              support + l * sympy.sin(a) + l2 * sympy.sin(b), -l * sympy.cos(a) - l2 * sympy.cos(b))))
    p = project_rheonomic(x, M, h, f, connection, (a, b))
    qa, qb = me.dynamicsymbols("qa qb")
    tt = me.dynamicsymbols._t
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    S = O.locatenew("S", A * sympy.sin(w * tt) * N.x)
    P1 = S.locatenew("P1", l * sympy.sin(qa) * N.x - l * sympy.cos(qa) * N.y)
    P2 = P1.locatenew("P2", l2 * sympy.sin(qb) * N.x - l2 * sympy.cos(qb) * N.y)
    for P in (P1, P2):
        P.set_vel(N, P.pos_from(O).dt(N))
    b1, b2 = me.Particle("b1", P1, m), me.Particle("b2", P2, m2)
    b1.potential_energy = m * g * P1.pos_from(O).dot(N.y)
    b2.potential_energy = m2 * g * P2.pos_from(O).dot(N.y)
    lm = me.LagrangesMethod(me.Lagrangian(N, b1, b2), [qa, qb])
    lm.form_lagranges_equations()
    ours = _accelerations(p)
    rng = np.random.default_rng(7)
    for _ in range(4):
        values = _random_point(rng, (m, m2, g, l, l2, A, w))
        st = [rng.uniform(-3, 3) for _ in range(4)] + [rng.uniform(0, 10)]

        def at(e):
            return np.array(e.subs({sympy.Derivative(qa, tt): st[2], sympy.Derivative(qb, tt): st[3]}).subs(
                {qa: st[0], qb: st[1], tt: st[4]}).subs(values).evalf(), dtype=float)

        theirs = np.linalg.solve(at(lm.mass_matrix), at(lm.forcing))
        mine = ours.subs({**values, a: st[0], b: st[1], velocity_symbol(a): st[2], velocity_symbol(b): st[3],
                          TIME: st[4]})
        assert np.allclose(np.array(mine, dtype=float), np.array(theirs, dtype=float), rtol=1e-10, atol=1e-12)


def _kapitza(values):
    th = symbol("th")
    x, M, h, f = _particles(1, 2)
    connection = {x[0]: l * sympy.sin(th), x[1]: A * sympy.cos(w * TIME) - l * sympy.cos(th)}
    p = project_rheonomic(x, M, h, f, connection, (th,))
    qdd = sympy.lambdify((TIME, th, velocity_symbol(th)), _accelerations(p)[0].subs(values), "math")
    return p, th, qdd


@pytest.mark.parametrize("w_value, stable", [(200.0, True), (60.0, False)])
def test_kapitza_pendulum_stands_upside_down_when_a2w2_exceeds_2gl(w_value, stable):
    values = {m: 1.0, g: 9.81, l: 1.0, A: 0.05, w: w_value}  # a^2 w^2 = 100 or 9 against 2 g l = 19.62
    _, _, qdd = _kapitza(values)
    run = solve_ivp(lambda t, y: (y[1], qdd(t, y[0], y[1])), (0.0, 3.0), (np.pi + 0.2, 0.0),
                    rtol=1e-9, atol=1e-11, max_step=0.002)
    deviation = np.max(np.abs(run.y[0] - np.pi))
    assert (deviation < 0.5) == stable


def test_the_drives_power_is_the_rate_of_the_energy():
    values = {m: 1.3, g: 9.81, l: 0.7, A: 0.1, w: 9.0}
    p, th, qdd = _kapitza(values)
    th_d, th_dd = velocity_symbol(th), acceleration_symbol(th)
    power = sympy.lambdify((TIME, th, th_d, th_dd), p.power.subs(values), "math")
    # T + V of the primitive particle along the drive
    px = l * sympy.sin(th)
    py = A * sympy.cos(w * TIME) - l * sympy.cos(th)
    vx, vy = (sympy.diff(e, th) * th_d + sympy.diff(e, TIME) for e in (px, py))
    energy = sympy.lambdify((TIME, th, th_d), (m * (vx**2 + vy**2) / 2 + m * g * py).subs(values), "math")

    def rates(t, y):
        a = qdd(t, y[0], y[1])
        return (y[1], a, power(t, y[0], y[1], a))

    run = solve_ivp(rates, (0.0, 2.0), (0.5, 0.0, 0.0), rtol=1e-11, atol=1e-12)
    gained = [energy(t, a, b) - energy(0.0, 0.5, 0.0) for t, a, b in zip(run.t, run.y[0], run.y[1])]
    assert np.max(np.abs(run.y[2])) > 0.1  # the drive does work
    assert np.allclose(gained, run.y[2], atol=1e-7)


def test_prescribed_coordinate_gives_its_driving_force():
    """A cart (free, ``s``) carrying a pendulum whose angle a motor drives through ``th(t)``."""
    s, th, M_c = symbol("s"), symbol("th"), symbol("M_c")
    x = [symbol("c_x"), symbol("b_x"), symbol("b_y")]
    M = sympy.diag(M_c, m, m)
    f = sympy.Matrix([0, 0, -m * g])
    connection = {x[0]: s, x[1]: s + l * sympy.sin(th), x[2]: -l * sympy.cos(th)}
    motion = A * sympy.sin(w * TIME)
    projection, forces = driving_force(x, M, sympy.zeros(3, 1), f, connection, (s, th), {th: motion})
    assert projection.coordinates == (s,)
    # hand Lagrangian of cart and pendulum, both free; its th row on the motion is the torque
    sd, thd, sdd, thdd = (symbol(n) for n in ("sd", "thd", "sdd", "thdd"))
    qs = (s, th)
    L = (M_c * sd**2 / 2 + m * ((sd + l * sympy.cos(th) * thd)**2 + (l * sympy.sin(th) * thd)**2) / 2
         + m * g * l * sympy.cos(th))
    dots, ddots = (sd, thd), (sdd, thdd)

    def row(k):
        p_k = sympy.diff(L, dots[k])
        dt = sum(sympy.diff(p_k, q) * d + sympy.diff(p_k, d) * dd for q, d, dd in zip(qs, dots, ddots))
        return dt - sympy.diff(L, qs[k])

    on_motion = {th: motion, thd: sympy.diff(motion, TIME), thdd: sympy.diff(motion, TIME, 2)}
    torque = row(1).subs(on_motion).subs({s: s, sd: velocity_symbol(s), sdd: acceleration_symbol(s)})
    assert sympy.simplify(forces[th] - torque) == 0
    cart = sympy.solve(row(0).subs(on_motion), sdd)[0].subs(sd, velocity_symbol(s))
    assert sympy.simplify(_accelerations(projection)[0] - cart) == 0


def test_prescribing_an_unknown_coordinate_is_refused():
    with pytest.raises(ValueError, match="not coordinates"):
        prescribe({symbol("p"): symbol("q")}, (symbol("q"),), {symbol("z"): TIME})
