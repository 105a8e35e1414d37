"""The one interface of the engines, read by ``simulate`` (:mod:`..run`) and ``accuracy``
(:mod:`..accuracy`) alike.

An engine is a module with two flags and one function: ``runner(problem, method)`` gives the
:class:`Runner` of one method (:class:`~kronsub.simulation.methods.Method`) on one
:class:`Problem` (a derived system, its parameters, its compiled right-hand side
``ydot = [qdot; Mbar^-1 (fbar - hbar)]``). A runner yields the rows of a streamed run
(``blocks``), times a run from t = 0 to its end (``timed``), records the steps of one
(``trace``, for the closed loops (25)-(29) of ``accuracy``) and says why it cannot run
(``unavailable``), building first what its method needs.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from ...core.known_system import KnownSystem
    from ..grid import Grid, Tail
    from ..methods import Method
    from ..native import NativeModel
    from ..rows import RunInProgress

__all__ = ["Engine", "Final", "Problem", "ProgressBar", "Rhs", "Rows", "Runner", "Steps", "Timed"]

Rows = Iterator[tuple[np.ndarray, np.ndarray]]
"""What a runner's ``blocks`` yields: times and states ``[q; qdot]``, a block at a time."""

Rhs = Callable[[float, np.ndarray], np.ndarray]
"""A right-hand side ``ydot = f(t, y)`` as scipy calls it."""

Final = tuple[object, "int | None", int, str]
"""What a timed run returns: ``(y_end, evaluations, steps, status)``; ``y_end`` in the
precision of the method, ``evaluations`` None when the engine does not count them, ``status``
'' when the run got to its end."""


class ProgressBar(Protocol):
    """Where an engine reports how far a run got (the driver's bar on stderr)."""

    def update(self, t: float) -> None: ...


@dataclass
class Problem:
    """One system at one parameter set, as every engine receives it.

    ``native``: the model compiled from its generated C (None: no compiler, or it failed;
    ``missing`` says why, '' when no reason is to be given); ``restart(tol)``: the right-hand
    side for a run at tolerance ``tol`` (with implicit constraints, Newton's method for the
    dependent coordinates restarted at that tolerance); ``events``: a terminal event function
    whose sign turns where the run must stop (an engine with ``EVENTS`` watches it between
    rows); ``diagnosed``: whether a failing run's message names what has no finite value there
    (False: the caller says it, as the switching of coordinates does)."""

    system: KnownSystem
    param: np.ndarray
    native: NativeModel | None
    restart: Callable[[float], Rhs]
    events: Callable[[float, np.ndarray], float] | None = None
    missing: str = ""
    diagnosed: bool = True


@dataclass(frozen=True)
class Steps:
    """How ``simulate`` steps a run: the tolerances of an adaptive method, the step ``dt`` of a
    fixed-step one (and the spacing of the rows), and how many chunks the grid is split into
    (restarts at which the progress bar moves)."""

    rtol: float
    atol: float
    dt: float
    chunks: int


@dataclass(frozen=True)
class Timed:
    """A run to be timed: ``run()`` returns its :data:`Final`; ``compile_seconds`` is what was
    built for it beforehand (None: nothing), timed apart."""

    run: Callable[[], Final]
    compile_seconds: float | None = None


class Runner(Protocol):
    """One method on one problem; ``backend`` names what computes its rows (``C``, ``numpy``
    when the model did not compile, ``heyoka``)."""

    backend: str

    def unavailable(self) -> str:
        """Why the method cannot run on this problem ('' when it can)."""
        ...

    def blocks(self, run: RunInProgress, grid: Grid | Tail, y0: np.ndarray, steps: Steps, bar: ProgressBar) -> Rows:
        """The rows ``(t, Y)`` of a run on ``grid`` from ``y0``, a block at a time; how the run
        ended is recorded on ``run`` (:meth:`~kronsub.simulation.rows.RunInProgress.stop`)."""
        ...

    def timed(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> Timed:
        """A run from t = 0 to ``t_end`` with a row at the end only: an adaptive method at
        ``rtol = atol = tol``, a fixed-step one with the step ``h``."""
        ...

    def trace(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> tuple[np.ndarray, np.ndarray]:
        """The times and states of every step of the run :meth:`timed` times (an engine whose
        methods run closed loops)."""
        ...


class Engine(Protocol):
    """An engine module: ``COMPILED_RHS``, whether it integrates the compiled right-hand side
    (else it builds its own integrator from the equations); ``EVENTS``, whether it watches
    :attr:`Problem.events` between rows; ``runner``."""

    COMPILED_RHS: bool
    EVENTS: bool

    def runner(self, problem: Problem, method: Method) -> Runner: ...
