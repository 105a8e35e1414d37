"""A closed loop used as a known system: the group property (13) across implicit constraints.

models/examples/geared_four_bar.yaml uses four_bar.yaml whole (`model:`) and connects its
crank explicitly to a motor through a gear; the linkage brings its constraints and branch.
Independent routes: the same mechanism written in one step (tests/data/
geared_four_bar_one_step.yaml) at 20 random states (Mbar, hbar, fbar, T); the kinetic
energy and the generalized forces against sympy.physics.mechanics' KanesMethod with
configuration constraints (reference.closed_loops.four_bar), the gear and the motor's
inertia added by hand, the spring's force by hand from the rocker's tip; a 10 s run that
keeps the loop closed and follows the one-step model's run.
"""
from __future__ import annotations

import io

import numpy as np
import sympy
from click.testing import CliRunner

from reference import closed_loops as loops
import kronsub
from conftest import MODELS, ROOT
from helpers import constraint_residual, implicit_numeric
from kronsub.cli import main

NESTED = MODELS / "examples" / "geared_four_bar.yaml"
ONE_STEP = ROOT / "tests" / "data" / "geared_four_bar_one_step.yaml"


def _systems():
    return kronsub.load(NESTED).derive(), kronsub.load(ONE_STEP).derive()


def test_nested_closed_loop_carries_its_constraints():
    nested, _ = _systems()
    imp = nested.implicit
    assert [q.name for q in nested.coordinates] == ["alpha"]
    assert sorted(d.name for d in imp.dependent) == ["theta2", "theta3"]
    assert sorted(c.name for c in imp.constraints) == ["linkage.B.x", "linkage.B.y"]


def test_nested_equals_one_step_at_20_random_states():
    nested, one = _systems()
    defaults = {p.name: float(p.value) for p in one.parameters}
    rng = np.random.default_rng(13)
    for _ in range(20):
        params = {k: v * rng.uniform(0.95, 1.05) for k, v in defaults.items()}
        params["tau"] = rng.uniform(-1, 1)
        q, qd = [6.0 + rng.uniform(-0.15, 0.15)], [rng.uniform(-3, 3)]
        a = implicit_numeric(nested, params)
        b = implicit_numeric(one, params)
        ga = [dict(nested.implicit.branch)[d] for d in nested.implicit.dependent]
        gb = [dict(one.implicit.branch)[d] for d in one.implicit.dependent]
        for x, y, what in zip(a(q, qd, guess=ga), b(q, qd, guess=gb), ("Mbar", "hbar", "fbar", "T")):
            assert np.allclose(x, y, rtol=1e-11, atol=1e-11), (what, params, q, qd, x, y)


def test_nested_against_kane_with_the_gear_by_hand():
    nested, _ = _systems()
    reference = loops.four_bar()
    defaults = {p.name: float(p.value) for p in nested.parameters}
    branch = dict(nested.implicit.branch)
    rng = np.random.default_rng(14)
    for _ in range(10):
        params = {k: v * rng.uniform(0.95, 1.05) for k, v in defaults.items()}
        params["tau"] = rng.uniform(-1, 1)
        n, Jm, k, l3, d = (params[s] for s in ("n", "Jm", "k", "l3", "d"))
        alpha, alpha_dot = 6.0 + rng.uniform(-0.15, 0.15), rng.uniform(-3, 3)
        guess = [branch[sympy.Symbol(name, real=True)] for name in reference.dependent]
        # the four-bar at theta1 = alpha/n, theta1_dot = alpha_dot/n (the gear)
        q, u = reference.state([alpha / n], [alpha_dot / n], guess, params)
        fr, T_ref, _ = reference.evaluate(q, u, params)
        T_ref += Jm * alpha_dot**2 / 2
        # the spring on the rocker's tip P3 = (d + l3 sin theta3, -l3 cos theta3), towards (1.2, 0):
        # -dV/dalpha = -k (P3 - c) . dP3/dtheta3 * dtheta3/dalpha
        theta3 = q[reference.independent.__len__() + reference.dependent.index("theta3")]
        _, per_alpha = reference.state([alpha / n], [1.0 / n], guess, params)
        dtheta3 = per_alpha[1 + reference.dependent.index("theta3")]
        P3 = np.array([d + l3 * np.sin(theta3), -l3 * np.cos(theta3)])
        f_spring = -k * (P3 - [1.2, 0.0]) @ np.array([l3 * np.cos(theta3), l3 * np.sin(theta3)]) * dtheta3
        M, h, f, T = implicit_numeric(nested, params)([alpha], [alpha_dot],
                                                      guess=[branch[d] for d in nested.implicit.dependent])
        assert abs(T - T_ref) <= 1e-10 * max(1.0, abs(T_ref)), (T, T_ref)
        assert np.allclose(f, fr / n + f_spring, rtol=1e-10, atol=1e-10), (f, fr / n + f_spring)


def _table(args):
    result = CliRunner().invoke(main, ["simulate", *args, "--t", "10"])
    assert result.exit_code == 0, result.output
    lines = [ln for ln in result.stdout.splitlines() if not ln.startswith("#") and ln.strip()]
    return lines[0].split(","), np.loadtxt(io.StringIO("\n".join(lines[1:])), delimiter=",", ndmin=2)


def test_nested_simulates_like_one_step():
    header, data = _table([str(NESTED), "--rtol", "1e-10", "--atol", "1e-10"])
    nested, _ = _systems()
    assert constraint_residual(nested, header, data) <= 1e-9
    header2, data2 = _table([str(ONE_STEP), "--rtol", "1e-10", "--atol", "1e-10"])
    col, col2 = {c: i for i, c in enumerate(header)}, {c: i for i, c in enumerate(header2)}
    for name in ("alpha", "alpha_dot", "theta2", "theta3"):
        assert np.allclose(data[:, col[name]], data2[:, col2[name]], rtol=1e-7, atol=1e-7), name
