"""A run's rows: the blocks it streams, the run in progress, the whole trajectory, and the error
of a run that could not start."""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import KronsubError

if TYPE_CHECKING:
    from .switching import Split

__all__ = ["BLOCK_ROWS", "SimulationError", "Trajectory", "Block", "RunInProgress"]


BLOCK_ROWS = 100_000  # rows per block of a streamed run (bounds the memory of long runs)


class SimulationError(KronsubError):
    """A run that could not start."""


@dataclass
class Trajectory:
    """Rows of a run: times, states ``[q; qdot]``, and how the run ended."""

    t: np.ndarray
    y: np.ndarray
    method: str
    complete: bool = True
    message: str = ""
    t_fail: float | None = None
    stats: dict = field(default_factory=dict)
    backend: str = ""
    energies: tuple[np.ndarray, np.ndarray] | None = None  # (T, V) per row, when computed in C
    y_fail: np.ndarray | None = None  # the state at which the right-hand side failed, when known
    dependent: np.ndarray | None = None  # implicit constraints: the dependent coordinates per row
    switches: list[tuple[float, str]] = field(default_factory=list)  # coordinates: auto: (t, what) per switch
    # coordinates: auto: (first row, end row, split, its own rows [q; qdot] in its own layout) per
    # stretch of rows computed with one choice of independent coordinates
    segments: list[tuple[int, int, Split, np.ndarray]] | None = None


@dataclass
class Block:
    """Consecutive rows of a run: times, states ``[q; qdot]`` and, when computed in C, ``(T, V)``."""

    t: np.ndarray
    y: np.ndarray
    energies: tuple[np.ndarray, np.ndarray] | None = None
    dependent: np.ndarray | None = None  # implicit constraints: the dependent coordinates per row
    split: Split | None = None  # coordinates: auto: the choice of independent coordinates that computed these rows
    own: np.ndarray | None = None  # ... and the rows in its own layout (the first choice's are in ``y``)


@dataclass
class RunInProgress:
    """A run in progress: iterate over it for its :class:`Block` s of rows, as they are
    computed; once the iteration ends, ``complete``, ``message``, ``t_fail`` and ``stats``
    say how the run ended."""

    method: str
    backend: str
    blocks: Iterator[Block] | None = None
    complete: bool = True
    message: str = ""
    t_fail: float | None = None
    stats: dict = field(default_factory=dict)
    y_fail: np.ndarray | None = None  # the state at which the right-hand side failed, when known
    switches: list[tuple[float, str]] = field(default_factory=list)  # coordinates: auto: (t, what) per switch
    pending: tuple[float, np.ndarray] | None = None  # (t, y) where scipy's toggle event stopped a segment
    library: Path | None = None  # the compiled model whose C computed the rows, when one did

    def __iter__(self):
        yield from self.blocks

    def stop(self, message: str, t_fail: float | None, stats: dict | None = None, y_fail=None) -> None:
        self.complete, self.message, self.t_fail = False, message, t_fail
        if y_fail is not None:
            self.y_fail = np.asarray(y_fail)
        if stats is not None:
            self.stats = stats
