"""A sweep's output: a folder of Parquet parts, one per chunk (``part-000012.parquet``, readable
as one dataset by pyarrow, pandas or DuckDB), and a JSON sidecar beside it (``runs.parquet`` ->
``runs.parquet.json``: the model and its sha256, the spec and seed, method, tolerances, versions,
the chunks written and the runs by status). Each part is written atomically, so a part that
exists is whole: ``--resume`` computes only the chunks without one."""
from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

from ..atomic import atomic_file, write_atomically
from ..errors import KronsubError

__all__ = ["Dataset", "DatasetError", "PART", "part_name"]

PART = re.compile(r"part-(\d{6,})\.parquet")


class DatasetError(KronsubError):
    """An output folder that is not this sweep's to write."""


def part_name(index: int) -> str:
    return f"part-{index:06d}.parquet"


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
        self.folder.mkdir(parents=True, exist_ok=True)
        return done

    def _clear(self) -> None:
        if self.folder.is_dir():
            foreign = [p.name for p in self.folder.iterdir() if not PART.fullmatch(p.name) and not p.name.startswith(".")]
            if foreign:
                raise DatasetError(f"{self.folder} holds files that are not a sweep's parts ({', '.join(sorted(foreign)[:3])})"
                                   f"\n  hint: --force replaces only a sweep's output; choose another {self.option}")
            shutil.rmtree(self.folder)
        self.sidecar.unlink(missing_ok=True)

    def table(self, rows: dict[str, object]):
        import pyarrow as pa

        types = {"int64": pa.int64(), "float64": pa.float64(), "string": pa.string()}
        return pa.table({name: pa.array(rows[name], type=types[kind]) for name, kind in self.columns})

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
