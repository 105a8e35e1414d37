"""What a trajectory file is made of, apart from the model that computed it: its rows (every
number in its shortest round-trip form), the name and the JSON of its metadata sidecar, and
the writer that streams the rows and keeps the metadata (:class:`RowWriter`: how far it got,
how the run ended, an interrupt or a reader gone). :class:`~.table.CsvWriter` makes the
columns and the metadata of a derived system; :mod:`.prepared` those recorded by an earlier
run, without SymPy: both write through this one writer."""
from __future__ import annotations

import contextlib
import json
import math
import signal
import threading
from pathlib import Path

import numpy as np

from ..interrupts import handled, signal_name, signal_of
from .rows import Block, RunInProgress

__all__ = ["METADATA_FORMAT", "RowWriter", "format_rows", "json_number", "metadata_json", "sidecar_path",
           "whole_rows"]

METADATA_FORMAT = "kronsub-trajectory-metadata/1"


def format_rows(data: np.ndarray) -> str:
    """Rows of numbers as CSV lines, each number in its shortest round-trip form."""
    return "".join(",".join(map(repr, row)) + "\n" for row in np.asarray(data, dtype=float).tolist())


@contextlib.contextmanager
def whole_rows():
    """Hold off Ctrl-C (SIGINT), SIGTERM and SIGHUP (:data:`kronsub.interrupts.HELD`) while rows
    are written, then deliver the first: a file interrupted mid-write still ends with a whole
    row, counted in the metadata. A signal whose handler is not Python's (the default action,
    ignored) is left alone."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught, previous = [], {}
    try:
        with handled(lambda signum: callable(signal.getsignal(signum)),
                     lambda number, frame: caught.append((number, frame))) as previous:
            yield
    finally:
        if caught:
            previous[caught[0][0]](*caught[0])


def sidecar_path(csv_path: Path) -> Path:
    """The metadata file of a CSV: ``out.csv`` -> ``out.json``; other names get ``.json`` added."""
    csv_path = Path(csv_path)
    if csv_path.suffix.lower() == ".csv":
        return csv_path.with_suffix(".json")
    return csv_path.with_name(csv_path.name + ".json")


def json_number(value):
    """A float for JSON: non-finite values (which JSON lacks) as null."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def metadata_json(meta: dict) -> str:
    """The metadata as JSON text (key order as built; deterministic)."""
    from ..emitters.escape import json_document  # jinja2 with it: only when metadata is written

    return json_document(meta, indent=2, allow_nan=False) + "\n"


class RowWriter:
    """Writes a run's CSV to ``out`` block by block under its header of ``columns``; ``rows``
    and ``last_t`` say how far it got, :meth:`metadata` everything about the run (``meta``, as
    it started; how it ended once :meth:`end` or :meth:`interrupted` was called).

    The numbers of a block (:meth:`data`): ``t``, the coordinates, the velocities and the
    energies ``T``, ``V``, ``T + V`` as ``want`` says, then :meth:`more`'s columns."""

    def __init__(self, out, columns: list[str], meta: dict, want: dict):
        self.out, self.columns, self._meta, self.want = out, list(columns), meta, want
        self.rows, self.last_t, self.stopped, self.reader_gone = 0, None, False, False
        self.signum: int | None = None  # the signal that interrupted the run (SIGINT for Ctrl-C)
        out.write(",".join(self.columns) + "\n")

    def metadata(self) -> dict:
        """The run's metadata: what it ran and, so far, how it went (a copy)."""
        return json.loads(json.dumps(self._meta))

    def block(self, block: Block, extra: np.ndarray | None = None) -> None:
        """Write the rows of ``block`` (``extra``: the values of the appended columns)."""
        text = format_rows(self.data(block, extra))
        with whole_rows():
            self.out.write(text)
            self.counted(block)

    def counted(self, block: Block) -> None:
        """Count the rows of ``block`` as written (in the metadata: ``rows``, ``last_t``)."""
        n = len(block.t)
        self.rows += n
        self.last_t = float(block.t[-1]) if n else self.last_t
        self._meta.update(rows=self.rows, last_t=json_number(self.last_t))

    def energies(self, block: Block) -> tuple[np.ndarray, np.ndarray]:
        """Kinetic and potential energy per row of ``block`` (computed in C with the rows)."""
        return block.energies

    def more(self, block: Block, Y: np.ndarray) -> list[np.ndarray]:
        """The columns after the energies (none here)."""
        return []

    def data(self, block: Block, extra: np.ndarray | None = None) -> np.ndarray:
        """The numbers of the rows of ``block``, one column per name of :attr:`columns`."""
        n = len(block.t)
        Y = block.y.reshape(n, -1)
        nq = Y.shape[1] // 2
        data = [block.t.reshape(-1, 1)]
        if self.want["coordinates"]:
            data.append(Y[:, :nq])
        if self.want["velocities"]:
            data.append(Y[:, nq:])
        if self.want["energies"]:
            T, V = self.energies(block)
            data += [T.reshape(-1, 1), V.reshape(-1, 1), (T + V).reshape(-1, 1)]
        data += self.more(block, Y)
        if extra is not None:
            data.append(np.asarray(extra, dtype=float).reshape(n, -1))
        return np.hstack(data)

    def end(self, stats: dict, complete: bool, t_fail: float | None = None, message: str = "",
            switches=()) -> None:
        """Record how the run ended: its cost, where and why it stopped when it did, and the
        times ``coordinates: auto`` chose other independent coordinates."""
        self._cost(stats)
        self._meta["complete"] = bool(complete)
        if switches:
            self._meta["coordinate_switches"] = [{"t": json_number(t), "what": str(what)} for t, what in switches]
        if complete:
            self._meta["status"] = "complete"
        else:
            self._meta.update(status="stopped", stopped_at=json_number(t_fail), stop_reason=message)

    def _cost(self, stats: dict) -> None:
        self._meta["cost"] = {k: (json_number(v) if k == "stiff_from" else int(v)) for k, v in stats.items()}

    def interrupted(self, stats: dict | None = None, signum: int = signal.SIGINT) -> None:
        """Record an interrupt (Ctrl-C, SIGTERM, SIGHUP: ``signum``): the rows so far, to
        ``last_t``, are all there is."""
        self.stopped = True
        self.signum = int(signum)
        if stats is not None:
            self._cost(stats)
        name = signal_name(signum)
        self._meta.update(status="interrupted", complete=False, stopped_at=json_number(self.last_t),
                          stop_reason=f"interrupted ({'Ctrl-C' if signum == signal.SIGINT else name})",
                          signal=name)

    def stream(self, run: RunInProgress, keep=None) -> None:
        """Write the blocks of ``run`` as they are computed, then record how it ended; ``keep(block)``,
        when given, sees every block too (for a plot). An interrupt (KeyboardInterrupt) is
        recorded (:meth:`interrupted`) and raised again, so the caller keeps the file and reports it."""
        try:
            for block in run:
                self.block(block)
                if keep is not None:
                    keep(block)
        except KeyboardInterrupt as exc:
            self.interrupted(run.stats, signal_of(exc))
            raise
        except BrokenPipeError:  # the reader went away (`| head`): the rows it took are all there is
            self.stopped = self.reader_gone = True
            self._cost(run.stats)
            self._meta.update(status="stopped", complete=False, stopped_at=json_number(self.last_t),
                              stop_reason="the reader of the output closed it")
            return
        self.end(run.stats, run.complete, run.t_fail, run.message, run.switches)
