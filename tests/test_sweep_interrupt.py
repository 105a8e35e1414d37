"""An interrupted sweep stops its runs under way instead of waiting for whole chunks: the
compiled ensemble starts no further run once stopped (:func:`kronsub.sweep.ensemble.stop`), and
Ctrl-C or SIGTERM during a long chunk ends ``kronsub sweep`` within a run, its finished chunks
kept and the sidecar marked interrupted."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")
pytest.importorskip("pyarrow")

from kronsub.commands.common import scene_system  # noqa: E402
from kronsub.model.scenes import initial_values  # noqa: E402
from kronsub.sweep import ensemble  # noqa: E402
from kronsub.sweep.axes import read_axes  # noqa: E402
from kronsub.sweep.chunk import ENSEMBLE, TAYLOR, run_chunk  # noqa: E402
from kronsub.sweep.study import make_job, make_plan  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SYSTEM1 = ROOT / "models" / "hoffmann" / "system1.yaml"


def _job(method):
    loaded, chosen, system = scene_system(SYSTEM1, None)
    plan = make_plan(*read_axes(("m2=0.5:2:3",), ()), None, 0)
    return make_job(system, plan, initial_values(loaded, chosen), {}, method=method, t_end=0.5, dt=0.05,
                    rtol=1e-10, atol=1e-10, chunk=3)


@pytest.mark.parametrize("method, route", [("dop853", ENSEMBLE), ("rk4", ENSEMBLE), ("taylor", TAYLOR)])
def test_a_stopped_ensemble_starts_no_run_and_says_so(method, route):
    job = _job(method)
    if job.route != route:
        pytest.skip(f"{method} takes the route {job.route} here")
    ran = run_chunk(job, 0)
    try:
        ensemble.stop()
        with pytest.raises(ensemble.EnsembleStopped, match="stopped after 0 of a block's 3 runs"):
            run_chunk(job, 0)
    finally:
        ensemble.stop(False)
    again = run_chunk(job, 0)
    assert list(again["status"]) == list(ran["status"]) == ["complete"] * 3
    assert all((again[k] == ran[k]).all() for k in ran if k.startswith("final_"))


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_during_a_long_chunk_ends_the_sweep_within_a_run(tmp_path, signum, code):
    """A chunk of 1000 runs that would take minutes: the signal, sent once the chunk is under way
    (its trajectory part begun), ends the command long before the chunk could finish."""
    common = [sys.executable, "-m", "kronsub", "sweep", str(SYSTEM1), "--workers", "1", "--dt", "1"]
    warm = subprocess.run([*common, "--grid", "m2=0.5:2:2", "--t", "1", "-o", str(tmp_path / "warm")],
                          capture_output=True, text=True, timeout=300)  # the library built once
    assert warm.returncode == 0, warm.stderr
    out, rows = tmp_path / "runs", tmp_path / "rows"
    proc = subprocess.Popen([*common, "--grid", "m2=0.5:2:1000", "--t", "30000", "-o", str(out),
                             "--trajectories", str(rows)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 120
        while not list(rows.glob(".part-000000.parquet.*.tmp")):  # the chunk is being computed
            assert proc.poll() is None and time.time() < deadline, proc.communicate()
            time.sleep(0.05)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)  # the chunk alone takes many minutes
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == code, err
    assert "Interrupted" in err and "0 of 1 chunks kept" in err and "Traceback" not in err
    assert json.loads((tmp_path / "runs.json").read_text())["state"] == "interrupted"
    assert not list(out.iterdir()) and not list(rows.iterdir())  # no part, no temporary file left
