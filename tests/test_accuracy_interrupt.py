"""An interrupt (Ctrl-C, SIGTERM) while ``kronsub accuracy`` measures its points keeps the points
measured so far: the CSV has them, the metadata says ``interrupted`` and by which signal, the exit
code is 128 + the signal's number. The API raises the interrupt unless asked to keep them."""
from __future__ import annotations

import json
import signal
from pathlib import Path

import pytest
from click.testing import CliRunner

import kronsub
import kronsub.simulation.accuracy as acc
from kronsub.cli import main
from kronsub.interrupts import Interrupted

ROOT = Path(__file__).resolve().parent.parent
SYSTEM1 = ROOT / "models" / "hoffmann" / "system1.yaml"


def _interrupt_at(monkeypatch, call: int, signum: int):
    """The ``call``-th timed run of a point raises the interrupt of ``signum``."""
    timed, calls = acc._timed, [0]

    def counted(*args, **kwargs):
        calls[0] += 1
        if calls[0] == call:
            raise KeyboardInterrupt() if signum == signal.SIGINT else Interrupted(signum)
        return timed(*args, **kwargs)

    monkeypatch.setattr(acc, "_timed", counted)


@pytest.mark.parametrize("signum, code, said", [(signal.SIGTERM, 143, "Interrupted by SIGTERM"),
                                                (signal.SIGINT, 130, "Interrupted:")])
def test_the_points_before_an_interrupt_are_kept_and_marked(tmp_path, monkeypatch, signum, code, said):
    _interrupt_at(monkeypatch, 4, signum)
    out = tmp_path / "wp.csv"
    result = CliRunner().invoke(main, ["accuracy", str(SYSTEM1), "--t", "0.2", "--methods", "dop853,rk4",
                                       "--tolerances", "1e-4:1e-8", "--quick", "-o", str(out),
                                       "--plot", str(tmp_path / "wp.png")])
    assert result.exit_code == code, result.output
    assert f"{said}" in result.output and f"the 3 points measured so far kept in {out}" in result.output
    assert "Traceback" not in result.output
    rows = out.read_text().splitlines()
    assert len(rows) == 1 + 3 and all(",ok" in row for row in rows[1:])
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "interrupted" and meta["interrupted_by"] == signal.Signals(signum).name
    assert not (tmp_path / "wp.png").exists() and not list(tmp_path.glob(".*"))


def test_a_complete_measurement_says_so(tmp_path):
    out = tmp_path / "wp.csv"
    result = CliRunner().invoke(main, ["accuracy", str(SYSTEM1), "--t", "0.2", "--methods", "dop853",
                                       "--tolerances", "1e-6", "--quick", "-o", str(out)])
    assert result.exit_code == 0, result.output
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "complete" and meta["interrupted_by"] is None


def test_the_api_raises_the_interrupt_unless_asked_to_keep_the_points(monkeypatch):
    system = kronsub.load(SYSTEM1).derive(scene="free")
    _interrupt_at(monkeypatch, 2, signal.SIGTERM)
    with pytest.raises(Interrupted):
        system.accuracy(t=0.2, methods="dop853", tolerances="1e-4:1e-6", quick=True)
    _interrupt_at(monkeypatch, 2, signal.SIGTERM)
    kept = system.accuracy(t=0.2, methods="dop853", tolerances="1e-4:1e-6", quick=True, keep_interrupted=True)
    assert kept.measurement.interrupted == signal.SIGTERM and len(kept.measurement.points) == 1
