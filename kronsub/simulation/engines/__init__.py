"""The engines of the integration methods, one module each: ``c`` (the methods wholly in C),
``scipy`` (scipy's solvers on the compiled right-hand side), ``taylor`` (a Taylor integrator
generated as C) and ``heyoka``. Each ``blocks`` generator yields the rows ``(t, Y)`` of a run on
its output grid and records on the :class:`~kronsub.simulation.rows.Run` how it ended; the
method table (:mod:`..methods`) says which engine runs which method."""
from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Protocol

import numpy as np

__all__ = ["ProgressBar", "Rhs", "Rows"]

Rows = Iterator[tuple[np.ndarray, np.ndarray]]
"""What an engine's ``blocks`` yields: times and states ``[q; qdot]``, a block at a time."""

Rhs = Callable[[float, np.ndarray], np.ndarray]
"""A right-hand side ``ydot = f(t, y)`` as scipy calls it."""


class ProgressBar(Protocol):
    """Where an engine reports how far a run got (the driver's bar on stderr)."""

    def update(self, t: float) -> None: ...
