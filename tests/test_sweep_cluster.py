"""kronsub sweep on a real Dask cluster on this machine: a `dask scheduler` and two `dask worker`
processes on 127.0.0.1 (free ports), a sweep sent with --scheduler; a worker killed mid-sweep
leaves the result complete and equal to a local run; --resume after a killed client computes
only the chunks it had not written."""
from __future__ import annotations

import functools
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")
pd = pytest.importorskip("pandas")
pytest.importorskip("pyarrow")

from kronsub.commands.common import scene_system  # noqa: E402
from kronsub.model.scenes import initial_values  # noqa: E402
from kronsub.sweep.axes import read_axes  # noqa: E402
from kronsub.sweep.chunk import run_chunk  # noqa: E402
from kronsub.sweep.study import make_job, make_plan  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SYSTEM1 = ROOT / "models" / "hoffmann" / "system1.yaml"
SPEC = ["--scene", "free", "--grid", "theta=-2:2:20", "--sample", "phi=uniform(-2, 2)", "--runs", "20",
        "--seed", "3", "--t", "20", "--chunk", "10"]  # 400 runs, 40 chunks
WAIT = 180.0  # seconds a step of the test may take on a loaded machine before it is a failure


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def spawn(*args) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True, cwd=ROOT)


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)


def until(condition, what: str) -> None:
    deadline = time.monotonic() + WAIT
    while not condition():
        assert time.monotonic() < deadline, f"waited {WAIT:.0f} s for {what}"
        time.sleep(0.05)


@pytest.fixture(scope="module")
def cluster():
    from distributed import Client

    address = f"tcp://127.0.0.1:{free_port()}"
    scheduler = spawn("-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
                      address.rsplit(":", 1)[1], "--no-dashboard")
    workers = [spawn("-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                     "--host", "127.0.0.1", "--name", f"w{i}") for i in range(2)]
    try:
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=WAIT)
        yield address, workers
    finally:
        for proc in [*workers, scheduler]:
            stop(proc)


def sweep(address: str, out: Path, *extra) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "kronsub", "sweep", str(SYSTEM1), *SPEC, "--scheduler", address,
                             "-o", str(out), *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, cwd=ROOT)


def parts(out: Path) -> list[Path]:
    return sorted(out.glob("part-*.parquet")) if out.is_dir() else []


@functools.lru_cache(maxsize=1)
def local_rows() -> pd.DataFrame:
    loaded, scene, system = scene_system(SYSTEM1, "free")
    plan = make_plan(*read_axes(("theta=-2:2:20",), ("phi=uniform(-2, 2)",)), 20, 3)
    job = make_job(system, plan, initial_values(loaded, scene), {}, method="dop853", t_end=20.0, dt=0.01,
                   rtol=1e-10, atol=1e-10, outputs=scene.outputs, chunk=400)
    return pd.concat([pd.DataFrame(run_chunk(job, i)) for i in range(job.chunks)], ignore_index=True)


def read(out: Path) -> pd.DataFrame:
    return pd.read_parquet(out).sort_values("run", ignore_index=True)


HELD_DISC = ROOT / "tests" / "models" / "nonholonomic" / "rolling_disc_height.yaml"


def test_a_model_in_speeds_on_the_workers(cluster, tmp_path):
    """The disc with its height held by a configuration constraint, in its speeds: its job (the
    equations in x not formed, deferred) goes to the worker processes, which hold each run's start
    and rows on the constraint; the rows are those of the same chunks run here."""
    address, _ = cluster
    out = tmp_path / "runs.parquet"
    grids = ("r=[0.2, 0.35]", "lean=[0.1, 0.3]")
    proc = subprocess.run([sys.executable, "-m", "kronsub", "sweep", str(HELD_DISC), *(a for g in grids for a in
                           ("--grid", g)), "--t", "1", "--dt", "0.1", "--chunk", "2", "--scheduler", address,
                           "-o", str(out)], capture_output=True, cwd=ROOT, timeout=WAIT)
    assert proc.returncode == 0, proc.stderr.decode()
    loaded, scene, system = scene_system(HELD_DISC, None)
    job = make_job(system, make_plan(*read_axes(grids, ()), None, 0), initial_values(loaded, scene), {},
                   method="dop853", t_end=1.0, dt=0.1, rtol=1e-10, atol=1e-10, chunk=2)
    here = pd.concat([pd.DataFrame(run_chunk(job, i)) for i in range(job.chunks)], ignore_index=True)
    pd.testing.assert_frame_equal(read(out), here, check_dtype=False)
    assert np.all(np.abs(here["final_z"] - here["r"] * np.cos(here["final_lean"])) < 1e-12)


def test_resume_after_a_killed_client_writes_only_the_missing_chunks(cluster, tmp_path):
    address, _ = cluster
    out = tmp_path / "runs.parquet"
    client = sweep(address, out)
    until(lambda: len(parts(out)) >= 3 or client.poll() is not None, "the first chunks")
    os.killpg(client.pid, signal.SIGKILL)
    client.wait(timeout=30)
    kept = {p.name: p.stat().st_mtime_ns for p in parts(out)}
    assert 3 <= len(kept) < 40, "the client was killed mid-sweep"
    resumed = sweep(address, out, "--resume")
    stdout, stderr = resumed.communicate(timeout=WAIT)
    assert resumed.returncode == 0, stderr.decode()
    assert f"{len(kept)} of 40 chunks already written" in stderr.decode()
    assert {p.name: p.stat().st_mtime_ns for p in parts(out) if p.name in kept} == kept  # not written again
    assert len(parts(out)) == 40
    pd.testing.assert_frame_equal(read(out), local_rows().copy(), check_dtype=False)


def test_a_worker_lost_mid_sweep_leaves_the_result_complete(cluster, tmp_path):
    address, workers = cluster
    out = tmp_path / "runs.parquet"
    client = sweep(address, out)
    until(lambda: len(parts(out)) >= 1 or client.poll() is not None, "the first chunk")
    stop(workers[0])  # killed with SIGKILL while it computes: its chunks go to the other worker
    assert len(parts(out)) < 40, "the worker was killed mid-sweep"
    stdout, stderr = client.communicate(timeout=WAIT)
    assert client.returncode == 0, stderr.decode()
    assert "400 complete" in stderr.decode()
    pd.testing.assert_frame_equal(read(out), local_rows().copy(), check_dtype=False)


def test_ctrl_c_keeps_the_finished_chunks(cluster, tmp_path):
    address, _ = cluster
    out = tmp_path / "runs.parquet"
    client = sweep(address, out)
    until(lambda: len(parts(out)) >= 2 or client.poll() is not None, "the first chunks")
    client.send_signal(signal.SIGINT)
    stdout, stderr = client.communicate(timeout=WAIT)
    kept = len(parts(out))
    assert client.returncode == 130, stderr.decode()
    assert f"Interrupted: {kept} of 40 chunks kept in {out}" in stderr.decode() and "Traceback" not in stderr.decode()
    meta = json.loads((tmp_path / "runs.parquet.json").read_text())
    assert meta["state"] == "interrupted" and meta["chunks_written"] == kept
    assert sum(meta["counts"].values()) == 10 * kept
    rows = read(out)
    pd.testing.assert_frame_equal(rows, local_rows().set_index("run").loc[rows["run"]].reset_index(), check_dtype=False)
