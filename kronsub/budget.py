"""One bound on the work of a command, so that no small model can take minutes or all memory.

The steps whose cost a model controls (reading an expression, expanding definitions,
expanding products of sines and cosines, choosing a printed form...) `charge` a count
of what they build (terms, nodes, operations) against the active `WorkBudget`. Counts
are deterministic, so the same model stops at the same place on any machine; CPU time
(`cpu_backstop`, around reading and deriving) is a backstop for work inside sympy that
no count sees. When the budget is spent, `charge` raises
`WorkBudgetExceeded` naming what grew; the layer that knows the place in the model file
re-raises it there with `WorkBudgetExceeded.at`, and the CLI prints it as any located
error (exit 1) with a hint: ``--budget``, a cache, a simpler form.

Usage::

    with budget.limited(units=10**7):      # a command (the CLI's ``--budget``)
        ...
    with budget.scope():                   # a library entry point: the active budget, or a default one
        budget.charge(len(a) * len(b), "terms of a product of sines and cosines")
"""
from __future__ import annotations

import signal
import threading
import time
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Iterator

from .errors import Location, ModelError, Problem

DEFAULT_UNITS = 20_000_000
"""The work budget of one command when none is given (``--budget``), in units of work:
one unit is about one term, node or operation formed (one to a few microseconds)."""

GROWS_FROM = 120
"""Coordinates of a primitive system beyond which a default budget grows, with their cube (the
derivation's work grows about so: ``Mbar = Cᵀ M C`` (9') of n coordinates); `allow_for`."""

SECONDS_PER_MILLION = 3.0
"""CPU seconds of the backstop (`cpu_backstop`) per million units of the budget, at least
`MIN_SECONDS`: work the counts do not see (inside sympy) still stops."""
MIN_SECONDS = 60.0

PER_OPERATION = {"print": 25, "factor": 25, "evaluate": 100}
"""Units charged per operation of an expression (``count_ops``, a definition used twice counted
twice) by the steps that walk it whole: printing it, sympy's ``factor_terms``, and sympy's
evaluation of a function or power of it as it is built (its assumptions: is it real, positive...)."""

HINT = ("raise the budget with --budget UNITS (default {default:,}), keep the derivation in a "
        "known system (`model:`, cached once derived), or write a simpler form")


class WorkBudgetExceeded(ModelError):
    """The work budget is spent: ``what`` grew beyond it (a located `ModelError`); ``seconds``
    when it was the CPU-time backstop that stopped it."""

    def __init__(self, what: str, units: int, location: Location | None = None, seconds: float | None = None,
                 hint: str | None = None):
        self.what, self.units, self.location, self.seconds, self.hint = what, units, location, seconds, hint
        limit = f"the work budget of {units:,} units" if seconds is None else \
            f"the {seconds:g} s of CPU time of the work budget of {units:,} units"
        super().__init__([Problem(location, f"stopped: {what} exceeded {limit}",
                                  hint or HINT.format(default=DEFAULT_UNITS))])

    def at(self, location: Location | None) -> "WorkBudgetExceeded":
        """The same error placed at ``location``, unless it is placed already."""
        if self.location is not None or location is None:
            return self
        return WorkBudgetExceeded(self.what, self.units, location, self.seconds, self.hint)

    def advised(self, hint: str) -> "WorkBudgetExceeded":
        """The same error with ``hint`` instead of the general one (a layer that knows a better route)."""
        return WorkBudgetExceeded(self.what, self.units, self.location, self.seconds, hint)


class WorkBudget:
    """``units`` of work, and optionally a deadline ``seconds`` from now; `charge` spends them."""

    __slots__ = ("units", "used", "deadline", "what", "fixed")

    def __init__(self, units: int = DEFAULT_UNITS, seconds: float | None = None, fixed: bool = False):
        self.units, self.used, self.what, self.fixed = int(units), 0, "the work", fixed
        self.deadline = None if seconds is None else time.monotonic() + seconds

    def charge(self, units: int, what: str) -> None:
        """Spend ``units``; raise `WorkBudgetExceeded` naming ``what`` once the budget is spent."""
        self.used += units
        self.what = what
        if self.used > self.units or (self.deadline is not None and time.monotonic() > self.deadline):
            raise WorkBudgetExceeded(what, self.units)

    def check(self, units: int, what: str) -> None:
        """Raise as `charge` would if ``units`` more were spent, without spending them."""
        if self.used + units > self.units:
            raise WorkBudgetExceeded(what, self.units)


_ACTIVE: ContextVar[WorkBudget | None] = ContextVar("kronsub_work_budget", default=None)
_BACKSTOP: ContextVar[WorkBudget | None] = ContextVar("kronsub_work_backstop", default=None)


def active() -> WorkBudget | None:
    """The budget work is charged to, or None outside `limited` and `scope`."""
    return _ACTIVE.get()


@contextmanager
def limited(units: int | None = None, seconds: float | None = None) -> Iterator[WorkBudget]:
    """A fresh budget of ``units`` (default `DEFAULT_UNITS`) for the block (a command)."""
    token = _ACTIVE.set(WorkBudget(DEFAULT_UNITS if units is None else units, seconds, fixed=units is not None))
    try:
        yield _ACTIVE.get()
    finally:
        _ACTIVE.reset(token)


@contextmanager
def scope() -> Iterator[WorkBudget]:
    """The active budget, or a default one for the block when none is active (so that a
    library call is bounded as a command is)."""
    current = _ACTIVE.get()
    if current is not None:
        yield current
        return
    with limited() as fresh:
        yield fresh


def default_units(coordinates: int) -> int:
    """The default budget of a model whose primitive system has ``coordinates`` coordinates:
    `DEFAULT_UNITS`, times ``(coordinates / GROWS_FROM)**3`` beyond `GROWS_FROM`."""
    return int(DEFAULT_UNITS * max(1.0, coordinates / GROWS_FROM) ** 3)


def allow_for(coordinates: int) -> None:
    """Let a default budget (none was given) grow to `default_units` of a primitive system of
    ``coordinates`` coordinates, and its CPU-time backstop with it; a given budget stays."""
    current = _ACTIVE.get()
    if current is None or current.fixed:
        return
    units = default_units(coordinates)
    if units > current.units:
        before = _seconds(current.units)
        current.units = units
        if _BACKSTOP.get() is current:
            left = signal.getitimer(signal.ITIMER_VIRTUAL)[0]
            if left > 0:
                signal.setitimer(signal.ITIMER_VIRTUAL, left + _seconds(units) - before)


def _seconds(units: int) -> float:
    return max(MIN_SECONDS, SECONDS_PER_MILLION * units / 1e6)


def charge(units: int, what: str) -> None:
    """Charge ``units`` of ``what`` to the active budget (nothing outside `limited`/`scope`)."""
    current = _ACTIVE.get()
    if current is not None:
        current.charge(units, what)


def check(units: int, what: str) -> None:
    """Refuse ahead, as `WorkBudget.check`, work known to cost ``units`` (nothing outside a budget)."""
    current = _ACTIVE.get()
    if current is not None:
        current.check(units, what)


@contextmanager
def cpu_backstop() -> Iterator[None]:
    """Stop the block once the process has spent the active budget's CPU seconds in it
    (`SECONDS_PER_MILLION`, at least `MIN_SECONDS`), naming what was last charged: a backstop
    for work inside sympy that no count sees. CPU time (``ITIMER_VIRTUAL``), so the load of
    other processes does not move it; only in the main thread, where signals arrive."""
    current = _ACTIVE.get()
    usable = current is not None and hasattr(signal, "setitimer") \
        and threading.current_thread() is threading.main_thread() \
        and signal.getitimer(signal.ITIMER_VIRTUAL) == (0.0, 0.0)
    if not usable:
        yield
        return

    def stop(signum, frame):
        raise WorkBudgetExceeded(current.what, current.units, seconds=_seconds(current.units))

    previous = signal.signal(signal.SIGVTALRM, stop)
    token = _BACKSTOP.set(current)
    signal.setitimer(signal.ITIMER_VIRTUAL, _seconds(current.units))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_VIRTUAL, 0)
        _BACKSTOP.reset(token)
        signal.signal(signal.SIGVTALRM, previous)


__all__ = ["DEFAULT_UNITS", "GROWS_FROM", "HINT", "MIN_SECONDS", "PER_OPERATION", "SECONDS_PER_MILLION", "WorkBudget",
           "WorkBudgetExceeded", "active", "allow_for", "charge", "check", "cpu_backstop", "default_units", "limited",
           "scope"]
