"""The damper's force ``f_a = -c ldot dl/dx^a`` (effects/elements.py): the factor shared by
every component is factored once, and the result is the very expression ``sympy.factor``
makes of each component whole (the printed equations do not change), on a line (where the
distance cancels), in the plane and in space."""
from __future__ import annotations

import pytest
import sympy

import kronsub
from conftest import MODELS, ROOT
from kronsub.effects.elements import Damper, separation

CASES = [
    MODELS / "examples" / "cart_pole.yaml",
    ROOT / "tests" / "models" / "polar_spring.yaml",
    ROOT / "tests" / "models" / "sweep" / "spherical_pendulum.yaml",
    ROOT / "tests" / "models" / "sweep" / "pendulum_on_wheel_rim.yaml",
    ROOT / "tests" / "models" / "sweep3" / "half_car.yaml",
]


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_damper_force_is_factor_of_each_component(path):
    model = kronsub.load(path, cache=False)
    dampers = [e for e in model.effects if isinstance(e, Damper)]
    assert dampers
    primitive = model.primitive
    for damper in dampers:
        d = separation(primitive, damper.ends)
        square = sympy.Add(*[c**2 for c in d])
        rate = primitive.rate(square)
        whole = [sympy.factor(-damper.coefficient * rate * g / (4 * square)) if g != 0 else sympy.Integer(0)
                 for g in primitive.gradient(square)]
        got = damper.generalized_force(primitive)
        assert [sympy.srepr(e) for e in got] == [sympy.srepr(e) for e in whole]
        assert any(e != 0 for e in got)
