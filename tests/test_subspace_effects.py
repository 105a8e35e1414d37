"""Effects written in generalized coordinates act directly in the subspace: checked against a
hand Lagrangian, against the same effects written in the primitive coordinates (where the
force is projected, fbar = C^T f (8')), and through a constrained model."""
from __future__ import annotations

import numpy as np
import pytest
import sympy
from click.testing import CliRunner
from scipy.integrate import solve_ivp

import kronsub
import kronsub.errors
from conftest import MODELS, every_model_file
from kronsub.cli import main

PENDULUM = """\
name: pendulum in q
parameters: {m: 2, L: 1.5, g: 9.81, k: 3, c: 0.4, tau: 0.7, rest: 0.1}
components:
  bob: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}
coordinates: [q]
connection: {x: L*sin(q), y: -L*cos(q)}
effects:
  gravity: {type: gravity, g: g}
  spring: {type: torsional_spring, angle: ANGLE, stiffness: k, rest: rest}
  drag: {type: torsional_damper, angle: ANGLE, coefficient: c}
  drive: {type: generalized_force, coordinate: q, value: tau*cos(q)}
initial: {q: 0.3}
"""


def _derive(tmp_path, text, name="m.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return kronsub.load(path).derive(cache=False)


def test_a_pendulum_with_effects_in_its_generalized_coordinate(tmp_path):
    system = _derive(tmp_path, PENDULUM.replace("ANGLE", "q"))
    q, qd = system.symbol("q"), system.symbol("q_dot")
    m, L, g, k, c, tau, rest = (system.symbol(n) for n in ("m", "L", "g", "k", "c", "tau", "rest"))
    # hand Lagrangian: T = m L^2 qd^2/2, V = -m g L cos q + k (q - rest)^2/2; Q = -c qd + tau cos q
    assert sympy.simplify(system.mass_matrix[0, 0] - m * L**2) == 0
    expected = -m * g * L * sympy.sin(q) - k * (q - rest) - c * qd + tau * sympy.cos(q)
    assert sympy.simplify(system.forces[0] - system.velocity_terms[0] - expected) == 0
    V = -m * g * L * sympy.cos(q) + k * (q - rest) ** 2 / 2
    assert sympy.simplify(system.potential_energy - V) == 0
    assert set(system.transition.direct_effects) == {"spring", "drag", "drive"}


def test_the_same_as_written_in_the_primitive_coordinates(tmp_path):
    """`angle: q` in the subspace and `angle: atan2(x, -y)` on the primitive give one fbar."""
    direct = _derive(tmp_path, PENDULUM.replace("ANGLE", "q"), "a.yaml")
    projected = _derive(tmp_path, PENDULUM.replace("ANGLE", "'atan2(x, -y)'"), "b.yaml")
    assert set(projected.transition.direct_effects) == {"drive"}
    names = ("q", "q_dot", "m", "L", "g", "k", "c", "tau", "rest")
    f = sympy.lambdify([direct.symbol(n) for n in names], list(direct.forces))
    h = sympy.lambdify([projected.symbol(n) for n in names], list(projected.forces))
    rng = np.random.default_rng(12)
    for _ in range(6):
        point = [rng.uniform(-1.4, 1.4), *rng.uniform(0.3, 2.0, len(names) - 1)]  # |q| < pi/2: atan2's branch
        assert f(*point) == pytest.approx(h(*point), rel=1e-12, abs=1e-12)


def test_the_simulation_follows_the_hand_equation(tmp_path):
    system = _derive(tmp_path, PENDULUM.replace("ANGLE", "q"))
    traj = system.simulate(t=1.0, dt=0.5, dataframe=False, rtol=1e-12, atol=1e-12)
    m, L, g, k, c, tau, rest = 2, 1.5, 9.81, 3, 0.4, 0.7, 0.1

    def rhs(t, y):
        q, qd = y
        return [qd, (-m * g * L * np.sin(q) - k * (q - rest) - c * qd + tau * np.cos(q)) / (m * L**2)]

    ref = solve_ivp(rhs, (0, 1.0), [0.3, 0.0], rtol=1e-12, atol=1e-12, t_eval=traj.t, method="DOP853")
    np.testing.assert_allclose(traj.y, ref.y.T, rtol=1e-8, atol=1e-9)


def test_a_spring_on_a_pivoted_rods_angle_in_a_closed_loop(tmp_path):
    """In the slider-crank, `psi` is the pivoted rod's angle (in y, not a primitive coordinate;
    the primitive has `rod_axis = psi - pi/2`): both spellings give the same equations."""
    text = (MODELS / "examples" / "slider_crank.yaml").read_text()
    spring = "  knee: {type: torsional_spring, angle: ANGLE, stiffness: 3, rest: 1.7}\n"
    head, _, tail = text.partition("effects:\n")
    a = _derive(tmp_path, head + "effects:\n" + spring.replace("ANGLE", "psi") + tail, "a.yaml")
    b = _derive(tmp_path, head + "effects:\n" + spring.replace("ANGLE", "rod_axis + pi/2") + tail, "b.yaml")
    la, lb = a.linearize(), b.linearize()
    np.testing.assert_allclose(la.A, lb.A, rtol=1e-9, atol=1e-9)
    assert float(la.point[0][1]) == pytest.approx(float(lb.point[0][1]), abs=1e-9)
    base = _derive(tmp_path, text, "c.yaml")
    assert not np.allclose(la.A, base.linearize().A)  # the spring does act


def test_reactions_need_forces_on_the_primitive(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text(PENDULUM.replace("ANGLE", "q"))
    result = CliRunner().invoke(main, ["derive", str(path), "--reactions"])
    assert result.exit_code == 1
    assert "'spring', 'drag', 'drive' are written in generalized coordinates" in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize("fmt,mark", [("markdown", "spring"), ("latex", r"\texttt{spring}")])
def test_the_report_names_the_effects_applied_in_the_subspace(tmp_path, fmt, mark):
    """Markdown and LaTeX both say which effects act in the subspace (they have no primitive force)."""
    path = tmp_path / "m.yaml"
    path.write_text(PENDULUM.replace("ANGLE", "q"))
    result = CliRunner().invoke(main, ["derive", str(path), "--format", fmt, "--no-cache"])
    assert result.exit_code == 0, result.output
    line = " ".join(result.output.split("applied directly in the subspace")[1].split("\n")[:3])
    for name in ("spring", "drag", "drive"):
        assert mark.replace("spring", name) in line, (fmt, line)



EVERY_MODEL_FILE = every_model_file()


@pytest.mark.parametrize("path", EVERY_MODEL_FILE, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_force_and_potential_are_the_effects_own(path):
    """`Effect.force_and_potential` builds ``V`` once for the default ``f = -dV/dx``: the very
    force and potential each effect of every bundled and test model gives apart."""
    model = kronsub.load(path)
    for effect in model.effects:
        f, V = effect.force_and_potential(model.primitive)
        assert [sympy.srepr(e) for e in f] == [sympy.srepr(e) for e in effect.generalized_force(model.primitive)]
        assert sympy.srepr(V) == sympy.srepr(effect.potential(model.primitive))


@pytest.mark.parametrize("path", EVERY_MODEL_FILE, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_gravity_built_in_one_sum_is_the_sum_body_by_body(path):
    """Gravity's ``V`` and ``dV/do`` are built as one sum each (`Gravity.potential`,
    `Gravity.translation`): the very expressions adding one body (one part) at a time gives."""
    from kronsub.effects.base import dot
    from kronsub.effects.gravity import Gravity

    model = kronsub.load(path)
    for effect in [e for e in model.effects if isinstance(e, Gravity)]:
        units = [(name, [c / sympy.sqrt(sum(c**2 for c in d)) for c in d]) for name, d in effect.parts]
        total = sympy.Integer(0)
        for name, unit in units:
            for body in model.primitive.part(name).bodies:
                if body.mass != 0:
                    total -= body.mass * effect.g * dot(unit, body.centre)
        assert sympy.srepr(effect.potential(model.primitive)) == sympy.srepr(sympy.expand(total))
        weights: list = []
        for name, unit in units:
            mass = sympy.Add(*[b.mass for b in model.primitive.part(name).bodies])
            weights += [sympy.Integer(0)] * (len(unit) - len(weights))
            for i, c in enumerate(unit):
                weights[i] -= mass * effect.g * c
        assert [sympy.srepr(t) for t in effect.translation(model.primitive)] == \
            [sympy.srepr(sympy.expand(t)) for t in weights]
