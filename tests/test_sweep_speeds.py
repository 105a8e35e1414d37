"""kronsub sweep of models in speeds (velocity constraints, the state [q; u], xdot = C(q) u + d):
each run's row equals the same run of `kronsub simulate --set ...` (final state, least and
greatest coordinates, cost, energy drift, bit for bit: the same integrator on the same pieces of
the output grid) for the rolling disc over a parameter and an initial speed, with dop853, rk4
and gauss4 (which integrates [q; u], there being no canonical form in the speeds); the disc
keeps its energy in every run; the disc with its height held by a configuration constraint
gives the plain disc's motion, its height put on the constraint at each run's start and in its
rows as simulate puts it; the Chaplygin sleigh ends straight at the speed its energy gives; a
change of velocity frame alone (a body's velocities in its own axes) gives the closed form; the Whipple bicycle, projected onto its speeds at run time in its
generated C, over the forward speed equals simulate and shows the weave: the lean grows below
the weave speed 4.29 m/s and decays between it and the capsize speed 6.02 m/s (Meijaard et al.
2007). Every sweep here runs on a Dask cluster of this machine; the job goes to the workers
without forming the bicycle's equations in the coordinates (DeferredMatrix unbuilt)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("distributed")
pd = pytest.importorskip("pandas")
pytest.importorskip("pyarrow")

from kronsub.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DISC = ROOT / "models" / "nonholonomic" / "rolling_disc.yaml"
HELD_DISC = ROOT / "tests" / "models" / "nonholonomic" / "rolling_disc_height.yaml"
BICYCLE = ROOT / "models" / "benchmarks" / "whipple_bicycle.yaml"
DISC_STATE = ["yaw", "lean", "spin", "x", "y", "yaw_dot", "lean_dot", "spin_dot"]
WEAVE, CAPSIZE = 4.29238253634111, 6.02426201538837  # m/s, Meijaard et al. (2007)


def swept(tmp_path, model, *args, name="runs.parquet"):
    out = tmp_path / name
    result = CliRunner().invoke(main, ["sweep", str(model), *map(str, args), "--workers", "1", "-o", str(out)])
    assert result.exit_code == 0, result.output
    return pd.read_parquet(out).sort_values("run", ignore_index=True), json.loads(Path(f"{out}.json").read_text())


def simulated(tmp_path, model, settings: dict, *args):
    """One run of `kronsub simulate`: its header, rows and metadata."""
    out = tmp_path / "one.csv"
    words = ["simulate", str(model), *map(str, args), "-o", str(out)]
    words += [a for name, value in settings.items() for a in ("--set", f"{name}={value!r}")]
    result = CliRunner().invoke(main, words)
    assert result.exit_code == 0, result.output
    with open(out) as fh:
        table = list(csv.reader(fh))
    return table[0], np.array(table[1:], dtype=float), json.loads(out.with_suffix(".json").read_text())


def assert_rows_are_simulate(tmp_path, model, rows, swept_names, state, coordinates, *args):
    for _, row in rows.iterrows():
        settings = {name: float(row[name]) for name in swept_names}
        header, data, meta = simulated(tmp_path, model, settings, *args)
        assert row["status"] == "complete" and meta["complete"]
        assert row["t_final"] == data[-1, 0]
        for name in state:
            assert row[f"final_{name}"] == data[-1, header.index(name)], name
        for name in coordinates:
            assert row[f"min_{name}"] == data[:, header.index(name)].min(), name
            assert row[f"max_{name}"] == data[:, header.index(name)].max(), name
        assert row["steps"] == meta["cost"]["steps"]
        assert row["evaluations"] == (meta["cost"].get("evaluations") or 0)
        energy = data[:, header.index("total_energy")]
        assert row["energy_drift"] == energy[-1] - energy[0]


@pytest.mark.parametrize("method", ["dop853", "rk4", "gauss4"])
def test_disc_rows_equal_simulate_and_keep_the_energy(tmp_path, method):
    args = ("--t", 1.0, "--dt", 0.01, "--method", method)
    rows, meta = swept(tmp_path, DISC, "--grid", "r=[0.2, 0.3]", "--grid", "spin_dot=[6, 9]", *args)
    assert meta["route"] == "ensemble" and len(rows) == 4
    assert [c for c in meta["columns"] if c.startswith("final_")] == [f"final_{n}" for n in DISC_STATE]  # [q; u]
    assert_rows_are_simulate(tmp_path, DISC, rows, ("r", "spin_dot"), DISC_STATE, DISC_STATE[:5], *args)
    # rolling does no work: T + V stays, to the integrator's error (fixed steps of 0.01: looser)
    energy = 0.5 * 9.81 * rows["r"]  # of the order of the potential energy, m g r cos(lean)
    bound = 1e-8 if method == "dop853" else 1e-6
    assert np.all(np.abs(rows["energy_drift"]) < bound * energy)


def test_disc_trajectories_are_simulate_rows(tmp_path):
    folder = tmp_path / "rows.parquet"
    rows, _ = swept(tmp_path, DISC, "--grid", "lean_dot=[-0.5, 0.5]", "--t", 1.0, "--dt", 0.1,
                    "--trajectories", folder)
    kept = pd.read_parquet(folder).sort_values(["run", "t"], ignore_index=True)
    assert list(kept.columns) == ["run", "t", *DISC_STATE]
    for run, value in enumerate(rows["lean_dot"]):
        header, data, _ = simulated(tmp_path, DISC, {"lean_dot": float(value)}, "--t", 1.0, "--dt", 0.1)
        mine = kept[kept["run"] == run]
        np.testing.assert_array_equal(mine[["t", *DISC_STATE]].to_numpy(), data[:, :len(DISC_STATE) + 1])
        assert header[:len(DISC_STATE) + 1] == ["t", *DISC_STATE]


def test_sleigh_ends_straight_at_the_speed_its_energy_gives(tmp_path):
    """The Chaplygin sleigh's speeds v, w (named quasi-velocities): every run ends moving straight
    (w -> 0) at the forward speed its kinetic energy gives, m v^2 = m v0^2 + (I + m a^2) w0^2, a
    user output written in the speeds, and a run equal to simulate."""
    sleigh = ROOT / "models" / "nonholonomic" / "chaplygin_sleigh.yaml"
    args = ("--t", 60.0, "--dt", 1.0)
    rows, _ = swept(tmp_path, sleigh, "--grid", "a=[0.1, 0.3]", "--grid", "w=[-2, 3]", "--summary", "top=max(abs(w))",
                    *args)
    m, inertia, v0 = 1.0, 0.05, 0.5
    assert np.all(rows["status"] == "complete")
    np.testing.assert_array_equal(rows["top"], np.abs(rows["w"]))  # w only decays
    np.testing.assert_allclose(rows["final_w"], 0.0, atol=1e-3)
    expected = np.sqrt(v0 ** 2 + (inertia + m * rows["a"] ** 2) * rows["w"] ** 2 / m)
    np.testing.assert_allclose(rows["final_v"], expected, rtol=1e-6)
    assert_rows_are_simulate(tmp_path, sleigh, rows.iloc[[3]], ("a", "w"), ["x", "y", "theta", "v", "w"],
                             ["x", "y", "theta"], *args)


FRAME = """\
name: body in its own axes
parameters: {m: 1.0, I: 0.2, g: 9.81}
components:
  body: {type: planar_body, parameters: {mass: m, inertia: I}}
coordinates: [x, y, theta]
connection: {body.x: x, body.y: y, body.angle: theta}
speeds:
  v: cos(theta)*x_dot + sin(theta)*y_dot
  w: -sin(theta)*x_dot + cos(theta)*y_dot
  r: theta_dot
effects:
  gravity: {type: gravity, g: g, direction: [0, -1]}
initial: {v: 1.0, r: 2.0}
"""


def test_speeds_alone_sweep_the_closed_form(tmp_path):
    """A change of velocity frame without constraint (the body's velocities in its own axes): a
    thrown body spinning at r, its speeds v, w in its axes at t are those of (1, -g t) turned by
    -r t (the closed form), swept over r and g."""
    model = tmp_path / "frame.yaml"
    model.write_text(FRAME)
    rows, _ = swept(tmp_path, model, "--grid", "r=[1, 3]", "--grid", "g=[9.81, 1.6]", "--t", 1.0, "--dt", 0.1)
    t, r, g = 1.0, rows["r"], rows["g"]
    np.testing.assert_allclose(rows["final_theta"], r * t, rtol=1e-12)
    np.testing.assert_allclose(rows["final_y"], -g * t ** 2 / 2, rtol=1e-9)
    np.testing.assert_allclose(rows["final_v"], np.cos(r * t) - g * t * np.sin(r * t), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(rows["final_w"], -np.sin(r * t) - g * t * np.cos(r * t), rtol=1e-9, atol=1e-9)
    assert_rows_are_simulate(tmp_path, model, rows.iloc[[2]], ("r", "g"), ["x", "y", "theta", "v", "w", "r"],
                             ["x", "y", "theta"], "--t", 1.0, "--dt", 0.1)


def test_held_height_follows_each_run_and_gives_the_plain_disc(tmp_path):
    """z is held by `touches: z - r cos(lean)`: each run's start (r swept, lean swept) puts it
    there, as simulate does, and the motion is the plain disc's (a route independent of the
    held coordinate's Newton method)."""
    args = ("--t", 1.0, "--dt", 0.1, "--grid", "r=[0.2, 0.35]", "--grid", "lean=[0.1, 0.3]")
    rows, _ = swept(tmp_path, HELD_DISC, *args)
    assert np.all(rows["status"] == "complete")
    held_state = ["yaw", "spin", "x", "y", "lean", "z", "yaw_dot", "lean_dot", "spin_dot"]
    for _, row in rows.iterrows():  # on the constraint at the end, to Newton's tolerance
        assert abs(row["final_z"] - row["r"] * np.cos(row["final_lean"])) < 1e-12
    plain, _ = swept(tmp_path, DISC, "--t", 1.0, "--dt", 0.1, "--grid", "r=[0.2, 0.35]", "--grid", "lean=[0.1, 0.3]",
                     name="plain.parquet")
    for name in DISC_STATE:
        np.testing.assert_allclose(rows[f"final_{name}"], plain[f"final_{name}"], rtol=1e-7, atol=1e-8)
    np.testing.assert_allclose(rows["energy_drift"], 0, atol=1e-8)
    header, data, meta = simulated(tmp_path, HELD_DISC, {"r": 0.2, "lean": 0.3}, "--t", 1.0, "--dt", 0.1)
    row = rows[(rows["r"] == 0.2) & (rows["lean"] == 0.3)].iloc[0]
    for name in held_state:  # the run as simulate makes it, its rows on the constraint as simulate puts them
        assert row[f"final_{name}"] == data[-1, header.index(name)], name
    for name in held_state[:6]:
        assert row[f"min_{name}"] == data[:, header.index(name)].min(), name
        assert row[f"max_{name}"] == data[:, header.index(name)].max(), name
    assert row["energy_drift"] == data[-1, header.index("total_energy")] - data[0, header.index("total_energy")]


def test_bicycle_sweep_equals_simulate_and_shows_the_weave(tmp_path):
    radius = 0.3  # rR: rear_dot = v / rR
    speeds = [3.0, 5.1]  # below the weave speed, between it and the capsize speed
    assert speeds[0] < WEAVE < speeds[1] < CAPSIZE
    args = ("--t", 3.0, "--dt", 0.05)
    folder = tmp_path / "rows.parquet"
    rows, meta = swept(tmp_path, BICYCLE, "--grid", f"rear_dot=[{speeds[0] / radius!r}, {speeds[1] / radius!r}]",
                       "--set", "roll=0.01", "--trajectories", folder, *args)
    assert meta["route"] == "ensemble"
    state = ["x", "y", "yaw", "roll", "rear", "steer", "front", "pitch", "roll_dot", "steer_dot", "rear_dot"]
    for _, row in rows.iterrows():
        header, data, _ = simulated(tmp_path, BICYCLE, {"rear_dot": float(row["rear_dot"]), "roll": 0.01}, *args)
        for name in state:
            assert row[f"final_{name}"] == data[-1, header.index(name)], name
        for name in state[:8]:
            assert row[f"min_{name}"] == data[:, header.index(name)].min(), name
            assert row[f"max_{name}"] == data[:, header.index(name)].max(), name
        assert row["energy_drift"] == data[-1, header.index("total_energy")] - data[0, header.index("total_energy")]
        assert abs(row["energy_drift"]) < 1e-8 * data[0, header.index("total_energy")]
    kept = pd.read_parquet(folder)  # the weave is the oscillation of the lean (the capsize mode is slow there)
    rate = [[kept[(kept["run"] == run) & (kept["t"] >= a) & (kept["t"] <= b)]["roll_dot"].abs().max()
             for a, b in ((0.0, 1.0), (2.0, 3.0))] for run in (0, 1)]
    assert rate[0][1] > 5 * rate[0][0]  # below the weave speed it grows (27-fold here)
    assert rate[1][1] < 0.5 * rate[1][0]  # above it, it decays (to 0.38 here)
    assert np.max(np.abs(kept[kept["run"] == 0]["roll"])) > 0.1  # the lean of 0.01 grew tenfold


def test_notebook_sweep_of_the_disc_is_the_command_s(tmp_path):
    """`System.sweep` of a model in speeds: the rows `kronsub sweep` writes, a speed set for all."""
    import kronsub

    system = kronsub.load(DISC).derive()
    mine = system.sweep(grid={"r": [0.2, 0.3]}, set={"yaw_dot": 0.25}, t=0.5, dt=0.1, workers=1)
    theirs, _ = swept(tmp_path, DISC, "--grid", "r=[0.2, 0.3]", "--set", "yaw_dot=0.25", "--t", 0.5, "--dt", 0.1)
    pd.testing.assert_frame_equal(mine, theirs, check_dtype=False)
    assert list(mine["final_spin_dot"]) != [8.0, 8.0] and "final_x_dot" not in mine


def test_a_held_value_set_for_all_runs_is_checked_in_each(tmp_path):
    """--set z with r swept: the runs where z is off the constraint by more than simulate allows
    are rows that say so (simulate refuses the same run), the others run."""
    rows, _ = swept(tmp_path, HELD_DISC, "--grid", "r=[0.2, 0.3]", "--set", "z=0.2985", "--t", 0.1)
    assert list(rows["status"]) == ["stopped", "complete"]
    assert "away from the configuration constraints 'touches'" in rows["reason"][0]
    result = CliRunner().invoke(main, ["simulate", str(HELD_DISC), "--set", "r=0.2", "--set", "z=0.2985", "--t", "0.1",
                                       "-o", str(tmp_path / "one.csv")])
    assert result.exit_code == 1 and "away from the configuration constraints 'touches'" in result.output


def test_requirements_are_checked_per_run(tmp_path):
    result = CliRunner().invoke(main, ["sweep", str(DISC), "--grid", "m=[1, -1]", "--t", "0.1",
                                       "-o", str(tmp_path / "runs.parquet")])
    assert result.exit_code == 1 and "run 1 (m = -1): mass of component 'disc' must not be negative" in result.output
    assert not (tmp_path / "runs.parquet").exists()


def test_a_bicycle_job_travels_without_forming_its_equations_in_x():
    """What Dask sends each worker (the job, cloudpickled): the bicycle's Mbar and hbar in x, which
    its runs never read, stay deferred there and here (forming them takes minutes); the job that
    arrives runs the same rows."""
    import cloudpickle

    from kronsub.commands.common import scene_system
    from kronsub.core.deferred import pending
    from kronsub.model.scenes import initial_values
    from kronsub.sweep.axes import read_axes
    from kronsub.sweep.chunk import run_chunk
    from kronsub.sweep.study import make_job, make_plan

    loaded, scene, system = scene_system(BICYCLE, None)
    job = make_job(system, make_plan(*read_axes(("rear_dot=[17]",), ()), None, 0), initial_values(loaded, scene),
                   {"roll": "0.01"}, method="dop853", t_end=0.5, dt=0.1, rtol=1e-10, atol=1e-10)
    sent = cloudpickle.loads(cloudpickle.dumps(job))
    assert pending(system.mass_matrix) and pending(system.velocity_terms)
    assert pending(sent.system.mass_matrix) and pending(sent.system.velocity_terms)
    pd.testing.assert_frame_equal(pd.DataFrame(run_chunk(sent, 0)), pd.DataFrame(run_chunk(job, 0)))
