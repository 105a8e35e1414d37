"""Systems and starting values the simulation tests share (tests/test_reference.py,
tests/test_taylor_c.py, tests/test_accuracy.py)."""
from __future__ import annotations

import json
from pathlib import Path

import mpmath
import sympy

import kronsub
from conftest import MODELS, ROOT
from kronsub.core.known_system import KnownSystem, ParameterInfo
from kronsub.core.symbols import TIME, symbol
from kronsub.simulation.values import resolve

DATA = Path(__file__).resolve().parent.parent / "data"
TEST_MODELS = ROOT / "tests" / "models"


def loaded(path, settings=None):
    """A model's derived system and its starting values (initial values, then ``settings``)."""
    model = kronsub.load(path)
    system = model.derive()
    return system, resolve(system, dict(model.initial), settings or {})


def functions_system():
    """A one-coordinate system whose equation uses every function the tape has a rule for."""
    q, c = symbol("q"), symbol("c")
    qd = kronsub.core.symbols.velocity_symbol(q)
    force = (-sympy.sin(q) + sympy.exp(-q ** 2) * sympy.cos(TIME) - c * sympy.atan(qd) + sympy.log(2 + q ** 2) / 5
             + sympy.asin(q / 4) * sympy.tan(q / 3) + sympy.tanh(qd) * sympy.sinh(q / 2) - sympy.cosh(q / 5)
             + sympy.sqrt(3 + q) / (1 + qd ** 2) + sympy.acos(qd / 5) / 7 + sympy.Abs(q - 5) / 10
             + sympy.sign(q - 4) * qd ** 3 / 20)
    mass = sympy.Matrix([[1 + sympy.cos(q) ** 2 / 2]])
    return KnownSystem("functions", (q,), mass, sympy.zeros(1, 1), {"f": sympy.Matrix([force])},
                       parameters=(ParameterInfo("c", c, sympy.Rational(3, 10)),))


def benchmark_problem():
    """System I as the benchmark's double pendulum of two rods, from exact inputs, and the
    40-digit state at t = 10 of ``tests/data/double_pendulum_rods.json``."""
    data = json.loads((DATA / "double_pendulum_rods.json").read_text())
    with mpmath.workdps(50):
        want = [mpmath.mpf(data["state_at_t_end"][k]) for k in ("q1", "q2", "u1", "u2")]
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive()
    half, twelfth = sympy.Rational(1, 2), sympy.Rational(1, 12)
    exact = {"m1": 1, "m2": 1, "a1": half, "a2": half, "I1": twelfth, "I2": twelfth,
             "g": sympy.Rational(981, 100), "F": 0}
    return system, [exact[p.name] for p in system.parameters], [2 * sympy.pi / 3, -sympy.pi / 18, 0, 0], want


def closed_loop(path, settings=None):
    """A closed-loop model's system, initial values projected onto its constraints, and y_d there."""
    from kronsub.simulation.constrained import project_initial

    model = kronsub.load(path)
    system = model.derive()
    values = resolve(system, dict(model.initial), settings or {})
    values, _, closure = project_initial(system, dict(model.initial), {}, values, 1e-14)
    return system, values, [float(v) for v in closure.guess]
