"""Known systems used as components: nested three levels deep, reused and placed, renamed,
with parameter overrides (also in time), gravity of the outer model acting on them; each against
an independent derivation in plain sympy of the whole assembled system (tests/reference/).
"""
from __future__ import annotations

import pytest
import sympy as sp

import kronsub
from helpers.compare import (compare_energies, compare_explicit, TOL,
                             walk_independent, worst)
from reference import sweep, sweep3, sweep5, sweep6
from reference.lagrange import (Constrained, damper_rows, dots, down, gradient_force, kinetic, lagrange, R,
                                rate_of, S, t, virtual_power)


def test_coupled_spring_pendulums_known_systems():
    r1, q1, r2, q2 = S("r1 q1 r2 q2")
    m, m2, d, e, kc, k, L0, c, cd, F0, w, g = S("m m2 d e kc k L0 c cd F0 w g")
    q = [r1, q1, r2, q2]
    b1 = sp.Matrix([r1 * sp.sin(q1), -r1 * sp.cos(q1)])
    b2 = sp.Matrix([d + r2 * sp.sin(q2), e - r2 * sp.cos(q2)])
    M, h = virtual_power([(m, b1), (m2, b2)], q)
    gap = b2 - b1
    V = (g * (m * b1[1] + m2 * b2[1]) + k * (r1 - L0) ** 2 / 2 + (2 * k + 1) * (r2 - L0) ** 2 / 2
         + kc * (sp.sqrt(gap.dot(gap)) - d) ** 2 / 2)
    r1d, _, r2d, _ = dots(q)
    F1 = -cd * rate_of(b1, q) + sp.Matrix([F0 * sp.sin(w * t), 0])
    F2 = -cd * rate_of(b2, q)  # the right one's push is overridden to F0 = 0
    f = sp.Matrix([-V.diff(a) + F1.dot(b1.diff(a)) + F2.dot(b2.diff(a)) - c * r1d * int(a == r1)
                   - c * r2d * int(a == r2) for a in q])
    err = compare_explicit(sweep.derived("coupled_spring_pendulums.yaml"), (M, h, f), 8,
                           fixed=lambda rng: {"r1": rng.uniform(0.3, 2), "r2": rng.uniform(0.3, 2)})
    assert err < TOL


def test_triple_pendulum_on_system1():
    """System I (with overridden m2, a2, F) as a known system and a rod hung from its end B."""
    th, ph, ps = q = list(S("theta phi psi"))
    m1, a1, I1, I2, g, m3, L3, c3 = S("m1 a1 I1 I2 g m3 L3 c3")
    Fa, w = S("Fa w")
    m2, a2, F = sp.Rational(13, 10), sp.Rational(7, 20), Fa * sp.cos(w * t)
    c1 = a1 * down(th)
    c2 = 2 * a1 * down(th) + a2 * down(ph)
    end = c2 + a2 * down(ph)
    c3p = end + L3 / 2 * down(ps)
    M, h = virtual_power([(m1, c1, th, I1), (m2, c2, ph, I2), (m3, c3p, ps, m3 * L3 ** 2 / 12)], q)
    V = g * (m1 * c1[1] + m2 * c2[1] + m3 * c3p[1])
    rel = ps - ph
    f = sp.Matrix([-V.diff(a) + F * c2[0].diff(a) - c3 * rate_of(rel, q) * rel.diff(a) for a in q])
    system = sweep3.derived("triple_pendulum.yaml")
    assert compare_explicit(system, (M, h, f), 31) < TOL
    assert compare_energies(system, kinetic(M, q), V, 31) < TOL


def test_cart_pendulum_two_levels():
    q, M, h, f, V = sweep3.cart_pendulum_reference()
    system = sweep3.derived("cart_pendulum.yaml")
    fixed = lambda rng: {"x": rng.uniform(0, 1)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 32, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 32, fixed=fixed) < TOL


def test_two_cart_pendulums_three_levels_placed():
    """Three levels of known systems; the second copy placed with `origin:` (its parts on a line
    and in the plane: it was refused, 'needs one entry per world axis entries')."""
    q, M, h, f, V = sweep3.two_cart_reference()
    system = sweep3.derived("two_cart_pendulums.yaml")
    fixed = lambda rng: {"x1": rng.uniform(0, 0.5), "x2": rng.uniform(0, 0.5)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 33, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 33, fixed=fixed) < TOL
    x1, th1, x2, th2 = (system.symbol(n) for n in ("x1", "th1", "x2", "th2"))
    d, L = system.symbol("d"), system.symbol("L")
    want = {"left.base.cart.centre": (x1, 0), "right.base.cart.centre": (x2 + d, 0),
            "right.pole.tip": (x2 + d + L * sp.sin(th2), -L * sp.cos(th2))}
    for label, (wx, wy) in want.items():  # the line's points are the plane's x axis, moved with the copy
        px, py = system.points[label]
        assert sp.simplify(px - wx) == 0 and sp.simplify(py - wy) == 0, (label, system.points[label])


def test_twin_system2_closed_loops_renamed_and_placed():
    """System II (a closed loop: phi dependent) twice, dependent coordinates renamed, the right
    copy placed and overridden (m2, and its push F in t); a spring and a damper between them, a
    generalized force on a dependent coordinate and a force in a dependent velocity."""
    th1, th2, ph1, ph2 = y = list(S("th1 th2 ph1 ph2"))
    params = S("m1 m2 a1 a2 I1 I2 g F c dx ks l0 cd Fa w cb")
    m1, m2, a1, a2, I1, I2, g, F, c, dx, ks, l0, cd, Fa, w, cb = params
    bodies, V, Q, lower, g_ = [], 0, sp.zeros(4, 1), [], []
    for th, ph, O, mass, push in ((th1, ph1, 0, m2, F), (th2, ph2, dx, 3 * m2 / 2, Fa * sp.sin(w * t))):
        c1 = sp.Matrix([O, 0]) + a1 * down(th)
        c2 = sp.Matrix([O, 0]) + 2 * a1 * down(th) + a2 * down(ph)
        bodies += [(m1, c1, th, I1), (mass, c2, ph, I2)]
        V += g * (m1 * c1[1] + mass * c2[1])
        Q += sp.Matrix([push * c2[0].diff(a) for a in y])
        lower.append(c2)
        g_.append(a1 * sp.sin(th) + a2 * sp.sin(ph) - c)
    gap = lower[1] - lower[0]
    V += ks * (sp.sqrt(gap.dot(gap)) - l0) ** 2 / 2
    rel = th2 - th1
    M, h = virtual_power(bodies, y)
    end_left = 2 * a1 * down(th1) + 2 * a2 * down(ph1)
    yd = dots(y)  # the brake on the dependent ph2 and the drag in ph1's velocity
    f = sp.Matrix([-V.diff(a) + Q[i] - cd * rate_of(rel, y) * rel.diff(a) - cb * yd[3] * int(a == ph2)
                   - cb * yd[2] * end_left[0].diff(a) for i, a in enumerate(y)])
    ref = Constrained(y, M, h, f, g_, [th1, th2], params)
    system = sweep3.derived("twin_system2.yaml")
    assert [s.name for s in system.coordinates] == ["th1", "th2"]
    pairs = walk_independent(system, ref, [0.3, 0.4], [0.3, 0.4, 1.1, 0.9], 46, step=0.05)
    assert worst(pairs) < TOL


def test_gravity_of_this_model_on_a_known_system_on_a_line_and_in_the_plane():
    """A gravity effect naming a known system acts on its bodies; on one with parts on a line and
    in the plane (no one world) it acted on nothing, silently (V = 0 from it: the pendulum
    weightless on the Moon)."""
    from kronsub.model.scenes import derive_scene, select_scene

    x, th = q = list(S("x th"))
    g_moon = S("g_moon")
    q_, M, h, f, V = sweep3.cart_pendulum_reference()
    g = S("g")
    earth = sp.Matrix([-(V - V.subs(g, 0)).diff(a) for a in q])  # the known system's own gravity
    moon = (V - V.subs(g, 0)).subs(g, g_moon)
    model = kronsub.load(sweep3.HERE / "cart_pendulum_on_moon.yaml")
    system = derive_scene(model, select_scene(model, "moon"))
    fixed = lambda rng: {"x": rng.uniform(0, 1)}  # noqa: E731
    f_moon = f - earth + sp.Matrix([-moon.diff(a) for a in q])
    assert compare_explicit(system, (M, h, f_moon), 47, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V.subs(g, 0) + moon, 47, fixed=fixed) < TOL


def test_nested_known_systems_with_overrides():
    q, M, h, f, V = sweep5.nested_reference()
    system = sweep5.derived("nested_scenes.yaml")
    assert compare_explicit(system, (M, h, f), 510) < TOL
    assert compare_energies(system, kinetic(M, q), V, 510) < TOL


def test_known_system_with_overrides_in_time_placed():
    """Overrides in t of parameters that enter the known system's effects only (its wall
    spring's rest length, its hinge's damping), another of its mass, and `origin:`."""
    s, th = q = list(S("s th"))
    mc, l, k, g, x0, A, w, c0, kt, mb = S("mc l k g x0 A w c0 kt mb")
    mp = R(3, 5)
    cart = sp.Matrix([x0 + s, 0])
    tip = cart + l * down(th)
    M, h = virtual_power([(mc, sp.Matrix([s])), (mp, cart + l / 2 * down(th), th, mp * l ** 2 / 12), (mb, tip)], q)
    gap = tip - sp.Matrix([R(6, 5), -R(3, 10)])
    V = (k * (sp.sqrt(s ** 2) - (R(2, 5) + A * sp.sin(w * t))) ** 2 / 2 + kt * gap.dot(gap) / 2
         + g * (mp + mb) * tip[1] - g * mp * l / 2 * down(th)[1])
    f = gradient_force(V, q, damper_rows(c0 * (1 + t / 2), th, q))
    system = sweep5.derived("override_in_time.yaml")
    assert compare_explicit(system, (M, h, f), 514) < TOL
    assert compare_energies(system, kinetic(M, q), V, 514) < TOL


def test_helix_known_system_reused_and_placed_in_space():
    system = sweep5.derived("helix_pair.yaml")
    assert [s.name for s in system.coordinates] == ["s1", "s2"]
    guess = [0.5, -0.3, 0.44, 0.24, 0.075, 0.48, -0.15, -0.045]
    assert worst(walk_independent(system, sweep5.helix_pair_reference(), [0.5, -0.3], guess, 515, step=0.3)) < TOL


@pytest.mark.parametrize("which", [None, "quiet"])
def test_two_particle_pendulums_as_known_systems_placed_and_tied(which):
    """particle_double_pendulum.yaml twice (one placed, overridden), and its scene without the
    nested dampers and push: equal to the hand equations with those loads left out."""
    q, T, V, Q = sweep6.twin_reference(quiet=which == "quiet")
    system = sweep6.scene("twin_particle_pendulums.yaml", which) if which else sweep6.derived("twin_particle_pendulums.yaml")
    assert compare_explicit(system, lagrange(T, V, q, Q), 615) < TOL
    assert compare_energies(system, T, V, 615) < TOL
