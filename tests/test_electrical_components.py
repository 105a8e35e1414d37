"""The circuit branches (components/electrical.py) and elements (effects/electrical.py) on
their own: the metric is the magnetic energy's, the elements' forces are the textbook
voltages, and bad values are located errors."""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
import sympy
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import MODELS
from kronsub.cli import main
from kronsub.components import REGISTRY
from kronsub.core.primitive import Primitive, part_from_component
from kronsub.core.symbols import symbol, velocity_symbol
from kronsub.effects.electrical import Capacitor, Gyrator, Resistor, VoltageSource

POSITIVE = st.floats(0.01, 10.0)


def coils(L1, L2, M):
    return REGISTRY["coupled_inductors"](x={"q1": symbol("a"), "q2": symbol("b")},
                                         p={"inductance1": L1, "inductance2": L2, "mutual": M})


@settings(max_examples=50, deadline=None)
@given(L1=POSITIVE, L2=POSITIVE, k=st.floats(-0.999, 0.999), i1=st.floats(-5, 5), i2=st.floats(-5, 5))
def test_coupled_coils_store_the_magnetic_energy(L1, L2, k, i1, i2):
    """``M = k sqrt(L1 L2)`` with ``|k| < 1``: the metric is positive definite and its energy is
    ``(L1 i1^2 + 2 M i1 i2 + L2 i2^2)/2``."""
    M = k * np.sqrt(L1 * L2)
    metric = np.array(coils(L1, L2, M).metric(), dtype=float)
    assert np.all(np.linalg.eigvalsh(metric) > 0)
    i = np.array([i1, i2])
    assert i @ metric @ i / 2 == pytest.approx((L1 * i1**2 + 2 * M * i1 * i2 + L2 * i2**2) / 2, abs=1e-12)


def test_coupling_beyond_one_is_refused_and_a_lone_branch_has_no_inductance():
    (_, value, kind), = [r for r in coils(1, 4, 3).requirements() if r[0] == "mutual"]
    assert kind == "coupling" and value == 1 * 4 - 3**2
    branch = REGISTRY["branch"](x={"q": symbol("q")})
    assert branch.metric() == sympy.zeros(1, 1) and branch.requirements() == ()
    inductor = REGISTRY["inductor"](x={"q": symbol("q")}, p={"inductance": symbol("L")})
    assert inductor.metric() == sympy.Matrix([[symbol("L")]])
    assert [(n, k) for n, _, k in inductor.requirements()] == [("inductance", "positive")]


def test_the_elements_are_the_textbook_voltages():
    """On two branches ``a``, ``b`` and the charge ``a - b`` of an element between them."""
    a, b = symbol("a"), symbol("b")
    ia, ib = velocity_symbol(a), velocity_symbol(b)
    C, R, e, k = sympy.symbols("C R e k", positive=True)
    primitive = Primitive(tuple(part_from_component(n, REGISTRY["branch"](x={"q": q}))
                                for n, q in (("a", a), ("b", b))))
    charge = a - b
    assert sympy.simplify(Capacitor("c", charge=charge, capacitance=C).potential(primitive) - charge**2 / (2 * C)) == 0
    assert sympy.expand(Resistor("r", charge=charge, resistance=R).generalized_force(primitive)[0]
                        + R * (ia - ib)) == 0
    assert VoltageSource("e", charge=charge, voltage=e).generalized_force(primitive) == [e, -e]
    f = Gyrator("g", first=a, second=b, constant=k).generalized_force(primitive)
    assert f == [-k * ib, k * ia]  # back-EMF on a, torque on b
    assert sympy.expand(f[0] * ia + f[1] * ib) == 0  # it does no work


def check(tmp_path, text):
    path = tmp_path / "circuit.yaml"
    path.write_text(text, encoding="utf-8")
    return CliRunner().invoke(main, ["check", str(path)])


@pytest.mark.parametrize("change, message, line", [
    (("L: {value: 0.5,", "L: {value: -0.5,"), "inductance of component 'coil' must be positive: L = -0.5", 8),
    (("R: {value: 1,", "R: {value: -1,"), "resistance of 'resistor' must be positive: R = -1", 9),
    (("C: {value: 0.02,", "C: {value: 0,"), "capacitance of 'capacitor' must be positive: C = 0", 10),
    (("charge: q_R,", "charge: q_R_dot,"), "the charge of 'resistor' depends on the velocity 'q_R_dot'", 25),
])
def test_bad_values_are_located_errors(tmp_path, change, message, line):
    text = (MODELS / "electrical" / "series_rlc.yaml").read_text(encoding="utf-8")
    assert change[0] in text
    result = check(tmp_path, text.replace(*change))
    assert result.exit_code == 1, result.output
    assert message in result.output
    assert f"circuit.yaml:{line}:" in result.output
    assert "Traceback" not in result.output


def test_a_gyrator_on_a_removed_branch_is_a_located_error(tmp_path):
    text = (MODELS / "electrical" / "dc_motor.yaml").read_text(encoding="utf-8")
    text = text.replace("coordinates: [q]}\n", "coordinates: [q]}\n  extra: {type: branch, coordinates: [q_x]}\n")
    text = text.replace("connection: {q: q, theta: theta}", "connection: {q: q, theta: theta, q_x: 0}")
    text = text.replace("between: [q, theta]", "between: [q_x, theta]")
    result = check(tmp_path, text)
    assert result.exit_code == 1, result.output
    line = text.splitlines().index(next(l for l in text.splitlines() if l.startswith("  machine:"))) + 1
    assert f"circuit.yaml:{line}:3: gyrator 'machine' couples nothing: its end q_x is 0" in result.output


def test_coils_coupled_beyond_their_inductances_are_refused_at_the_value(tmp_path):
    text = (MODELS / "electrical" / "transformer.yaml").read_text(encoding="utf-8")
    result = check(tmp_path, text.replace("M: {value: 0.09,", "M: {value: 0.2,"))
    assert result.exit_code == 1, result.output
    assert ("mutual of component 'coils' couples more than the coils allow (M^2 <= L1 L2): "
            "L1*L2 - M**2 = -0.03 (L1 = 0.2, L2 = 0.05, M = 0.2)") in result.output
    ideal = check(tmp_path, text.replace("M: {value: 0.09,", "M: {value: -0.1,"))  # |k| = 1: allowed, but then
    assert "the loop (0.5*q1 + q2) has resistance but no inductance" in ideal.output  # a loop has no inductance
    assert "couples more" not in ideal.output


RC = """name: rc
parameters: {C: 1, R: 2}
components:
  cap: {type: branch, coordinates: [q_C]}
  res: {type: branch, coordinates: [q_R]}
coordinates: [q]
connection: {q_C: q, q_R: q}
effects:
  cap: {type: capacitor, charge: q_C, capacitance: C}
  res: {type: resistor, charge: q_R, resistance: RESISTANCE}
"""


@pytest.mark.parametrize("resistance", ["R", "R*(2 + sin(t))"])
def test_a_resisted_loop_without_inductance_is_a_first_order_coordinate(tmp_path, resistance):
    """No inductance but a resistance of its own: accepted (tests/test_first_order.py integrates it)."""
    result = check(tmp_path, RC.replace("RESISTANCE", resistance))
    assert result.exit_code == 0, result.output


LEAVES = st.one_of(st.sampled_from(["m", "L", "y", "q", "y_dot", "q_dot", "t", "0", "1/0", "sqrt(-1)", "cos(y)",
                                    "m*y**2", "", "[", "x.y", "L*q_dot"]),
                   st.integers(-3, 3), st.none(), st.booleans(), st.floats(allow_nan=True, allow_infinity=True))
NESTED = st.recursive(LEAVES, lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.sampled_from(["a", "y"]),
                                                                                          inner, max_size=2),
                      max_leaves=8)


@settings(max_examples=60, deadline=None)
@given(coordinates=st.one_of(NESTED, st.lists(st.sampled_from(["y", "q", "m", "t", "y_dot", "1y"]), max_size=3)),
       metric=NESTED, potential=NESTED, dissipation=NESTED)
def test_any_textbook_component_is_read_or_refused_never_a_crash(coordinates, metric, potential, dissipation):
    """Whatever a component given by its equations holds, ``check`` accepts it or reports
    located problems: never an internal error."""
    import yaml

    model = {"name": "fuzz", "parameters": {"m": 1, "L": 2},
             "components": {"c": {"coordinates": coordinates, "metric": metric, "potential": potential,
                                  "dissipation": dissipation}},
             "coordinates": "auto" if not isinstance(coordinates, list) else coordinates}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.yaml"
        path.write_text(yaml.safe_dump(model), encoding="utf-8")
        result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code in (0, 1), result.output
    assert "internal error" not in result.output


def test_textbook_charges_must_be_its_coordinates(tmp_path):
    text = (MODELS / "electrical" / "magnetic_suspension.yaml").read_text(encoding="utf-8")
    result = check(tmp_path, text.replace("charges: [q]", "charges: [x]"))
    assert result.exit_code == 1, result.output
    assert "`charges:` of 'magnet' names 'x', which is not one of its coordinates (y, q)" in result.output
    assert "Traceback" not in result.output


def test_textbook_charges_listed_twice_are_a_located_error(tmp_path):
    """`charges: [q, q]` was taken silently; now placed at the second, alone (its current `i` still
    a name of the dissipation)."""
    text = (MODELS / "electrical" / "magnetic_suspension.yaml").read_text(encoding="utf-8")
    result = check(tmp_path, text.replace("charges: [q]", "charges: [q, q]"))
    assert result.exit_code == 1, result.output
    assert "`charges:` of 'magnet' names 'q' twice" in result.output and result.output.count("Error:") == 1
