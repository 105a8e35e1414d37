"""Prescribed motions in model files: `t` in `connection:` and `prescribed:`, derived through
the loader and the projection (core/subspace.py) and compared with core/rheonomic.py and with
Lagrange's equations written by hand; the outputs' drive block; the refusals."""
import json
from pathlib import Path

import numpy as np
import pytest
import sympy
from click.testing import CliRunner
from scipy.integrate import solve_ivp

import kronsub
from kronsub.cli import main
from kronsub.core.symbols import TIME, symbol, velocity_symbol

MODELS = Path(__file__).resolve().parent.parent / "models" / "motion"


def _accelerations(system):
    return system.mass_matrix.LUsolve(system.forces - system.velocity_terms)


def test_bead_on_turning_hoop_model_is_the_hand_lagrangian():
    system = kronsub.load(MODELS / "bead_on_turning_hoop.yaml").derive()
    th, m, R, w, g = (symbol(n) for n in ("theta", "m", "R", "w", "g"))
    thd = velocity_symbol(th)
    # L = m R^2 (thd^2 + w^2 sin^2 th) / 2 + m g R cos th
    hand = (m * R**2 * w**2 * sympy.sin(th) * sympy.cos(th) - m * g * R * sympy.sin(th)) / (m * R**2)
    assert sympy.simplify(_accelerations(system)[0] - hand) == 0
    assert thd not in _accelerations(system)[0].free_symbols


def test_kapitza_model_prescribes_the_pivot_and_matches_the_hand_equation():
    system = kronsub.load(MODELS / "kapitza_pendulum.yaml").derive()
    assert [q.name for q in system.coordinates] == ["theta"]
    th, m, l, a, w, g = (symbol(n) for n in ("theta", "m", "l", "a", "w", "g"))
    # pivot height s = a cos(w t): m l^2 thdd + m l (g + sdd) sin th = 0
    sdd = sympy.diff(a * sympy.cos(w * TIME), TIME, 2)
    hand = -(g + sdd) * sympy.sin(th) / l
    assert sympy.simplify(_accelerations(system)[0] - hand) == 0


def test_a_time_dependent_connection_written_directly_equals_the_prescribed_one(tmp_path):
    text = (MODELS / "kapitza_pendulum.yaml").read_text()
    direct = text.replace("coordinates: [theta, s]", "coordinates: [theta]").replace(
        "prescribed:\n  s: a*cos(w*t)\n", "").replace("py: s - l*cos(theta)", "py: a*cos(w*t) - l*cos(theta)")
    assert direct != text
    one = kronsub.load(MODELS / "kapitza_pendulum.yaml").derive()
    other = kronsub.load(tmp_path / "direct.yaml", text=direct).derive()
    assert sympy.simplify(_accelerations(one)[0] - _accelerations(other)[0]) == 0


def test_outputs_say_the_drive_puts_energy_in():
    result = CliRunner().invoke(main, ["derive", str(MODELS / "bead_on_turning_hoop.yaml"), "--format", "json"])
    assert result.exit_code == 0, result.output
    drive = json.loads(result.output)["primitive"]["drive"]
    assert drive["energy_conserved"] is False
    assert drive["velocity"]["bz"] == "0" and "w" in drive["velocity"]["bx"]
    th, m, R, w = (symbol(n) for n in ("theta", "m", "R", "w"))
    extra = sympy.sympify(drive["velocity_terms"][0], locals={n: symbol(n) for n in ("theta", "m", "R", "w")})
    assert sympy.simplify(extra + m * R**2 * w**2 * sympy.sin(th) * sympy.cos(th)) == 0
    markdown = CliRunner().invoke(main, ["derive", str(MODELS / "bead_on_turning_hoop.yaml")]).output
    assert "x = x(xbar, t)" in markdown and "Terms the drive adds to `hbar`" in markdown
    assert "T + V` is not conserved" in markdown
    # a model without a drive has no drive block
    plain = CliRunner().invoke(main, ["derive", str(Path(__file__).resolve().parent.parent / "models" / "examples"
                                                      / "double_pendulum.yaml"), "--format", "json"])
    assert "drive" not in json.loads(plain.output).get("primitive", {})


def test_kapitza_model_simulated_stays_upside_down():
    system = kronsub.load(MODELS / "kapitza_pendulum.yaml").derive()
    f = sympy.lambdify((TIME, system.coordinates[0], system.velocities[0]),
                       _accelerations(system)[0].subs({symbol(p.name): p.value for p in system.parameters}), "math")
    from scipy.integrate import solve_ivp

    run = solve_ivp(lambda t, y: (y[1], f(t, y[0], y[1])), (0.0, 3.0), (3.0, 0.0), rtol=1e-9, atol=1e-11,
                    max_step=0.002)
    assert np.max(np.abs(run.y[0] - np.pi)) < 0.5


BASE = """name: driven
parameters: {m: 1, l: 1, w: 2, g: 9.81}
components:
  bob: {type: particle2d, parameters: {mass: m}, coordinates: [px, py]}
coordinates: [theta, s]
connection:
  px: l*sin(theta)
  py: s - l*cos(theta)
"""


@pytest.mark.parametrize("extra, message", [
    ("prescribed:\n  z: sin(w*t)\n", "prescribed 'z' is not a listed coordinate"),
    ("prescribed:\n  s: sin(w*t)\n  theta: t\n", "every coordinate is prescribed"),
    ("prescribed:\n  s: sin(q*t)\n", "'q'"),
    ("prescribed:\n  s: sin(w*t)\neffects:\n  spring: {type: potential, value: s**2 + theta**2}\n",
     "effect 'spring' names the prescribed coordinate 's'"),
])
def test_bad_prescribed_motions_are_located_errors(tmp_path, extra, message):
    path = tmp_path / "model.yaml"
    path.write_text(BASE + extra)
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1
    assert f"Error: {path}:" in result.output and message in result.output and "hint:" in result.output
    assert "Traceback" not in result.output


def test_time_in_a_connection_with_constraints_is_refused(tmp_path):
    path = tmp_path / "model.yaml"
    path.write_text("""name: loop
parameters: {m: 1, w: 2}
components:
  a: {type: particle2d, parameters: {mass: m}, coordinates: [ax, ay]}
coordinates: [q]
connection:
  ax: q + sin(w*t)
constraints:
  ring: ax**2 + ay**2 - 1
""")
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1
    assert "together with `constraints:` is not supported yet" in result.output and "hint:" in result.output


def test_reactions_of_a_prescribed_motion_give_the_force_that_drives_it():
    """Kapitza's pivot: the vertical reaction on the bob is the force the shaker pushes with,
    ``m (yddot + g)`` with ``y = a cos(w t) - l cos(theta)``."""
    from kronsub.core.reactions import reactions
    from kronsub.core.symbols import acceleration_symbol

    system = kronsub.load(MODELS / "kapitza_pendulum.yaml").derive()
    found = dict(reactions(system))
    th, m, l, a, w, g = (symbol(n) for n in ("theta", "m", "l", "a", "w", "g"))
    thd, thdd = velocity_symbol(th), acceleration_symbol(th)
    y = a * sympy.cos(w * TIME) - l * sympy.cos(th)
    ydd = sympy.diff(y, TIME, 2) + sympy.diff(y, th) * thdd + sympy.diff(y, th, 2) * thd**2
    assert sympy.simplify(found["R_py"] - m * (ydd + g)) == 0
    x = l * sympy.sin(th)
    xdd = sympy.diff(x, th) * thdd + sympy.diff(x, th, 2) * thd**2
    assert sympy.simplify(found["R_px"] - m * xdd) == 0
    # C^T R = 0 on the motion: the reactions do no work in the free coordinate
    on_motion = {thdd: _accelerations(system)[0]}
    assert sympy.simplify((l * sympy.cos(th) * found["R_px"] + l * sympy.sin(th) * found["R_py"]).subs(on_motion)) == 0


def test_simulated_driven_model_agrees_across_methods_and_places_its_points(tmp_path):
    """The generated C (velocity terms and points take t; the canonical form of gauss4 keeps the
    drive's terms) against scipy's DOP853 on the numpy module, and the points against the connection."""
    rows = {}
    for method in ("dop853", "gauss4", "DOP853"):
        out = tmp_path / f"{method}.csv"
        result = CliRunner().invoke(main, ["simulate", str(MODELS / "bead_on_turning_hoop.yaml"), "--t", "2",
                                           "--method", method, "--points", "--output", str(out)])
        assert result.exit_code == 0, result.output
        assert "Warning" not in result.output, result.output
        lines = out.read_text().splitlines()
        rows[method] = dict(zip(lines[0].split(","), map(float, lines[-1].split(","))))
        meta = json.loads(out.with_suffix(".json").read_text())
        assert meta["prescribed_motion"]["energy_conserved"] is False
    assert rows["dop853"]["theta"] == pytest.approx(rows["DOP853"]["theta"], abs=1e-7)
    assert rows["gauss4"]["theta"] == pytest.approx(rows["dop853"]["theta"], abs=1e-5)
    last = rows["dop853"]
    R, w, t, th = 0.5, 7.0, last["t"], last["theta"]
    assert last["bead.centre.x"] == pytest.approx(R * np.sin(th) * np.cos(w * t), abs=1e-12)
    assert last["bead.centre.y"] == pytest.approx(R * np.sin(th) * np.sin(w * t), abs=1e-12)
    assert last["bead.centre.z"] == pytest.approx(-R * np.cos(th), abs=1e-12)


@pytest.mark.parametrize("motion", ["a*abs(t - 1/10)", "a*sign(t - 1/10)"])
def test_a_motion_with_a_kink_or_a_jump_is_taken_where_its_derivatives_exist(tmp_path, motion):
    """A pivot moved as ``a |t - t1|`` (a kink) or ``a sign(t - t1)`` (a jump): ``s'' = 0``
    wherever it exists, so the pendulum's equation is the fixed pivot's, ``m l^2 thdd + m l g
    sin th = 0``, and no DiracDelta (an impulse no backend evaluates: the run failed with an
    internal NameError, and derive printed it) reaches the equations, the drive's power or the
    outputs; the run equals the fixed pendulum's."""
    text = (MODELS / "kapitza_pendulum.yaml").read_text().replace("s: a*cos(w*t)", f"s: {motion}")
    path = tmp_path / "kinked.yaml"
    path.write_text(text)
    system = kronsub.load(path).derive(cache=False)
    th, l, g = (symbol(n) for n in ("theta", "l", "g"))
    assert sympy.simplify(_accelerations(system)[0] + g * sympy.sin(th) / l) == 0
    result = CliRunner().invoke(main, ["derive", str(path), "--format", "json", "--no-cache"])
    assert result.exit_code == 0 and "DiracDelta" not in result.output
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(path), "--t", "0.3", "--rtol", "1e-11", "--atol", "1e-12",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    rows = np.genfromtxt(out, delimiter=",", names=True)
    assert np.all(np.isfinite(rows["drive_power"]))
    values = {p.name: float(p.value) for p in system.parameters}
    fixed = solve_ivp(
        lambda t, y: [y[1], -values["g"] / values["l"] * np.sin(y[0])], (0, 0.3), [3.0, 0.0],
        t_eval=rows["t"], rtol=1e-12, atol=1e-12)
    assert np.allclose(rows["theta"], fixed.y[0], atol=1e-8)
