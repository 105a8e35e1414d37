"""``definitions:``: named helper expressions substituted where they are used, checked
against hand Lagrangians and against the same model written out."""
from __future__ import annotations

import re

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from conftest import MODELS
from kronsub.cli import main

SLIDER = """\
name: slider-crank, massless rod
parameters: {r: 0.1, l: 0.3, m: 1, mp: 0.5, k: 10, s0: 0.35}
definitions:
  beta: asin(r*sin(theta)/l)        # the rod's angle
  xs: r*cos(theta) + l*cos(beta)    # the piston's place, in beta
components:
  crank: {type: pinned_rod, parameters: {mass: m, length: r}, coordinates: {angle: theta}}
  piston: {type: particle1d, parameters: {mass: mp}, coordinates: [x]}
coordinates: [theta]
connection:
  x: xs
effects:
  spring: {type: spring, between: [piston.centre, [0]], stiffness: k, length: s0}
initial: {theta: 0.2}
"""

PENDULUM = """\
name: pendulum in a generalized coordinate q1 (not a primitive one)
parameters: {m: 1, L: 1}
definitions:
  swing: 2*q1
components:
  bob: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}
coordinates: [q1]
connection:
  x: L*sin(q1)
  y: -L*cos(q1)
"""


def _load(tmp_path, text, name="m.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return kronsub.load(path)


def _check(tmp_path, text):
    path = tmp_path / "m.yaml"
    path.write_text(text)
    return CliRunner().invoke(main, ["check", str(path)])


def test_slider_crank_with_definitions_against_a_hand_lagrangian(tmp_path):
    system = _load(tmp_path, SLIDER).derive(cache=False)
    th, thd = sympy.symbols("theta theta_dot", real=True)
    r, l, m, mp, k, s0 = sympy.symbols("r l m mp k s0", real=True)
    x = r * sympy.cos(th) + l * sympy.sqrt(1 - (r * sympy.sin(th) / l) ** 2)  # cos(asin(u)) = sqrt(1 - u^2)
    xd = sympy.diff(x, th)
    # L = T - V, T = (m r^2/3) thd^2/2 + mp (x' thd)^2/2, V = k (x - s0)^2/2 (x > 0 here)
    M = m * r**2 / 3 + mp * xd**2
    rest = mp * xd * sympy.diff(xd, th) * thd**2 + k * (x - s0) * xd  # M thdd + rest = 0
    names = {p.name: system.symbol(p.name) for p in system.parameters}
    to_model = {th: system.symbol("theta"), thd: system.symbol("theta_dot"),
                **{s: names[s.name] for s in (r, l, m, mp, k, s0)}}
    rng = np.random.default_rng(3)
    for _ in range(5):
        point = {system.symbol("theta"): rng.uniform(-3, 3), system.symbol("theta_dot"): rng.uniform(-2, 2),
                 **{names[n]: v for n, v in zip(("r", "l", "m", "mp", "k", "s0"), (0.1, 0.3, 1, 0.5, 10, 0.35))}}
        Mk = float(system.mass_matrix[0, 0].subs(point))
        lhs = float((system.velocity_terms[0] - system.forces[0]).subs(point))
        assert Mk == pytest.approx(float(M.xreplace(to_model).subs(point)), rel=1e-12)
        assert lhs == pytest.approx(float(rest.xreplace(to_model).subs(point)), rel=1e-10, abs=1e-12)


def test_definitions_are_substituted_not_new_symbols(tmp_path):
    """The model with definitions derives to the very equations of the model written out."""
    written = SLIDER.replace("  x: xs", "  x: r*cos(theta) + l*cos(asin(r*sin(theta)/l))")
    written = re.sub(r"definitions:\n(  .*\n)+", "", written)
    a = _load(tmp_path, SLIDER, "a.yaml").derive(cache=False)
    b = _load(tmp_path, written, "b.yaml").derive(cache=False)
    assert [p.name for p in a.parameters] == [p.name for p in b.parameters]
    assert [q.name for q in a.coordinates] == ["theta"]
    assert sympy.simplify(a.mass_matrix - b.mass_matrix) == sympy.zeros(1, 1)
    assert sympy.simplify(a.forces - b.forces) == sympy.zeros(1, 1)
    assert "beta" not in {s.name for s in a.mass_matrix.free_symbols | a.forces.free_symbols}


def test_definitions_in_effects_initial_values_and_constraints(tmp_path):
    base = (MODELS / "hoffmann" / "system1.yaml").read_text()
    with_defs = base.replace("components:", "definitions:\n  bend: phi - theta\n  start: pi/6 + 0*a1\n"
                                            "  kb: 2*m1\ncomponents:", 1)
    with_defs = with_defs.replace("  push: {type: force,", "  knee: {type: torsional_spring, angle: bend, "
                                                           "stiffness: kb}\n  push: {type: force,")
    with_defs = with_defs.replace("initial: {theta: 0.5, phi: -0.2}", "initial: {theta: start, phi: -start}")
    inline = base.replace("  push: {type: force,", "  knee: {type: torsional_spring, angle: phi - theta, "
                                                   "stiffness: 2*m1}\n  push: {type: force,")
    inline = inline.replace("initial: {theta: 0.5, phi: -0.2}", "initial: {theta: pi/6, phi: -pi/6}")
    a, b = _load(tmp_path, with_defs, "a.yaml"), _load(tmp_path, inline, "b.yaml")
    assert {k.name: sympy.nsimplify(v) for k, v in a.initial.items()} == \
        {k.name: sympy.nsimplify(v) for k, v in b.initial.items()}
    sa, sb = a.derive(cache=False), b.derive(cache=False)
    assert sympy.simplify(sa.forces - sb.forces) == sympy.zeros(2, 1)
    # by hand: the knee spring adds -dV/dq with V = kb (phi - theta)^2 / 2
    th, ph, m1 = sa.symbol("theta"), sa.symbol("phi"), sa.symbol("m1")
    spring = sympy.Matrix([2 * m1 * (ph - th), -2 * m1 * (ph - th)])
    without = _load(tmp_path, base, "c.yaml").derive(cache=False)
    assert sympy.simplify(sa.forces - without.forces - spring) == sympy.zeros(2, 1)


def test_a_definition_in_a_constraint(tmp_path):
    import shutil

    shutil.copy(MODELS / "hoffmann" / "system1.yaml", tmp_path / "system1.yaml")  # its known system
    text = (MODELS / "hoffmann" / "system2_implicit.yaml").read_text()
    m = re.search(r"(?m)^constraints:\n((?:  .*\n)+)", text)
    first = m.group(1).splitlines()[0]
    name, _, expr = first.strip().partition(":")
    if expr.strip().startswith("{"):
        pytest.skip("the model's constraint is a joint, not an expression")
    defined = text.replace(first, f"  {name}: gap", 1).replace("constraints:", f"definitions:\n  gap: {expr.strip()}"
                                                               "\nconstraints:", 1)
    a = _load(tmp_path, defined, "a.yaml").derive(cache=False)
    b = _load(tmp_path, text, "b.yaml").derive(cache=False)
    assert [str(c.expression) for c in a.implicit.constraints] == [str(c.expression) for c in b.implicit.constraints]


@pytest.mark.parametrize("definitions, message", [
    ("  a1: 2*g", "definition 'a1' has the name of the parameter 'a1'"),
    ("  theta: 2*g", "definition 'theta' has the name of the coordinate 'theta'"),
    ("  sin: 2*g", "definition 'sin' has the name of the function 'sin'"),
    ("  upper: 2*g", "definition 'upper' has the name of the component 'upper'"),
    ("  phi_dot: 1", "definition 'phi_dot' has the name of the velocity 'phi_dot'"),
    ("  u: v + 1\n  v: 2*w\n  w: u", "definitions form a cycle: u -> v -> w -> u"),
    ("  u: u + 1", "definitions form a cycle: u -> u"),
])
def test_clashes_and_cycles_are_located_errors(tmp_path, definitions, message):
    text = (MODELS / "hoffmann" / "system1.yaml").read_text().replace("components:", "definitions:\n"
                                                                      + definitions + "\ncomponents:", 1)
    result = _check(tmp_path, text)
    assert result.exit_code == 1, result.output
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.startswith("definitions:")) + 1
    assert re.search(rf"Error: .*m\.yaml:{line}:3: {re.escape(message)}", result.output), result.output
    assert "Traceback" not in result.output and "1 problems" not in result.output


def test_one_bad_definition_is_one_error(tmp_path):
    """A typo inside a definition is reported once, not again at every place that uses it."""
    text = SLIDER.replace("asin(r*sin(theta)/l)", "asin(r*sin(thetta)/l)")
    result = _check(tmp_path, text)
    assert result.exit_code == 1
    assert result.output.count("Error:") == 1, result.output
    assert "unknown name 'thetta'" in result.output and "did you mean 'theta'" in result.output


def test_a_definition_used_where_its_names_cannot_be(tmp_path):
    text = SLIDER.replace("initial: {theta: 0.2}", "initial: {theta: beta}")
    result = _check(tmp_path, text)
    assert result.exit_code == 1
    assert "in initial value of 'theta': definition 'beta' uses 'theta', which cannot appear here" in result.output
    result = _check(tmp_path, PENDULUM + "effects:\n  s: {type: torsional_spring, angle: swing, stiffness: 2}\n"
                              "initial: {q1: swing}\n")
    assert result.exit_code == 1  # an effect may use q1 (applied in the subspace); an initial value not
    assert "in initial value of 'q1': definition 'swing' uses 'q1'" in result.output
    assert result.output.count("Error:") == 1


def test_a_definition_may_use_primitive_coordinates_in_effects(tmp_path):
    text = SLIDER.replace("definitions:\n", "definitions:\n  stretch: x - s0\n").replace(
        "  spring: {type: spring, between: [piston.centre, [0]], stiffness: k, length: s0}",
        "  spring: {type: potential, value: k*stretch**2/2}")
    a = _load(tmp_path, text, "a.yaml").derive(cache=False)
    b = _load(tmp_path, SLIDER, "b.yaml").derive(cache=False)
    theta = a.symbol("theta")
    # Abs/sign of the spring vanish where the piston is at x > 0 (every crank angle here)
    for value in (0.3, 1.1, 2.9):
        assert float((a.forces[0] - b.forces[0]).subs(theta, value).subs(
            {a.symbol(n): v for n, v in (("r", 0.1), ("l", 0.3), ("k", 10), ("s0", 0.35))})) == \
            pytest.approx(0, abs=1e-12)


def test_a_definition_in_a_component_parameter_says_why_not(tmp_path):
    text = SLIDER.replace("definitions:\n", "definitions:\n  crank_mass: 2*m\n").replace(
        "parameters: {mass: m, length: r}", "parameters: {mass: crank_mass, length: r}")
    result = _check(tmp_path, text)
    assert result.exit_code == 1
    assert "unknown name 'crank_mass'" in result.output
    assert "definitions are read after the parameters and components" in result.output
    assert result.output.count("Error:") == 1
