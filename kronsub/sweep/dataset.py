"""A sweep's output: a folder of Parquet parts, one per chunk (``part-000012.parquet``, readable
as one dataset by pyarrow, pandas or DuckDB), and a JSON sidecar beside it (``runs.parquet`` ->
``runs.parquet.json``: the model and its sha256, the spec and seed, method, tolerances, versions,
the chunks written and the runs by status). Each part is written atomically, so a part that
exists is whole: ``--resume`` computes only the chunks without one."""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from ..atomic import atomic_file, temporary_pattern, write_atomically
from ..errors import KronsubError

__all__ = ["Dataset", "DatasetError", "PART", "arrow_column", "owned", "part_name"]

PART = re.compile(r"part-(\d{6,})\.parquet")


class DatasetError(KronsubError):
    """An output folder that is not this sweep's to write."""


def part_name(index: int) -> str:
    return f"part-{index:06d}.parquet"


def owned(name: str) -> bool:
    """Whether ``name`` is a part's (``part-000012.parquet``) or the temporary file of a part
    being written (:func:`~kronsub.atomic.temporary_pattern`): what ``--force`` may remove."""
    if PART.fullmatch(name):
        return True
    part = PART.match(name[1:]) if name.startswith(".") else None
    return part is not None and temporary_pattern(part.group(0)).fullmatch(name) is not None


def arrow_column(values, kind: str):
    """``values`` as an Arrow array of ``kind`` (``int64``, ``float64`` or ``string``), made from
    its buffers: ``pyarrow.array`` imports pandas to ask whether they are a pandas object, which
    the client would wait for before its first part."""
    import pyarrow as pa

    if kind == "string":
        encoded = [str(v).encode() for v in values]
        offsets = np.zeros(len(encoded) + 1, dtype=np.int64)
        np.cumsum(np.array([len(b) for b in encoded], dtype=np.int64), out=offsets[1:])
        return pa.Array.from_buffers(pa.large_string(), len(encoded), [None, pa.py_buffer(offsets),
                                                                      pa.py_buffer(b"".join(encoded))]).cast(pa.string())
    data = np.ascontiguousarray(values, dtype=np.int64 if kind == "int64" else np.float64)
    if data.ndim != 1:
        raise ValueError(f"a column is one-dimensional, not of shape {data.shape}")
    return pa.Array.from_buffers(pa.int64() if kind == "int64" else pa.float64(), len(data), [None, pa.py_buffer(data)])


class Dataset:
    """The output folder of a sweep and its sidecar."""

    def __init__(self, folder: Path, columns: list[tuple[str, str]], option: str = "-o"):
        """``option``: the option that named the folder, for the hints."""
        from ..simulation.table import sidecar_path

        self.folder, self.option = Path(folder), option
        self.sidecar = sidecar_path(self.folder)
        self.columns = columns

    def prepare(self, identity: dict, *, resume: bool, force: bool) -> set[int]:
        """Make the folder ready; the chunks already written (resume). An existing output is
        refused unless ``resume`` (the same sweep: its identity in the sidecar) or ``force``."""
        exists = self.folder.exists() or self.sidecar.exists()
        if exists and self.folder.exists() and not self.folder.is_dir():
            raise DatasetError(f"{self.folder} exists and is not a folder\n  hint: a sweep writes a folder of "
                               f"Parquet parts; choose another {self.option}")
        if exists and not (resume or force):
            raise DatasetError(f"{self.folder} exists\n  hint: --resume finishes the sweep written there, "
                               f"--force replaces it, or choose another {self.option}")
        if exists and force and not resume:
            self._clear()
            exists = False
        done: set[int] = set()
        if exists:
            try:
                told = json.loads(self.sidecar.read_text())
            except (OSError, ValueError):
                raise DatasetError(f"{self.folder} has no readable sidecar {self.sidecar}: it is not a sweep's "
                                   "output\n  hint: --force replaces it") from None
            if told.get("identity") != identity:
                raise DatasetError(f"{self.folder} holds another sweep (its model, spec, method, tolerances or "
                                   f"chunk size differ; see {self.sidecar})\n  hint: --force replaces it, or "
                                   f"choose another {self.option}")
            done = {int(m.group(1)) for p in self.folder.iterdir() if (m := PART.fullmatch(p.name))}
        # a link to a folder not there yet: the folder it names is made, the link stays
        made = Path(os.path.realpath(self.folder)) if self.folder.is_symlink() else self.folder
        made.mkdir(parents=True, exist_ok=True)
        return done

    def _clear(self) -> None:
        """Remove a sweep's own files (its parts, the temporary files of parts being written, the
        sidecar), keeping the folder (a link to it stays a link); refuse before removing anything
        when the folder holds anything else, hidden or not."""
        if self.folder.is_dir():
            ours, foreign = [], []
            for entry in sorted(os.scandir(self.folder), key=lambda e: e.name):
                (ours if entry.is_file(follow_symlinks=False) and owned(entry.name) else foreign).append(entry)
            if foreign:
                names = ", ".join(e.name for e in foreign[:3]) + (", ..." if len(foreign) > 3 else "")
                raise DatasetError(f"{self.folder} holds files that are not a sweep's parts ({names})"
                                   f"\n  hint: --force replaces only a sweep's output; choose another {self.option}")
            for entry in ours:
                os.unlink(entry.path)
        self.sidecar.unlink(missing_ok=True)

    def table(self, rows: dict[str, object]):
        import pyarrow as pa

        return pa.Table.from_arrays([arrow_column(rows[name], kind) for name, kind in self.columns],
                                    names=[name for name, _ in self.columns])

    def write(self, index: int, rows: dict[str, object]) -> None:
        """Chunk ``index``'s rows as its part (atomically)."""
        import pyarrow.parquet as pq

        with atomic_file(self.folder / part_name(index), binary=True) as fh:
            pq.write_table(self.table(rows), fh)

    def write_sidecar(self, info: dict) -> None:
        write_atomically(self.sidecar, json.dumps(info, indent=2, sort_keys=True, allow_nan=False) + "\n")

    def counts(self, parts=None, known: dict[str, int] | None = None) -> dict[str, int]:
        """Runs by status over every part written (``parts``: those of these chunks only), added to
        ``known`` (the counts of other parts, tallied as they were written)."""
        import pyarrow.parquet as pq

        counts: dict[str, int] = dict(known or {})
        paths = sorted(self.folder.glob("part-*.parquet")) if parts is None else \
            [self.folder / part_name(i) for i in sorted(parts)]
        for path in paths:
            for status in pq.read_table(path, columns=["status"]).column("status").to_pylist():
                counts[status] = counts.get(status, 0) + 1
        return dict(sorted(counts.items()))
