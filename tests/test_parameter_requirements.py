"""What components need of their parameters' values (kronsub/model/requirements.py): a negative
mass or moment of inertia, a length that is not positive, an inertia tensor no body has, is
refused with the parameter's name, its value and where it was given (the model file, a scene,
``--set NAME``); zero mass and inertia stay allowed (a massless rod, docs/model-format.md)."""
from __future__ import annotations

import pytest
from click.testing import CliRunner

import kronsub
from conftest import MODELS
from kronsub.cli import main
from kronsub.components import REGISTRY
from kronsub.components.base import NONNEGATIVE, POSITIVE
from kronsub.errors import ModelError

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _write(tmp_path, text, name="model.yaml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _where(text: str, line_text: str, token: str) -> str:
    """``LINE:COL`` of ``token`` on the line that contains ``line_text``."""
    for number, line in enumerate(text.splitlines(), 1):
        if line_text in line:
            return f"{number}:{line.index(token) + 1}"
    raise AssertionError(line_text)


def test_a_negative_mass_given_with_set_is_refused_before_the_run():
    result = _run("simulate", SYSTEM1, "--set", "m1=-0.1", "--t", "0.1")
    assert result.exit_code == 1, result.output
    assert result.output.startswith("Error: --set m1: mass of component 'upper' must not be negative: m1 = -0.1\n"
                                    "  hint: give it a value of zero or more")
    assert result.stdout == ""  # no row
    result = _run("simulate", SYSTEM1, "--set", "I2=-1e-9", "--t", "0.1")
    assert result.exit_code == 1 and "--set I2: inertia of component 'lower' must not be negative" in result.output
    massless = _run("simulate", SYSTEM1, "--set", "m1=0", "--t", "0.1", "--dt", "0.05")
    assert massless.exit_code == 0, massless.output  # zero: a massless rod, as documented


def test_the_library_api_refuses_it_too():
    system = kronsub.load(SYSTEM1).derive()
    with pytest.raises(ModelError, match="mass of component 'upper' must not be negative: m1 = -2"):
        system.simulate(0.1, 0.05, set={"m1": -2})


MODEL = """\
name: negative values
parameters:
  m: {value: 0.3, unit: kg}
  L: {value: -1.5, unit: m}
components:
  rod: {type: pinned_rod, parameters: {mass: m, length: L}, coordinates: [theta]}
  disc: {type: disc, parameters: {mass: 2*m - 1, radius: 0.2}, coordinates: [x, y, a]}
  wheel: {type: flywheel, parameters: {inertia: -0.5}, coordinates: [w]}
coordinates: [theta, x, y, a, w]
"""


def test_every_value_is_reported_where_it_is_given(tmp_path):
    """A parameter's default at its declaration, a formula or a number at the component's value,
    all in one run."""
    path = _write(tmp_path, MODEL)
    result = _run("check", path)
    assert result.exit_code == 1, result.output
    at = {what: f"{path}:{_where(MODEL, line, token)}" for what, line, token in (
        ("L", "  L: {value", "L"), ("disc", "disc: {type", "2*m - 1"), ("wheel", "wheel:", "-0.5"))}
    assert f"Error: {at['L']}: length of component 'rod' must be positive: L = -1.5\n" in result.output
    assert (f"Error: {at['disc']}: mass of component 'disc' must not be negative: 2*m - 1 = -0.4 (m = 0.3)\n"
            in result.output)
    assert f"Error: {at['wheel']}: inertia of component 'wheel' must not be negative: -0.5\n" in result.output
    assert "3 problems found." in result.output
    assert _run("derive", path).exit_code == 1


def test_a_scene_value_is_checked_at_the_scene(tmp_path):
    text = SYSTEM1.read_text(encoding="utf-8").replace("scenes:\n", "scenes:\n  light:\n    parameters: {m2: -3}\n")
    path = _write(tmp_path, text)
    result = _run("check", path)
    assert result.exit_code == 1, result.output
    where = _where(text, "parameters: {m2: -3}", "-3")
    assert f"{path}:{where}: mass of component 'lower' must not be negative: m2 = -3" in result.output


def test_a_known_system_s_bodies_need_the_same(tmp_path):
    (tmp_path / "system1.yaml").write_text(SYSTEM1.read_text(encoding="utf-8"), encoding="utf-8")
    text = "name: outer\ncomponents:\n  s: {model: system1.yaml, parameters: {m1: -1}}\ncoordinates: [theta, phi]\n"
    result = _run("check", _write(tmp_path, text, "outer.yaml"))
    assert result.exit_code == 1 and "mass of body 's.upper' must not be negative: -1" in result.output, \
        result.output
    result = _run("simulate", _write(tmp_path, text.replace("-1", "1"), "outer.yaml"), "--set", "I1=-2", "--t", "0.1")
    assert result.exit_code == 1 and "--set I1: inertia of body 's.upper' must not be negative" in result.output


TOP = """\
name: top
parameters: {m: 1, A: 1, B: 1, C: C_VALUE, P: P_VALUE}
components:
  top: {type: rigid_body3d, parameters: {mass: m, Ixx: A, Iyy: B, Izz: C, Ixy: P}}
coordinates: [top_x, top_y, top_z, top_psi, top_theta, top_phi]
"""


@pytest.mark.parametrize("c, p, moments", [
    (3, 0, "1, 1, 3"),  # 3 > 1 + 1: the triangle inequality
    (1, 2, "-1, 1, 3"),  # a product of inertia that makes the tensor indefinite
    (-1, 0, "-1, 1, 1"),  # a negative moment
], ids=["triangle", "indefinite", "negative moment"])
def test_an_inertia_tensor_no_body_has_is_refused(tmp_path, c, p, moments):
    text = TOP.replace("C_VALUE", str(c)).replace("P_VALUE", str(p))
    path = _write(tmp_path, text)
    result = _run("check", path)
    assert result.exit_code == 1, result.output
    assert (f"{path}:{_where(text, 'Ixx: A', 'A, Iyy')}: the inertia tensor of component 'top' is not a body's: "
            f"its principal moments {moments} must not be negative and each at most the sum of the other two"
            ) in result.output
    assert result.output.count("Error:") == 1  # the moments have no sign of their own: the tensor says it


def test_a_body_s_tensor_at_the_edge_is_allowed(tmp_path):
    """A thin rod (moments 0, I, I) and a flat plate (I1 + I2 = I3) are bodies."""
    for c, a in ((1, 0), (2, 1)):
        text = TOP.replace("C_VALUE", str(c)).replace("P_VALUE", "0").replace("A: 1,", f"A: {a},")
        assert _run("check", _write(tmp_path, text)).exit_code == 0
    top = _write(tmp_path, TOP.replace("C_VALUE", "1.5").replace("P_VALUE", "0"))
    result = _run("simulate", top, "--set", "C=2.5", "--t", "0.1")
    assert result.exit_code == 1 and "--set C: the inertia tensor of component 'top'" in result.output


def _library_model(type_name: str, values: dict) -> str:
    cls = REGISTRY[type_name]
    given = {ps.name: 1 for ps in cls.parameters if ps.default is None}
    given.update(values)
    parameters = ", ".join(f"{k}: {v}" for k, v in given.items())
    coordinates = ", ".join(f"c_{q}" for q in cls.coordinates)
    return f"name: one\ncomponents:\n  c: {{type: {type_name}, parameters: {{{parameters}}}}}\ncoordinates: [{coordinates}]\n"


SIGNED = [(t, ps.name, ps.sign) for t, cls in sorted(REGISTRY.items()) for ps in cls.parameters if ps.sign]


def test_the_components_declare_what_they_need():
    """Masses and moments of inertia not negative, lengths, radii and inductances positive; no
    other parameter of the library (pivot places, products of inertia, a mutual inductance) has
    a sign."""
    inductances = ("inductance", "inductance1", "inductance2")
    for type_name, name, sign in SIGNED:
        expected = POSITIVE if name in ("length", "radius", *inductances) else NONNEGATIVE
        assert sign == expected and name in ("mass", "inertia", "length", "radius", *inductances), (type_name, name)
    assert {(t, n) for t, n, _ in SIGNED} >= {("particle1d", "mass"), ("rod", "length"), ("disc", "radius"),
                                               ("flywheel", "inertia"), ("rigid_body3d", "mass")}


@pytest.mark.parametrize("type_name, name, sign", SIGNED, ids=[f"{t}.{n}" for t, n, _ in SIGNED])
def test_every_declared_sign_is_checked(tmp_path, type_name, name, sign):
    """For every library component and parameter that declares a sign: a negative value is
    refused at it, zero only where it must be positive."""
    bad = _run("check", _write(tmp_path, _library_model(type_name, {name: -0.25})))
    assert bad.exit_code == 1, bad.output
    assert f"{name} of component 'c' must" in bad.output, bad.output
    zero = _run("check", _write(tmp_path, _library_model(type_name, {name: 0})))
    assert (zero.exit_code == 1) == (sign == POSITIVE), zero.output


@pytest.mark.parametrize("command", [["simulate", "--t", "0.1"], ["accuracy", "--quick", "--t", "0.1"],
                                     ["animate", "-o", "a.gif", "--t", "0.1"], ["linearize"]])
def test_every_command_that_takes_values_checks_them(tmp_path, command, monkeypatch):
    monkeypatch.chdir(tmp_path)
    option = "--at" if command[0] == "linearize" else "--set"
    result = _run(command[0], SYSTEM1, *command[1:], option, "a2=-0.3")
    assert result.exit_code == 1, result.output
    assert f"Error: {option} a2: length of component 'lower' must be positive: 2*a2 = -0.6 (a2 = -0.3)" \
        in result.output


def test_a_tensor_in_small_units_is_judged_by_its_own_scale(tmp_path):
    text = TOP.replace("A: 1, B: 1", "A: 1e-20, B: 1e-20").replace("C_VALUE", "3e-20").replace("P_VALUE", "0")
    result = _run("check", _write(tmp_path, text))
    assert result.exit_code == 1 and "principal moments 1e-20, 1e-20, 3e-20" in result.output, result.output
    assert _run("check", _write(tmp_path, text.replace("3e-20", "2e-20"))).exit_code == 0
