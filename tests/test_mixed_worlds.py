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
