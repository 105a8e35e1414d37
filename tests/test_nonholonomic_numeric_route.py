"""Systems under velocity constraints whose projection onto the speeds is too large to make
symbolically: the generated C makes it at run time (kronsub/emitters/projected_speeds.py,
tests/test_projected_speeds.py), and without a C compiler a run projects in numpy at every
evaluation (kronsub/simulation/numeric_speeds.py): ``C``, ``Cdot u``, ``Mbar = C^T M C`` and
``fbar - hbar`` formed from the primitive's metric, the forces and the constraints' rows at each
state, the held coordinates put on their configuration constraints by Newton's method first.

- On the small models, where the symbolic projection is made (the generated numpy module), the
  numpy route gives the same rates and energies at random states to ~1e-12: the rolling disc,
  the Chaplygin sleigh, the differential drive, the disc rolling by a joint (the contact's rows
  as made), the disc with its centre's height held by a configuration constraint, the sleigh on a
  moving belt (``xdot = C u + d(x, t)``) and the sleigh beside two beads held on wires.
- The route is taken by the measured projection work: not for those, for the Whipple bicycle's
  model file (models/benchmarks/whipple_bicycle.yaml), which the API and the CLI then simulate
  in its generated C within the default work budget: from upright running at 5 m/s rolled by
  1e-3 rad the roll and steer follow ``exp(A t)`` of the model file's own linearisation (second
  order in the roll), the energy (gravity alone does work) is kept, the front contact stays on
  the ground; without a compiler the numpy route runs the same motion; the CSV has the columns and
  metadata of every run (and --plot its figure). Its contact forces (--reactions), named points
  (--points) and animation: tests/test_numeric_reactions.py.
"""
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.linalg import expm

import kronsub
from kronsub.cli import main
from kronsub.simulation.fallback import module_energies, numpy_module
from kronsub.core.projection_work import NUMERIC_FROM, projection_work
from kronsub.core.projection_work import projected_in_numbers as numeric_route
from kronsub.simulation.numeric_speeds import NumericSpeeds

ROOT = Path(__file__).resolve().parent.parent
SMALL = [ROOT / "models" / "nonholonomic" / f"{name}.yaml" for name in
         ("rolling_disc", "chaplygin_sleigh", "differential_drive")] + \
        [ROOT / "tests" / "models" / "nonholonomic" / f"{name}.yaml" for name in
         ("rolling_disc_joint", "rolling_disc_height", "sleigh_on_a_belt", "sleigh_and_beads")]
BICYCLE = ROOT / "models" / "benchmarks" / "whipple_bicycle.yaml"
SPEED, ROLL, SPAN, RR = 5.0, 1e-3, 2.0, 0.3


def _param(system):
    return np.array([float(p.value) for p in system.parameters])


@pytest.mark.parametrize("path", SMALL, ids=lambda p: p.stem)
def test_the_same_rates_and_energies_as_the_symbolic_projection(path):
    system = kronsub.load(path).derive(cache=False)
    assert not numeric_route(system) and 0 < projection_work(system) < NUMERIC_FROM
    param = _param(system)
    module = numpy_module(system)
    numeric = NumericSpeeds(system, param)
    rng = np.random.default_rng(37)
    n, width = len(system.coordinates), len(system.coordinates) + len(system.speeds.speeds)
    for _ in range(8):
        y = rng.uniform(-1.0, 1.0, width)
        t = float(rng.uniform(0.0, 1.0))
        ours, theirs = numeric.rhs(t, y), np.asarray(module["rhs"](t, y, param), dtype=float)
        assert np.max(np.abs(ours - theirs)) <= 1e-12 * max(1.0, np.max(np.abs(theirs))), (path.stem, ours, theirs)
        on = np.concatenate([numeric.on_constraints(t, y[:n]), y[n:]])
        T, V = numeric.energies([t], [on])
        T0, V0 = module_energies(module, np.array([t]), np.array([on]), param)
        assert T[0] == pytest.approx(T0[0], rel=1e-12, abs=1e-12) and V[0] == pytest.approx(V0[0], rel=1e-12, abs=1e-12)


@pytest.fixture(scope="module")
def bicycle():
    return kronsub.load(BICYCLE).derive()  # within the default work budget


@pytest.fixture(scope="module")
def run(bicycle):
    return bicycle.simulate(t=SPAN, dt=0.05, set={"roll": ROLL, "rear_dot": SPEED / RR}, dataframe=False)


def test_the_bicycle_takes_the_numeric_route(bicycle):
    assert numeric_route(bicycle) and projection_work(bicycle) >= NUMERIC_FROM


def test_the_bicycle_follows_its_linearisation(bicycle, run):
    assert run.metadata["complete"] and run.metadata["right_hand_side"] == "C"  # projected at run time
    lin = bicycle.linearize(at={"rear_dot": SPEED / RR})
    assert [s.name for s in lin.state] == ["roll", "steer", "roll_dot", "steer_dot", "rear_dot"]
    linear = np.array([expm(lin.A * t) @ [ROLL, 0.0, 0.0, 0.0, 0.0] for t in run.t])
    for k, name in enumerate(["roll", "steer", "roll_dot", "steer_dot"]):
        assert np.max(np.abs(run[name] - linear[:, k])) < 1e-4 * ROLL, name  # second order in ROLL
    assert np.max(np.abs(run["steer"])) > 0.1 * ROLL  # the steer answers the roll
    assert np.max(np.abs(run["rear_dot"] - SPEED / RR)) < 1e-3 * SPEED / RR


def test_without_a_compiler_the_numpy_route_runs_the_same_motion(bicycle, run, monkeypatch):
    from kronsub.simulation import run as runs
    from kronsub.simulation.native import CompilerNotFound

    def missing(*args, **kwargs):
        raise CompilerNotFound("none here")

    monkeypatch.setattr(runs, "native_model", missing)
    with pytest.warns(UserWarning) as caught:
        short = bicycle.simulate(t=0.3, dt=0.05, set={"roll": ROLL, "rear_dot": SPEED / RR}, dataframe=False)
    said = " ".join(str(w.message) for w in caught)
    assert "no C compiler" in said and "using scipy's DOP853 instead" in said
    assert short.metadata["right_hand_side"] == "numpy" and short.metadata["complete"]
    for name in ("roll", "steer", "roll_dot", "steer_dot", "rear_dot", "pitch"):
        assert np.allclose(short[name], run[name][:len(short.t)], rtol=1e-6, atol=1e-8 * ROLL), name


def test_the_bicycle_keeps_its_energy_and_its_front_contact(bicycle, run):
    work = np.ptp(run["potential_energy"])  # gravity's work: of the size of the perturbation's energy
    assert work > 0.1 * 85 * 9.81 * ROLL ** 2
    assert np.max(np.abs(run["total_energy"] - run["total_energy"][0])) < 1e-6 * work
    numeric = NumericSpeeds(bicycle, _param(bicycle))
    n = len(bicycle.coordinates)
    rows = np.column_stack([run[q.name] for q in bicycle.coordinates])
    assert max(abs(numeric.rates.constraint(q, float(t))[0][0]) for t, q in zip(run.t, rows)) < 1e-12
    assert rows.shape[1] == n


def test_the_cli_writes_the_same_columns_and_metadata(bicycle, run, tmp_path):
    out = tmp_path / "bike.csv"
    result = CliRunner().invoke(main, ["simulate", str(BICYCLE), "--t", "0.2", "--dt", "0.1", "--set", f"roll={ROLL}",
                                       "--set", f"rear_dot={SPEED / RR}", "-o", str(out), "--plot",
                                       str(tmp_path / "bike.png")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "bike.png").stat().st_size > 0  # its panels sorted without forming Mbar in x
    header = out.read_text().splitlines()[0].split(",")
    assert header == list(run.table_columns)
    meta = json.loads(out.with_suffix(".json").read_text())
    assert set(meta) == set(run.metadata) and meta["columns"] == header and meta["complete"]
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    api_rows = np.column_stack([run[c][[0, 2, 4]] for c in header[1:]])
    assert np.allclose(rows[:, 1:], api_rows, rtol=1e-6, atol=1e-9)  # runs of other spans: to the tolerance
