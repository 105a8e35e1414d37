"""The circle state (emitters/circle.py): angles integrated as (cos q, sin q) beside q.

Independent routes: the circle right-hand side against the ordinary one (``ks_rhs``) at random
states, with ``cos q`` and ``sin q`` put into the state by numpy; which coordinates qualify
against what the equations plainly show (a spring's angle enters as itself); a run in the
circle state against a run in ``[q; qdot]`` of the same model and tolerances.
"""
from __future__ import annotations

import shutil
import sys

import numpy as np
import pytest
import sympy

import kronsub
from conftest import MODELS
from kronsub.emitters.circle import circle_equations
from kronsub.emitters.block import Block
from kronsub.emitters.numeric import NearAxis
from kronsub.model.scenes import derive_scene, select_scene
from kronsub.simulation.compiled import compiled_library
from kronsub.simulation.native import NativeModel
from kronsub.simulation.values import resolve

sys.path.insert(0, str(MODELS / "chain"))
from generate import chain_yaml  # noqa: E402

needs_cc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
Q = sympy.symbols("q[0] q[1] q[2]")
X = sympy.symbols("x0:4")


def _native(system):
    return NativeModel(compiled_library(system), len(system.coordinates), len(system.parameters))


def test_an_angle_seen_only_through_sines_and_cosines_is_a_circle_coordinate():
    s0, c0, s1, c1 = sympy.sin(Q[0]), sympy.cos(Q[0]), sympy.sin(Q[1]), sympy.cos(Q[1])
    block = Block(((X[0], s0 * c1 - c0 * s1),), (("r[0]", X[0] * c0 + s1), ("r[1]", 3 * Q[2] + s0)))
    circle, rewritten = circle_equations(block, Q)
    assert circle == (0, 1)  # q[2] enters as itself and has no sine here
    cq, sq = sympy.symbols("cq[0:2]"), sympy.symbols("sq[0:2]")
    assert rewritten.temporaries == ((X[0], sq[0] * cq[1] - cq[0] * sq[1]),)
    assert dict(rewritten.outputs) == {"r[0]": X[0] * cq[0] + sq[1], "r[1]": 3 * Q[2] + sq[0]}


def test_an_angle_also_seen_as_itself_or_halved_is_not():
    s0, s1, c2 = sympy.sin(Q[0]), sympy.sin(Q[1]), sympy.cos(Q[2])
    spring = Block(((X[0], Q[0] - Q[1]),), (("r[0]", s0 + 2 * X[0]), ("r[1]", s1 * c2)))
    circle, rewritten = circle_equations(spring, Q)
    assert circle == (2,)
    assert ("r[0]", s0 + 2 * X[0]) in rewritten.outputs
    halved = Block((), (("r[0]", s0 * sympy.sin(Q[0] / 2)),))
    assert circle_equations(halved, Q) == ((), None)
    assert circle_equations(Block((), (("r[0]", Q[0] ** 2),)), Q) == ((), None)


def test_guards_go_only_with_a_circle_coordinate_in_their_angle():
    """``NearAxis`` (numeric.py) takes a small sine from the angle itself: in the circle state
    there is none, so the product stays; an angle of non-circle coordinates keeps its guard."""
    s = [sympy.sin(q) for q in Q]
    c = [sympy.cos(q) for q in Q]
    p01, p12 = s[0] * c[1] - c[0] * s[1], s[1] * c[2] - c[1] * s[2]
    block = Block(((X[0], Q[1] - Q[2]),),
                  (("r[0]", NearAxis(Q[0] - Q[1], 0, p01, p01)),
                   ("r[1]", NearAxis(X[0], 0, p12, p12) + Q[1] + Q[2])))
    circle, rewritten = circle_equations(block, Q)
    assert circle == (0,)
    out = dict(rewritten.outputs)
    cq0, sq0 = sympy.Symbol("cq[0]"), sympy.Symbol("sq[0]")
    assert out["r[0]"] == sq0 * c[1] - cq0 * s[1]
    assert out["r[1]"].has(NearAxis) and rewritten.temporaries == ((X[0], Q[1] - Q[2]),)


def _hinged(tmp_path, n=3):
    path = tmp_path / "hinged.yaml"
    path.write_text(chain_yaml(n, hinges=True))
    model = kronsub.load(path)
    return model, {name: derive_scene(model, select_scene(model, name)) for name in ("full", "gravity_only")}


@needs_cc
def test_a_spring_at_every_hinge_keeps_the_angles_and_a_scene_without_them_drops_them(tmp_path):
    _, systems = _hinged(tmp_path)
    assert _native(systems["full"]).nc == 0
    assert _native(systems["gravity_only"]).nc == 3


@needs_cc
@pytest.mark.parametrize("source", ["hoffmann/system1.yaml", "examples/cart_pole.yaml", "examples/watt_governor.yaml",
                                    "chain5", "gravity_only"])
def test_the_circle_right_hand_side_is_the_ordinary_one(source, tmp_path):
    if source == "chain5":
        system = kronsub.load("chain5.yaml", text=chain_yaml(5)).derive()
    elif source == "gravity_only":
        system = _hinged(tmp_path, 4)[1]["gravity_only"]
    else:
        system = kronsub.load(MODELS / source).derive()
    native = _native(system)
    n, nc = len(system.coordinates), native.nc
    assert nc > 0
    rng = np.random.default_rng(5)
    for _ in range(50):
        y = np.concatenate([rng.uniform(-7, 7, n), rng.uniform(-3, 3, n)])
        param = rng.uniform(0.5, 1.5, len(system.parameters))
        z = native.circle_state(y)
        assert np.array_equal(z[:2 * n], y)
        angles = []
        zdot = native.rhs_circle(0.0, z, param)
        ydot = native.rhs(0.0, y, param)
        scale = max(1.0, float(np.max(np.abs(ydot))))
        assert np.max(np.abs(zdot[:2 * n] - ydot)) <= 1e-12 * scale
        # the circle part: d/dt (cos q, sin q) = (-sin q, cos q) qdot of one coordinate each
        c, s = z[2 * n:2 * n + nc], z[2 * n + nc:]
        for k in range(nc):
            matches = [i for i in range(n) if np.isclose(c[k], np.cos(y[i]), rtol=0, atol=1e-15)
                       and np.isclose(s[k], np.sin(y[i]), rtol=0, atol=1e-15)]
            assert matches, k
            angles.append(matches[0])
            assert zdot[2 * n + k] == pytest.approx(-s[k] * y[n + matches[0]], rel=1e-15, abs=1e-300)
            assert zdot[2 * n + nc + k] == pytest.approx(c[k] * y[n + matches[0]], rel=1e-15, abs=1e-300)
        assert angles == sorted(set(angles))


@needs_cc
@pytest.mark.parametrize("method, setting, bound", [("dop853", 1e-9, 1e-6), ("rk4", 2e-3, 1e-5)])
def test_a_run_on_the_circle_is_as_accurate_as_the_run_in_angles(method, setting, bound):
    """System I from 120 and -10 degrees (the chaotic double pendulum) to t = 3, in the circle
    state and in ``[q; qdot]`` at the same tolerance (dop853) or step (rk4): both as far from a
    run in ``[q; qdot]`` at tol 1e-14, within a factor of 3 of each other."""
    model = kronsub.load(MODELS / "hoffmann/system1.yaml")
    system = model.derive()
    native = _native(system)
    param = np.array(resolve(system, dict(model.initial), {}).parameters)
    y0 = np.array([2 * np.pi / 3, -np.pi / 18, 0.0, 0.0])
    _, exact, _ = native.integrate("dop853", 0.0, y0, 3.0, 0.1, param, rtol=1e-14, atol=1e-14, circle=False)
    errors = {}
    for circle in (False, True):
        kwargs = dict(rtol=setting, atol=setting) if method == "dop853" else dict(h=setting)
        t, Y, result = native.integrate(method, 0.0, y0, 3.0, 0.1, param, circle=circle, **kwargs)
        assert result.ok and Y.shape == (31, 4) and np.allclose(t, np.linspace(0, 3, 31))
        errors[circle] = float(np.max(np.abs(Y - exact)))
    assert 0 < errors[True] <= bound and errors[False] <= bound
    assert errors[True] <= 3 * errors[False] and errors[False] <= 3 * errors[True], errors


@needs_cc
def test_a_run_that_fails_on_the_circle_is_told_in_angles():
    """System II stops where its lower rod reaches the line (the square root of (27) at 0): the
    run is repeated in ``[q; qdot]``, which finds the edge of the domain in theta itself."""
    model = kronsub.load(MODELS / "hoffmann/system2.yaml")
    system = model.derive()
    native = _native(system)
    assert native.nc == 1
    values = resolve(system, dict(model.initial), {"theta": "1.0"})
    param, y0 = np.array(values.parameters), np.array(values.y0)
    runs = [native.integrate("dop853", 0.0, y0, 5.0, 0.01, param, rtol=1e-10, atol=1e-10, circle=c)
            for c in (None, False)]
    (t1, Y1, r1), (t2, Y2, r2) = runs
    assert r1.status == r2.status != 0 and r1.t_fail == r2.t_fail
    assert np.array_equal(Y1, Y2) and np.array_equal(r1.y_fail, r2.y_fail)


@needs_cc
def test_the_circle_state_compiled_apart_computes_what_it_computes_in_one_file(tmp_path):
    """A run's library has the circle state's right-hand side in a file of its own
    (``emit_c(circle_apart=True)``), compiled beside the rest: the same C, moved, so the same
    numbers to the last bit as the library built from one file; the model's other functions
    are unchanged; a model whose circle equations need the projection's helpers stays whole."""
    from kronsub.emitters.code import emit_c
    from kronsub.simulation.native import compile_library

    system = kronsub.load("chain4.yaml", text=chain_yaml(4)).derive()
    whole = emit_c(system, "model", terms_apart=False, canonical=False)
    apart = emit_c(system, "model", terms_apart=False, canonical=False, circle_apart=True)
    assert [g.name for g in whole] == ["model.h", "model.c"]
    assert [g.name for g in apart] == ["model.h", "model.c", "model_circle.c"]
    assert apart[0].text == whole[0].text and "ks_rhs_circle_pre" not in apart[1].text
    solve, circle = apart[2].text.index("/* Solve M x"), apart[2].text.index("/* The circle state")
    assert apart[2].text[solve:circle].strip() in whole[1].text  # its own static copy of the solve
    assert whole[1].text.replace("\n" + apart[2].text[circle:], "") == apart[1].text  # moved, nothing else
    n, nparam = len(system.coordinates), len(system.parameters)
    one, two = (NativeModel(compile_library([(g.name, g.text) for g in files], "model"), n, nparam)
                for files in (whole, apart))
    assert one.path != two.path and one.nc == two.nc == 4
    rng = np.random.default_rng(3)
    for _ in range(20):
        y = np.concatenate([rng.uniform(-7, 7, n), rng.uniform(-3, 3, n)])
        param = rng.uniform(0.5, 1.5, nparam)
        z = one.circle_state(y)
        assert np.array_equal(one.rhs_circle(0.0, z, param), two.rhs_circle(0.0, z, param))
        assert np.array_equal(one.rhs(0.0, y, param), two.rhs(0.0, y, param))
    param = np.ones(nparam)
    runs = [m.integrate("dop853", 0.0, np.r_[np.full(n, 0.5), np.zeros(n)], 2.0, 0.5, param)[1] for m in (one, two)]
    assert np.array_equal(runs[0], runs[1])
    projected = emit_c(system, "model", terms_apart=False, canonical=False, circle_apart=True, route="projected")
    assert [g.name for g in projected] == ["model.h", "model.c"] and "ks_rhs_circle_pre" in projected[1].text
