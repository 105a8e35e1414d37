"""SIGTERM and SIGHUP stop a running ``simulate`` as Ctrl-C does (:mod:`kronsub.interrupts`):
the rows so far are kept, the metadata says ``status: interrupted`` and which signal, and the
exit code is 128 + the signal's number."""
from __future__ import annotations

import gc
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from conftest import MODELS
from kronsub.cli import EXIT_CODES
from kronsub.interrupts import Interrupted, exit_code, signals_as_interrupts

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"


def _rows(text: str) -> list[list[float]]:
    return [[float(v) for v in line.split(",")] for line in text.splitlines()[1:]]


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGINT, 130)])
def test_a_signal_during_a_long_simulate_keeps_the_rows_and_the_metadata(tmp_path, signum, code):
    out = tmp_path / "long.csv"
    proc = subprocess.Popen([sys.executable, "-m", "kronsub", "simulate", str(SYSTEM1), "--t", "1e5", "--dt", "0.01",
                             "--method", "gauss4", "--output", str(out)], env={**os.environ, "PYTHONUNBUFFERED": "1"},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 120
        while time.time() < deadline:  # until rows are being written
            tmps = list(tmp_path.glob(".long.csv.*.tmp"))
            if tmps and tmps[0].stat().st_size > 200_000:
                break
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.05)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err
    rows = _rows(out.read_text())
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "interrupted" and meta["complete"] is False
    assert meta["signal"] == signal.Signals(signum).name and meta["rows"] == len(rows) > 1000
    assert meta["stopped_at"] == rows[-1][0]
    assert "Interrupted" in err and "kept in" in err and "Traceback" not in err
    assert not list(tmp_path.glob(".*.tmp"))


def test_a_signal_before_the_rows_exits_with_its_code(tmp_path):
    """Stopped while deriving (no rows yet): a one-line message and 128 + signum, no traceback."""
    model = tmp_path / "m.yaml"
    model.write_text(SYSTEM1.read_text())
    code = ("import os, signal, sys\n"
            "import importlib\n"
            "from kronsub import cli\n"
            "command = importlib.import_module('kronsub.commands.simulate')\n"
            "real = command.scene_system\n"
            "def hung(*a, **k):\n"
            "    os.kill(os.getpid(), signal.SIGTERM)\n"
            "    return real(*a, **k)\n"
            "command.scene_system = hung\n"
            f"sys.argv = ['kronsub', 'simulate', {str(model)!r}, '--t', '1']\n"
            "cli.main()\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 143, proc.stderr
    assert proc.stderr.strip() == "Interrupted by SIGTERM."


def test_the_handlers_are_restored_and_an_ignored_signal_stays_ignored():
    before = signal.getsignal(signal.SIGTERM)
    old_hup = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    gc.disable()  # a handler run inside a gc callback (hypothesis installs one) has its exception swallowed
    try:
        with signals_as_interrupts():
            assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
            with pytest.raises(Interrupted) as caught:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(1)
            assert exit_code(caught.value) == 143
        assert signal.getsignal(signal.SIGTERM) is before
    finally:
        gc.enable()
        signal.signal(signal.SIGHUP, old_hup)


def test_the_signal_codes_are_documented():
    assert {129, 130, 143} <= set(EXIT_CODES)
    for doc in (MODELS.parent / "docs" / "cli.md", MODELS.parent / "docs" / "errors.md"):
        text = doc.read_text()
        for code in (129, 130, 143):
            assert f"| {code} |" in text or f"| `{code}` |" in text, (doc, code)
