"""The engines of the integration methods, one module each, all with the one interface of
:mod:`.interface`: ``c`` (the methods wholly in C), ``taylor`` (a Taylor integrator generated as
C), ``scipy`` (scipy's solvers on the compiled right-hand side), ``heyoka`` and ``extended``
(extrapolation in extended precision, ``accuracy`` only). The method table
(:mod:`..methods`) names each method's engine; :func:`engine_of` is that engine."""
from __future__ import annotations

from ..methods import Method
from . import c, extended, heyoka, scipy, taylor
from .interface import Engine, Final, Problem, ProgressBar, Rhs, Rows, Runner, Steps, Timed

__all__ = ["ENGINES", "Engine", "Final", "Problem", "ProgressBar", "Rhs", "Rows", "Runner", "Steps", "Timed",
           "engine_of", "runner"]

ENGINES: dict[str, Engine] = {"c": c, "taylor": taylor, "scipy": scipy, "heyoka": heyoka, "extended": extended}
"""The engine of each name a method's ``engine`` may take (:data:`..methods.ENGINES`, tested equal)."""


def engine_of(method: Method) -> Engine:
    """The engine that runs ``method``."""
    return ENGINES[method.engine]


def runner(problem: Problem, method: Method) -> Runner:
    """The runner of ``method`` on ``problem``, from the method's engine."""
    return engine_of(method).runner(problem, method)
