"""Springs and dampers join points of different worlds as pins do (components.base.in_world: a
point of the line lies on the plane's x axis, a point of the plane in space's z = 0 plane),
checked against a hand Lagrangian with a Rayleigh dissipation function in plain sympy."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from kronsub.cli import main

CART_AND_PENDULUM = """\
name: cart tied to a pendulum
parameters: {m: 1.5, M: 2, L: 1.2, H: 2, g: 9.81, k: 3, l0: 0.4, c: 0.7, k2: 5, d: 0.3}
components:
  s: {type: particle1d, parameters: {mass: m}, coordinates: [x]}
  p: {type: pinned_rod, parameters: {mass: M, length: L, pivot_y: H}, coordinates: [theta]}
coordinates: [x, theta]
effects:
  gravity: {type: gravity, g: g, components: [p]}
  tie: {type: spring, between: [s.centre, p.tip], stiffness: k, length: l0}
  drag: {type: damper, between: [p.tip, s.centre], coefficient: c}
  anchor: {type: spring, between: [p.centre, [d]], stiffness: k2}
"""


def _derive(tmp_path, text):
    path = tmp_path / "model.yaml"
    path.write_text(text)
    return kronsub.load(path).derive(cache=False)


def test_a_cart_on_the_line_tied_to_a_pendulum_in_the_plane(tmp_path):
    system = _derive(tmp_path, CART_AND_PENDULUM)
    S = system.symbol
    x, th, xd, thd = S("x"), S("theta"), S("x_dot"), S("theta_dot")
    m, M, L, H, g, k, l0, c, k2, d = (S(n) for n in ("m", "M", "L", "H", "g", "k", "l0", "c", "k2", "d"))
    q, qd = [x, th], [xd, thd]
    # by hand: the cart at (x, 0), the tip at (L sin th, H - L cos th), the centre half way
    tip = sympy.Matrix([L * sympy.sin(th), H - L * sympy.cos(th)])
    centre = sympy.Matrix([L * sympy.sin(th) / 2, H - L * sympy.cos(th) / 2])
    cart, anchor = sympy.Matrix([x, 0]), sympy.Matrix([d, 0])
    length = sympy.sqrt(sum((tip - cart).applyfunc(lambda e: e**2)))
    T = m * xd**2 / 2 + (M * L**2 / 12 + M * (L / 2) ** 2) * thd**2 / 2
    V = (M * g * centre[1] + k * (length - l0) ** 2 / 2
         + k2 * sum((centre - anchor).applyfunc(lambda e: e**2)) / 2)
    rate = sum(sympy.diff(length, a) * b for a, b in zip(q, qd))
    D = c * rate**2 / 2  # Rayleigh: the damper's force is -dD/dqdot
    mass = sympy.hessian(T, qd)
    # d/dt dT/dqdot - dT/dq + dV/dq + dD/dqdot = 0, without the accelerations: hbar - fbar
    rest = [sum(sympy.diff(sympy.diff(T, b), a) * ad for a, ad in zip(q, qd)) - sympy.diff(T, a)
            + sympy.diff(V, a) + sympy.diff(D, b) for a, b in zip(q, qd)]
    for i in range(2):
        for j in range(2):
            assert sympy.simplify(system.mass_matrix[i, j] - mass[i, j]) == 0
    assert sympy.simplify(system.potential_energy - V) == 0
    names = [x, th, xd, thd, m, M, L, H, g, k, l0, c, k2, d]
    ours = sympy.lambdify(names, list(system.velocity_terms - system.forces))
    hand = sympy.lambdify(names, rest)
    rng = np.random.default_rng(7)
    for _ in range(8):
        values = list(rng.uniform(-2, 2, 4)) + list(rng.uniform(0.3, 2, 10))
        assert np.allclose(ours(*values), hand(*values), rtol=1e-12, atol=1e-12)
    assert {"drag"} <= set(system.effect_forces) and any(e != 0 for e in system.effect_forces["drag"])


PARTICLES = {1: ("particle1d", ["u1"]), 2: ("particle2d", ["u1", "u2"]), 3: ("particle3d", ["u1", "u2", "u3"])}


@pytest.mark.parametrize("worlds", list(itertools.permutations((1, 2, 3), 2)))
def test_every_pair_of_worlds_a_pin_joins(tmp_path, worlds):
    """Particles of two worlds, a spring and a damper between them: ``V = k/2 |b - a|^2`` and
    ``f = -c ldot dl/dq`` with the smaller world's point padded with zeros, by hand; a pin
    between the same points is accepted too."""
    (ta, na), (tb, nb) = PARTICLES[worlds[0]], PARTICLES[worlds[1]]
    a_names, b_names = [f"a_{n}" for n in na], [f"b_{n}" for n in nb]
    text = f"""\
name: two worlds
parameters: {{k: 2, c: 0.5}}
components:
  a: {{type: {ta}, parameters: {{mass: 1}}, coordinates: [{', '.join(a_names)}]}}
  b: {{type: {tb}, parameters: {{mass: 1}}, coordinates: [{', '.join(b_names)}]}}
coordinates: [{', '.join(a_names + b_names)}]
effects:
  k: {{type: spring, between: [a.centre, b.centre], stiffness: k}}
  c: {{type: damper, between: [a.centre, b.centre], coefficient: c}}
"""
    system = _derive(tmp_path, text)
    S = system.symbol
    k, c = S("k"), S("c")
    a = [S(n) for n in a_names] + [0] * (3 - len(a_names))
    b = [S(n) for n in b_names] + [0] * (3 - len(b_names))
    q = [S(n) for n in a_names + b_names]
    square = sum((bi - ai) ** 2 for ai, bi in zip(a, b))
    assert sympy.expand(system.potential_energy - k * square / 2) == 0
    length = sympy.sqrt(square)
    rate = sum(sympy.diff(length, s) * S(f"{s.name}_dot") for s in q)
    for qi, f in zip(q, system.effect_forces["c"]):
        assert sympy.cancel(f + c * rate * sympy.diff(length, qi)) == 0
    pinned = text.replace(f"coordinates: [{', '.join(a_names + b_names)}]",
                          "coordinates: auto\nconstraints:\n  j: {pin: [a.centre, b.centre]}")
    (tmp_path / "pinned.yaml").write_text(pinned)
    result = CliRunner().invoke(main, ["check", str(tmp_path / "pinned.yaml")])
    assert result.exit_code == 0, result.output


CART_POLE = """\
name: cart-pole
parameters: {mc: 1.3, mp: 0.4, l: 0.9, g: 9.81, a: 0.3}
components:
  cart: {type: particle1d, parameters: {mass: mc}, coordinates: [x]}
  pole: {type: pinned_rod, parameters: {mass: mp, length: l}, coordinates: {angle: theta}, pivot: cart.centre}
coordinates: [x, theta]
effects:
  gravity: GRAVITY
"""


def _cart_pole_by_hand(S, direction):
    """``(Mbar, hbar - fbar)`` of the cart-pole by Lagrange: the cart at ``(x, 0)`` (a line is the
    plane's x axis), the pole's centre ``l/2 (sin theta, -cos theta)`` from it, gravity ``g`` along
    the unit ``direction`` on both bodies."""
    x, th, xd, thd = S("x"), S("theta"), S("x_dot"), S("theta_dot")
    mc, mp, l, g = S("mc"), S("mp"), S("l"), S("g")
    q, qd = [x, th], [xd, thd]
    d = sympy.Matrix(direction) / sympy.sqrt(sum(c**2 for c in direction))
    cart = sympy.Matrix([x, 0])
    centre = cart + l / 2 * sympy.Matrix([sympy.sin(th), -sympy.cos(th)])
    velocity = centre.diff(x) * xd + centre.diff(th) * thd
    T = mc * xd**2 / 2 + mp * velocity.dot(velocity) / 2 + mp * l**2 / 12 * thd**2 / 2
    V = -g * (mc * d.dot(cart) + mp * d.dot(centre))
    rest = [sum(sympy.diff(sympy.diff(T, b), a) * ad for a, ad in zip(q, qd)) - sympy.diff(T, a) + sympy.diff(V, a)
            for a, b in zip(q, qd)]
    return sympy.hessian(T, qd), rest, [x, th, xd, thd, mc, mp, l, g]


@pytest.mark.parametrize("direction", [(0, -1), (sympy.sin(sympy.Symbol("a")), -sympy.cos(sympy.Symbol("a")))],
                         ids=["horizontal rail", "tilted gravity"])
def test_a_cart_on_its_rail_feels_gravity_along_the_rail_only(tmp_path, direction):
    """Gravity over a line and the plane, its direction given in the plane: the line is the
    plane's x axis, so the cart feels ``g (d . e_x)`` along it (none for a horizontal rail), as a
    hand Lagrangian of the cart-pole says."""
    written = "[0, -1]" if direction == (0, -1) else "[sin(a), -cos(a)]"
    system = _derive(tmp_path, CART_POLE.replace("GRAVITY", f"{{type: gravity, g: g, direction: {written}}}"))
    S = system.symbol
    a = S("a")
    direction = [sympy.sympify(c).xreplace({sympy.Symbol("a"): a}) for c in direction]
    mass, rest, names = _cart_pole_by_hand(S, direction)
    for i in range(2):
        for j in range(2):
            assert sympy.simplify(system.mass_matrix[i, j] - mass[i, j]) == 0
    weight_on_cart = system.effect_forces["gravity"][0]  # fbar along x
    assert sympy.simplify(weight_on_cart - (S("mc") + S("mp")) * S("g") * direction[0]) == 0
    ours = sympy.lambdify(names + [a], list(system.velocity_terms - system.forces))
    hand = sympy.lambdify(names + [a], rest)
    rng = np.random.default_rng(3)
    for _ in range(6):
        values = list(rng.uniform(-2, 2, 4)) + list(rng.uniform(0.3, 2, 5))
        assert np.allclose(ours(*values), hand(*values), rtol=1e-12, atol=1e-12)


def _check(tmp_path, text):
    (tmp_path / "model.yaml").write_text(text)
    return CliRunner().invoke(main, ["check", str(tmp_path / "model.yaml")])


def test_gravity_over_worlds_without_a_direction_is_refused_where_it_is_written(tmp_path):
    """Each world's own "down" (along the line, -y in the plane) disagrees with the others' once a
    line is the plane's x axis: ``check`` refuses the gravity, located, with the way out."""
    result = _check(tmp_path, CART_POLE.replace("GRAVITY", "{type: gravity, g: g}"))
    assert result.exit_code == 1, result.output
    assert ("model.yaml:8:12: gravity 'gravity' has no `direction:` and acts on components of different "
            "worlds (line: cart; plane: pole)") in result.output
    assert "hint: give `direction:` in the plane, e.g. `[0, -1]`" in result.output
    space = CART_POLE.replace("  pole:", "  top: {type: particle3d, parameters: {mass: mp}, coordinates: [u, v, w]}\n"
                                         "  pole:").replace("[x, theta]", "[x, theta, u, v, w]")
    result = _check(tmp_path, space.replace("GRAVITY", "{type: gravity, g: g}"))
    assert result.exit_code == 1 and "(line: cart; plane: pole; space: top)" in result.output, result.output
    assert "e.g. `[0, 0, -1]`" in result.output
    one_world = CART_POLE.replace("GRAVITY", "{type: gravity, g: g, components: [pole]}")
    assert _check(tmp_path, one_world).exit_code == 0


def test_a_listed_component_gravity_does_nothing_on_is_refused(tmp_path):
    """Listing the cart under a gravity straight across its rail asks for a force it never feels."""
    result = _check(tmp_path, CART_POLE.replace(
        "GRAVITY", "{type: gravity, g: g, direction: [0, -1], components: [cart, pole]}"))
    assert result.exit_code == 1, result.output
    assert ("gravity 'gravity' does nothing on component 'cart': its direction is across the line the "
            "component moves in (the plane's x axis)") in result.output
    tilted = CART_POLE.replace("GRAVITY", "{type: gravity, g: g, direction: [1, -3], components: [cart, pole]}")
    assert _check(tmp_path, tilted).exit_code == 0
