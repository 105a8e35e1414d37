"""kronsub sweep: the rows of a sweep equal the same runs done one by one with `kronsub simulate`
(final state bit for bit, min and max over the output rows, the cost), for an explicit model,
a closed loop and a scene; the same spec and seed give the same rows in any partitioning; the
command writes a Parquet dataset with its sidecar, refuses an existing output, resumes; bad
input is a located error."""
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
from kronsub.commands.common import scene_system  # noqa: E402
from kronsub.model.scenes import initial_values  # noqa: E402
from kronsub.sweep.axes import read_axes  # noqa: E402
from kronsub.sweep.chunk import ENSEMBLE, ONE_BY_ONE, TAYLOR, run_chunk  # noqa: E402
from kronsub.sweep.plan import Plan  # noqa: E402
from kronsub.sweep.study import make_job, make_plan  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SYSTEM1 = ROOT / "models" / "hoffmann" / "system1.yaml"
FOUR_BAR = ROOT / "models" / "examples" / "four_bar.yaml"
SLIDER_CRANK = ROOT / "models" / "examples" / "slider_crank.yaml"


def job_of(model, scene, grids=(), samples=(), runs=None, seed=0, method="dop853", t_end=2.0, dt=0.05, chunk=4):
    loaded, chosen, system = scene_system(model, scene)
    plan = make_plan(*read_axes(grids, samples), runs, seed)
    return make_job(system, plan, initial_values(loaded, chosen), {}, method=method, t_end=t_end, dt=dt,
                    rtol=1e-10, atol=1e-10, outputs=chosen.outputs if chosen is not None else None, chunk=chunk)


def rows_of(job) -> pd.DataFrame:
    frames = [pd.DataFrame(run_chunk(job, i)) for i in range(job.chunks)]
    return pd.concat(frames, ignore_index=True)


def simulated(tmp_path, model, scene, settings: dict, method, t_end, dt):
    """One run of `kronsub simulate`: its rows and its metadata."""
    out = tmp_path / "one.csv"
    args = ["simulate", str(model), "--t", repr(t_end), "--dt", repr(dt), "--method", method, "-o", str(out)]
    args += [a for name, value in settings.items() for a in ("--set", f"{name}={value!r}")]
    if scene is not None:
        args += ["--scene", scene]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    with open(out) as fh:
        table = list(csv.reader(fh))
    header, data = table[0], np.array(table[1:], dtype=float)
    return header, data, json.loads(out.with_suffix(".json").read_text())


@pytest.mark.parametrize("model, scene, grids, samples, method, route", [
    (SYSTEM1, None, ("theta=-2:2:2",), ("phi_dot=normal(0, 1)",), "dop853", ENSEMBLE),  # explicit, whole model
    (SYSTEM1, "pushed", ("m2=[0.5, 2]",), ("phi=uniform(-2, 2)",), "gauss4", ENSEMBLE),  # a scene, swept parameter
    (SYSTEM1, "free", (), ("theta=uniform(-2, 2)",), "rk4", ENSEMBLE),
    (SYSTEM1, "free", ("phi=-1:1:2",), ("theta_dot=uniform(-1, 1)",), "taylor", TAYLOR),
    (FOUR_BAR, None, ("theta1=1.5:2.5:2",), (), "dop853", ENSEMBLE),  # a closed loop, in the ensemble
    (FOUR_BAR, None, ("theta1=1.5:2.5:2",), (), "rk4", ENSEMBLE),
    (SLIDER_CRANK, None, ("theta=0.5:1.5:2",), (), "dop853", ONE_BY_ONE),  # coordinates: auto, one by one
], ids=["explicit", "scene-gauss4", "scene-rk4", "taylor", "closed-loop", "closed-loop-rk4", "closed-loop-auto"])
def test_sweep_rows_equal_simulate(tmp_path, model, scene, grids, samples, method, route):
    job = job_of(model, scene, grids, samples, runs=1 if samples else None, seed=11, method=method, chunk=3)
    assert job.route == route
    rows = rows_of(job)
    assert len(rows) == job.plan.count and list(rows["run"]) == list(range(job.plan.count))
    names = [q.name for q in job.system.coordinates]
    states = names + [v.name for v in job.system.velocities]
    for _, row in rows.iterrows():
        settings = {name: float(row[name]) for name in job.plan.names}
        header, data, meta = simulated(tmp_path, model, scene, settings, method, job.t_end, job.dt)
        assert row["status"] == "complete" and meta["complete"]
        assert row["t_final"] == data[-1, 0] == job.t_end
        for name in states:  # bit for bit: the same integrator on the same pieces of the grid
            assert row[f"final_{name}"] == data[-1, header.index(name)], name
        for name in names:
            assert row[f"min_{name}"] == data[:, header.index(name)].min()
            assert row[f"max_{name}"] == data[:, header.index(name)].max()
        assert row["steps"] == meta["cost"]["steps"]
        assert row["evaluations"] == (meta["cost"].get("evaluations") or 0)
        if route in (ENSEMBLE, TAYLOR) and not np.isnan(row["energy_drift"]):
            energy = data[:, header.index("total_energy")]
            assert row["energy_drift"] == energy[-1] - energy[0]


def test_energy_drift_only_where_energy_is_conserved():
    conservative = rows_of(job_of(SYSTEM1, "free", ("theta=0.5:1:2",)))
    assert np.all(np.isfinite(conservative["energy_drift"]))
    assert np.all(np.abs(conservative["energy_drift"]) < 1e-6)
    driven = rows_of(job_of(SYSTEM1, "pushed", ("theta=0.5:1:2",)))  # the force F does work
    assert np.all(np.isnan(driven["energy_drift"]))


def test_same_rows_in_any_partitioning():
    a = rows_of(job_of(SYSTEM1, "free", ("theta=-1:1:3",), ("phi=loguniform(0.1, 2)",), runs=4, seed=5, chunk=3))
    b = rows_of(job_of(SYSTEM1, "free", ("theta=-1:1:3",), ("phi=loguniform(0.1, 2)",), runs=4, seed=5, chunk=7))
    pd.testing.assert_frame_equal(a, b)
    c = rows_of(job_of(SYSTEM1, "free", ("theta=-1:1:3",), ("phi=loguniform(0.1, 2)",), runs=4, seed=6, chunk=3))
    assert not np.array_equal(a["phi"], c["phi"])


def test_draws_follow_their_distributions():
    (_, samples) = read_axes((), ("a=uniform(2, 3)", "b=normal(1, 0.5)", "c=loguniform(1e-3, 1e3)"))
    values = Plan((), tuple(samples), 20000, 1).inputs(0, 20000)
    assert 2 < values["a"].min() and values["a"].max() < 3 and abs(values["a"].mean() - 2.5) < 0.01
    assert abs(values["b"].mean() - 1) < 0.02 and abs(values["b"].std() - 0.5) < 0.02
    assert abs(np.log10(values["c"]).mean()) < 0.05 and values["c"].min() >= 1e-3
    lhs = Plan((), tuple(samples[:1]), 100, 1, latin=True).inputs(0, 100)["a"]
    assert sorted(np.floor((lhs - 2) * 100).astype(int)) == list(range(100))  # one draw per stratum


@pytest.mark.parametrize("count", [1, 2, 3, 5, 16, 17, 1000, 4099])
def test_latin_strata_are_a_permutation_evaluated_in_pieces(count):
    from kronsub.sweep.plan import strata

    whole = strata(7, 0, count, np.arange(count))
    assert sorted(whole) == list(range(count))
    pieces = np.concatenate([strata(7, 0, count, np.arange(a, min(a + 3, count))) for a in range(0, count, 3)])
    assert np.array_equal(pieces, whole)
    if count >= 16:  # another seed, another axis: another permutation
        assert not np.array_equal(strata(8, 0, count, np.arange(count)), whole)
        assert not np.array_equal(strata(7, 1, count, np.arange(count)), whole)


def test_latin_memory_follows_the_chunk_not_the_sweep():
    import tracemalloc

    (_, samples) = read_axes((), ("a=uniform(0, 1)", "b=normal(0, 1)"))
    plan = Plan((), tuple(samples), 10**9, 3, latin=True)  # a permutation of all draws would be 8 GB an axis
    plan.inputs(0, 1)  # what the draws import lazily (scipy's inverse normal), imported before the count
    tracemalloc.start()
    values = plan.inputs(10**9 - 50, 10**9)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1 << 20 and len(values["a"]) == 50 and np.all((0 < values["a"]) & (values["a"] < 1))


def test_grid_order_and_values():
    grids, _ = read_axes(("x=0:1:3", "y=log:1:100:3", "z=[1, 2*pi]"), ())
    values = Plan(tuple(grids), (), 1, 0).inputs(0, 18)
    assert list(values["x"][:6]) == [0.0] * 6 and list(values["y"][:2]) == [1.0, 1.0]
    assert values["z"][1] == 2 * np.pi and values["y"][2] == pytest.approx(10) and values["y"][4] == 100


@pytest.mark.parametrize("max_steps", [10**7, 7, 1])
def test_taylor_summaries_without_rows_equal_those_of_whole_rows(max_steps):
    """Without rows asked for, the Taylor ensemble computes the coordinates inside a step only; a run
    stopped by the step limit, whose last row lies inside a step, is run again for its whole last row."""
    from kronsub.simulation.grid import Grid
    from kronsub.sweep.chunk import inputs_of
    from kronsub.sweep.ensemble import load_taylor

    job = job_of(SYSTEM1, "free", ("theta=[0.5, 2.5]",), ("phi=uniform(-2, 2)",), runs=2, method="taylor", t_end=2.0,
                 dt=0.01)
    _, param, y0 = inputs_of(job, 0, job.plan.count)
    taylor, grid = load_taylor(job.taylor_sources), Grid(job.t_end, job.dt)
    times = grid[0:len(grid)]
    bare = taylor.run(times, job.rtol, param, y0, None, max_steps=max_steps)
    whole, rows, written = taylor.run(times, job.rtol, param, y0, None, with_rows=True, max_steps=max_steps)
    np.testing.assert_array_equal(bare, whole)
    for r in range(len(y0)):
        kept = rows[r, :written[r], 1:]
        assert np.array_equal(bare[r, 5:9], kept[-1])  # the final state: the last row, whole
        assert np.array_equal(bare[r, 9:11], kept[:, :2].min(axis=0))
        assert np.array_equal(bare[r, 11:13], kept[:, :2].max(axis=0))
    assert np.all(bare[:, 0] == (0 if max_steps > 1000 else 4)) and np.all(written[:] > 1 if max_steps > 1 else True)


def test_a_failed_run_is_a_row():
    loaded, chosen, system = scene_system(SYSTEM1, "free")  # the upper rod massless; the lower one too in run 1:
    plan = make_plan(*read_axes(("m2=[1, 0]",), ()), None, 0)  # then Mbar is singular
    job = make_job(system, plan, initial_values(loaded, chosen), {"m1": "0", "I1": "0"}, method="dop853",
                   t_end=1.0, dt=0.05, rtol=1e-10, atol=1e-10, chunk=4)
    rows = rows_of(job)
    assert list(rows["status"]) == ["complete", "stopped"]
    assert "mass matrix" in rows["reason"][1] and rows["t_final"][1] < 1.0


def run(args, **kwargs):
    return CliRunner().invoke(main, ["sweep", *map(str, args)], **kwargs)


def test_command_writes_a_dataset_refuses_and_resumes(tmp_path):
    out = tmp_path / "runs.parquet"
    args = [SYSTEM1, "--scene", "free", "--grid", "theta=-1:1:3", "--sample", "phi=uniform(-1, 1)", "--runs", "3",
            "--seed", "9", "--t", "1", "--dt", "0.05", "--chunk", "2", "--workers", "1", "-o", out]
    result = run(args)
    assert result.exit_code == 0, result.output
    table = pd.read_parquet(out).sort_values("run", ignore_index=True)
    expected = rows_of(job_of(SYSTEM1, "free", ("theta=-1:1:3",), ("phi=uniform(-1, 1)",), runs=3, seed=9,
                              t_end=1.0, dt=0.05, chunk=5))
    pd.testing.assert_frame_equal(table, expected, check_dtype=False)
    meta = json.loads((tmp_path / "runs.parquet.json").read_text())
    assert meta["state"] == "complete" and meta["counts"] == {"complete": 9} and meta["chunks"] == 5
    assert meta["identity"]["spec"]["seed"] == 9 and meta["route"] == ENSEMBLE
    again = run(args)
    assert again.exit_code == 1 and "runs.parquet exists" in again.output and "--resume" in again.output
    parts = sorted(out.glob("part-*.parquet"))
    (out / "part-000003.parquet").unlink()
    kept = {p.name: p.stat().st_mtime_ns for p in parts if p.name != "part-000003.parquet"}
    resumed = run([*args, "--resume"])
    assert resumed.exit_code == 0, resumed.output
    assert "4 of 5 chunks already written" in resumed.output
    assert json.loads((tmp_path / "runs.parquet.json").read_text())["counts"] == {"complete": 9}  # old parts + new
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("part-*.parquet") if p.name in kept} == kept
    pd.testing.assert_frame_equal(pd.read_parquet(out).sort_values("run", ignore_index=True), table)
    other = run([*args[:-2], "--seed", "10", "-o", out, "--resume"])  # another sweep is not resumed into it
    assert other.exit_code == 1 and "holds another sweep" in other.output


@pytest.mark.parametrize("option", ["-o", "--trajectories"])
def test_an_output_that_is_not_a_folder_is_refused_as_such_before_force_is_suggested(tmp_path, option):
    """A file (or a FIFO) where a sweep would write its folder of parts: the error says it is not a
    folder, and suggests nothing (`--force` would not replace it), whether or not --force is given;
    the file is left as it was."""
    blocker = tmp_path / "blocker"
    blocker.write_text("not a sweep")
    out = tmp_path / "runs.parquet"
    outputs = ["-o", blocker] if option == "-o" else ["-o", out, "--trajectories", blocker]
    for force in ([], ["--force"]):
        result = run([SYSTEM1, "--grid", "theta=-1:1:2", "--t", "0.1", "--workers", "1", *outputs, *force])
        assert result.exit_code == 1 and "blocker exists and is not a folder" in result.output, result.output
        assert f"choose another {option}" in result.output and "--force" not in result.output
    assert blocker.read_text() == "not a sweep" and not out.exists()


CRASHING = """
import ctypes, resource, sys, time
from pathlib import Path

import kronsub.sweep.driver as driver
from kronsub.cli import main

resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
out, crash_at = Path(sys.argv[1]), int(sys.argv[2])
run_chunk = driver.run_chunk


def crashing(job, index):
    if index == crash_at:  # a fault in compiled code, in a worker thread, once a part is written
        deadline = time.monotonic() + 60
        while not any(out.glob("part-*.parquet")) and time.monotonic() < deadline:
            time.sleep(0.01)
        ctypes.string_at(0)
    return run_chunk(job, index)


driver.run_chunk = crashing
main(["sweep", *sys.argv[3:], "-o", str(out)])
"""


def test_a_crash_in_a_worker_thread_keeps_the_written_chunks_and_resume_finishes(tmp_path):
    import signal
    import subprocess
    import sys

    out = tmp_path / "runs.parquet"
    args = [str(SYSTEM1), "--scene", "free", "--grid", "theta=-1:1:5", "--sample", "phi=uniform(-1, 1)", "--runs",
            "2", "--t", "1", "--dt", "0.05", "--chunk", "2", "--workers", "1"]
    crashed = subprocess.run([sys.executable, "-c", CRASHING, str(out), "3", *args], cwd=tmp_path,
                             capture_output=True, timeout=300)
    assert crashed.returncode == -signal.SIGSEGV, crashed.stderr.decode()
    kept = {p.name: p.stat().st_mtime_ns for p in out.glob("part-*.parquet")}
    assert 1 <= len(kept) <= 4 and "part-000003.parquet" not in kept
    for name in kept:  # each part written whole
        assert len(pd.read_parquet(out / name)) == 2
    assert json.loads((tmp_path / "runs.parquet.json").read_text())["state"] == "running"
    resumed = run([*args, "-o", out, "--resume"])
    assert resumed.exit_code == 0, resumed.output
    assert f"{len(kept)} of 5 chunks already written" in resumed.output
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("part-*.parquet") if p.name in kept} == kept
    expected = rows_of(job_of(SYSTEM1, "free", ("theta=-1:1:5",), ("phi=uniform(-1, 1)",), runs=2, t_end=1.0,
                              dt=0.05, chunk=10))
    pd.testing.assert_frame_equal(pd.read_parquet(out).sort_values("run", ignore_index=True), expected,
                                  check_dtype=False)
    meta = json.loads((tmp_path / "runs.parquet.json").read_text())
    assert meta["state"] == "complete" and meta["counts"] == {"complete": 10}


@pytest.mark.parametrize("extra, code, told", [
    (["--grid", "thetx=0:1:3"], 1, "--grid thetx=0:1:3: thetx: no parameter, coordinate or velocity"),
    (["--grid", "theta=1:0:3"], 1, "--grid theta=1:0:3: the grid of theta is inverted"),
    (["--grid", "theta=1:1:3"], 1, "the grid of theta is empty"),
    (["--grid", "theta=0:1:0"], 1, "must be a whole number from 1"),
    (["--grid", "theta=log:0:1:3"], 1, "a logarithmic grid of theta needs a start above 0"),
    (["--grid", "theta=0:foo:3"], 1, "--grid theta=0:foo:3:"),
    (["--sample", "theta=normal(0, -1)", "--runs", "3"], 1, "the standard deviation of theta must be above 0"),
    (["--sample", "theta=uniform(2, 1)", "--runs", "3"], 1, "uniform(2, 1) of theta is empty or inverted"),
    (["--sample", "theta=beta(2, 1)", "--runs", "3"], 1, "unknown distribution 'beta'"),
    (["--sample", "theta=uniform(1)", "--runs", "3"], 1, "uniform takes 2 arguments"),
    (["--sample", "theta=uniform(0, 1)"], 2, "--sample needs --runs N"),
    (["--grid", "theta=0:1:10000000", "--grid", "phi=0:1:10000000"], 2, "more than 1,000,000,000"),
    (["--grid", "theta=0:1:3", "--sample", "theta=uniform(0, 1)", "--runs", "2"], 1, "theta is swept twice"),
    ([], 2, "nothing to sweep"),
    (["--grid", "m1=-1:1:3"], 1, "--grid m1=-1:1:3: run 0 (m1 = -1): mass of component 'upper' must not be negative"),
    (["--grid", "a2=1:0:2"], 1, "--grid a2=1:0:2: the grid of a2 is inverted"),
    (["--grid", "a2=0:1:2", "--grid", "m1=1:2:2"], 1,
     "--grid a2=0:1:2: run 0 (a2 = 0, m1 = 1): length of component 'lower' must be positive"),
    (["--sample", "m2=normal(1, 10)", "--runs", "50"], 1, "--sample m2=normal(1, 10): run "),
])
def test_bad_input_is_a_located_error(tmp_path, extra, code, told):
    result = run([SYSTEM1, "--scene", "free", *extra, "-o", tmp_path / "out.parquet"])
    assert result.exit_code == code, result.output
    assert told in result.output and "Traceback" not in result.output
    assert not (tmp_path / "out.parquet").exists()


@pytest.mark.parametrize("how", ["option", "environment"])
def test_unreachable_scheduler_is_an_error(tmp_path, monkeypatch, how):
    import socket

    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    if how == "environment":
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", address)
    result = run([SYSTEM1, "--scene", "free", "--grid", "theta=0:1:2", "--t", "0.1",
                  *(["--scheduler", address] if how == "option" else []), "-o", tmp_path / "out.parquet"])
    assert result.exit_code == 1, result.output
    assert f"cannot reach the Dask scheduler at tcp://127.0.0.1:{port} within 5 s" in result.output


def test_without_dask_the_command_says_how_to_install(tmp_path, monkeypatch):
    import builtins

    real = builtins.__import__

    def refuse(name, *args, **kwargs):
        if name in ("distributed", "pyarrow"):
            raise ImportError(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", refuse)
    result = run([SYSTEM1, "--grid", "theta=0:1:2", "-o", tmp_path / "out.parquet"])
    assert result.exit_code == 1 and "pip install 'kronsub[sweep]'" in result.output


def test_system_sweep_returns_the_rows_as_a_dataframe():
    import kronsub

    system = kronsub.load(SYSTEM1).derive()
    rows = system.sweep(grid={"theta": [0.5, 1.0]}, sample={"phi": "uniform(-1, 1)"}, runs=2, seed=4, t=1.0, dt=0.05,
                        workers=1)
    expected = rows_of(job_of(SYSTEM1, None, ("theta=[0.5, 1.0]",), ("phi=uniform(-1, 1)",), runs=2, seed=4,
                              t_end=1.0, dt=0.05))
    pd.testing.assert_frame_equal(rows, expected)



def test_system_sweep_to_a_dataset_writes_the_rows_of_the_dataframe(tmp_path):
    """``output=``: the same rows as the DataFrame, as a Parquet dataset written a chunk at a time
    with its sidecar (counts by status); an existing one is refused unless ``force``."""
    import json

    import kronsub
    from kronsub.sweep.dataset import DatasetError

    system = kronsub.load(SYSTEM1).derive()
    options = dict(grid={"theta": [0.5, 1.0, 1.5]}, sample={"phi": "uniform(-1, 1)"}, runs=3, seed=4, t=1.0,
                   dt=0.05, workers=1, chunk=4)
    rows = system.sweep(**options)
    folder = system.sweep(**options, output=tmp_path / "runs.parquet")
    assert folder == tmp_path / "runs.parquet" and len(list(folder.glob("part-*.parquet"))) == 3  # 9 runs, 4 a chunk
    pd.testing.assert_frame_equal(pd.read_parquet(folder).reset_index(drop=True), rows, check_dtype=False)
    sidecar = json.loads((tmp_path / "runs.parquet.json").read_text())
    assert sidecar["state"] == "complete" and sidecar["counts"] == {"complete": 9} and sidecar["runs"] == 9
    with pytest.raises(DatasetError):
        system.sweep(**options, output=folder)
    assert system.sweep(**options, output=folder, force=True) == folder

def test_user_outputs_equal_the_rows_of_simulate(tmp_path):
    summaries = ("max(abs(theta))", "flip=first_time(abs(phi) > pi)", "final(theta)", "e=mean(m1*theta_dot)")
    for method, route in (("dop853", ENSEMBLE), ("dop853", ONE_BY_ONE), ("taylor", TAYLOR)):
        loaded, scene, system = scene_system(SYSTEM1, "free")
        plan = make_plan(*read_axes(("theta=[2.5, 0.3]",), ()), None, 0)
        job = make_job(system, plan, initial_values(loaded, scene), {}, method=method, t_end=5.0, dt=0.05,
                       rtol=1e-10, atol=1e-10, outputs=scene.outputs, summaries=summaries,
                       compiled=route != ONE_BY_ONE)
        assert job.route == route
        rows = rows_of(job)
        for _, row in rows.iterrows():
            header, data, _ = simulated(tmp_path, SYSTEM1, "free", {"theta": row["theta"]}, method, 5.0, 0.05)
            theta, phi = data[:, header.index("theta")], data[:, header.index("phi")]
            assert row["max(abs(theta))"] == np.max(np.abs(theta))
            assert row["final(theta)"] == theta[-1] == row["final_theta"]
            assert row["e"] == pytest.approx(np.mean(data[:, header.index("theta_dot")]), rel=1e-15)
            flips = np.flatnonzero(np.abs(phi) > np.pi)
            assert (row["flip"] == data[flips[0], 0]) if len(flips) else np.isnan(row["flip"])
        assert not np.isnan(rows["flip"][0]) and np.isnan(rows["flip"][1])  # from 2.5 rad it flips, from 0.3 never


@pytest.mark.parametrize("summary, told", [
    ("max(abs(thetx))", "unknown name 'thetx'"),
    ("largest(theta)", "'largest(theta)' is not an output"),
    ("first_time(phi)", "first_time takes one comparison"),
    ("max(phi > 1)", "max takes an expression, not a comparison"),
    ("final(__import__('os'))", "--summary final(__import__('os'))"),
    ("status=final(theta)", "the output name status is a column of every row already"),
])
def test_bad_outputs_are_located_errors(tmp_path, summary, told):
    result = run([SYSTEM1, "--scene", "free", "--grid", "theta=0:1:2", "--summary", summary, "-o",
                  tmp_path / "out.parquet"])
    assert result.exit_code == 1, result.output
    assert told in result.output and "Traceback" not in result.output


def test_plot_needs_two_grid_axes(tmp_path):
    one_axis = run([SYSTEM1, "--scene", "free", "--grid", "theta=-3:3:4", "--plot", tmp_path / "map.png", "-o",
                    tmp_path / "x"])
    assert one_axis.exit_code == 2 and "exactly two --grid axes" in one_axis.output


def study(tmp_path, body: str) -> Path:
    path = tmp_path / "STUDY.yaml"
    path.write_text(f"sweep:\n  model: {SYSTEM1}\n  scene: free\n" + body)
    return path


def test_a_sweep_file_runs_as_the_options_would(tmp_path):
    path = study(tmp_path, '  t: 1\n  dt: 0.05\n  grid: {theta: "-1:1:3", phi: [0.5, 1]}\n  chunk: 4\n'
                           '  summaries: {top: "max(abs(theta))"}\n  output: runs.parquet\n')
    result = run([path, "--workers", "1", "--plot", tmp_path / "map.png", "--plot-column", "top"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"  # a heat map over the two grid axes
    rows = pd.read_parquet(tmp_path / "runs.parquet").sort_values("run", ignore_index=True)
    loaded, scene, system = scene_system(SYSTEM1, "free")
    plan = make_plan(*read_axes(("theta=-1:1:3", "phi=[0.5, 1]"), ()), None, 0)
    job = make_job(system, plan, initial_values(loaded, scene), {}, method="dop853", t_end=1.0, dt=0.05, rtol=1e-10,
                   atol=1e-10, outputs=scene.outputs, chunk=4, summaries=("top=max(abs(theta))",))
    pd.testing.assert_frame_equal(rows, rows_of(job), check_dtype=False)


@pytest.mark.parametrize("body, told", [
    ('  grid: {theta: "1:0:3"}\n  output: o.parquet\n', "STUDY.yaml:4:17: the grid of theta is inverted"),
    ('  grid: {theta: "0:1:3"}\n  seeds: 3\n  output: o.parquet\n', "STUDY.yaml:5:3: unknown key 'seeds'"),
    ('  grid: {theta: "0:1:3"}\n  t: ten\n  output: o.parquet\n', "STUDY.yaml:5:6: t must be a number"),
    ('  grid: {theta: "0:1:3"}\n', "no output folder"),
])
def test_a_bad_sweep_file_is_a_located_error(tmp_path, body, told):
    result = run([study(tmp_path, body)])
    assert result.exit_code in (1, 2) and told in result.output, result.output


def test_a_table_of_runs(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    (tmp_path / "runs.csv").write_text("theta,m2\n0.5,1\n-1.25,2.5\n")
    pq.write_table(pa.table({"theta": [0.5, -1.25], "m2": [1.0, 2.5]}), tmp_path / "runs.parquet")
    for name in ("runs.csv", "runs.parquet"):
        loaded, scene, system = scene_system(SYSTEM1, "free")
        plan = make_plan(*read_axes(("phi=[0, 1]",), (), (str(tmp_path / name),)), None, 0)
        assert plan.count == 4 and plan.names == ("theta", "m2", "phi")
        job = make_job(system, plan, initial_values(loaded, scene), {}, method="dop853", t_end=1.0, dt=0.05,
                       rtol=1e-10, atol=1e-10, outputs=scene.outputs)
        rows = rows_of(job)
        assert list(rows["theta"]) == [0.5, 0.5, -1.25, -1.25] and list(rows["m2"]) == [1, 1, 2.5, 2.5]
        assert list(rows["phi"]) == [0, 1, 0, 1]
        header, data, _ = simulated(tmp_path, SYSTEM1, "free", {"theta": -1.25, "m2": 2.5, "phi": 1.0}, "dop853",
                                    1.0, 0.05)
        assert rows["final_theta"][3] == data[-1, header.index("theta")]


@pytest.mark.parametrize("text, told", [
    ("theta,m3\n1,2\n", "--table T.csv: column m3: m3: no parameter, coordinate or velocity"),
    ("theta,m2\n1,x\n", "--table T.csv: column m2 is not numeric: row 1 holds 'x'"),
    ("m2,m2\n1,2\n", "--table T.csv: column m2 appears 2 times"),
    ("m2,,\n1,2,3\n", "--table T.csv: column 2 has no name"),
    ("m2\n1\n-0.5\n", "--table T.csv: column m2: run 1 (m2 = -0.5): mass of component 'lower' must not be negative"),
    ("theta,m2\n1,\n", "--table T.csv: column m2, row 1: not a finite number"),
    ("theta\n", "--table T.csv: the table has no rows"),
])
def test_a_bad_table_is_a_located_error(tmp_path, monkeypatch, text, told):
    monkeypatch.chdir(tmp_path)
    Path("T.csv").write_text(text)
    result = run([SYSTEM1, "--scene", "free", "--table", "T.csv", "-o", "out.parquet"])
    assert result.exit_code == 1 and told in result.output, result.output


def test_a_worker_without_a_compiler_uses_the_numpy_module(monkeypatch, tmp_path):
    from kronsub.sweep import ensemble

    job = job_of(SYSTEM1, "free", ("theta=0.5:1:2",), t_end=1.0)
    compiled = rows_of(job)
    monkeypatch.setattr(ensemble, "_LOADED", {})  # a fresh worker
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    fallback = rows_of(job)
    assert list(fallback["status"]) == ["complete", "complete"]
    assert not np.array_equal(fallback["evaluations"], compiled["evaluations"])  # another integrator ran
    for name in ("final_theta", "final_phi", "final_theta_dot", "final_phi_dot", "max_theta", "min_phi"):
        assert np.allclose(fallback[name], compiled[name], rtol=0, atol=1e-7), name  # scipy's DOP853 on numpy


def test_progress_shows_runs_rate_and_time_left(capsys):
    from kronsub.sweep.driver import SweepProgress

    bar = SweepProgress(1000, enabled=True)
    bar.update(250)
    bar.close()
    shown = capsys.readouterr().err
    assert "250/1,000 runs" in shown and "runs/s" in shown and "s left" in shown and shown.endswith("\n")
    quiet = SweepProgress(10, enabled=False)
    quiet.update(5)
    quiet.close()
    assert capsys.readouterr().err == ""


NAMED_LIKE_ROWS = ROOT / "tests" / "models" / "sweep_names" / "pendulum_named_like_rows.yaml"


@pytest.mark.parametrize("axis, told", [
    (["--grid", "steps=1:2:2"], "--grid steps=1:2:2: steps: a sweep's row has a column steps of its own"),
    (["--sample", "run=uniform(0, 1)", "--runs", "2"], "--sample run=uniform(0, 1): run: a sweep's row has a column run"),
])
def test_a_swept_name_like_a_row_column_is_a_located_error(tmp_path, axis, told):
    """A parameter named steps, a coordinate named run: swept, their columns would replace the row's own."""
    result = run([NAMED_LIKE_ROWS, *axis, "--t", "0.1", "-o", tmp_path / "out.parquet"])
    assert result.exit_code == 1, result.output
    assert told in result.output and "hint: rename it in the model file" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "out.parquet").exists()
    rows = rows_of(job_of(NAMED_LIKE_ROWS, None, ("m=[1, 2]",), t_end=0.1))  # swept under another name: no clash
    assert list(rows["run"]) == [0, 1] and list(rows["steps"]) == [rows["steps"][0]] * 2
    assert list(rows.columns).count("run") == 1 and "final_run" in rows.columns


@pytest.mark.parametrize("method, route", [("taylor", TAYLOR), ("dop853", ENSEMBLE)])
def test_local_threads_give_the_rows_of_one_process(method, route):
    """The local cluster for runs in C is a worker of two threads in this process: the chunks run
    side by side there (the C call releases the GIL) and give the rows a single process gives."""
    from distributed import Client

    from kronsub.sweep.driver import execute, local_cluster

    job = job_of(SYSTEM1, "free", ("theta=-2:2:5",), ("phi=uniform(-2, 2)",), runs=4, seed=3, method=method,
                 t_end=1.0, dt=0.05, chunk=2)
    assert job.route == route
    parts = {}
    with local_cluster(2, threads=True) as cluster, Client(cluster, set_as_default=False) as client:
        info = client.scheduler_info()["workers"]
        assert [w["nthreads"] for w in info.values()] == [2]  # one worker, a thread per core asked for
        execute(job, range(job.chunks), parts.__setitem__, scheduler=cluster.scheduler_address)
    rows = pd.concat([pd.DataFrame(parts[i]) for i in sorted(parts)], ignore_index=True)
    pd.testing.assert_frame_equal(rows, rows_of(job))


def test_a_closed_loop_in_the_ensemble_gives_the_rows_of_one_by_one():
    """The four-bar's runs in the ensemble (each projected onto the constraints, its own Newton
    state) equal those run one by one as simulate runs them, also the runs that stop: a coupler too
    short to close the loop (the projection fails), a toggle reached mid-run (run again one by one)."""
    import dataclasses

    loaded, _, system = scene_system(FOUR_BAR, None)
    plan = make_plan(*read_axes(("l2=[0.1, 1.0]", "l3=[0.8, 0.6]", "theta1_dot=[1, 8]"), ()), None, 0)
    job = make_job(system, plan, initial_values(loaded, None), {}, method="dop853", t_end=2.0, dt=0.05, rtol=1e-10,
                   atol=1e-10, chunk=8)
    assert job.route == ENSEMBLE
    rows = pd.DataFrame(run_chunk(job, 0))
    pd.testing.assert_frame_equal(rows, pd.DataFrame(run_chunk(dataclasses.replace(job, route=ONE_BY_ONE), 0)))
    assert list(rows["status"]) == ["stopped"] * 4 + ["complete"] * 4
    assert "violates the constraints" in rows["reason"][0] and 0 < rows["t_final"][3] < 2.0  # projection; mid-run


def test_parts_are_written_without_pandas(tmp_path):
    """pyarrow.array imports pandas to ask whether its argument is a pandas object; the client
    makes its columns from their buffers, with the same types and values."""
    import subprocess
    import sys

    script = ("import sys\nfrom pathlib import Path\nimport numpy as np\nfrom kronsub.sweep.dataset import Dataset\n"
              "d = Dataset(Path(sys.argv[1]), [('run', 'int64'), ('x', 'float64'), ('status', 'string')])\n"
              "d.prepare({}, resume=False, force=False)\n"
              "d.write(0, {'run': np.arange(3), 'x': np.array([1.5, np.nan, -0.0]), 'status': ['complete', '', 'ü']})\n"
              "d.write(1, {'run': np.arange(0), 'x': np.zeros(0), 'status': []})\n"
              "assert 'pandas' not in sys.modules\n")
    done = subprocess.run([sys.executable, "-c", script, str(tmp_path / "out")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    import pyarrow as pa
    import pyarrow.parquet as pq

    assert pq.read_schema(tmp_path / "out" / "part-000000.parquet").types == [pa.int64(), pa.float64(), pa.string()]
    table = pd.read_parquet(tmp_path / "out" / "part-000000.parquet")
    assert list(table["run"]) == [0, 1, 2] and list(table["status"]) == ["complete", "", "ü"]
    assert table["x"][0] == 1.5 and np.isnan(table["x"][1]) and np.signbit(table["x"][2])
    assert len(pd.read_parquet(tmp_path / "out" / "part-000001.parquet")) == 0


def test_the_local_cluster_leaves_out_what_only_its_dashboard_would_show():
    from kronsub.sweep.driver import local_cluster

    with local_cluster(2, threads=True) as cluster:
        (worker,) = cluster.workers.values()
        assert "profile" not in worker.periodic_callbacks and worker.state.nthreads == 2
        assert worker.periodic_callbacks["tick"].callback_time >= 500


def test_requirements_over_many_runs_fail_where_one_run_at_a_time_fails():
    """first_unmet (numpy over the runs) against unmet (one run at a time, in SymPy) on random
    values: a mass, a coupling and a body's inertia tensor."""
    import sympy

    from kronsub.components.base import COUPLING, INERTIA, NONNEGATIVE, Requirement
    from kronsub.model.requirements import first_unmet, unmet

    a, b, c = sympy.symbols("a b c")
    reqs = [Requirement("mass", a - b / 2, NONNEGATIVE, None), Requirement("mutual", a * c - b**2, COUPLING, None),
            Requirement("tensor", sympy.Matrix([[a, 0, 0], [0, c, b], [0, b, a + c]]), INERTIA, None)]
    rng = np.random.default_rng(7)
    for trial in range(40):
        columns = [rng.uniform(-0.2, 2, 30), rng.uniform(-1, 1, 30), rng.uniform(0, 2, 30)]
        one_by_one = [r for r in range(30)
                      if unmet(reqs, {s: float(col[r]) for s, col in zip((a, b, c), columns)})]
        found = first_unmet(reqs, [a, b, c], columns)
        if not one_by_one:
            assert found is None
            continue
        row, req, problem = found
        assert row == one_by_one[0]
        assert problem.message in [p.message for p in unmet(reqs, {s: float(col[row]) for s, col in
                                                                    zip((a, b, c), columns)})]
    assert first_unmet(reqs[:1], [c], [np.array([-1.0])]) is None  # not in the values: not judged here
