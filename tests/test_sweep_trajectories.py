"""kronsub sweep --trajectories DIR: each run's rows in the dataset the workers write equal the
CSV of `kronsub simulate` for that run, bit for bit (the same integrator on the same pieces of
the grid, the same snapping of times; closed loops by the very code simulate runs), for an
explicit model on the compiled ensemble and on the Taylor integrator, and a closed loop run by
run; the command refuses an existing DIR, and --resume writes only the missing parts."""
from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("distributed")
pd = pytest.importorskip("pandas")
pytest.importorskip("pyarrow")

from kronsub.cli import main  # noqa: E402
from kronsub.commands.common import scene_system  # noqa: E402
from kronsub.model.scenes import initial_values  # noqa: E402
from kronsub.sweep.axes import read_axes  # noqa: E402
from kronsub.sweep.chunk import ENSEMBLE, TAYLOR, run_chunk  # noqa: E402
from kronsub.sweep.study import make_job, make_plan  # noqa: E402
from kronsub.sweep.trajectories import trajectory_columns  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SYSTEM1 = ROOT / "models" / "hoffmann" / "system1.yaml"
FOUR_BAR = ROOT / "models" / "examples" / "four_bar.yaml"


def simulated(folder: Path, model, scene, settings: dict, method: str, t_end: float, dt: float):
    """`kronsub simulate` of one run: its header and rows."""
    out = folder / "one.csv"
    args = ["simulate", str(model), "--t", repr(t_end), "--dt", repr(dt), "--method", method, "-o", str(out)]
    args += [a for name, value in settings.items() for a in ("--set", f"{name}={value!r}")]
    args += ["--scene", scene] if scene is not None else []
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    with open(out) as fh:
        table = list(csv.reader(fh))
    return table[0], np.array(table[1:], dtype=float)


@pytest.mark.parametrize("model, scene, grids, method, route", [
    (SYSTEM1, None, ("theta=-2:2:3",), "dop853", ENSEMBLE),  # explicit, the whole model
    (SYSTEM1, "pushed", ("m2=[0.5, 2]",), "gauss4", ENSEMBLE),  # a scene, a swept parameter, velocities from p
    (SYSTEM1, "free", ("phi=[0.3, 2.5]",), "taylor", TAYLOR),
    (FOUR_BAR, None, ("theta1=1.5:2.5:2",), "dop853", ENSEMBLE),  # a closed loop: with rows, one by one
], ids=["explicit", "scene-gauss4", "taylor", "closed-loop"])
def test_each_runs_trajectory_equals_simulate(tmp_path, model, scene, grids, method, route):
    loaded, chosen, system = scene_system(model, scene)
    plan = make_plan(*read_axes(grids, ()), None, 0)
    job = make_job(system, plan, initial_values(loaded, chosen), {}, method=method, t_end=1.5, dt=0.05, rtol=1e-10,
                   atol=1e-10, outputs=chosen.outputs if chosen is not None else None, chunk=2)
    assert job.route == route
    folder = tmp_path / "rows.parquet"
    folder.mkdir()
    job = dataclasses.replace(job, trajectories=str(folder))
    summaries = pd.concat([pd.DataFrame(run_chunk(job, i)) for i in range(job.chunks)], ignore_index=True)
    assert sorted(p.name for p in folder.iterdir()) == [f"part-{i:06d}.parquet" for i in range(job.chunks)]
    rows = pd.read_parquet(folder)
    names = [name for name, _ in trajectory_columns(system, job.outputs)]
    assert list(rows.columns) == names and rows["run"].dtype == np.int64
    assert sorted(set(rows["run"])) == list(range(plan.count))
    for _, summary in summaries.iterrows():
        settings = {name: float(summary[name]) for name in plan.names}
        header, data = simulated(tmp_path, model, scene, settings, method, job.t_end, job.dt)
        mine = rows[rows["run"] == summary["run"]]
        assert len(mine) == len(data) == 31
        for name in names[1:]:  # t, coordinates, velocities (and the dependent coordinates), bit for bit
            assert np.array_equal(mine[name].to_numpy(), data[:, header.index(name)], equal_nan=True), name
        last = mine.iloc[-1]
        assert all(summary[f"final_{v.name}"] == last[v.name] for v in system.velocities)
    if system.implicit is not None:
        assert [d.name for d in system.implicit.dependent] == names[-len(system.implicit.dependent):]


def sweep(args):
    return CliRunner().invoke(main, ["sweep", *map(str, args)])


def test_the_command_writes_refuses_and_resumes_only_missing_parts(tmp_path):
    out, traj = tmp_path / "runs.parquet", tmp_path / "rows.parquet"
    args = [SYSTEM1, "--scene", "free", "--grid", "theta=-1:1:3", "--grid", "phi=[0.5, 1]", "--t", "1",
            "--dt", "0.1", "--chunk", "2", "--workers", "1", "-o", out, "--trajectories", traj]
    first = sweep(args)
    assert first.exit_code == 0, first.output
    rows = pd.read_parquet(traj).sort_values(["run", "t"], ignore_index=True)
    summaries = pd.read_parquet(out).sort_values("run", ignore_index=True)
    assert len(rows) == 6 * 11 and list(rows.groupby("run").size()) == [11] * 6
    finals = rows.groupby("run").last()
    assert np.array_equal(finals["theta"].to_numpy(), summaries["final_theta"].to_numpy())
    assert np.array_equal(finals["phi_dot"].to_numpy(), summaries["final_phi_dot"].to_numpy())
    meta = json.loads((tmp_path / "rows.parquet.json").read_text())
    assert meta["state"] == "complete" and meta["chunks_written"] == 3 and meta["columns"][:2] == ["run", "t"]
    assert json.loads((tmp_path / "runs.parquet.json").read_text())["trajectories"] == str(traj)

    refused = sweep([*args[:-4], "-o", tmp_path / "other.parquet", "--trajectories", traj])  # DIR exists
    assert refused.exit_code == 1 and "rows.parquet exists" in refused.output and "--resume" in refused.output
    assert not (tmp_path / "other.parquet").exists()

    (traj / "part-000000.parquet").unlink()  # chunk 0 lost its trajectories, chunk 2 its summaries
    (out / "part-000002.parquet").unlink()
    before = {p: p.stat().st_mtime_ns for p in [*out.iterdir(), *traj.iterdir()]}
    resumed = sweep([*args, "--resume"])
    assert resumed.exit_code == 0, resumed.output
    assert "1 of 3 chunks already written" in resumed.output
    for untouched in (out / "part-000001.parquet", traj / "part-000001.parquet"):  # chunk 1 was whole
        assert untouched.stat().st_mtime_ns == before[untouched]
    assert (traj / "part-000000.parquet").exists() and (out / "part-000002.parquet").exists()
    pd.testing.assert_frame_equal(pd.read_parquet(traj).sort_values(["run", "t"], ignore_index=True), rows)
    pd.testing.assert_frame_equal(pd.read_parquet(out).sort_values("run", ignore_index=True), summaries)

    study = tmp_path / "STUDY.yaml"  # the same sweep from a sweep file, replacing both folders
    study.write_text(f"sweep:\n  model: {SYSTEM1}\n  scene: free\n  t: 1\n  dt: 0.1\n  chunk: 2\n"
                     '  grid: {theta: "-1:1:3", phi: [0.5, 1]}\n  output: runs.parquet\n  trajectories: rows.parquet\n')
    (traj / "part-000001.parquet").unlink()
    forced = sweep([study, "--workers", "1", "--force"])
    assert forced.exit_code == 0, forced.output
    pd.testing.assert_frame_equal(pd.read_parquet(traj).sort_values(["run", "t"], ignore_index=True), rows)


def test_trajectories_inside_the_output_are_refused(tmp_path):
    result = sweep([SYSTEM1, "--grid", "theta=0:1:2", "-o", tmp_path / "runs.parquet", "--trajectories",
                    tmp_path / "runs.parquet" / "rows"])
    assert result.exit_code == 2 and "one inside the other" in result.output and "Traceback" not in result.output


def test_a_coordinate_named_like_a_trajectory_column_is_refused(tmp_path):
    """The coordinate run beside the rows' own run column: refused before any folder is made."""
    model = ROOT / "tests" / "models" / "sweep_names" / "pendulum_named_like_rows.yaml"
    result = sweep([model, "--grid", "m=1:2:2", "--t", "0.1", "-o", tmp_path / "runs.parquet", "--trajectories",
                    tmp_path / "rows.parquet"])
    assert result.exit_code == 1, result.output
    assert "the trajectories would have two columns named run" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "runs.parquet").exists() and not (tmp_path / "rows.parquet").exists()


def test_system_sweep_keeps_the_trajectories_and_user_outputs(tmp_path):
    import kronsub
    from kronsub.sweep.dataset import DatasetError

    system = kronsub.load(SYSTEM1).derive(scene="free")
    folder = tmp_path / "rows.parquet"
    rows = system.sweep(grid={"theta": [0.5, 1.0, 1.5]}, t=0.5, dt=0.1, method="taylor", workers=1, chunk=2,
                        trajectories=folder, summaries=["top=max(abs(phi))"])
    kept = pd.read_parquet(folder).sort_values(["run", "t"], ignore_index=True)
    assert sorted(p.name for p in folder.iterdir()) == ["part-000000.parquet", "part-000001.parquet"]
    assert list(kept.groupby("run").size()) == [6, 6, 6] and list(kept["theta"][::6]) == [0.5, 1.0, 1.5]
    last = kept.groupby("run").last()
    for name in ("theta", "phi", "theta_dot", "phi_dot"):  # each run's last row is its final state
        assert np.array_equal(last[name].to_numpy(), rows[f"final_{name}"].to_numpy()), name
    assert np.array_equal(kept.groupby("run")["phi"].agg(lambda v: np.abs(v).max()).to_numpy(), rows["top"].to_numpy())
    assert json.loads((tmp_path / "rows.parquet.json").read_text())["state"] == "complete"
    with pytest.raises(DatasetError, match="exists"):
        system.sweep(grid={"theta": [0.5]}, t=0.5, dt=0.1, workers=1, trajectories=folder)
