"""A time limit for a block of a test: a hang becomes a failure, not a stuck run."""
from __future__ import annotations

import contextlib
import signal


class Hung(AssertionError):
    """The block ran past its time limit."""


@contextlib.contextmanager
def within(seconds: float, what: str = "the call"):
    """Fail with `Hung` when the block runs longer than ``seconds`` (main thread, POSIX).

    This bounds a test that would otherwise hang; it is not a speed assertion:
    the limits are many times the normal run time.
    """
    def expire(signum, frame):
        raise Hung(f"{what} ran longer than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
