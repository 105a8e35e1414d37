"""Closed loops: implicit constraints g(x) = 0 (Hoffmann's (25)-(29) and example III).

Each closed-loop model against an independent route: System II written with (25) equals
System II written with (26) (system2.yaml) at 20 random states; every closed-loop model
against sympy.physics.mechanics' KanesMethod with configuration constraints
(tests/reference/closed_loops.py): generalized active forces (fbar), kinetic energy (Mbar) and
accelerations (with those, hbar) at random consistent states; the pendulum on a cart with
``pivot:`` against the hand-connected cart-pole's mechanics reference.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy

from reference import closed_loops as loops
import kronsub
from reference import mechanics as ref
from conftest import MODELS
from helpers import implicit_numeric as _numeric


def test_system2_implicit_equals_system2_at_20_random_states():
    explicit = kronsub.load(MODELS / "hoffmann" / "system2.yaml").derive()
    implicit = kronsub.load(MODELS / "hoffmann" / "system2_implicit.yaml").derive()
    assert implicit.implicit.dependent == (sympy.Symbol("phi", real=True),)
    assert implicit.implicit.closed_form  # asin, as (26), on the branch of the initial configuration
    rng = np.random.default_rng(25)
    for _ in range(20):
        params = {p.name: rng.uniform(0.3, 1.7) for p in implicit.parameters}
        params.update(a1=rng.uniform(0.3, 0.6), a2=rng.uniform(0.9, 1.2), c=rng.uniform(0.1, 0.3))
        q, qd = [rng.uniform(-0.3, 0.3)], [rng.uniform(-1.5, 1.5)]
        a = _numeric(explicit, params)(q, qd)
        b = _numeric(implicit, params)(q, qd, guess=[0.0])
        for x, y, what in zip(a, b, ("Mbar", "hbar", "fbar", "T")):
            assert np.allclose(x, y, rtol=1e-12, atol=1e-12), (what, params, q, qd, x, y)


def test_system2_implicit_prints_the_papers_structure():
    system = kronsub.load(MODELS / "hoffmann" / "system2_implicit.yaml").derive()
    lam = system.implicit.sensitivities[0, 0]
    assert lam.name == "lambda_phi_theta"  # never the keyword lambda: printed entries parse back
    definition = dict(system.implicit.definitions)[lam]
    a1, a2, theta, phi = (sympy.Symbol(n, real=True) for n in ("a1", "a2", "theta", "phi"))
    assert sympy.simplify(definition + a1 * sympy.cos(theta) / (a2 * sympy.cos(phi))) == 0  # (28)
    m2, I2 = sympy.Symbol("m2", real=True), sympy.Symbol("I2", real=True)
    M = sympy.expand(system.mass_matrix[0, 0])
    assert sympy.simplify(M.coeff(lam, 2) - (I2 + a2**2 * m2)) == 0
    assert sympy.simplify(M.coeff(lam, 1) - 4 * a1 * a2 * m2 * sympy.cos(phi - theta)) == 0
    # exact and polynomial in the intermediates: no square root, no asin, no division entered
    for entry in list(system.mass_matrix) + list(system.velocity_terms) + list(system.forces):
        assert all(p.exp.is_Integer and p.exp > 0 for p in entry.atoms(sympy.Pow)), entry
        assert not entry.has(sympy.asin)


CLOSED = {
    "examples/four_bar.yaml": (loops.four_bar, {}),
    "examples/slider_crank.yaml": (loops.slider_crank, {}),
    "hoffmann/system3.yaml": (loops.system3, {}),
    "hoffmann/system2_implicit.yaml": (loops.system2, {"c": (0.55, 0.65)}),
}


@pytest.mark.parametrize("path", sorted(CLOSED))
def test_closed_loop_matches_kane_with_configuration_constraints(path):
    make, ranges = CLOSED[path]
    reference = make()
    model = kronsub.load(MODELS / path)
    system = model.derive()
    imp = system.implicit
    assert [q.name for q in imp.independent] == reference.independent
    defaults = {p.name: float(p.value) for p in system.parameters if p.value is not None}
    ours = None
    rng = np.random.default_rng(7)
    branch = dict(imp.branch)
    start = {q: float(model.initial.get(q, 0)) for q in imp.independent}
    for trial in range(20):
        params = {k: v * rng.uniform(0.95, 1.05) for k, v in defaults.items()}
        for k, r in ranges.items():
            params[k] = rng.uniform(*r)
        if "F" in params:
            params["F"] = rng.uniform(-1, 1)
        if "tau" in params:
            params["tau"] = rng.uniform(-1, 1)
        ours = _numeric(system, params)
        q_ind = np.array([start[q] + rng.uniform(-0.05, 0.05) for q in imp.independent])
        u_ind = rng.uniform(-1.5, 1.5, len(q_ind))
        guess = [branch[d] for d in imp.dependent]
        ref_guess = [branch[sympy.Symbol(n, real=True)] for n in reference.dependent]
        q, u = reference.state(q_ind, u_ind, ref_guess, params)
        fr, T_ref, acc_ref = reference.evaluate(q, u, params)
        M, h, f, T = ours(q_ind, u_ind, guess=guess)
        # the same dependent coordinates on the same branch
        solved = dict(zip(reference.dependent, q[len(q_ind):]))
        ev = ours.evaluator
        ev.guess = np.array(guess)
        for d, v in zip(imp.dependent, ev.dependent(q_ind)):
            assert abs(v - solved[d.name]) < 1e-9, (d, v, solved)
        assert np.allclose(f, fr, rtol=1e-10, atol=1e-10), ("fbar", f, fr)
        assert abs(T - T_ref) <= 1e-10 * max(1.0, abs(T_ref)), ("T", T, T_ref)
        acc = np.linalg.solve(M, f - h)
        assert np.allclose(acc, acc_ref, rtol=1e-9, atol=1e-9), ("qddot", acc, acc_ref)


def test_pendulum_on_cart_with_pivot_matches_cart_pole_reference():
    system = kronsub.load(MODELS / "examples" / "pendulum_on_cart.yaml").derive()
    reference = ref.cart_pole()
    assert tuple(q.name for q in system.coordinates) == reference.coordinates
    exprs = [system.mass_matrix, system.velocity_terms, system.forces]
    syms = sorted(set().union(*(e.free_symbols for e in exprs)), key=lambda s: s.name)
    fn = sympy.lambdify(syms, exprs, "numpy")
    rng = np.random.default_rng(3)
    for _ in range(20):
        values = {n: rng.uniform(0.3, 1.7) for n in ("mc", "mp", "l", "g", "b", "u")}
        values.update({n: rng.uniform(-1.5, 1.5) for n in ("x", "theta", "x_dot", "theta_dot")})
        M, h, f = (np.array(a, float) for a in fn(*[values[s.name] for s in syms]))
        Mr, hr, fr = ref.numeric(reference, values)
        assert np.allclose(M, Mr, rtol=1e-12, atol=1e-12)
        assert np.allclose(h.ravel(), hr, rtol=1e-12, atol=1e-12)
        assert np.allclose(f.ravel(), fr, rtol=1e-12, atol=1e-12)


def test_auto_picks_and_reports_the_independent_coordinate():
    system = kronsub.load(MODELS / "examples" / "slider_crank.yaml").derive()
    assert system.implicit.choice == "auto"
    assert [q.name for q in system.coordinates] == ["theta"]
    from kronsub.emitters import emit_markdown

    assert "picked by `coordinates: auto`" in emit_markdown(system)


JOINT_HEAD = """name: bead
parameters: {m: 0.7, M: 1.3, L: 1.2, g: 9.81}
components:
  rod: {type: pinned_rod, parameters: {mass: M, length: L}, coordinates: {angle: th}}
  bead: {type: particle2d, parameters: {mass: m}, coordinates: [bx, by]}
coordinates: [th, bx]
effects:
  gravity: {type: gravity, g: g, direction: [0, -1]}
"""


@pytest.mark.parametrize("joint", [
    "  s: {slider: {point: bead.centre, body: rod}}",  # the rod's own axis, through its centre
    "  s: {slider: {point: bead.centre, body: rod, through: [0.3, 0], direction: [2, 0]}}",
    "  s: {point_on_line: {point: bead.centre, through: rod.pivot, direction: [sin(th), -cos(th)]}}",
])
def test_joints_equal_the_parametric_form(tmp_path, joint):
    """A bead on a pinned rod: `slider` (a line fixed in the body) and `point_on_line` (a moving
    line) against the parametric connection by = -bx cot(th) of the same line."""
    implicit_path = tmp_path / "implicit.yaml"
    implicit_path.write_text(JOINT_HEAD + "constraints:\n" + joint + "\ninitial: {th: 0.8, bx: 0.4, by: -0.3}\n")
    explicit_path = tmp_path / "explicit.yaml"
    explicit_path.write_text(JOINT_HEAD + "connection:\n  by: -bx*cos(th)/sin(th)\n")
    implicit = kronsub.load(implicit_path).derive()
    explicit = kronsub.load(explicit_path).derive()
    assert [d.name for d in implicit.implicit.dependent] == ["by"]
    rng = np.random.default_rng(8)
    params = {p.name: float(p.value) for p in implicit.parameters}
    a_at, b_at = _numeric(explicit, params), _numeric(implicit, params)
    for _ in range(10):
        q, qd = [rng.uniform(0.4, 1.2), rng.uniform(0.2, 1.0)], rng.uniform(-1.5, 1.5, 2)
        for x, y, what in zip(a_at(q, qd), b_at(q, qd, guess=[-q[1] / np.tan(q[0])]), ("M", "h", "f", "T")):
            assert np.allclose(x, y, rtol=1e-11, atol=1e-11), (joint, what, x, y)


def test_pivot_on_a_pivoted_rod_matches_the_rod_chain(tmp_path):
    """pivot: on a part that itself hangs from a moving point (the connection is composed)."""
    text = ["name: chain3", "parameters: {m1: 1.1, m2: 0.9, m3: 1.3, l1: 0.7, l2: 1.1, l3: 0.5, g: 9.81}",
            "components:",
            "  r1: {type: pinned_rod, parameters: {mass: m1, length: l1}, coordinates: {angle: q1}}",
            "  r2: {type: pinned_rod, parameters: {mass: m2, length: l2}, coordinates: {angle: q2}, pivot: r1.tip}",
            "  r3: {type: pinned_rod, parameters: {mass: m3, length: l3}, coordinates: {angle: q3}, pivot: r2.tip}",
            "coordinates: [q1, q2, q3]",
            "effects:", "  gravity: {type: gravity, g: g, direction: [0, -1]}"]
    path = tmp_path / "chain3.yaml"
    path.write_text("\n".join(text) + "\n")
    system = kronsub.load(path).derive()
    reference = ref.rod_chain(3)
    exprs = [system.mass_matrix, system.velocity_terms, system.forces]
    syms = sorted(set().union(*(e.free_symbols for e in exprs)), key=lambda s: s.name)
    fn = sympy.lambdify(syms, exprs, "numpy")
    rng = np.random.default_rng(9)
    for _ in range(10):
        values = {n: rng.uniform(0.3, 1.7) for n in ("m1", "m2", "m3", "l1", "l2", "l3", "g")}
        values.update({f"q{i}{s}": rng.uniform(-1.5, 1.5) for i in (1, 2, 3) for s in ("", "_dot")})
        M, h, f = (np.array(a, float) for a in fn(*[values[s.name] for s in syms]))
        Mr, hr, fr = ref.numeric(reference, values)
        assert np.allclose(M, Mr, rtol=1e-12, atol=1e-12)
        assert np.allclose(h.ravel(), hr, rtol=1e-12, atol=1e-12)
        assert np.allclose(f.ravel(), fr, rtol=1e-12, atol=1e-12)
