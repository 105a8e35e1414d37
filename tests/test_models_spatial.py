"""Models in space without closed loops (bodies on Cardan, gimbal and Euler-angle joints with
products of inertia, tops, a Furuta pendulum, particles in central and magnetic fields, worlds tied
together), each against an independent derivation in plain sympy (tests/reference/lagrange.py:
virtual power over the bodies ``M = sum m Jv^T Jv + Jw^T I Jw``, or Lagrange's equations): ``Mbar``,
``hbar``, ``fbar`` at random states and perturbed parameters, the compiled C and the numpy module.
"""
from __future__ import annotations

import numpy as np
import sympy as sp
from click.testing import CliRunner

from helpers import generated_numpy_module, Rx, Ry, Rz
from helpers.compare import accelerations_agree, compare_energies, compare_explicit, TOL, worst
from kronsub.cli import main
from reference import sweep, sweep3, sweep4, sweep5, sweep6
from reference.lagrange import (dots, gradient_force, kinetic, lagrange, norm, rate_of, S, t, virtual_power,
                                world_angular_velocity)


def test_spherical_pendulum_along_minus_y():
    th, ph = S("th ph")
    m, L, k, l0, c, P, g = S("m L k l0 c P g")
    q = [th, ph]
    p = sp.Matrix([L * sp.sin(th) * sp.cos(ph), -L * sp.cos(th), L * sp.sin(th) * sp.sin(ph)])
    v = p.jacobian(q) * sp.Matrix(dots(q))
    T = m * v.dot(v) / 2
    anchor = sp.Matrix([sp.Rational(3, 10), -sp.Rational(9, 10), sp.Rational(1, 10)])
    wall = sp.Matrix([0, sp.Rational(1, 5), -sp.Rational(1, 2)])
    V = m * g * p[1] + k * (sp.sqrt((p - anchor).dot(p - anchor)) - l0) ** 2 / 2
    length = sp.sqrt((p - wall).dot(p - wall))
    Q = [-c * rate_of(length, q) * length.diff(a) + P * p[2].diff(a) for a in q]
    assert compare_explicit(sweep.derived("spherical_pendulum.yaml"), lagrange(T, V, q, Q), 4) < TOL


def test_sideways_top_zxz():
    psi, th, phi = S("psi theta phi")
    m, h, A, B, C, D, E, tau, cs, g = S("m h A B C D E tau cs g")
    q = [psi, th, phi]
    R = Rz(psi) * Rx(th) * Rz(phi)
    centre = R * sp.Matrix([0, 0, h])
    M, hh = virtual_power([(m, centre, R, sp.Matrix([[A, 0, D], [0, B, E], [D, E, C]]))], q)
    omega = world_angular_velocity(R, q)
    torque = sp.Matrix([0, tau, tau / 2])
    f = sp.Matrix([-(m * g * centre[1]).diff(a) + torque.dot(omega.diff(ad)) - cs * ad * int(a == phi)
                   for a, ad in zip(q, dots(q))])
    assert compare_explicit(sweep.derived("sideways_top.yaml"), (M, hh, f), 5) < TOL


def test_box_on_springs_3d():
    x, y, z, psi, th, phi = q = list(S("x y z psi theta phi"))
    m, A, B, C, k, l0, g = S("m A B C k l0 g")
    cz, sz, cy, sy, cx, sx = sp.cos(psi), sp.sin(psi), sp.cos(th), sp.sin(th), sp.cos(phi), sp.sin(phi)
    R = (sp.Matrix([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) * sp.Matrix([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
         * sp.Matrix([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))
    centre = sp.Matrix([x, y, z])
    M, h = virtual_power([(m, centre, R, sp.diag(A, B, C))], q)
    V = m * g * z
    for offset, anchor in (([-0.2, 0.1, 0.05], [-0.3, 0, 1]), ([0.2, -0.1, 0.05], [0.3, 0, 1])):
        d = centre + R * sp.Matrix([sp.nsimplify(v) for v in offset]) - sp.Matrix([sp.nsimplify(v) for v in anchor])
        V += k * (sp.sqrt(d.dot(d)) - l0) ** 2 / 2
    f = sp.Matrix([-V.diff(a) for a in q])
    assert compare_explicit(sweep.derived("box_on_springs_3d.yaml"), (M, h, f), 10, spread=1) < TOL


def test_cardan_body_with_products_of_inertia(tmp_path):
    """X-Y-Z angles (a, b, 0); the mass centre at (u, 0, -h) from the joint in body axes; the
    tensor [[A, D, F], [D, B, E], [F, E, C]] (products as entries); slanted gravity, a world
    torque vector, a spring with rest length and a force at points given from the centre."""
    a, b = q = list(S("a b"))
    m, h, u, A, B, C, D, E, F, k, l0, tx, tz, P, g = S("m h u A B C D E F k l0 tx tz P g")
    R = Rx(a) * Ry(b)
    centre = R * sp.Matrix([u, 0, -h])
    I3 = sp.Matrix([[A, D, F], [D, B, E], [F, E, C]])
    M, hh = virtual_power([(m, centre, R, I3)], q)
    down_ = sp.Matrix([1, 0, -3]) / sp.sqrt(10)
    tip = centre + R * sp.Matrix([0, sp.Rational(1, 10), -h])
    side = centre + R * sp.Matrix([sp.Rational(1, 10), 0, 0])
    gap = tip - sp.Matrix([sp.Rational(1, 5), sp.Rational(1, 10), -sp.Rational(7, 10)])
    V = -m * g * down_.dot(centre) + k * (sp.sqrt(gap.dot(gap)) - l0) ** 2 / 2
    omega = world_angular_velocity(R, q)
    torque, push = sp.Matrix([tx, 0, tz]), sp.Matrix([0, P * sp.sin(t), P])
    f = sp.Matrix([-V.diff(v) + torque.dot(omega.diff(vd)) + push.dot(side.diff(v)) for v, vd in zip(q, dots(q))])
    system = sweep3.derived("cardan_body.yaml")
    assert compare_explicit(system, (M, hh, f), 39, spread=1.2) < TOL
    assert compare_energies(system, kinetic(M, q), V, 39, spread=1.2) < TOL
    assert accelerations_agree(system, M, hh, f, 39, spread=1.2,
                               numpy_module=sweep3.numpy_module(tmp_path, "cardan_body.yaml")) < TOL


def test_bead_on_a_cone_in_spherical_coordinates():
    r, ph = q = list(S("r ph"))
    m, al, k, l0, cd, eps, g = S("m al k l0 cd eps g")
    th = sp.pi - al
    p = r * sp.Matrix([sp.sin(th) * sp.cos(ph), sp.sin(th) * sp.sin(ph), sp.cos(th)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    V = m * g * p[2] + k * (r - l0) ** 2 / 2 + eps * sp.cos(2 * ph)  # r > 0: the distance from the apex
    f = sp.Matrix([(-cd * v).dot(p.diff(a)) for a in q])
    M, h, fc = lagrange(T, V, q, [0, 0])
    system = sweep3.derived("bead_in_cone.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.2, 2)}  # noqa: E731
    assert compare_explicit(system, (M, h, fc + f), 40, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 40, fixed=fixed) < TOL


def test_two_heavy_tops_placed_in_space_and_tied():
    """heavy_top.yaml (Z-X-Z, a product of inertia, a motor about world z) twice, the second
    placed at (D, 0, 0) in space with 3/2 the mass and no motor, crowns tied by a cord."""
    psi1, th1, ph1, psi2, th2, ph2 = q = list(S("psi1 th1 ph1 psi2 th2 ph2"))
    m, h, A, C, P, tm, g, D, kc, l0 = S("m h A C P tm g D kc l0")
    I3 = sp.Matrix([[A, P, 0], [P, A, 0], [0, 0, C]])
    bodies, V, crowns, f = [], 0, [], sp.zeros(6, 1)
    for (psi, th, ph), mass, origin, motor in (((psi1, th1, ph1), m, 0, tm), ((psi2, th2, ph2), 3 * m / 2, D, 0)):
        R = Rz(psi) * Rx(th) * Rz(ph)
        centre = sp.Matrix([origin, 0, 0]) + R * sp.Matrix([0, 0, h])
        bodies.append((mass, centre, R, I3))
        crowns.append(centre + R * sp.Matrix([0, 0, h]))
        V += mass * g * centre[2]
        omega = world_angular_velocity(R, q)
        f += sp.Matrix([motor * omega[2].diff(vd) for vd in dots(q)])
    gap = crowns[1] - crowns[0]
    V += kc * (sp.sqrt(gap.dot(gap)) - l0) ** 2 / 2
    M, hh = virtual_power(bodies, q)
    f += sp.Matrix([-V.diff(v) for v in q])
    system = sweep3.derived("two_tops.yaml")
    fixed = lambda rng: {"th1": rng.uniform(0.2, 1.2), "th2": rng.uniform(0.2, 1.2)}  # noqa: E731  (off gimbal lock)
    assert compare_explicit(system, (M, hh, f), 42, spread=2, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 42, spread=2, fixed=fixed) < TOL


def test_gyroscope_on_gimbals_zxy_offset_centre(tmp_path):
    q, M, h, f, V = sweep4.gimbal_reference()
    system = sweep4.derived("gimbal_gyro.yaml")
    fixed = lambda rng: {"theta": rng.uniform(-1.2, 1.2)}  # noqa: E731  (off gimbal lock)
    assert compare_explicit(system, (M, h, f), 51, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 51, fixed=fixed) < TOL
    module = sweep4.numpy_module(tmp_path, "gimbal_gyro.yaml")
    assert accelerations_agree(system, M, h, f, 51, spread=1.0, numpy_module=module) < TOL


def test_free_box_xzx_products_of_inertia():
    x, y, z, a, b, c3 = q = list(S("x y z a b c3"))
    m, Ix, Iy, Iz, Pxy, Pyz, k, F, w, g = S("m Ix Iy Iz Pxy Pyz k F w g")
    R = Rx(a) * Rz(b) * Rx(c3)
    centre = sp.Matrix([x, y, z])
    I3 = sp.Matrix([[Ix, Pxy, 0], [Pxy, Iy, Pyz], [0, Pyz, Iz]])
    M, h = virtual_power([(m, centre, R, I3)], q)
    hook = centre + R * sp.Matrix([sp.Rational(1, 10), sp.Rational(1, 5), sp.Rational(3, 20)])
    side = centre + R * sp.Matrix([sp.Rational(1, 5), 0, sp.Rational(1, 20)])
    gap = hook - sp.Matrix([sp.Rational(1, 10), 0, 1])
    V = m * g * z + k * gap.dot(gap) / 2
    shake = sp.Matrix([0, F * sp.sin(w * t), F * sp.cos(w * t)])
    f = gradient_force(V, q, [shake.dot(side.diff(v)) for v in q])
    system = sweep4.derived("tumbling_box_xzx.yaml")
    fixed = lambda rng: {"b": rng.uniform(0.2, 2.9)}  # noqa: E731  (X-Z-X: singular at b = 0, pi)
    assert compare_explicit(system, (M, h, f), 52, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 52, fixed=fixed) < TOL


def test_particle_on_three_springs_with_quadratic_drag(tmp_path):
    x, y, z = q = list(S("x y z"))
    m, k1, k2, k3, L1, L2, cq, A, w, g = S("m k1 k2 k3 L1 L2 cq A w g")
    p = sp.Matrix(q)
    a1, a2, a3 = (sp.Matrix(v) for v in ([1, 0, 1], [-sp.Rational(1, 2), sp.Rational(4, 5), 1],
                                          [-sp.Rational(1, 2), -sp.Rational(4, 5), 1]))
    V = (m * g * z + k1 * (norm(p - a1) - L1) ** 2 / 2 + k2 * (norm(a2 - p) - L2) ** 2 / 2
         + k3 * (p - a3).dot(p - a3) / 2)
    v = sp.Matrix(dots(q))
    drag = -cq * norm(v) * v
    T = m * v.dot(v) / 2
    M, hh, f = lagrange(T, V, q, [drag[i] + (A * sp.sin(w * t) * sp.exp(-t / 2) if i == 2 else 0) for i in range(3)])
    system = sweep4.derived("drag_particle3d.yaml")
    assert compare_explicit(system, (M, hh, f), 53) < TOL
    assert compare_energies(system, T, V, 53) < TOL
    assert accelerations_agree(system, M, hh, f, 53, numpy_module=sweep4.numpy_module(tmp_path, "drag_particle3d.yaml")) < TOL


def test_particle_around_an_oblate_body_spherical():
    r, th, ph = q = list(S("r th ph"))
    m, mu, J2, R, c, ca, zero = S("m mu J2 R c ca zero")
    p = r * sp.Matrix([sp.sin(th) * sp.cos(ph), sp.sin(th) * sp.sin(ph), sp.cos(th)])
    v = rate_of(p, q)
    T = m * v.dot(v) / 2
    V = -mu * m / r * (1 - J2 * (R / r) ** 2 * (3 * sp.cos(th) ** 2 - 1) / 2)
    rd, thd, phd = dots(q)
    Q = [-c * rd, -zero * thd, -ca * phd]  # the dashpot to O is along r (r > 0)
    system = sweep4.derived("spherical_oblate.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.3, 2)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, Q), 56, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 56, fixed=fixed) < TOL


def test_line_plane_and_space_tied_across_worlds(tmp_path):
    q, T, V, Q = sweep5.worlds_reference()
    M, h, f = lagrange(T, V, q, Q)
    system = sweep5.derived("line_plane_space.yaml")
    assert compare_explicit(system, (M, h, f), 504) < TOL
    assert compare_energies(system, T, V, 504) < TOL


def test_elastic_spherical_pendulum():
    q, T, V, Q = sweep6.elastic_reference()
    system = sweep6.derived("elastic_spherical_pendulum.yaml")
    assert compare_explicit(system, lagrange(T, V, q, Q), 602, fixed=sweep6.positive_r) < TOL
    assert compare_energies(system, T, V, 602, fixed=sweep6.positive_r) < TOL


def test_furuta_pendulum():
    q, M, h, f, V = sweep6.furuta_reference()
    system = sweep6.derived("furuta.yaml")
    assert compare_explicit(system, (M, h, f), 605) < TOL
    assert compare_energies(system, kinetic(M, q), V, 605) < TOL


def test_furuta_pendulum_generated_c_and_numpy(tmp_path):
    """The accelerations of the compiled C right-hand side and of `codegen --lang python`."""
    _, M, h, f, _ = sweep6.furuta_reference()
    mod = generated_numpy_module(tmp_path, sweep6.HERE / "furuta.yaml")
    assert accelerations_agree(sweep6.derived("furuta.yaml"), M, h, f, 606, numpy_module=mod) < TOL


def test_heavy_top_on_a_sliding_base():
    """The top's support moves with a coordinate (no prescribed motion): ``M`` couples ``s`` to
    the angles; a torque vector in the angles by ``tau . d omega/d qdot``."""
    q, M, h, f, V, _, _ = sweep6.top_reference()
    system = sweep6.derived("top_on_sliding_base.yaml")
    fixed = lambda rng: {"th": rng.uniform(0.2, 2.9)}  # noqa: E731  (Z-X-Z: singular at th = 0, pi)
    assert compare_explicit(system, (M, h, f), 616, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 616, fixed=fixed) < TOL


def test_heavy_top_on_a_sliding_base_reactions_at_the_cup():
    """`derive --reactions`: on the top's centre coordinates the cup's force on the top,
    ``m a_c + m g e_z - F`` (Newton, the flick's force ``F`` at the rim); on the cart's ``s`` minus
    its x component (Newton's third law at the cup); ``C^T R = 0``. At the hand accelerations."""
    import json

    q, M, h, f, _, centre, flick = sweep6.top_reference()
    m, g = S("m g")
    result = CliRunner().invoke(main, ["derive", str(sweep6.HERE / "top_on_sliding_base.yaml"), "--reactions",
                                       "--format", "json"])
    assert result.exit_code == 0, result.output
    expressions = json.loads(result.stdout)["reactions"]["expressions"]
    prim = ["s", "x", "y", "z", "psi", "th", "phi"]
    assert list(expressions) == [f"R_{n}" for n in prim]
    qd, qdd = dots(q), [sp.Symbol(f"{v.name}_ddot") for v in q]
    names = {v.name: v for v in [*q, *qd, *qdd, t, *S("mc m h A C k l0 c u F g")]}
    ours = sp.Matrix([sp.sympify(expressions[f"R_{n}"], locals=names) for n in prim])  # test code, not kronsub
    Cm = sp.Matrix([q[0], *centre, *q[1:]]).jacobian(q)
    rate = rate_of(centre, q)
    accel = rate.jacobian(qd) * sp.Matrix(qdd) + rate.jacobian(q) * sp.Matrix(qd)
    joint = m * accel + sp.Matrix([0, 0, m * g]) - flick
    values = {names[p.name]: float(p.value) for p in sweep6.derived("top_on_sliding_base.yaml").parameters}
    args = [t, *q, *qd, *qdd]
    checks = [sp.lambdify(args, e.xreplace(values), "numpy")
              for e in (ours[1:4, :], joint, sp.Matrix([ours[0] + ours[1]]), Cm.T * ours)]
    fM, frhs = (sp.lambdify([t, *q, *qd], e.xreplace(values), "numpy") for e in (M, f - h))
    rng = np.random.default_rng(622)
    pairs = []
    for _ in range(6):
        tt, qv, qdv = rng.uniform(0, 3), rng.uniform(-2, 2, 4), rng.uniform(-2, 2, 4)
        qv[2] = rng.uniform(0.2, 2.9)
        acc = np.linalg.solve(np.array(fM(tt, *qv, *qdv), dtype=float),
                              np.array(frhs(tt, *qv, *qdv), dtype=float).ravel())
        mine, hand, third, work = (np.array(fn(tt, *qv, *qdv, *acc), dtype=float).ravel() for fn in checks)
        pairs += [(mine, hand), (third, np.zeros(1)), (work, np.zeros(4))]
    assert worst(pairs) < 1e-9


def test_charge_in_a_central_and_a_magnetic_field():
    """A potential in the generalized ``r`` beside one in the primitive ``z``, forces in the
    primitive velocities (the Lorentz force's rows are gyroscopic: ``Q . qdot = 0``)."""
    q, T, V, Q = sweep6.charge_reference()
    system = sweep6.derived("charge_in_central_field.yaml")
    fixed = lambda rng: {"r": rng.uniform(0.3, 2), "th": rng.uniform(0.2, 2.9)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, Q), 617, fixed=fixed) < TOL
    assert compare_energies(system, T, V, 617, fixed=fixed) < TOL
    _, _, _, lorentz = sweep6.charge_reference(drag=False)
    assert sp.simplify(sum(row * v for row, v in zip(lorentz, dots(q)))) == 0  # the hand force does no work
