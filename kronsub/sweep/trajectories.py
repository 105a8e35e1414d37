"""A sweep's trajectories (``--trajectories DIR``): every run's rows on the output grid, the
columns of ``kronsub simulate``'s CSV for the same run (``t``, the coordinates and velocities,
or speeds, the scene's outputs keep, a closed loop's dependent coordinates) after a ``run``
column, as a Parquet dataset of one part per chunk named as the summaries' parts (:mod:`.dataset`).

The worker that computes a chunk writes its part (a row group per :data:`GROUP_BYTES` of rows,
so its memory stays bounded), atomically, before it hands the chunk's summaries to the client:
a chunk whose summary part exists has its trajectory part, and ``--resume`` recomputes a chunk
without both. Nothing of the trajectories goes through the client."""
from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from ..atomic import atomic_file
from ..errors import KronsubError
from .dataset import arrow_column, part_name

__all__ = ["GROUP_BYTES", "ColumnClash", "TrajectoryPart", "trajectory_columns"]

GROUP_BYTES = 1 << 25  # rows held by a worker before they go to the part as a row group


def _wanted(outputs, what: str) -> bool:
    return outputs is None or bool(getattr(outputs, what))


class ColumnClash(KronsubError):
    """A name of the model that is also the name of another column of the trajectories."""


def trajectory_columns(system, outputs=None) -> list[tuple[str, str]]:
    """``(name, type)`` of a trajectory row: ``run``, then ``simulate``'s columns of the state.
    Raises :class:`ColumnClash` when a coordinate or velocity is named like another column."""
    columns = [("run", "int64"), ("t", "float64")]
    if _wanted(outputs, "coordinates"):
        columns += [(q.name, "float64") for q in system.coordinates]
    if _wanted(outputs, "velocities"):
        columns += [(system.name_of(v), "float64") for v in system.state_velocities]
    if system.implicit is not None:
        columns += [(d.name, "float64") for d in system.implicit.dependent]
    names = [name for name, _ in columns]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise ColumnClash(f"the trajectories would have two columns named {', '.join(twice)}: a row's own "
                          "run and t, and the model's coordinate or velocity of that name"
                          "\n  hint: rename it in the model file, or leave out --trajectories")
    return columns


class TrajectoryPart:
    """The trajectory part of one chunk, written as its runs are computed (a context manager:
    the part exists, whole, once the block ends without an exception)."""

    def __init__(self, folder: str | Path, index: int, system, outputs=None):
        self.path = Path(folder) / part_name(index)
        self.columns = trajectory_columns(system, outputs)
        self.nq, self.ny = len(system.coordinates), len(system.coordinates) + len(system.state_velocities)
        self.keep_q, self.keep_v = _wanted(outputs, "coordinates"), _wanted(outputs, "velocities")
        self.dependent = system.implicit is not None
        self.held: list[np.ndarray] = []
        self.bytes = 0

    def __enter__(self):
        import pyarrow as pa
        import pyarrow.parquet as pq

        self.schema = pa.schema([(name, pa.int64() if kind == "int64" else pa.float64())
                                 for name, kind in self.columns])
        self.opened = atomic_file(self.path, binary=True)
        self.writer = pq.ParquetWriter(self.opened.__enter__(), self.schema)
        return self

    def __exit__(self, kind, value, trace):
        if kind is None:
            try:
                self.flush()
                self.writer.close()
            except BaseException as exc:
                self.opened.__exit__(type(exc), exc, exc.__traceback__)
                raise
            return self.opened.__exit__(None, None, None)
        with contextlib.suppress(Exception):
            self.writer.close()
        return self.opened.__exit__(kind, value, trace)

    def add(self, run: int, t: np.ndarray, y: np.ndarray, dependent: np.ndarray | None = None) -> None:
        """Rows of run ``run``: times ``t`` (on the grid), states ``y`` ``[q, qdot]`` (``[q, u]`` in
        the speeds) per row and a closed loop's dependent coordinates."""
        n = len(t)
        if not n:
            return
        y = np.asarray(y, dtype=float).reshape(n, -1)
        parts = [np.full((n, 1), float(run)), np.asarray(t, dtype=float).reshape(n, 1)]
        if self.keep_q:
            parts.append(y[:, :self.nq])
        if self.keep_v:
            parts.append(y[:, self.nq:self.ny])
        if self.dependent:
            width = len(self.columns) - sum(p.shape[1] for p in parts)
            parts.append(np.full((n, width), np.nan) if dependent is None else
                         np.asarray(dependent, dtype=float).reshape(n, width))
        block = np.hstack(parts)
        self.held.append(block)
        self.bytes += block.nbytes
        if self.bytes >= GROUP_BYTES:
            self.flush()

    def flush(self) -> None:
        import pyarrow as pa

        if not self.held:
            return
        rows = np.concatenate(self.held)
        self.held, self.bytes = [], 0
        arrays = [arrow_column(rows[:, 0], "int64")] + [arrow_column(rows[:, k], "float64")
                                                        for k in range(1, rows.shape[1])]
        self.writer.write_table(pa.Table.from_arrays(arrays, schema=self.schema))
