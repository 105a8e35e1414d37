"""An interrupt stops a long call of the compiled dop853 within a step: the call runs while the
main thread waits on it (``interruptible``, as ``simulate`` asks), the library's ``ks_interrupt``
stops it, the interrupt is raised and the library is left ready for the next call."""
from __future__ import annotations

import ctypes
import os
import signal
import threading
from pathlib import Path

import numpy as np
import pytest

from helpers.deadline import Hung, within
from kronsub.model.loader import load_model
from kronsub.simulation import compiled

ROOT = Path(__file__).resolve().parent.parent
SYSTEM1 = ROOT / "models" / "hoffmann" / "system1.yaml"


@pytest.fixture(scope="module")
def native():
    return compiled.native_model(load_model(SYSTEM1).derive())


def _param(native):
    return np.array([1.0, 1.0, 0.5, 0.5, 1 / 12, 1 / 12, 9.81, 0.0])[:native.nparam]


def test_an_interrupt_stops_an_unbounded_call_and_the_next_call_runs(native):
    """No step bound (max_steps 0) and rows 1e6 s apart to 1e7 s: the call would take many
    minutes; SIGINT (from another thread, as a terminal sends it) ends it."""
    y0 = np.array([0.5, -0.2, 0.0, 0.0])
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with within(120, "an interrupted dop853 call"), pytest.raises(KeyboardInterrupt):
            native.integrate("dop853", 0.0, y0, 1e7, 1e6, _param(native), max_steps=0, interruptible=True)
    finally:
        timer.cancel()
    assert ctypes.c_int.in_dll(native._lib, "ks_interrupt").value == 0
    t, Y, result = native.integrate("dop853", 0.0, y0, 1.0, 0.5, _param(native), interruptible=True)
    again = native.integrate("dop853", 0.0, y0, 1.0, 0.5, _param(native))
    assert result.status == 0 and list(t) == [0.0, 0.5, 1.0] and np.array_equal(Y, again[1])


def test_a_deadline_stops_it_too(native):
    y0 = np.array([0.5, -0.2, 0.0, 0.0])
    with pytest.raises(Hung):
        with within(0.5, "an unbounded dop853 call"):
            native.integrate("dop853", 0.0, y0, 1e7, 1e6, _param(native), max_steps=0, interruptible=True)
