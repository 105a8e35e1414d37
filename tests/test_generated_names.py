"""Names kronsub makes never silently meet the model's names (issue 6, section 3), and names
are whole identifiers (section 1).

A parameter ``q_dot`` beside a coordinate ``q`` used to replace the velocity: the damped
pendulum's energy stopped decaying. The independent route is the energy balance of a damped
pendulum, ``dE/dt = -c qdot^2 < 0``, on the model with the parameter renamed.
"""
from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from kronsub.cli import main
from kronsub.errors import ModelError

PENDULUM = """\
name: damped pendulum
parameters: {{m: 1, L: 1, g: 9.81, {damping}: 0.5}}
components:
  bob: {{type: particle2d, parameters: {{mass: m}}, coordinates: [x, y]}}
coordinates: [q]
connection: {{x: L*sin(q), y: -L*cos(q)}}
effects:
  gravity: {{type: gravity, g: g}}
  drag: {{type: generalized_force, coordinate: x, value: -{damping}*x_dot}}
"""


def _load(tmp_path, text, name="model.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return kronsub.load(path, cache=False)


def _problems(tmp_path, text) -> list[str]:
    with pytest.raises(ModelError) as info:
        _load(tmp_path, text)
    return [p.format() for p in info.value.problems]


def test_damping_named_like_a_velocity_is_refused_naming_both(tmp_path):
    (problem,) = _problems(tmp_path, PENDULUM.format(damping="q_dot"))
    assert "parameter 'q_dot'" in problem and "velocity of coordinate 'q'" in problem
    assert problem.startswith(f"{tmp_path / 'model.yaml'}:2:")  # where the parameter is declared
    assert ":5:" in problem  # where the coordinate is declared
    assert "hint: rename parameter 'q_dot'" in problem


def test_the_same_pendulum_with_another_name_loses_energy(tmp_path):
    system = _load(tmp_path, PENDULUM.format(damping="c")).derive()
    ns = {}
    from kronsub.emitters.code import emit_python

    exec(compile(emit_python(system, "m")[0].text, "m.py", "exec"), ns)  # our own generated code
    param = np.array([float(p.value) for p in system.parameters])
    y = np.array([0.7, 1.3])
    ydot = ns["rhs"](0.0, y, param)
    eps = 1e-6
    energy = lambda s: ns["kinetic_energy"](s, param) + ns["potential_energy"](0.0, s, param)  # noqa: E731
    dE = (energy(y + eps * ydot) - energy(y - eps * ydot)) / (2 * eps)
    qdot = y[1]
    c, L = 0.5, 1.0  # the drag acts on x_dot = L cos(q) qdot
    assert dE == pytest.approx(-c * (L * np.cos(y[0]) * qdot) ** 2, rel=1e-6)


@pytest.mark.parametrize("damping, meaning, owner", [("x_dot", "velocity", "coordinate 'x' of component 'bob'"),
                                                     ("q_ddot", "acceleration", "coordinate 'q'"),
                                                     ("y_ddot", "acceleration", "coordinate 'y' of component 'bob'")])
def test_every_made_name_is_checked(tmp_path, damping, meaning, owner):
    text = PENDULUM.format(damping=damping).replace(f"-{damping}*x_dot", "-x_dot")
    problems = _problems(tmp_path, text)
    assert any(f"parameter '{damping}'" in p and f"{meaning} of {owner}" in p for p in problems), problems


def test_coordinates_a_and_a_dot_are_refused(tmp_path):
    text = """\
name: two carts
components:
  one: {type: particle1d, parameters: {mass: 1}, coordinates: [a]}
  two: {type: particle1d, parameters: {mass: 2}, coordinates: [a_dot]}
coordinates: [a, a_dot]
"""
    problems = _problems(tmp_path, text)
    assert any("coordinate 'a_dot'" in p and "velocity of coordinate 'a'" in p for p in problems), problems


def test_a_parameter_from_a_known_system_is_checked_too(tmp_path):
    (tmp_path / "sub.yaml").write_text("""\
name: sub
parameters: {m: 1, theta_dot: 2}
components:
  cart: {type: particle1d, parameters: {mass: m*theta_dot}, coordinates: [u]}
coordinates: [u]
""")
    text = """\
name: parent
components:
  sub: {model: sub.yaml}
  wheel: {type: flywheel, parameters: {inertia: 1}, coordinates: [theta]}
coordinates: [u, theta]
"""
    problems = _problems(tmp_path, text)
    assert any("parameter 'theta_dot'" in p and "velocity of coordinate 'theta'" in p and ":3:" in p
               for p in problems), problems


def test_the_cli_reports_the_clash_without_a_traceback(tmp_path):
    path = tmp_path / "model.yaml"
    path.write_text(PENDULUM.format(damping="q_dot"))
    for command in (["derive", str(path)], ["codegen", str(path), "-o", str(tmp_path)],
                    ["simulate", str(path), "--t", "0.1"]):
        result = CliRunner().invoke(main, command)
        assert result.exit_code == 1, result.output
        assert "'q_dot'" in result.output and "Traceback" not in result.output


@pytest.mark.parametrize("where", ["parameters: {m: 1, \"g\\n\": 9.81}", "coordinates: [\"q\\n\"]",
                                   "parameters: {m: 1, \"g \": 9.81}", "coordinates: [\"q\\u2028\"]"])
def test_a_name_must_be_a_whole_identifier(tmp_path, where):
    text = PENDULUM.format(damping="c")
    key = where.split(":")[0]
    text = "\n".join(where if line.startswith(key + ":") else line for line in text.splitlines()) + "\n"
    problems = _problems(tmp_path, text)
    assert any("is not a valid name" in p for p in problems), problems


def test_codegen_refuses_a_system_built_past_the_loader():
    """A known system made in Python with a parameter ``q_dot`` beside ``q``: no code, an error."""
    import sympy

    from kronsub.core.known_system import KnownSystem, ParameterInfo
    from kronsub.core.symbols import symbol
    from kronsub.emitters.code import emit_c
    from kronsub.errors import KronsubError

    q, c = symbol("q"), symbol("q_dot")
    system = KnownSystem("damped", (q,), sympy.Matrix([[1]]), sympy.Matrix([0]), {"drag": sympy.Matrix([-c])},
                         parameters=(ParameterInfo("q_dot", c),))
    with pytest.raises(KronsubError, match="q_dot"):
        emit_c(system, "m")
