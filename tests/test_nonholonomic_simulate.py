"""`simulate` of systems under velocity constraints (models/nonholonomic): the state [q; u] run by
the compiled right-hand side, against sympy's KanesMethod integrated from the same start, the
energy kept, the sleigh's straight end, the contact-force columns of --reactions, and the methods
refused for now."""
from pathlib import Path

import jinja2
import numpy as np
import pytest
import sympy
from click.testing import CliRunner
from scipy.integrate import solve_ivp

import kronsub
import kronsub.emitters.code as code
from kronsub.cli import main
from kronsub.emitters.escape import environment
from reference.nonholonomic import rolling_disc_kane

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "models" / "nonholonomic"


@pytest.fixture(autouse=True)
def _worktree_templates(monkeypatch):
    """The templates of this checkout (an editable install may map kronsub.templates elsewhere)."""
    monkeypatch.setattr(code, "template_environment",
                        lambda: environment(jinja2.FileSystemLoader(str(ROOT / "templates"))))


def _simulate(tmp_path, name, *args):
    """``kronsub simulate`` of a bundled model into a CSV: its header and rows."""
    out = tmp_path / f"{name}.csv"
    result = CliRunner().invoke(main, ["simulate", str(MODELS / f"{name}.yaml"), "--rtol", "1e-11", "--atol", "1e-12",
                                       "-o", str(out), *args])
    assert result.exit_code == 0, result.output
    header = out.read_text().splitlines()[0].split(",")
    return header, np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)


def test_rolling_disc_run_against_kanes_method(tmp_path):
    header, data = _simulate(tmp_path, "rolling_disc", "--t", "1.5", "--dt", "0.25")
    assert header[:9] == ["t", "yaw", "lean", "spin", "x", "y", "yaw_dot", "lean_dot", "spin_dot"]
    energy = data[:, header.index("total_energy")]
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * abs(energy[0])
    m, g, r = (sympy.Symbol(n, real=True) for n in ("m", "g", "r"))
    q, u, kane, _ = rolling_disc_kane(m, g, r)
    values = {m: 1.0, g: 9.81, r: 0.3}
    parts = sympy.lambdify([*q, *u], [kane.mass_matrix.xreplace(values), kane.forcing.xreplace(values)], "numpy")

    def field(t, z):  # z = [q (5); yaw_dot, lean_dot, spin_dot]: Kane's dependent speeds from the rolling
        yaw, spin_dot = z[0], z[7]
        full = [*z[5:8], values[r] * np.cos(yaw) * spin_dot, values[r] * np.sin(yaw) * spin_dot]
        M, F = parts(*z[:5], *full)
        return [*full, *np.linalg.solve(np.array(M, float), np.array(F, float).ravel())[:3]]

    start = data[0, 1:9]
    run = solve_ivp(field, (0.0, 1.5), start, t_eval=data[:, 0], method="DOP853", rtol=1e-12, atol=1e-12)
    assert np.allclose(run.y.T, data[:, 1:9], rtol=1e-7, atol=1e-8)


def test_sleigh_run_ends_straight_and_keeps_its_energy(tmp_path):
    header, data = _simulate(tmp_path, "chaplygin_sleigh", "--t", "60", "--dt", "5", "--reactions")
    v, w = data[:, header.index("v")], data[:, header.index("w")]
    energy = data[:, header.index("total_energy")]
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * energy[0]
    assert abs(w[-1]) < 1e-6 and v[-1] == pytest.approx(np.sqrt(2 * energy[0] / 1.0), rel=1e-8)
    # the knife edge's force column: -I w'/a with w' = -m a v w / (I + m a^2) at each row
    I, a, m = 0.05, 0.2, 1.0
    assert np.allclose(data[:, header.index("mu_knife_edge")], I * m * v * w / (I + m * a**2), rtol=1e-8, atol=1e-12)


def test_differential_drive_through_the_api():
    system = kronsub.load(str(MODELS / "differential_drive.yaml")).derive()
    run = system.simulate(t=1.0, dt=0.5, dataframe=False)
    assert run.columns == ("x", "y", "theta", "phi_l", "phi_r", "phi_l_dot", "phi_r_dot")
    # the state [q; u]: five coordinates, two speeds (not halves of y)
    assert run.q.shape == (len(run.t), 5) and run.qdot.shape == (len(run.t), 2)
    assert np.array_equal(run.q[:, 2], run["theta"]) and np.array_equal(run.qdot[:, 1], run["phi_r_dot"])
    # from rest, the wheels' rates grow as Mbar^-1 tau: the right motor pulls harder, so it turns left
    R, b = 0.05, 0.15
    phi_l, phi_r, theta = run.y[-1, 3], run.y[-1, 4], run.y[-1, 2]
    assert theta == pytest.approx(R * (phi_r - phi_l) / (2 * b), rel=1e-9) and theta > 0
    assert np.all(np.isfinite(run.y))
    # energy balance: the constant motor torques' work tau_l phi_l + tau_r phi_r is the kinetic energy
    # gained (rolling without slipping does no work; V = 0)
    tau_l, tau_r = 0.02, 0.03
    work = tau_l * (run.y[:, 3] - run.y[0, 3]) + tau_r * (run.y[:, 4] - run.y[0, 4])
    assert np.allclose(run.kinetic_energy - run.kinetic_energy[0], work, rtol=1e-8, atol=1e-12)


def test_methods_without_the_state_in_the_speeds_are_refused():
    result = CliRunner().invoke(main, ["simulate", str(MODELS / "chaplygin_sleigh.yaml"), "--method", "taylor",
                                       "--t", "1"])
    assert result.exit_code == 1 and "not supported yet with velocity constraints" in result.output
    assert "Traceback" not in result.output


def test_reference_solution_in_the_speeds_against_the_sleigh_by_hand():
    """The accuracy command's mpmath reference (Taylor series) of the state [q; u], against the
    sleigh's hand-derived equations m v' = m a w^2, (I + m a^2) w' = -m a v w integrated by scipy."""
    from kronsub.simulation.reference import taylor

    system = kronsub.load(str(MODELS / "chaplygin_sleigh.yaml")).derive()
    param = [float(p.value) for p in system.parameters]  # m, I, a
    m, I, a = param
    y0 = [0.1, -0.2, 0.3, 0.5, 2.0]

    def hand(t, z):
        x, y, theta, v, w = z
        return [v * np.cos(theta) - a * w * np.sin(theta), v * np.sin(theta) + a * w * np.cos(theta), w,
                a * w**2, -m * a * v * w / (I + m * a**2)]

    times = [0.5, 1.0]
    ours = taylor(system, param, y0, times, digits=16)
    theirs = solve_ivp(hand, (0, 1.0), y0, t_eval=times, method="DOP853", rtol=1e-13, atol=1e-14)
    assert np.allclose(np.array(ours.states, dtype=float), theirs.y.T, rtol=1e-10, atol=1e-11)


def test_accuracy_command_runs_the_state_in_the_speeds(tmp_path):
    result = CliRunner().invoke(main, ["accuracy", str(MODELS / "chaplygin_sleigh.yaml"), "--t", "1",
                                       "--methods", "dop853,taylor", "--tolerances", "1e-6,1e-10"])
    assert result.exit_code == 0, result.output
    assert "| dop853 | tol 1e-10 |" in result.output
    assert "taylor: skipped, it is not supported yet with velocity constraints" in result.output


def test_scenes_choose_effects_and_start_named_speeds(tmp_path):
    """A scene of a model with velocity constraints: its effects in the speeds' forces, its
    initial values of named speeds (the sleigh's v, w) where the run starts."""
    text = (MODELS / "chaplygin_sleigh.yaml").read_text()
    text += ("effects:\n  push: {type: generalized_force, coordinate: x, value: F}\n"
             "scenes:\n  pushed: {effects: [push], initial: {v: 0.2, w: -1.0}}\n  free: {effects: []}\n")
    text = text.replace("parameters:\n", "parameters:\n  F: {value: 0.3}\n", 1)
    path = tmp_path / "sleigh.yaml"
    path.write_text(text)
    model = kronsub.load(str(path))
    pushed, free = model.derive(scene="pushed"), model.derive(scene="free")
    theta = sympy.Symbol("theta", real=True)
    assert sympy.simplify(pushed.speeds.forces[0] - sympy.Symbol("F", real=True) * sympy.cos(theta)) == 0
    assert free.speeds.forces == sympy.zeros(2, 1)
    run = pushed.simulate(t=0.5, dt=0.5, dataframe=False)
    assert list(run.y[0, 3:]) == [0.2, -1.0]


def test_the_api_knows_the_speeds_by_name():
    system = kronsub.load(str(MODELS / "chaplygin_sleigh.yaml")).derive()
    v, w_dot = system.symbol("v"), system.symbol("w_dot")
    assert v in system.speeds.mass_matrix.free_symbols | system.speeds.velocity_terms.free_symbols
    assert w_dot.name == "w_dot" and w_dot.is_real


def test_plot_of_a_run_in_the_speeds(tmp_path):
    pytest.importorskip("matplotlib")
    plot = tmp_path / "sleigh.png"
    result = CliRunner().invoke(main, ["simulate", str(MODELS / "chaplygin_sleigh.yaml"), "--t", "1",
                                       "-o", str(tmp_path / "sleigh.csv"), "--plot", str(plot)])
    assert result.exit_code == 0, result.output
    assert plot.stat().st_size > 0


@pytest.mark.parametrize("ratio, upright", [(1.3, True), (0.7, False)])
def test_rolling_disc_stays_upright_above_its_critical_spin(ratio, upright):
    """Upright rolling of a thin disc is stable when its spin exceeds sqrt(g / (3 r)) (its rolling
    speed v^2 > g r / 3): a lean of 0.001 stays small above it and grows to order one below."""
    system = kronsub.load(str(MODELS / "rolling_disc.yaml")).derive()
    critical = np.sqrt(9.81 / (3 * 0.3))
    run = system.simulate(t=10.0, dt=0.05, set={"lean": 0.001, "yaw_dot": 0, "spin_dot": ratio * critical},
                          dataframe=False)
    lean = np.max(np.abs(run.y[:, 1]))
    assert (lean < 0.01) if upright else (lean > 0.3)


def test_a_constraint_in_time_holds_along_the_run(tmp_path):
    """A knife edge on a moving belt, A(x) xdot + b(x, t) = 0 with b in t: the run's positions,
    differentiated by central differences, keep the edge's velocity across it equal to the belt's."""
    path = ROOT / "tests" / "models" / "nonholonomic" / "sleigh_on_a_belt.yaml"
    out = tmp_path / "belt.csv"
    result = CliRunner().invoke(main, ["simulate", str(path), "--t", "2", "--dt", "0.001", "--rtol", "1e-12",
                                       "--atol", "1e-12", "-o", str(out)])
    assert result.exit_code == 0, result.output
    header = out.read_text().splitlines()[0].split(",")
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    t, x, y, theta = (data[:, header.index(c)] for c in ("t", "x", "y", "theta"))
    dt = t[1] - t[0]
    xd, yd, thd = ((c[2:] - c[:-2]) / (2 * dt) for c in (x, y, theta))
    th, tm = theta[1:-1], t[1:-1]
    a, V, w_b = 0.2, 0.3, 2.0
    residual = -np.sin(th) * xd + np.cos(th) * yd - a * thd + V * np.sin(th) * np.cos(w_b * tm)
    assert np.max(np.abs(residual)) < 1e-5
    assert np.max(np.abs(V * np.sin(th) * np.cos(w_b * tm))) > 0.05  # the belt's term matters here


def test_a_start_where_the_kinematic_equations_divide_by_zero_is_named(tmp_path):
    """A scene that starts where ``xdot = C u`` has no value (``y_dot = -x_dot/tan(theta)`` at
    ``theta = 0``): the run stops at once (exit 3) and says which kinematic equation divides by
    zero, not that the exact values are finite (the equations in the speeds are looked at, with
    the state ``[x; u]``)."""
    path = tmp_path / "edge.yaml"
    path.write_text("""name: edge
parameters: {m: 1}
components:
  body: {type: planar_body, parameters: {mass: m, inertia: 1}}
coordinates: [x, y, theta]
connection: {body.x: x, body.y: y, body.angle: theta}
velocity_constraints:
  edge: cos(theta)*x_dot + sin(theta)*y_dot
initial: {theta: 1}
scenes:
  flat: {initial: {theta: 0}, t_end: 0.1}
""")
    result = CliRunner().invoke(main, ["simulate", str(path), "--scene", "flat", "-o", str(tmp_path / "run.csv")])
    assert result.exit_code == 3, result.output
    assert "1/tan(theta) in y_dot of the kinematic equations is a division by zero" in result.output
    assert "finite when evaluated exactly" not in result.output


@pytest.mark.parametrize("name", ["chaplygin_sleigh", "rolling_disc"])
def test_gauss4_runs_the_state_in_the_speeds(tmp_path, name):
    """gauss4 (fixed step, the documented methods for the speeds) integrates ``[q; u]``: the
    model has no canonical form ``[q; p]``, which it took and stopped at t = 0 ("mass matrix
    singular"). Against dop853 from the same start; the energy kept."""
    header, fixed = _simulate(tmp_path, name, "--t", "0.5", "--dt", "0.001", "--method", "gauss4")
    _, adaptive = _simulate(tmp_path, name, "--t", "0.5", "--dt", "0.001")
    assert fixed.shape == adaptive.shape
    assert np.allclose(fixed, adaptive, rtol=1e-8, atol=1e-8)
    energy = fixed[:, header.index("total_energy")]
    assert np.max(np.abs(energy - energy[0])) <= 1e-9 * max(1.0, abs(energy[0]))
