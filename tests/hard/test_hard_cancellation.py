"""Hard case 7: cancellation in the generated right-hand side.

What could go wrong: ``sin(theta - phi)`` computed in the generated code as
``sin(theta) cos(phi) - cos(theta) sin(phi)``: for theta close to phi at large angles the two
products are nearly equal, their difference keeps only the digits they do not share, and the
velocity terms (everything, without gravity) come out with a relative error of
``eps / |theta - phi|`` -- 1e-7 at a difference of 1e-9 -- while the direct form is exact:
``theta - phi`` has no rounding error when the two are within a factor of two (Sterbenz).
Criteria: the derived equations hold the combined angle (``sin(phi - theta)``, not products of
single-angle sines); the accelerations of the generated C and Python right-hand sides of the
double pendulum of rods (System I) at random large angles with ``|theta - phi|`` from 1e-3 down
to 1e-12 agree with a 50-digit evaluation of the paper's equations (22)-(24) in mpmath to
``32 eps`` relative, component by component, without gravity (the cancelling terms alone) and
with it.
"""
from __future__ import annotations

import importlib.util
import shutil

import mpmath
import numpy as np
import pytest
import sympy

import kronsub
from conftest import MODELS
from kronsub.emitters.code import emit_c, emit_python
from kronsub.simulation.native import NativeModel, compile_library
from kronsub.simulation.values import resolve

EPS = np.finfo(float).eps
GAPS = (1e-3, 1e-6, 1e-9, 1e-12)


@pytest.fixture(scope="module")
def system1(tmp_path_factory):
    model = kronsub.load(MODELS / "hoffmann/system1.yaml")
    system = model.derive()
    (generated,) = emit_python(system, "model")
    path = tmp_path_factory.mktemp("gen") / "model.py"
    path.write_text(generated.text)
    spec = importlib.util.spec_from_file_location("gen_system1_cancellation", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    native = None
    if shutil.which("gcc") or shutil.which("cc"):
        native = NativeModel(compile_library([(g.name, g.text) for g in emit_c(system, "model")], "model"),
                             2, len(system.parameters))
    return model, system, module, native


def _exact(y, p):
    """The accelerations of System I in 50 digits, from the paper's (22)-(24) written out:
    ``Mbar = [[I1 + m1 a1^2 + 4 m2 a1^2, 2 m2 a1 a2 cos(theta - phi)], [., I2 + m2 a2^2]]``,
    ``hbar = 2 m2 a1 a2 sin(theta - phi) (phidot^2, -thetadot^2)``,
    ``fbar = -g (a1 (m1 + 2 m2) sin theta, m2 a2 sin phi)`` (F = 0)."""
    mpmath.mp.dps = 50
    th, ph, thd, phd = (mpmath.mpf(float(v)) for v in y)
    m1, m2, a1, a2, I1, I2, g = (mpmath.mpf(float(p[k])) for k in ("m1", "m2", "a1", "a2", "I1", "I2", "g"))
    d = th - ph
    M = mpmath.matrix([[I1 + m1 * a1 ** 2 + 4 * m2 * a1 ** 2, 2 * m2 * a1 * a2 * mpmath.cos(d)],
                       [2 * m2 * a1 * a2 * mpmath.cos(d), I2 + m2 * a2 ** 2]])
    h = [2 * m2 * a1 * a2 * mpmath.sin(d) * phd ** 2, -2 * m2 * a1 * a2 * mpmath.sin(d) * thd ** 2]
    f = [-g * a1 * (m1 + 2 * m2) * mpmath.sin(th), -g * m2 * a2 * mpmath.sin(ph)]
    r = mpmath.matrix([f[0] - h[0], f[1] - h[1]])
    acc = mpmath.lu_solve(M, r)
    inverse = M ** -1
    # |Mbar^-1| |fbar - hbar|: the size of the terms each acceleration sums (the scale of its
    # rounding when the inputs are exact to a few eps, whatever cancels among them)
    bound = [sum(abs(inverse[i, k]) * abs(r[k]) for k in range(2)) for i in range(2)]
    return np.array([float(acc[0]), float(acc[1])]), np.array([float(b) for b in bound])


def _states(seed=11, offset=0.0):
    """Large angles (many turns) whose difference is ``offset`` plus a small gap."""
    rng = np.random.default_rng(seed)
    for gap in GAPS:
        for _ in range(4):
            # far enough from 0 that theta - phi is exact (Sterbenz), as for any offset
            theta = (rng.uniform(8, 60) + 2 * abs(offset)) * rng.choice([-1, 1])
            phi = theta - offset + gap * rng.choice([-1, 1]) * rng.uniform(1, 2)
            yield np.array([theta, phi, rng.uniform(-3, 3), rng.uniform(-3, 3)])


def test_equations_hold_the_combined_angle(system1):
    _, system, _, _ = system1
    theta, phi = system.coordinates
    text = [*system.mass_matrix, *system.velocity_terms]
    assert any(e.has(sympy.sin(theta - phi)) or e.has(sympy.sin(phi - theta)) for e in text)
    assert any(e.has(sympy.cos(theta - phi)) for e in text)
    for e in text:  # no product of single-angle sines and cosines stands for the difference
        assert not (e.has(sympy.sin(theta)) and e.has(sympy.cos(phi)))


PI = float(mpmath.pi)
SMALL_SINE = (0.0, PI, -PI, 2 * PI)
"""Offsets where the sine of the difference is small: accurate component by component."""


@pytest.mark.parametrize("offset", [*SMALL_SINE, 0.1, 0.13, 1.0, PI / 2, -3 * PI / 2])
@pytest.mark.parametrize("gravity", ["0", "9.81"])
def test_generated_right_hand_side_is_accurate_near_equal_angles(system1, gravity, offset):
    """Near equal angles (offset 0), folded back or turned over (a multiple of pi: the sine of the
    difference small again), a cosine small (an odd multiple of pi/2), and on either side of
    the C's guard (1/8) between a polynomial in the difference and products of single-angle
    sines and cosines (numeric.py, ``_guarded``; the C's ``near_axis`` away from 0)."""
    model, system, module, native = system1
    values = resolve(system, dict(model.initial), {"g": gravity})
    params = {p.name: v for p, v in zip(system.parameters, values.parameters)}
    worst = 0.0
    for y in _states(offset=offset):
        exact, terms = _exact(y, params)
        candidates = [("python", np.asarray(module.rhs(0.0, y, values.parameters))[2:])]
        if native is not None:
            candidates.append(("C", native.rhs(0.0, y, values.parameters)[2:]))
        # component by component where the difference's sine is what cancels (against the
        # terms each acceleration sums: Mbar^-1 may subtract them); elsewhere normwise
        scale = terms if offset in SMALL_SINE else np.max(np.abs(exact))
        for name, got in candidates:
            err = np.max(np.abs(got - exact) / scale)
            worst = max(worst, err)
            assert err <= 32 * EPS, f"{name}: relative error {err:.3g} at {y.tolist()}"
    print(f"g = {gravity}: worst relative error {worst / EPS:.1f} eps")


def test_generated_right_hand_side_at_huge_angles(system1):
    """Beyond |theta - phi| = 2^20 the C keeps the single-angle products (near_axis's reduction
    by multiples of pi/2 is exact only below): still accurate normwise, and never NaN."""
    model, system, module, native = system1
    if native is None:
        pytest.skip("no C compiler")
    values = resolve(system, dict(model.initial), {})
    params = {p.name: v for p, v in zip(system.parameters, values.parameters)}
    rng = np.random.default_rng(5)
    for _ in range(20):
        theta = rng.uniform(1e6, 4e6) * rng.choice([-1, 1])
        phi = -theta * rng.uniform(0.2, 1.0)
        y = np.array([theta, phi, rng.uniform(-3, 3), rng.uniform(-3, 3)])
        exact, _ = _exact(y, params)
        got = native.rhs(0.0, y, values.parameters)[2:]
        assert np.max(np.abs(got - exact)) <= 32 * EPS * np.max(np.abs(exact)), (y.tolist(), got, exact)
