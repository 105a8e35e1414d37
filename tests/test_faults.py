"""Faults: exit codes, interrupted and failed runs keep their rows, atomic writes (full disk,
stale temporaries, file modes), and rows streamed as they are computed."""
from __future__ import annotations

import errno
import math
from decimal import Decimal
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from click.testing import CliRunner

from conftest import MODELS
from kronsub import atomic
from kronsub.cli import EXIT_CODES, main
from kronsub.model import kept
from kronsub.model.loader import load_model
from kronsub.simulation import grid as grid_module
from kronsub.simulation import rows as rows_module
from kronsub.simulation import run as run_module
from kronsub.simulation.values import resolve

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"
SYSTEM2 = MODELS / "hoffmann" / "system2.yaml"


def cli(*args, **env):
    return CliRunner(env=env or None).invoke(main, [*map(str, args)])


def rows_of(text: str) -> np.ndarray:
    lines = text.splitlines()[1:]
    return np.array([[float(v) for v in line.split(",")] for line in lines])


def test_the_documented_exit_codes():
    assert sorted(EXIT_CODES) == [0, 1, 2, 3, 4, 129, 130, 143]
    readme = (MODELS.parent / "docs" / "cli.md").read_text()
    for code in EXIT_CODES:
        assert f"| {code} |" in readme


@pytest.mark.parametrize("args, needle", [
    (("--t", "inf"), "--t must be a positive finite time"),
    (("--t", "nan"), "--t must be a positive finite time"),
    (("--t", "-1"), "--t must be a positive finite time"),
    (("--dt", "1e-300"), "raise --dt"),
    (("--dt", "0"), "--dt must be a positive finite interval"),
    (("--dt", "inf"), "--dt must be a positive finite interval"),
    (("--method", "euler"), "unknown method"),
    (("--no-such-option",), "No such option"),
])
def test_usage_errors_exit_2_with_a_message(args, needle):
    result = cli("simulate", SYSTEM1, *args)
    assert result.exit_code == 2, result.output
    assert needle in result.output and "Traceback" not in result.output


def test_a_model_error_exits_1(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\ncoordinates: [q]\n")
    assert cli("derive", bad).exit_code == 1


def test_an_internal_error_exits_4_with_a_short_message(monkeypatch):
    from kronsub import emitters

    def broken(system):
        raise RuntimeError("deliberate fault\nsecond line")

    monkeypatch.setitem(emitters.EMITTERS, "json", broken)
    monkeypatch.setattr(kept, "load", lambda key: None)  # the emitter runs (no text kept from an earlier test)
    result = cli("derive", SYSTEM1, "--format", "json")
    assert result.exit_code == 4
    assert "internal error (RuntimeError: deliberate fault)" in result.output
    assert "report" in result.output and "KRONSUB_DEBUG=1" in result.output
    assert "Traceback" not in result.output and "second line" not in result.output
    debug = cli("derive", SYSTEM1, "--format", "json", KRONSUB_DEBUG="1")
    assert isinstance(debug.exception, RuntimeError)  # the traceback is shown
    monkeypatch.setenv("KRONSUB_DEBUG", "")  # off; restored (removed) after the test, which --debug sets
    flag = cli("--debug", "derive", SYSTEM1, "--format", "json")
    assert isinstance(flag.exception, RuntimeError)


def test_a_numerical_failure_exits_3_and_keeps_the_rows(tmp_path):
    path = tmp_path / "blowup.yaml"
    path.write_text("name: blow-up\nparameters: {m: 1}\ncomponents:\n  p: {type: particle1d, parameters: {mass: m},"
                    " coordinates: [x]}\ncoordinates: [x]\neffects:\n"
                    "  kick: {type: generalized_force, coordinate: x, value: 1/(t - 1/2)**3}\n")
    out = tmp_path / "t.csv"
    result = cli("simulate", path, "--t", "1", "--dt", "0.1", "--output", out)
    assert result.exit_code == 3, result.output
    text = out.read_text()
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "stopped" and meta["complete"] is False and meta["rows"] == len(rows_of(text))
    assert len(rows_of(text)) >= 5 and f"kept in {out}" in result.output


def test_heyoka_at_the_singular_angle_is_a_numerical_failure():
    pytest.importorskip("heyoka")
    from kronsub.simulation.heyoka_backend import available

    if not available():
        pytest.skip("heyoka is not usable")
    # (c - a1 sin theta)/a2 = 1: the lower rod is horizontal, dphi/dtheta is infinite (26)
    result = cli("simulate", SYSTEM2, "--method", "heyoka", "--t", "1", "--dt", "0.5",
                 "--set", "theta=asin((0.6-0.5)/0.5)")
    assert result.exit_code == 3, result.output
    assert "the run stopped at t = " in result.output and "Traceback" not in result.output
    assert "at t = nan" not in result.output


def _interrupt_after(monkeypatch, calls: int):
    """NativeModel.integrate raising KeyboardInterrupt (as Ctrl-C does) on call ``calls + 1``."""
    from kronsub.simulation.native import NativeModel

    real = NativeModel.integrate
    count = [0]

    def integrate(self, *args, **kwargs):
        count[0] += 1
        if count[0] > calls:
            raise KeyboardInterrupt
        return real(self, *args, **kwargs)

    monkeypatch.setattr(NativeModel, "integrate", integrate)


def test_ctrl_c_keeps_the_rows_so_far_marked_incomplete(tmp_path, monkeypatch):
    full = cli("simulate", SYSTEM1, "--t", "2", "--dt", "0.01", "--method", "gauss4")
    assert full.exit_code == 0, full.output
    monkeypatch.setattr(rows_module, "BLOCK_ROWS", 50)
    _interrupt_after(monkeypatch, 2)
    out = tmp_path / "traj.csv"
    result = cli("simulate", SYSTEM1, "--t", "2", "--dt", "0.01", "--method", "gauss4", "--output", out)
    assert result.exit_code == 130, result.output
    assert "Interrupted after t = " in result.output and "rows computed so far are kept" in result.output
    text = out.read_text()
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "interrupted" and meta["rows"] == len(rows_of(text))
    assert meta["stopped_at"] == rows_of(text)[-1, 0] and str(out.with_suffix(".json")) in result.output
    kept, reference = rows_of(text), rows_of(full.stdout)
    assert 50 <= len(kept) < len(reference)
    np.testing.assert_allclose(kept, reference[: len(kept)], rtol=1e-9, atol=1e-12)
    assert not list(tmp_path.glob(".*.tmp"))


def test_a_real_sigint_keeps_the_rows(tmp_path):
    """SIGINT to a running ``kronsub simulate`` process: exit 130, the file keeps its rows."""
    out = tmp_path / "long.csv"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "kronsub", "simulate", str(SYSTEM1), "--t", "1e5", "--dt", "0.01",
                             "--method", "gauss4", "--output", str(out)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline:
        tmps = list(tmp_path.glob(".long.csv.*.tmp"))
        if tmps and tmps[0].stat().st_size > 200_000:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    text = out.read_text()
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "interrupted" and meta["rows"] == len(rows_of(text)) > 1000
    assert not list(tmp_path.glob(".*.tmp"))


# ---------------------------------------------------------------------------------------------
# Streaming
# ---------------------------------------------------------------------------------------------

def test_rows_are_written_while_the_run_goes_on(monkeypatch):
    """Each block reaches the output before the next is computed; the rows equal an in-memory run."""
    from kronsub.simulation.table import CsvWriter

    monkeypatch.setattr(rows_module, "BLOCK_ROWS", 40)
    system = load_model(SYSTEM1).derive()
    values = resolve(system, dict(load_model(SYSTEM1).initial), {})
    run = run_module.start(system, values, 3.0, 0.01, "gauss4", progress=False)
    produced = []
    blocks = run.blocks
    run.blocks = (produced.append(b) or b for b in blocks)

    class Out:
        def __init__(self):
            self.parts, self.seen = [], []

        def write(self, text):
            self.parts.append(text)
            self.seen.append(len(produced))

    out = Out()
    writer = CsvWriter(out, system, "m.yaml", values, run.method, run.backend, 1e-10, 1e-10)
    writer.stream(run)
    assert len(produced) >= 8 and writer.rows == 301
    row_writes = [seen for text, seen in zip(out.parts, out.seen) if text and text[0].isdigit()]
    assert row_writes == list(range(1, len(produced) + 1))  # block k written before block k+1 exists
    whole = run_module.simulate(system, values, 3.0, 0.01, "gauss4", progress=False)
    np.testing.assert_allclose(rows_of("".join(out.parts))[:, 1:5], whole.y, rtol=1e-9, atol=1e-12)


def test_grid_matches_the_in_memory_grid():
    for t_end, dt in [(10.0, 0.01), (3.7, 0.013), (1.0, 0.3), (1.0, 1.0), (2.0, 0.7), (1e3, 1e-3)]:
        # every multiple of dt before t_end, then t_end (as the C integrators' dense output writes)
        grid = np.append(np.arange(math.ceil(t_end / dt - 1e-9)) * dt, t_end)
        lazy = grid_module.Grid(t_end, dt)
        # the same times, each the double nearest k dt in decimal (arange's k * dt may be an ulp off)
        ulps = 2 * np.spacing(np.maximum(np.abs(grid), dt))
        assert len(lazy) == len(grid) and np.all(np.abs(lazy[:] - grid) <= ulps)
        assert lazy[len(grid) - 1] == t_end and np.array_equal(lazy[3:len(grid)], lazy[:][3:])
        assert all(lazy[k] == float(Decimal(repr(dt)) * k) for k in range(0, len(grid) - 1, 7))
    assert list(grid_module.Grid(1.0, 5.0)[:]) == [0.0, 1.0]  # the first row is at t = 0, even when dt > t


# ---------------------------------------------------------------------------------------------
# Atomic writes
# ---------------------------------------------------------------------------------------------

def test_a_full_disk_names_the_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    real = os.fdopen

    class Full:
        def __init__(self, handle):
            self.handle = handle

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.handle.close()

        def write(self, text):
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.os, "fdopen", lambda fd, *a, **k: Full(real(fd, *a, **k)))
    out = tmp_path / "eqs.json"
    result = cli("derive", SYSTEM1, "--format", "json", "--output", out)
    assert result.exit_code == 1
    assert f"Error: {out}: No space left on device" in result.output
    assert list(tmp_path.iterdir()) == []


def test_stale_temporaries_of_our_naming_are_removed(tmp_path):
    out = tmp_path / "eqs.md"
    old = time.time() - 3600
    stale = tmp_path / ".eqs.md.abcd_123.tmp"
    fresh = tmp_path / ".eqs.md.zyxw9876.tmp"  # a write still running
    foreign = [tmp_path / ".eqs.md.tmp", tmp_path / "eqs.md.abcdefgh.tmp", tmp_path / ".other.md.abcdefgh.tmp",
               tmp_path / ".eqs.md.abcdefgh.tmp.bak"]
    for path in [stale, fresh, *foreign]:
        path.write_text("x")
        os.utime(path, (old, old))
    os.utime(fresh, None)
    (tmp_path / ".eqs.md.abcdefgh.tmp").mkdir()  # not a file: left alone
    stale.write_text("partial")
    os.utime(stale, (old, old))
    assert cli("derive", SYSTEM1, "--output", out).exit_code == 0
    assert not stale.exists()
    assert fresh.exists() and all(p.exists() for p in foreign)


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_output_files_follow_the_umask(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        out = tmp_path / "eqs.md"
        assert cli("derive", SYSTEM1, "--output", out).exit_code == 0
        csv = tmp_path / "t.csv"
        assert cli("simulate", SYSTEM1, "--t", "0.1", "--output", csv).exit_code == 0
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == mode
    assert csv.stat().st_mode & 0o777 == mode


def test_a_replaced_file_keeps_its_mode(tmp_path):
    out = tmp_path / "eqs.md"
    out.write_text("old")
    out.chmod(0o640)
    assert cli("derive", SYSTEM1, "--output", out).exit_code == 0
    assert out.stat().st_mode & 0o777 == 0o640 and out.read_text().startswith("# System I")


def test_heyoka_runs_are_streamed_in_blocks_too(monkeypatch):
    pytest.importorskip("heyoka")
    from kronsub.simulation.heyoka_backend import available

    if not available():
        pytest.skip("heyoka is not usable")
    system = load_model(SYSTEM1).derive()
    values = resolve(system, dict(load_model(SYSTEM1).initial), {})
    whole = run_module.simulate(system, values, 1.0, 0.05, "heyoka", rtol=1e-14)
    monkeypatch.setattr(rows_module, "BLOCK_ROWS", 6)
    run = run_module.start(system, values, 1.0, 0.05, "heyoka", rtol=1e-14)
    blocks = list(run)
    assert len(blocks) >= 3 and run.complete
    t = np.concatenate([b.t for b in blocks])
    assert np.array_equal(t, whole.t)
    np.testing.assert_allclose(np.concatenate([b.y for b in blocks]), whole.y, rtol=1e-10, atol=1e-12)
