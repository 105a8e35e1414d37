"""Models on a line and in the plane without closed loops, each against an independent
derivation in plain sympy (tests/reference/lagrange.py: Lagrange's equations of a hand-written
``T`` and ``V``, or virtual power over the bodies, plus generalized forces by virtual work):
kronsub's ``Mbar``, ``hbar``, ``fbar`` (and ``T``, ``V``) at random states and randomly perturbed
parameters; for some, the accelerations of the compiled C and of the generated numpy module.
Pulleys and gears by explicit connections, rolling discs and wheels, particles on massless rods,
one pendulum in absolute and in relative angles. The models are in tests/models/sweep*/, their
hand derivations in tests/reference/sweep*.py.
"""
from __future__ import annotations

import numpy as np
import sympy as sp
from click.testing import CliRunner

from helpers.compare import (accelerations_agree, compare_energies, compare_explicit, largest_difference, TOL,
                             worst)
from kronsub.cli import main
from reference import sweep, sweep3, sweep4, sweep5, sweep6
from reference.lagrange import (add, damper_rows, dots, down, gradient_force, kinetic, lagrange, R, rate_of, S,
                                spring_V, t, virtual_power)


def test_spring_pendulum():
    r, q, rd, qd = S("r q r_dot q_dot")
    m, k, L0, c, cd, F0, w, g = S("m k L0 c cd F0 w g")
    x, y = r * sp.sin(q), -r * sp.cos(q)
    v = sp.Matrix([x, y]).jacobian([r, q]) * sp.Matrix([rd, qd])
    T = m * v.dot(v) / 2
    V = m * g * y + k * (r - L0) ** 2 / 2  # r > 0: the rod's length
    F = -cd * v + sp.Matrix([F0 * sp.sin(w * t), 0])
    Q = [F.dot(sp.Matrix([x, y]).diff(a)) - c * rd * int(a == r) for a in (r, q)]
    err = compare_explicit(sweep.derived("spring_pendulum.yaml"), lagrange(T, V, [r, q], Q), 1,
                           fixed=lambda rng: {"r": rng.uniform(0.3, 2)})
    assert err < TOL


def test_disc_on_seesaw():
    beta, s = S("beta s")
    M_, L, m, R, J, kb, cr, u, g = S("M L m R J kb cr u g")
    q = [beta, s]
    along, normal = sp.Matrix([sp.cos(beta), sp.sin(beta)]), sp.Matrix([-sp.sin(beta), sp.cos(beta)])
    centre = s * along + R * normal
    roll = beta - s / R  # no slip on the turning beam
    M, h = virtual_power([(M_, [0, 0], beta, M_ * L ** 2 / 12), (m, centre, roll, J)], q)
    V = m * g * centre[1] + kb * (beta - sp.Rational(1, 20)) ** 2 / 2
    relative = roll - beta
    f = sp.Matrix([-V.diff(a) + u * int(a == beta) - cr * rate_of(relative, q) * relative.diff(a) for a in q])
    assert compare_explicit(sweep.derived("disc_on_seesaw.yaml"), (M, h, f), 6, spread=2) < TOL


def test_double_pendulum_driven():
    q1, q2 = S("q1 q2")
    m1, m2, L1, L2, I2, px, py, k, c1, c2, tau1, tau2, w, P, g = S("m1 m2 L1 L2 I2 px py k c1 c2 tau1 tau2 w P g")
    q = [q1, q2]
    q1d, q2d = dots(q)
    down = lambda a: sp.Matrix([sp.sin(a), -sp.cos(a)])  # noqa: E731
    pivot = sp.Matrix([px, py])
    c1p, elbow = pivot + L1 / 2 * down(q1), pivot + L1 * down(q1)
    c2p = elbow + L2 / 2 * down(q2)
    hook = c2p + L2 / 4 * down(q2) + sp.Rational(1, 20) * sp.Matrix([sp.cos(q2), sp.sin(q2)])
    M, h = virtual_power([(m1, c1p, q1, m1 * L1 ** 2 / 12), (m2, c2p, q2, I2)], q)
    V = g * (m1 * c1p[1] + m2 * c2p[1]) + k * (q2 - q1 - sp.Rational(1, 5)) ** 2 / 2
    F = P * sp.Matrix([3, -4]) / 5
    f = sp.Matrix([-V.diff(a) + tau1 * int(a == q1) + tau2 * sp.cos(w * t) * int(a == q2) + F.dot(hook.diff(a))
                   - c1 * q1d * int(a == q1) - c2 * (q2d - q1d) * (q2 - q1).diff(a) for a in q])
    assert compare_explicit(sweep.derived("double_pendulum_driven.yaml"), (M, h, f), 7) < TOL


def test_bead_on_hoop():
    psi, al = S("psi al")
    J, m, R, tau, b, cb, eps, kz, g = S("J m R tau b cb eps kz g")
    q = [psi, al]
    psid, ald = dots(q)
    p = sp.Matrix([R * sp.sin(al) * sp.cos(psi), R * sp.sin(al) * sp.sin(psi), -R * sp.cos(al)])
    v = p.jacobian(q) * sp.Matrix([psid, ald])
    T = J * psid ** 2 / 2 + m * v.dot(v) / 2
    V = m * g * p[2] + eps * p[0] * p[2] + kz * p[2] ** 4
    assert compare_explicit(sweep.derived("bead_on_hoop.yaml"), lagrange(T, V, q, [tau - b * psid, -cb * ald]), 9) < TOL


def test_atwood_stepped_pulley():
    (a,) = q = [S("a")]
    J, r1, r2, m1, m2, x10, x20, k, l0, h, b, tm, g = S("J r1 r2 m1 m2 x10 x20 k l0 h b tm g")
    x1, x2 = x10 + r1 * a, x20 - r2 * a
    ad = dots(q)[0]
    T = J * ad ** 2 / 2 + m1 * rate_of(x1, q) ** 2 / 2 + m2 * rate_of(x2, q) ** 2 / 2
    V = g * (m1 * x1 + m2 * x2) + k * (x2 + h - l0) ** 2 / 2  # the right mass stays above the floor
    system = sweep3.derived("atwood_pulley.yaml")
    fixed = lambda rng: {"a": rng.uniform(-2, 2)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, [tm - b * ad]), 35, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 35, fixed=fixed) < TOL


def test_gear_train_with_belt_and_compliant_shaft(tmp_path):
    a, b = q = list(S("a b"))
    Jm, Jp, Jg, Jb, JL, rp, rg, rb1, rb2, ks, cs, T0, kw, TL, om = S("Jm Jp Jg Jb JL rp rg rb1 rb2 ks cs T0 kw TL om")
    ad, bd = dots(q)
    gear = -rp / rg * a
    pulley = gear * rb1 / rb2
    T = (Jm + Jp) * ad ** 2 / 2 + Jg * rate_of(gear, q) ** 2 / 2 + Jb * rate_of(pulley, q) ** 2 / 2 + JL * bd ** 2 / 2
    twist = b - pulley
    V = ks * twist ** 2 / 2
    Q = [(T0 - kw * ad) * int(v == a) - TL * sp.cos(om * t) * int(v == b) - cs * rate_of(twist, q) * twist.diff(v)
         for v in q]
    M, h, f = lagrange(T, V, q, Q)
    system = sweep3.derived("gear_train.yaml")
    assert compare_explicit(system, (M, h, f), 36) < TOL
    assert compare_energies(system, T, V, 36) < TOL
    assert accelerations_agree(system, M, h, f, 36, numpy_module=sweep3.numpy_module(tmp_path, "gear_train.yaml")) < TOL


def test_half_car_bar_on_spring_damper_legs():
    x, y, th = q = list(S("x y th"))
    m, L, Iz, kf, kr, cr, l0, P, T0, om, g = S("m L Iz kf kr cr l0 P T0 om g")
    e = sp.Matrix([sp.cos(th), sp.sin(th)])
    centre = sp.Matrix([x, y])
    end_a, end_b = centre - L / 2 * e, centre + L / 2 * e
    mast = centre + L / 4 * e + sp.Rational(3, 10) * sp.Matrix([-sp.sin(th), sp.cos(th)])
    front = end_a - sp.Matrix([-L / 2, -sp.Rational(1, 10)])
    rear = sp.Matrix([L / 2, 0]) - end_b
    lf, lr = sp.sqrt(front.dot(front)), sp.sqrt(rear.dot(rear))
    M, h = virtual_power([(m, centre, th, Iz)], q)
    V = m * g * y + kf * (lf - l0) ** 2 / 2 + kr * (lr - l0) ** 2 / 2
    wind = sp.Matrix([P, -P / 3])
    f = sp.Matrix([-V.diff(a) - cr * rate_of(lr, q) * lr.diff(a) + wind.dot(mast.diff(a))
                   + T0 * sp.sin(om * t) * int(a == th) for a in q])
    system = sweep3.derived("half_car.yaml")
    def fixed(rng):  # the legs stretched, the bar near level
        return {"x": rng.uniform(-0.3, 0.3), "y": rng.uniform(0.2, 0.8), "th": rng.uniform(-0.5, 0.5)}

    assert compare_explicit(system, (M, h, f), 37, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 37, fixed=fixed) < TOL


def test_pendulum_on_the_peg_of_a_rolling_wheel():
    a, th = q = list(S("a th"))
    Mw, R, e, m, L, k, l0, cp, tw, g = S("M R e m L k l0 cp tw g")
    centre = sp.Matrix([-R * a, R])
    peg = centre + sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]]) * sp.Matrix([e, sp.Rational(1, 50)])
    rod = peg + L / 2 * down(th)
    M, h = virtual_power([(Mw, centre, a, Mw * R ** 2 / 2), (m, rod, th, m * L ** 2 / 12)], q)
    stretch = centre[0] + 1  # the wall is at x = -1, level with the centre
    V = g * (Mw * centre[1] + m * rod[1]) + k * (stretch - l0) ** 2 / 2
    rel = th - a
    f = sp.Matrix([-V.diff(v) + tw * int(v == a) - cp * rate_of(rel, q) * rel.diff(v) for v in q])
    system = sweep3.derived("wheel_pendulum.yaml")
    fixed = lambda rng: {"a": rng.uniform(-2, 2)}  # noqa: E731  (the centre right of the wall)
    assert compare_explicit(system, (M, h, f), 38, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 38, fixed=fixed) < TOL


def test_polar_bob_with_a_dashpot_to_a_corner():
    r, a = q = list(S("r a"))
    m, k, l0, c, P, g = S("m k l0 c P g")
    p = r * sp.Matrix([sp.cos(a), sp.sin(a)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    d = sp.Matrix([1, -4]) / sp.sqrt(17)
    V = -m * g * d.dot(p) + k * (r - l0) ** 2 / 2  # r > 0
    gap = p - sp.Matrix([sp.Rational(3, 5), -sp.Rational(3, 10)])
    length = sp.sqrt(gap.dot(gap))
    push = P * sp.Matrix([sp.cos(a), sp.sin(a)])
    Q = [-c * rate_of(length, q) * length.diff(x) + push.dot(p.diff(x)) for x in q]
    M, h, f = lagrange(T, V, q, Q)
    system = sweep3.derived("polar_bob_damped.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.1, 2)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 44, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 44, fixed=fixed) < TOL


def test_kepler_polar_thrust_and_abs_drag():
    """The full model (every effect): ``derive()`` of the model, not of its one scene."""
    q, T, V, Q = sweep4.kepler_reference()
    system = sweep4.derived("kepler_polar.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.3, 2)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, Q), 54, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 54, fixed=fixed) < TOL


def test_rod_stock_torsion_springs_on_expressions():
    th1, th2 = q = list(S("th1 th2"))
    bodies, V, rows = sweep4.torsion_parts(th1, th2, S("rho"))
    M, h = virtual_power(bodies, q)
    system = sweep4.derived("torsion_pendulum.yaml")
    assert compare_explicit(system, (M, h, gradient_force(V, q, rows)), 57) < TOL
    assert compare_energies(system, kinetic(M, q), V, 57) < TOL


def test_planar_body_tethered(tmp_path):
    q, M, h, f, V = sweep5.plate_reference()
    system = sweep5.derived("planar_body_tethered.yaml")
    assert compare_explicit(system, (M, h, f), 501) < TOL
    assert compare_energies(system, kinetic(M, q), V, 501) < TOL


def test_rods_with_axis_down_and_an_off_axis_peg():
    al, be = q = list(S("al be"))
    m1, m2, L1, L2, e, k, kt, ct, T0, g = S("m1 m2 L1 L2 e k kt ct T0 g")
    c1 = L1 / 2 * down(al)
    c2 = L1 * down(al) + L2 / 2 * down(be)
    # axis down: the rod along body -y, so body x is across it; the peg at (e, -L2/4) in body axes
    peg = c2 + sweep5.turn(be) * sp.Matrix([e, -L2 / 4])
    M, h = virtual_power([(m1, c1, al, m1 * L1 ** 2 / 12), (m2, c2, be, m2 * L2 ** 2 / 10)], q)
    V = (g * (m1 * c1[1] + m2 * c2[1]) + spring_V(k, peg, sp.Matrix([R(9, 10), -R(19, 10)]), R(3, 10))
         + kt * (be - al - R(1, 5)) ** 2 / 2)
    f = gradient_force(V, q, add(damper_rows(ct, al, q), [0, T0 * sp.sin(2 * t)]))
    system = sweep5.derived("rods_axis_down.yaml")
    assert compare_explicit(system, (M, h, f), 502) < TOL
    assert compare_energies(system, kinetic(M, q), V, 502) < TOL


def test_disc_rolling_inside_a_ring():
    (u,) = q = [S("u")]
    m, r, Rr, k, T0, g = S("m r Rr k T0 g")
    centre = (Rr - r) * down(u)
    spin = -(Rr - r) / r * u
    rim = centre + r * sp.Matrix([sp.cos(spin), sp.sin(spin)])
    M, h = virtual_power([(m, centre, spin, m * r ** 2 / 2)], q)
    V = m * g * centre[1] + spring_V(k, rim, sp.zeros(2, 1), R(1, 2))
    f = gradient_force(V, q, [T0 * spin.diff(u)])
    system = sweep5.derived("disc_in_ring.yaml")
    assert compare_explicit(system, (M, h, f), 503) < TOL
    assert compare_energies(system, kinetic(M, q), V, 503) < TOL


def test_double_pendulum_of_particles_on_massless_rods():
    """Massless pinned_rods carry only geometry: ``T`` is the bobs' alone, the spring hangs from
    the middle of the upper (massless) rod."""
    q = list(S("q1 q2"))
    T, V, Q, _ = sweep6.particle_pendulum_parts(*q, q)
    system = sweep6.derived("particle_double_pendulum.yaml")
    assert compare_explicit(system, lagrange(T, V, q, Q), 601) < TOL
    assert compare_energies(system, T, V, 601) < TOL


def test_cart_with_two_pendulums_on_points_of_its_own():
    q, M, h, f, V = sweep6.cart_twin_reference()
    system = sweep6.derived("cart_twin_pendulums.yaml")
    fixed = lambda rng: {"s": rng.uniform(-1, 1)}  # noqa: E731  (the wall spring stays stretched one way)
    assert compare_explicit(system, (M, h, f), 604, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 604, fixed=fixed) < TOL


def test_elastic_pendulum_carrying_a_rod_and_the_pin_between_them():
    """A rod hung from a bob in polar coordinates; `derive --reactions` (the hinge damper is
    written in the rod's pivoted angle) at the hand accelerations: the pin pushes the rod with
    ``F = (R_rod_x, R_rod_y)`` and the bob with ``-F``, so ``R_r = -F . e_r`` and
    ``R_a = -r F . e_a`` (Newton's third law)."""
    from kronsub.core.reactions import reactions

    r, a, th = q = list(S("r a th"))
    m, mr, L, k, l0, c, g = S("m mr L k l0 c g")
    bob = r * sp.Matrix([sp.cos(a), sp.sin(a)])
    centre = bob + L / 2 * down(th)
    M, h = virtual_power([(m, bob), (mr, centre, th, mr * L ** 2 / 12)], q)
    V = g * (m * bob[1] + mr * centre[1]) + k * (r - l0) ** 2 / 2  # r > 0: the spring's length
    f = gradient_force(V, q, damper_rows(c, th - a, q))
    system = sweep6.derived("elastic_double_pendulum.yaml")
    positive = lambda rng: {"r": rng.uniform(0.3, 2)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 623, fixed=positive) < TOL
    assert compare_energies(system, kinetic(M, q), V, 623, fixed=positive) < TOL
    items = dict(reactions(system))
    assert list(items) == ["R_r", "R_a", "R_rod_x", "R_rod_y", "R_rod_axis"]
    plain = lambda e: e.xreplace({s: sp.Symbol(s.name) for s in e.free_symbols})  # noqa: E731
    F = sp.Matrix([plain(items["R_rod_x"]), plain(items["R_rod_y"])])
    laws = sp.Matrix([plain(items["R_r"]) + F.dot(bob.diff(r)), plain(items["R_a"]) + F.dot(bob.diff(a))])
    qd, qdd = dots(q), [sp.Symbol(f"{v.name}_ddot") for v in q]
    values = {s: float(p.value) for p in system.parameters for s in (M.free_symbols | f.free_symbols)
              if s.name == p.name}
    fM, frhs = (sp.lambdify([*q, *qd], e.xreplace(values), "numpy") for e in (M, f - h))
    flaw = sp.lambdify([*q, *qd, *qdd], laws.xreplace({sp.Symbol(s.name): v for s, v in values.items()}), "numpy")
    rng = np.random.default_rng(624)
    pairs = []
    for _ in range(6):
        qv, qdv = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        qv[0] = rng.uniform(0.3, 2)
        acc = np.linalg.solve(np.array(fM(*qv, *qdv), dtype=float), np.array(frhs(*qv, *qdv), dtype=float).ravel())
        pairs.append((np.array(flaw(*qv, *qdv, *acc), dtype=float).ravel(), np.zeros(2)))
    assert worst(pairs) < 1e-9


def test_triple_pendulum_in_absolute_and_in_relative_angles():
    """Each against the hand equations, and the two against each other through the change of
    variables ``a = J q`` (``J`` constant): ``Mbar_q = J^T Mbar_a J``, ``hbar_q = J^T hbar_a``,
    ``fbar_q = J^T fbar_a``, the group property (13) of two subspaces of one primitive."""
    a = list(S("a1 a2 a3"))
    q = list(S("q1 q2 q3"))
    absolute, relative = sweep6.derived("triple_absolute.yaml"), sweep6.derived("triple_relative.yaml")
    M, h, f, V = sweep6.triple_parts(*a, a)
    assert compare_explicit(absolute, (M, h, f), 607) < TOL
    assert compare_energies(absolute, kinetic(M, a), V, 607) < TOL
    M, h, f, V = sweep6.triple_parts(q[0], q[0] + q[1], q[0] + q[1] + q[2], q)
    assert compare_explicit(relative, (M, h, f), 608) < TOL
    assert compare_energies(relative, kinetic(M, q), V, 608) < TOL
    # kronsub's absolute equations carried to the relative angles
    J = sp.Matrix([[1, 0, 0], [1, 1, 0], [1, 1, 1]])
    by_name = {s.name: s for e in (absolute.mass_matrix, absolute.velocity_terms, absolute.forces)
               for s in e.free_symbols}
    qs = {n: sp.Symbol(n) for n in ("q1", "q2", "q3", "q1_dot", "q2_dot", "q3_dot")}
    rel = J * sp.Matrix([qs["q1"], qs["q2"], qs["q3"]])
    reld = J * sp.Matrix([qs["q1_dot"], qs["q2_dot"], qs["q3_dot"]])
    change = {by_name[n]: rel[i] for i, n in enumerate(("a1", "a2", "a3")) if n in by_name}
    change.update({by_name[n]: reld[i] for i, n in enumerate(("a1_dot", "a2_dot", "a3_dot")) if n in by_name})
    carried = [J.T * absolute.mass_matrix.xreplace(change) * J, J.T * absolute.velocity_terms.xreplace(change),
               J.T * absolute.forces.xreplace(change)]
    ours = [relative.mass_matrix, relative.velocity_terms, relative.forces]
    plain = lambda e: e.xreplace({s: sp.Symbol(s.name) for s in e.free_symbols})  # noqa: E731
    assert largest_difference(relative, [plain(e) for e in ours], [plain(e) for e in carried], 609) < TOL


def test_beads_on_a_hoop_in_a_ring_of_springs():
    def apart(rng):  # the beads in their order round the hoop
        return {n: a + rng.uniform(-0.4, 0.4) for n, a in zip(("u1", "u2", "u3", "u4"), (0, 1.6, 3.1, 4.7))}

    u, T, V, Q = sweep6.ring_reference()
    system = sweep6.derived("bead_ring.yaml")
    assert compare_explicit(system, lagrange(T, V, u, Q), 610, fixed=apart) < TOL
    assert compare_energies(system, T, V, 610, fixed=apart) < TOL


def test_swinging_atwood_machine():
    """Two gravities, one per world (the counterweight's line is vertical: its direction ``[-1]``)."""
    q, T, V, Q = sweep6.atwood_reference()
    system = sweep6.derived("swinging_atwood.yaml")
    positive = lambda rng: {"r": rng.uniform(0.2, 2.5)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, Q), 611, fixed=positive) < TOL
    assert compare_energies(system, T, V, 611, fixed=positive) < TOL


def test_segway_motor_torques_act_and_react():
    """One motor torque (a definition in the state and t) on the wheel and minus it on the body:
    by virtual work ``tau (d wheel_angle - d th)``, ``wheel_angle = -x/Rw`` (rolling)."""
    x, th = q = list(S("x th"))
    Mw, Rw, mb, L, Ib, kp, kd, u0, cb, g = S("Mw Rw mb L Ib kp kd u0 cb g")
    wheel_angle = -x / Rw
    centre = sp.Matrix([x, Rw])
    body = centre + L / 2 * down(th)
    M, h = virtual_power([(Mw, centre, wheel_angle, Mw * Rw ** 2 / 2), (mb, body, th, Ib)], q)
    V = g * (Mw * Rw + mb * body[1])
    tau = kp * sp.sin(th) - kd * dots(q)[1] + u0 * sp.cos(3 * t)
    rows = add([tau * (wheel_angle - th).diff(v) for v in q], damper_rows(cb, wheel_angle - th, q))
    system = sweep6.derived("segway.yaml")
    f = gradient_force(V, q, rows)
    assert compare_explicit(system, (M, h, f), 612) < TOL
    assert compare_energies(system, kinetic(M, q), V, 612) < TOL
    assert accelerations_agree(system, M, h, f, 612) < TOL


def test_segway_reactions_with_an_effect_on_the_pivoted_rods_angle():
    """`derive --reactions` of the segway, whose bearing damper is written in the body's angle
    ``th`` (a pivoted rod's angle, not a primitive coordinate: the primitive has
    ``body_axis = th - pi/2``). Such an effect once acted in the subspace only and the reactions
    were refused; ``th`` is ``body_axis + pi/2`` exactly, so the damper now acts on the primitive.
    ``R = M xddot + h - f`` on the six primitive coordinates from a hand primitive (two free
    bodies, the motor's and the bearing's torques on their angles), at the hand accelerations;
    ``C^T R = 0``."""
    import json

    x, th = q = list(S("x th"))
    Mw, Rw, mb, L, Ib, kp, kd, u0, cb, g = S("Mw Rw mb L Ib kp kd u0 cb g")
    prim = list(S("wx wy wa body_x body_y body_axis"))
    qd, qdd = dots(q), [sp.Symbol(f"{s.name}_ddot") for s in q]
    wa_d, axis_d = sp.Symbol("wa_dot"), sp.Symbol("body_axis_dot")
    tau = kp * sp.sin(th) - kd * qd[1] + u0 * sp.cos(3 * t)
    bearing = -cb * (wa_d - axis_d)  # on wa, minus it on body_axis
    Mx = sp.diag(Mw, Mw, Mw * Rw ** 2 / 2, mb, mb, Ib)
    fx = sp.Matrix([0, -Mw * g, tau + bearing, 0, -mb * g, -tau - bearing])
    image = sp.Matrix([x, Rw, -x / Rw, x + L / 2 * sp.sin(th), Rw - L / 2 * sp.cos(th), th - sp.pi / 2])
    C = image.jacobian(q)
    xdot = C * sp.Matrix(qd)
    xddot = C * sp.Matrix(qdd) + xdot.jacobian(q) * sp.Matrix(qd)
    r_hand = (Mx * xddot - fx).xreplace({wa_d: xdot[2], axis_d: xdot[5]})
    result = CliRunner().invoke(main, ["derive", str(sweep6.HERE / "segway.yaml"), "--reactions", "--format", "json"])
    assert result.exit_code == 0, result.output
    expressions = json.loads(result.stdout)["reactions"]["expressions"]
    assert list(expressions) == [f"R_{a.name}" for a in prim]
    names = {s.name: s for s in [*q, *qd, *qdd, t, Mw, Rw, mb, L, Ib, kp, kd, u0, cb, g]}
    ours = sp.Matrix([sp.sympify(expressions[f"R_{a.name}"], locals=names) for a in prim])  # test code
    values = {names[p.name]: float(p.value) for p in sweep6.derived("segway.yaml").parameters}
    M, h = virtual_power([(Mw, image[:2, :], image[2], Mw * Rw ** 2 / 2), (mb, image[3:5, :], th, Ib)], q)
    f = C.T * fx.xreplace({wa_d: xdot[2], axis_d: xdot[5]})
    fns = [sp.lambdify([t, *q, *qd], e.xreplace(values), "numpy") for e in (M, f - h)]
    args = [t, *q, *qd, *qdd]
    f_ours, f_hand, f_work = (sp.lambdify(args, e.xreplace(values), "numpy") for e in (ours, r_hand, C.T * ours))
    rng = np.random.default_rng(618)
    pairs = []
    for _ in range(6):
        tt, qv, qdv = rng.uniform(0, 3), rng.uniform(-3, 3, 2), rng.uniform(-2, 2, 2)
        acc = np.linalg.solve(np.array(fns[0](tt, *qv, *qdv), dtype=float),
                              np.array(fns[1](tt, *qv, *qdv), dtype=float).ravel())
        a = (tt, *qv, *qdv, *acc)
        pairs += [(np.array(f_ours(*a), dtype=float).ravel(), np.array(f_hand(*a), dtype=float).ravel()),
                  (np.array(f_work(*a), dtype=float).ravel(), np.zeros(2))]
    assert worst(pairs) < 1e-9


def test_a_generalized_force_on_a_pivoted_rods_angle_acts_on_its_axis(tmp_path):
    """`generalized_force` on ``th`` (``body_axis + pi/2``) is the force on ``body_axis``: the row
    ``th`` of ``fbar`` gains the value, and the reaction on the axis loses it (``R = ... - f``)."""
    import kronsub
    from kronsub.core.reactions import reactions
    from kronsub.core.symbols import symbol

    text = (sweep6.HERE / "segway.yaml").read_text().replace(
        "  bearing:", "  nudge: {type: generalized_force, coordinate: th, value: 0.3*th_dot + 0.2}\n  bearing:")
    path = tmp_path / "segway_nudged.yaml"
    path.write_text(text)
    nudged, plain = kronsub.load(path).derive(), sweep6.derived("segway.yaml")
    assert not nudged.transition.direct_effects
    extra = R(3, 10) * symbol("th_dot") + R(1, 5)
    assert sp.expand(nudged.forces - plain.forces - sp.Matrix([0, extra])) == sp.zeros(2, 1)
    ours, theirs = dict(reactions(nudged)), dict(reactions(plain))
    assert sp.expand(ours["R_body_axis"] - theirs["R_body_axis"] + extra) == 0
    assert all(sp.expand(ours[k] - theirs[k]) == 0 for k in ours if k != "R_body_axis")
