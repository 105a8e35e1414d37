"""Models kronsub must refuse with a clear message (parameters in ``t``, a parameter given two
values, conservative effects in the velocities, multipliers sharing a name, a pivoted rod's angle
that is no generalized coordinate, a Python keyword where an expression uses it) and names other
tools reserve, which it must accept.
"""
from __future__ import annotations

import json

import pytest
import sympy as sp
from click.testing import CliRunner

from conftest import MODELS

import kronsub
from helpers.compare import accelerations_agree, compare_energies, compare_explicit, TOL
from kronsub.cli import main
from kronsub.errors import ModelError
from reference import sweep, sweep3, sweep4, sweep5, sweep6
from reference.lagrange import damper_rows, dots, gradient_force, kinetic, S, virtual_power


@pytest.mark.parametrize("name, key", [("shaken_pendulum.yaml", "pivot_x"), ("growing_mass.yaml", "mass")])
def test_component_parameters_in_t_are_refused(name, key):
    """A component's equations are those of constant parameters: a pivot or a mass given in t
    would lose the inertial terms of the motion it prescribes (a shaken pivot's
    m L/2 (xp'' cos q + yp'' sin q), a growing mass's mdot xdot), so it is refused, where written."""
    path = sweep.SWEEP / name
    with pytest.raises(ModelError) as info:
        kronsub.load(path, cache=False)
    text = str(info.value)
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if f"{key}: " in ln)
    assert f"{path.name}:{line}:" in text and f"parameter '{key}'" in text and "depends on t" in text
    assert "hint:" in text


def test_animate_a_model_without_points_says_so(tmp_path):
    """gear_train.yaml (flywheels only) stopped `animate` with an internal error (exit 4,
    numpy's 'need at least one array to concatenate'); its flywheels are drawn as dials now,
    and a model with nothing to draw (a circuit) is a plain error."""
    pytest.importorskip("matplotlib")
    result = CliRunner().invoke(main, ["animate", str(sweep3.HERE / "gear_train.yaml"), "--t", "0.1", "-o",
                                       str(tmp_path / "g.gif")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "g.gif").exists()
    result = CliRunner().invoke(main, ["animate", str(MODELS / "electrical" / "series_rlc.yaml"), "--t",
                                       "0.1", "-o", str(tmp_path / "c.gif")])
    assert result.exit_code == 1, result.output
    assert "nothing to draw" in result.output and "internal error" not in result.output
    assert not (tmp_path / "c.gif").exists()


def test_known_systems_bringing_one_parameter_with_two_values():
    """sprung_cart.yaml (k = 30, l0 = 0.4) and atwood_pulley.yaml (k = 40, l0 = 0.3) in one model:
    the shared k, l0 took the cart's values, silently (the pulley's a_ddot coefficient of a
    went from k r2^2 = 0.9 to 0.675). Now an error at the second `model:`; with overrides each
    keeps its own spring."""
    path = sweep3.HERE / "cart_and_pulley.yaml"
    with pytest.raises(ModelError) as info:
        kronsub.load(path, cache=False)
    text = str(info.value)
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if "pulley: {model:" in ln)
    assert f"cart_and_pulley.yaml:{line}:" in text
    assert "parameter 'k' is 40 in 'pulley' but 30 in 'cart'" in text and "'l0'" in text and "hint:" in text
    system = sweep3.derived("cart_and_pulley_fixed.yaml")
    values = {p.name: float(p.value) for p in system.parameters}
    row = system.forces[1].subs({system.symbol(k): v for k, v in values.items()})
    row = row.subs({s: 0 for s in system.velocities} | {system.symbol("x"): 0, system.symbol("t"): 0})
    a = system.symbol("a")
    stiffness = float(row.subs(a, 0) - row.subs(a, sp.Rational(1, 100))) * 100  # the pulley's spring: k r2^2
    assert stiffness == pytest.approx(values["kp"] * values["r2"] ** 2)
    assert values["k"] == 30 and values["l0"] == pytest.approx(0.4)


def test_gravity_that_acts_on_no_component(tmp_path):
    """Without `components:` a gravity acts on the library components with mass only (known
    systems bring their own): over a known system alone it acted on nothing, silently, while
    docs/model-format.md said it acted on the known system's bodies. Now an error that says
    to name them."""
    text = (sweep3.HERE / "cart_pendulum_on_moon.yaml").read_text().replace(", components: [rig]", "")
    path = tmp_path / "moon.yaml"
    path.write_text(text.replace("model: cart_pendulum.yaml", f"model: {sweep3.HERE / 'cart_pendulum.yaml'}"))
    with pytest.raises(ModelError) as info:
        kronsub.load(path, cache=False)
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if "moon: {type: gravity" in ln)
    text = str(info.value)
    assert f"moon.yaml:{line}:" in text and "gravity 'moon' acts on no component" in text
    assert "components: [rig]" in text


def test_parameter_value_in_other_parameters_is_a_clear_error(tmp_path):
    """A parameter's value may not use other parameters (docs/model-format.md): said at its
    place with a hint, never a traceback."""
    text = (sweep4.HERE / "torsion_pendulum.yaml").read_text().replace("c0: {value: 0,", "c0: {value: cr/2,")
    path = tmp_path / "p.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if "c0: {value: cr/2" in ln)
    assert f"p.yaml:{line}:" in result.output and "hint:" in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize("model, old, new, what", [
    ("kepler_polar.yaml", "value: -mu*m/r + m*eps/r**2", "value: -mu*m/r + m*eps*r_dot**2", "the potential of 'well'"),
    ("torsion_pendulum.yaml", "angle: th1 + th2/2 - sin(th1)/3", "angle: th1 + th2_dot/2", "the angle of 'twist'"),
    ("torsion_pendulum.yaml", "stiffness: k0}", "stiffness: k0*(1 + th1_dot**2)}", "the stiffness of 'tie'"),
    ("torsion_pendulum.yaml", "angle: th2 - th1, coefficient: cr", "angle: th2 - th1_dot, coefficient: cr",
     "the angle of 'knee'"),
    ("drag_particle3d.yaml", "stiffness: k1, length: L1", "stiffness: k1, length: L1 + x_dot",
     "the rest length of 's1'"),
])
def test_conservative_effects_in_the_velocities_are_refused(tmp_path, model, old, new, what):
    """A potential in a velocity (``m eps r_dot^2``) derived without it, silently: the radial
    equation was ``-m mu/r^2`` alone (``-dV/dr``, no ``d/dt dV/dr_dot = 2 m eps r_ddot``).
    Likewise a spring's or a torsional spring's terms and a torsional damper's angle. Now an
    error at the expression; a velocity stays allowed in a damper's coefficient."""
    text = (sweep4.HERE / model).read_text()
    assert old in text
    path = tmp_path / model
    path.write_text(text.replace(old, new))
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if new in ln)
    assert f"{model}:{line}:" in result.output and f"{what} depends on the velocity" in result.output
    assert "hint:" in result.output and "Traceback" not in result.output


def test_a_damper_coefficient_in_the_velocities_stays_allowed(tmp_path):
    text = (sweep4.HERE / "torsion_pendulum.yaml").read_text()
    path = tmp_path / "p.yaml"
    path.write_text(text.replace("angle: th2 - th1, coefficient: cr", "angle: th2 - th1, coefficient: cr*abs(th1_dot)"))
    system = kronsub.load(path, cache=False).derive()
    th1, th2 = q = list(S("th1 th2"))
    bodies, V, _ = sweep4.torsion_parts(th1, th2, S("rho"))
    cr, c0 = S("cr c0")
    rows = [x + y for x, y in zip(damper_rows(cr * sp.Abs(dots(q)[0]), th2 - th1, q),
                                  damper_rows(c0, th1 - 2 * th2, q))]
    M, h = virtual_power(bodies, q)
    assert compare_explicit(system, (M, h, gradient_force(V, q, rows)), 67) < TOL


def test_hint_lists_each_valid_name_once(tmp_path):
    """A generalized force on a velocity: the hint listed 'a, a, r, r' (a coordinate that is
    both primitive and generalized came twice)."""
    path = tmp_path / "k.yaml"
    text = (sweep4.HERE / "kepler_polar.yaml").read_text()
    path.write_text(text.replace("coordinate: r, value", "coordinate: a_dot, value"))
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1 and "'a_dot' is not a primitive or generalized coordinate" in result.output
    hint = next(ln for ln in result.output.splitlines() if "hint:" in ln)
    names = hint.split("valid names:")[1].split(",")
    assert sorted(n.strip() for n in names) == ["a", "r", "sat.a", "sat.angle", "sat.r"], hint


def test_names_other_tools_reserve(tmp_path):
    """Coordinates `nan`, `E` (numpy's and SymPy's constants), parameters `I`, `oo`, `zoo`,
    `Abs` (SymPy's), `double`, `main` (C's) and primitive coordinates `q`, `param` (the
    generated code's arguments): derived, the numpy module and the compiled C agree with the hand equations."""
    q, M, h, f, V = sweep5.odd_reference()
    system = sweep5.derived("odd_names.yaml")
    fixed = lambda rng: {"E": rng.uniform(0.2, 2)}  # noqa: E731
    assert compare_explicit(system, (M, h, f), 505, fixed=fixed) < TOL
    assert compare_energies(system, kinetic(M, q), V, 505, fixed=fixed) < TOL
    module = sweep5.numpy_module(tmp_path, "odd_names.yaml")
    assert accelerations_agree(system, M, h, f, 505, spread=0.9, numpy_module=module) < TOL


@pytest.mark.parametrize("kind, name", [("parameter", "return"), ("parameter", "None"), ("coordinate", "lambda")])
def test_a_python_keyword_as_a_name_is_an_error_where_an_expression_uses_it(tmp_path, kind, name):
    """Expressions are read with Python's syntax, where a keyword is no name: one declared
    may stay unused (tests/models/internal_names.yaml), and an expression using it is an
    error at the keyword with a hint to rename it (a parameter `None` was told "use 1 or 0")."""
    text = (sweep5.HERE / "odd_names.yaml").read_text()
    if kind == "parameter":
        text = text.replace("  zoo: {value", f"  {name}: {{value: 1}}\n  zoo: {{value", 1)
        unused = text
        text = text.replace("vector: [oo*cos(zoo*t), 0]", f"vector: [oo*cos(zoo*t), {name}]")
    else:
        text = unused = text.replace("nan", name)
    path = tmp_path / "k.yaml"
    if kind == "parameter":
        path.write_text(unused)
        assert CliRunner().invoke(main, ["derive", str(path), "--format", "json"]).exit_code == 0
    path.write_text(text)
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if f"{name})" in ln or f", {name}]" in ln)
    assert f"k.yaml:{line}:" in result.output
    assert f"'{name}' is a reserved word and cannot be used as a name" in result.output
    assert f"hint: rename it, e.g. '{name}_'" in result.output and "Traceback" not in result.output


@pytest.mark.parametrize("where", ["here", "known"])
def test_constraints_whose_multipliers_share_a_name_are_refused(tmp_path, where):
    """A joint `B` (equations `B.x`, `B.y`) beside a constraint `B_x`: both multipliers were
    `mu_B_x`, so `derive --reactions --format json` kept two of the three (the pin's x force
    lost) and the markdown listed `mu_B_x` twice with different expressions. Likewise a
    constraint `left_cx` beside the known system `left`'s `cx` (`mu_left_cx`). Now refused at
    the constraint, naming both."""
    if where == "here":
        text, name, both = sweep5.CLASHING, "B_x", ("'B.x'", "'B_x'", "'mu_B_x'")
    else:
        (tmp_path / "bead_on_helix.yaml").write_text((sweep5.HERE / "bead_on_helix.yaml").read_text())
        text = (sweep5.HERE / "helix_pair.yaml").read_text()
        fly = "  fly: {type: flywheel, parameters: {inertia: 1}, coordinates: [w]}\n"
        text = text.replace("  right:\n", fly + "  right:\n")
        text = text.replace("effects:\n", "constraints:\n  left_cx: w - s1\neffects:\n")
        name, both = "left_cx", ("'left.cx'", "'left_cx'", "'mu_left_cx'")
    path = tmp_path / "clash.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["derive", str(path), "--reactions", "--format", "json"])
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.startswith(f"  {name}:"))
    assert f"clash.yaml:{line}:3:" in result.output and all(b in result.output for b in both), result.output
    assert "hint: rename one of them" in result.output and "Traceback" not in result.output
    fixed = text.replace(f"  {name}:", f"  {name}_:")
    path.write_text(fixed)
    result = CliRunner().invoke(main, ["derive", str(path), "--reactions", "--format", "json"])
    assert result.exit_code == 0, result.output
    reactions = json.loads(result.stdout)["reactions"]
    names = list(reactions["expressions"]) if "expressions" in reactions else reactions["linear_system"]["unknowns"]
    assert len(names) == len(set(names)) and f"mu_{name}_" in names, names


@pytest.mark.parametrize("coordinates, connected, line, message", [
    ("[q1]", "", 5, "the angle 'b2' of 'r2' (hung from `pivot: r1.tip`) is not a generalized coordinate"),
    ("[q1, q2]", "  b2: q1 + q2", 9, "'b2' is the angle of 'r2', which hangs from `pivot: r1.tip`"),
])
def test_a_pivoted_rods_angle_must_be_a_generalized_coordinate(tmp_path, coordinates, connected, line, message):
    """Left out of `coordinates:`, a pivoted rod's angle was a frozen symbol: the model derived
    with ``b2`` a constant in ``V`` and the rod's swing missing from ``Mbar``. Connected (a
    relative angle), it was "not a coordinate of the primitive system" with a hint naming the
    other rod's angle. Both are now one error at its place, with the way to relative angles."""
    path = tmp_path / "relative.yaml"
    path.write_text(sweep6.RELATIVE_PIVOT.replace("COORDINATES", coordinates).replace("CONNECTED", connected))
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"relative.yaml:{line}:" in result.output and message in result.output
    assert "`rod` with `axis: down`" in result.output and "problems found" not in result.output
