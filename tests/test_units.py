"""Units read from the parameters' ``unit:`` texts (kronsub/model/units.py): dimensions of the
SI names against identities of physics, and a sum of terms of different dimensions reported as a
located warning, never an error."""
from __future__ import annotations

import warnings

import pytest
import sympy

from conftest import MODELS
from kronsub.model.loader import load_model
from kronsub.model.units import UnitsWarning, check_units, dimension


@pytest.mark.parametrize("left, right", [
    ("N m/A", "V s"),          # a motor's torque constant is its back-EMF constant
    ("ohm F", "s"),            # RC is a time
    ("H/ohm", "s"),            # L/R is a time
    ("J", "N m"),
    ("W", "V A"),
    ("T m", "N/A"),            # a loudspeaker's force factor Bl
    ("kg m^2", "kg m**2"),
    ("m/s^2", "m s^-2"),
    ("1/s", "Hz"),
    ("rad/s", "1/s"),
])
def test_dimensions_of_equal_units_agree(left, right):
    assert dimension(left) is not None and dimension(left) == dimension(right)


@pytest.mark.parametrize("text", ["", "mH", "furlong", "m/s/s", "kg^x"])
def test_units_not_read_have_no_dimension(text):
    assert dimension(text) is None


def symbols_with(units):
    return {sympy.Symbol(name, real=True): dimension(unit) for name, unit in units.items()}


def warned(text, units):
    table = symbols_with(units)
    names = {s.name: s for s in table} | {"y": sympy.Symbol("y", real=True), "t": sympy.Symbol("t", real=True)}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_units(sympy.sympify(text, locals=names), table, "model.yaml:3:4")
    return [str(w.message) for w in caught if issubclass(w.category, UnitsWarning)]


def test_a_voltage_added_to_a_force_is_reported_where_it_is_written():
    messages = warned("V - F", {"V": "V", "F": "N"})
    assert messages == ["model.yaml:3:4: the units do not match: V is a voltage and F is a force, added in one sum "
                        "(from the parameters' `unit:`)"]


@pytest.mark.parametrize("text, units", [
    ("V - k*w", {"V": "V", "k": "N m/A", "w": "rad/s"}),     # a back-EMF is a voltage
    ("E*sin(w*t)", {"E": "V", "w": "rad/s"}),
    ("L1 + L0*a/(a + y)", {"L1": "H", "L0": "H", "a": "m"}),  # a coordinate's term is not compared
    ("m*g*y + c", {"m": "kg", "g": "m/s^2", "c": "N"}),
    ("1 + sign(t - t1)", {"t1": "s"}),
])
def test_consistent_or_undecidable_sums_are_quiet(text, units):
    assert warned(text, units) == []


def test_the_bundled_circuits_and_examples_are_quiet():
    paths = sorted((MODELS / "electrical").glob("*.yaml")) + sorted((MODELS / "examples").glob("*.yaml"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for path in paths:
            load_model(path, cache=False)
    assert [str(w.message) for w in caught if issubclass(w.category, UnitsWarning)] == []
