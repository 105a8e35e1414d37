"""Hard case: high multiples of an angle in the generated right-hand side.

What could go wrong: a geared part turns ``k`` times as fast as its coordinate, so ``cos(k q)``
and ``sin(k q)`` enter the equations. Written as polynomials in ``cos q`` and ``sin q`` (the
power form of ``expand_trig``), their coefficients grow as ``(1 + sqrt 2)^k``: at ``k = 12`` the
accelerations lost half their digits, at ``k = 40`` the mass matrix came out not positive
definite and the run stopped at its start. Criterion: a pendulum hung from the rim of a rotor
geared ``k : 1`` to the coordinate ``theta``, whose Lagrangian is written out here by hand, gives
in the generated C and Python right-hand sides the accelerations of a 50-digit evaluation (mpmath)
to ``8 k eps`` of the terms each sums, for ``k`` from 2 to 80, at random states.
"""
from __future__ import annotations

import importlib.util
import shutil

import mpmath
import numpy as np
import pytest

import kronsub
from kronsub.emitters.code import emit_c, emit_python
from kronsub.simulation.native import NativeModel, compile_library
from kronsub.simulation.values import resolve

EPS = np.finfo(float).eps

MODEL = """\
name: Pendulum on a geared rotor
parameters:
  J: {{value: 0.02}}
  m: {{value: 0.7}}
  e: {{value: 0.3}}
  l: {{value: 1.1}}
  g: {{value: 9.81}}
components:
  rotor: {{type: flywheel, parameters: {{inertia: J}}, coordinates: [turn]}}
  bob: {{type: particle2d, parameters: {{mass: m}}, coordinates: [px, py]}}
coordinates: [theta, phi]
connection:
  turn: {k}*theta
  px: e*cos({k}*theta) + l*sin(phi)
  py: e*sin({k}*theta) - l*cos(phi)
effects:
  gravity: {{type: gravity, g: g, direction: [0, -1]}}
initial: {{theta: 0.3, phi: 0.2}}
"""


def _exact(y, p, k):
    """The accelerations in 50 digits from the hand Lagrangian:
    ``T = (J + m e^2 k^2) thetadot^2 / 2 + m l^2 phidot^2 / 2 + m e k l sin(phi - k theta) thetadot phidot``,
    ``V = m g (e sin(k theta) - l cos phi)``."""
    mpmath.mp.dps = 50
    th, ph, thd, phd = (mpmath.mpf(float(v)) for v in y)
    J, m, e, l, g = (mpmath.mpf(float(p[name])) for name in ("J", "m", "e", "l", "g"))
    d = ph - k * th
    c = m * e * k * l
    M = mpmath.matrix([[J * k**2 + m * e**2 * k**2, c * mpmath.sin(d)], [c * mpmath.sin(d), m * l**2]])
    h = [c * mpmath.cos(d) * phd**2, -c * k * mpmath.cos(d) * thd**2]
    f = [-m * g * e * k * mpmath.cos(k * th), -m * g * l * mpmath.sin(ph)]
    r = mpmath.matrix([f[0] - h[0], f[1] - h[1]])
    acc = mpmath.lu_solve(M, r)
    inverse = M**-1
    bound = [sum(abs(inverse[i, j]) * abs(r[j]) for j in range(2)) for i in range(2)]
    return np.array([float(a) for a in acc]), np.array([float(b) for b in bound])


@pytest.mark.parametrize("k", [2, 5, 12, 40, 80])
def test_geared_rotor_accelerations_are_accurate(tmp_path, k):
    path = tmp_path / f"geared{k}.yaml"
    path.write_text(MODEL.format(k=k))
    model = kronsub.load(path)
    system = model.derive()
    (generated,) = emit_python(system, "model")
    (tmp_path / "model.py").write_text(generated.text)
    spec = importlib.util.spec_from_file_location(f"gen_geared_{k}", tmp_path / "model.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    values = resolve(system, dict(model.initial), {})
    params = {p.name: v for p, v in zip(system.parameters, values.parameters)}
    candidates = [("python", lambda y: np.asarray(module.rhs(0.0, y, values.parameters))[2:])]
    if shutil.which("gcc") or shutil.which("cc"):
        native = NativeModel(compile_library([(g.name, g.text) for g in emit_c(system, "model")], "model"),
                             2, len(system.parameters))
        candidates.append(("C", lambda y: native.rhs(0.0, y, values.parameters)[2:]))
    rng = np.random.default_rng(k)
    for _ in range(12):
        y = np.array([rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-2, 2), rng.uniform(-2, 2)])
        exact, terms = _exact(y, params, k)
        for name, rhs in candidates:
            err = np.max(np.abs(rhs(y) - exact) / terms)
            assert err <= 8 * k * EPS, f"{name}, k = {k}: relative error {err:.3g} ({err / EPS:.0f} eps) at {y.tolist()}"
