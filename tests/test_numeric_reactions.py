"""Contact forces and named points of a system projected onto its speeds in numbers at run time
(kronsub/core/numeric_reactions.py, kronsub/simulation/named_points.py).

- On the small models under velocity constraints, where the symbolic route exists (the reaction
  expressions of kronsub/core/nonholonomic.py ``velocity_multipliers`` and the generated numpy
  module's points), the numeric route forced on the same run gives the same columns, under the
  same names, to ~1e-9: the rolling disc, the Chaplygin sleigh, the differential drive, the disc
  by a rolling joint (the contact's rows as made), the disc with its height held by a
  configuration constraint, the sleigh on a moving belt (``xdot = C u + d(x, t)``) and the sleigh
  beside two beads held on wires (two configuration constraints).
- Newton's law for the disc with a held height, forced numeric route: ``m a = F + m g`` for the
  centre's acceleration from the run's own points (finite differences), ``F`` the multipliers of
  the two rolling rows and of the height's constraint (the contact force in world axes).
- The Whipple bicycle (models/benchmarks/whipple_bicycle.yaml), which takes the numeric route:
  running straight and upright at steady speed, the front wheel carries the share of the weight
  the moment balance about the rear contact gives (``m_T g x_T / w``, Table 1's masses and mass
  centres) and no rolling force acts; rolled and steered, the total mass times the horizontal
  acceleration of the mass centre (from the four bodies' centres, ``--points``) is the sum of the
  rolling forces; ``animate`` draws it. These runs take the numpy route (no C compiler: the same
  pieces, tests/test_nonholonomic_numeric_route.py), which spares the tests the bicycle's C.
- Constraints dependent at a state have no multipliers (a row of NaN in a run); a point in a symbol
  without a value is reported.
"""
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from kronsub.cli import main
from kronsub.core.linearize_numerics import LinearizationError
from kronsub.core.nonholonomic_linearize import MotionParts
from kronsub.core.numeric_reactions import multipliers
from kronsub.errors import KronsubError
from kronsub.core.projection_work import projected_in_numbers as numeric_route
from kronsub.simulation import reactions as reaction_rows
from kronsub.simulation import table
from kronsub.simulation.named_points import point_namespace

from conftest import ROOT

SMALL = [ROOT / "models" / "nonholonomic" / f"{name}.yaml" for name in
         ("rolling_disc", "chaplygin_sleigh", "differential_drive")] + \
        [ROOT / "tests" / "models" / "nonholonomic" / f"{name}.yaml" for name in
         ("rolling_disc_joint", "rolling_disc_height", "sleigh_on_a_belt", "sleigh_and_beads")]
BICYCLE = ROOT / "models" / "benchmarks" / "whipple_bicycle.yaml"
BODIES = {"rear_wheel": "mR", "rear_frame": "mB", "front_frame": "mH", "front_wheel": "mF"}


def quiet_without_c(test):
    """The warnings of a run without a C compiler, expected here, kept out of the report."""
    for said in ("no C compiler", "method 'dop853' runs in compiled C"):
        test = pytest.mark.filterwarnings(f"ignore:{said}")(test)
    return test


def _numeric_route(monkeypatch):
    """The reactions and points of every system taken as a system projected in numbers takes them."""
    monkeypatch.setattr(reaction_rows, "projected_in_numbers", lambda system: True)
    monkeypatch.setattr(table, "projected_in_numbers", lambda system: True)


def _second_derivative(values, dt):
    """The fourth-order central difference at the rows 2 .. -2."""
    return (-values[4:] + 16 * values[3:-1] - 30 * values[2:-2] + 16 * values[1:-3] - values[:-4]) / (12 * dt * dt)


@pytest.mark.parametrize("path", SMALL, ids=lambda p: p.stem)
def test_the_same_multipliers_and_points_as_the_symbolic_route(path, monkeypatch):
    system = kronsub.load(path).derive()
    assert not numeric_route(system)
    symbolic = system.simulate(t=0.5, dt=0.05, points=True, reactions=True, dataframe=False)
    _numeric_route(monkeypatch)
    numeric = system.simulate(t=0.5, dt=0.05, points=True, reactions=True, dataframe=False)
    assert numeric.table_columns == symbolic.table_columns
    names = [c for c in symbolic.table_columns if c.startswith("mu_")]
    assert names == [f"mu_{name}" for name in system.speeds.constraint_names]
    points = [c for c in symbolic.table_columns if "." in c and not c.startswith("mu_")]
    assert points and all(c.rsplit(".", 1)[0] in system.points for c in points)
    assert np.array_equal(numeric.y, symbolic.y)  # the same run
    ours = np.column_stack([numeric[c] for c in names])
    theirs = np.column_stack([symbolic[c] for c in names])
    assert np.all(np.isfinite(ours))
    assert np.max(np.abs(ours - theirs)) <= 1e-9 * max(1.0, np.max(np.abs(theirs))), (path.stem, ours, theirs)
    for c in points:
        assert np.allclose(numeric[c], symbolic[c], rtol=1e-12, atol=1e-12), c


def test_newtons_law_for_the_disc_with_a_held_height(monkeypatch):
    _numeric_route(monkeypatch)
    system = kronsub.load(ROOT / "tests" / "models" / "nonholonomic" / "rolling_disc_height.yaml").derive()
    dt = 0.002
    run = system.simulate(t=0.2, dt=dt, points=True, reactions=True, dataframe=False)
    m, g = run.parameters["m"], run.parameters["g"]
    centre = np.column_stack([run[f"disc.centre.{axis}"] for axis in "xyz"])
    force = np.column_stack([run["mu_roll_x"], run["mu_roll_y"], run["mu_touches"] - m * g])[2:-2]
    assert np.max(np.abs(force[:, :2])) > 0.5  # the disc turns: the rolling rows carry force
    assert np.max(np.abs(m * _second_derivative(centre, dt) - force)) < 1e-5 * m * g


@pytest.fixture(scope="module")
def bicycle():
    return kronsub.load(BICYCLE).derive()


@pytest.fixture
def no_compiler(monkeypatch):
    from kronsub.simulation import run as runs
    from kronsub.simulation.native import CompilerNotFound

    def missing(*args, **kwargs):
        raise CompilerNotFound("none here")

    monkeypatch.setattr(runs, "native_model", missing)


@quiet_without_c
def test_the_bicycle_running_upright_carries_its_weight_on_the_front_wheel_by_the_moment_balance(bicycle, tmp_path,
                                                                                                 no_compiler):
    assert numeric_route(bicycle)
    out = tmp_path / "bike.csv"
    result = CliRunner().invoke(main, ["simulate", str(BICYCLE), "--t", "0.02", "--dt", "0.01", "--reactions",
                                       "--points", "--set", "rear_dot=20", "-o", str(out)])
    assert result.exit_code == 0, result.output
    header = out.read_text().splitlines()[0].split(",")
    names = ["mu_rear_rolls.x", "mu_rear_rolls.y", "mu_front_rolls.x", "mu_front_rolls.y", "mu_front_touches"]
    assert header[-5:] == names
    assert all(f"{body}.centre.{axis}" in header for body in BODIES for axis in "xyz")
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    p = {q.name: float(q.value) for q in bicycle.parameters}
    mass = sum(p[m] for m in BODIES.values())
    reach = (p["xB"] * p["mB"] + p["xH"] * p["mH"] + p["w"] * p["mF"]) / mass  # the mass centre ahead of the rear contact
    weight = mass * p["g"]
    front = rows[:, header.index("mu_front_touches")]
    assert np.allclose(front, weight * reach / p["w"], rtol=1e-9)
    assert np.max(np.abs(rows[:, [header.index(n) for n in names[:4]]])) < 1e-9 * weight


@quiet_without_c
def test_the_bicycles_rolling_forces_move_its_mass_centre(bicycle, no_compiler):
    dt = 0.002
    run = bicycle.simulate(t=0.06, dt=dt, points=True, reactions=True, dataframe=False,
                           set={"roll": 0.05, "rear_dot": 10.0, "steer_dot": 0.3})
    assert run.metadata["complete"] and run.metadata["right_hand_side"] == "numpy"
    masses = {body: run.parameters[m] for body, m in BODIES.items()}
    total = sum(masses.values())
    centre = sum(m * np.column_stack([run[f"{body}.centre.{axis}"] for axis in "xy"])
                 for body, m in masses.items()) / total
    force = np.column_stack([run["mu_rear_rolls.x"] + run["mu_front_rolls.x"],
                             run["mu_rear_rolls.y"] + run["mu_front_rolls.y"]])[2:-2]
    assert np.max(np.abs(force)) > 10.0  # it turns: the wheels push it sideways
    assert np.max(np.abs(total * _second_derivative(centre, dt) - force)) < 1e-5 * np.max(np.abs(force))


@quiet_without_c
def test_the_bicycle_is_animated(bicycle, tmp_path, no_compiler):
    pytest.importorskip("matplotlib")
    pytest.importorskip("PIL.Image")
    frames = bicycle.animate(tmp_path / "bike.gif", t=0.1, set={"rear_dot": 10.0, "roll": 0.05})
    assert frames > 1 and (tmp_path / "bike.gif").stat().st_size > 0


def test_dependent_constraints_have_no_multipliers():
    # S = [A; Y] with the two rows of A equal: S_c^T nu = r has no unique solve
    frame = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    parts = MotionParts(frame=frame, rates=np.zeros(3), transformation=np.array([[0.0], [0.0], [1.0]]),
                        convective=np.zeros(3), metric=np.eye(3), velocity_terms=np.zeros(3), force=np.zeros(3))
    with pytest.raises(LinearizationError, match="not independent"):
        multipliers(parts, np.zeros(1), held=0)
    frame[1] = [1.0, -1.0, 0.0]  # independent: the force along each row
    parts = dataclasses.replace(parts, frame=frame, force=np.array([-3.0, 1.0, 0.0]))
    assert np.allclose(multipliers(parts, np.zeros(1), held=0), [1.0, 2.0])


def test_a_point_in_a_symbol_without_a_value_is_reported():
    system = kronsub.load(SMALL[0]).derive()
    with pytest.raises(KronsubError, match="named point 'p': zeta is neither a parameter"):
        point_namespace(dataclasses.replace(system, points={"p": (sympy.Symbol("zeta"), sympy.Integer(0))}))


def test_a_row_where_the_multipliers_fail_stays_nan(monkeypatch):
    _numeric_route(monkeypatch)
    system = kronsub.load(SMALL[4]).derive()  # the disc with a held height
    param = np.array([float(p.value) for p in system.parameters])
    good = system.simulate(t=0.1, dt=0.1, dataframe=False).y[-1]
    traj = SimpleNamespace(t=np.array([0.0, 0.1]), y=np.array([good, np.full_like(good, np.nan)]), segments=None,
                           dependent=None)
    names, values = reaction_rows.reaction_columns(system, traj, param)
    assert names == ["mu_roll_x", "mu_roll_y", "mu_touches"]
    assert np.all(np.isfinite(values[0])) and np.all(np.isnan(values[1]))
