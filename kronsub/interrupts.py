"""Termination signals treated as Ctrl-C: SIGTERM and SIGHUP raise :class:`Interrupted`.

Python turns SIGINT into ``KeyboardInterrupt``; :func:`signals_as_interrupts` makes SIGTERM
(``kill``, a CI job's timeout, a container stopping) and SIGHUP (a closed terminal) raise
:class:`Interrupted`, a ``KeyboardInterrupt`` that knows its signal, so a run keeps its rows and
says it was interrupted whichever of them stopped it. The exit code is ``128 + signum``
(:func:`exit_code`): 130, 143, 129.
"""
from __future__ import annotations

import contextlib
import signal
import threading

HELD = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
"""The signals that interrupt a run (and that :mod:`kronsub.simulation.trajectory_file` holds off while a
block of rows is written)."""


class Interrupted(KeyboardInterrupt):
    """A run stopped by SIGTERM or SIGHUP (``signum``), as Ctrl-C stops it."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(signal_name(signum))


def signal_of(exc: BaseException) -> int:
    """The signal an interrupt came from (SIGINT for Ctrl-C's ``KeyboardInterrupt``)."""
    return getattr(exc, "signum", signal.SIGINT)


def signal_name(signum: int) -> str:
    """``SIGTERM`` for 15 (the number where it has no name)."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def exit_code(exc: BaseException) -> int:
    """``128 + signum``, as a shell reports a process its signal ended."""
    return 128 + int(signal_of(exc))


def _raise(signum, frame):
    raise Interrupted(signum)


@contextlib.contextmanager
def handled(which, handler):
    """``handler`` for each signal of :data:`HELD` that ``which(signum)`` accepts, during the
    block; the previous handlers restored after. Yields them (signum -> handler)."""
    previous = {}
    try:
        for signum in HELD:
            if which(signum):
                previous[signum] = signal.signal(signum, handler)
    except (ValueError, OSError):  # no signals here (an embedded interpreter)
        pass
    try:
        yield previous
    finally:
        for signum, old in previous.items():
            signal.signal(signum, old)


@contextlib.contextmanager
def signals_as_interrupts():
    """SIGTERM and SIGHUP raise :class:`Interrupted` inside the block (main thread only; a
    signal someone set to be ignored stays ignored)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    with handled(lambda signum: signum != signal.SIGINT and signal.getsignal(signum) is not signal.SIG_IGN,
                 _raise):
        yield


__all__ = ["HELD", "Interrupted", "exit_code", "handled", "signal_name", "signal_of", "signals_as_interrupts"]
