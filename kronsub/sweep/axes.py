"""The axes of a sweep, read from ``--grid`` and ``--sample``: grids (linear ``a:b:n``,
logarithmic ``log:a:b:n``, lists ``[v1, v2, ...]``) and distributions (``uniform(a, b)``,
``normal(mu, sd)``, ``loguniform(a, b)``). Every bound is a constant read by the model's safe
expression reader (:mod:`kronsub.model.expressions`); every problem is collected and reported at
its option, e.g. ``--grid m2=2:1:16``."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ..errors import Location, ModelError, Problem, option
from ..model.expressions import constant_value, parse_expression

__all__ = ["DISTRIBUTIONS", "GridAxis", "MAX_GRID_POINTS", "SampleAxis", "TableAxis", "parse_grid", "parse_sample",
           "read_axes", "read_table"]

MAX_GRID_POINTS = 10**7  # points of one grid axis: more is a typing mistake, not a study

DISTRIBUTIONS = {  # name: (its arguments, a one-line description)
    "uniform": (("a", "b"), "uniform on [a, b], a < b"),
    "normal": (("mu", "sd"), "normal with mean mu and standard deviation sd > 0"),
    "loguniform": (("a", "b"), "log-uniform on [a, b], 0 < a < b"),
}


@dataclass(frozen=True)
class GridAxis:
    """A grid over one name: ``count`` values from ``start`` to ``stop`` (value ``i`` is
    ``start + (stop - start) i / (count - 1)``, or its logarithmic kind, the ends exact), or the
    ``listed`` values. Values are made when asked for (:meth:`at`): a long grid costs nothing
    to send to the workers."""

    name: str
    text: str
    start: float = 0.0
    stop: float = 0.0
    count: int = 1
    log: bool = False
    listed: tuple[float, ...] | None = None

    def __len__(self) -> int:
        return len(self.listed) if self.listed is not None else self.count

    def at(self, index: np.ndarray) -> np.ndarray:
        """The values at ``index`` (integers from 0 to ``len - 1``)."""
        index = np.asarray(index)
        if self.listed is not None:
            return np.asarray(self.listed, dtype=float)[index]
        if self.count == 1:
            return np.full(index.shape, self.start)
        share = index / (self.count - 1)
        if self.log:
            values = np.exp(math.log(self.start) + (math.log(self.stop) - math.log(self.start)) * share)
        else:
            values = self.start + (self.stop - self.start) * share
        values = np.where(index == 0, self.start, values)
        return np.where(index == self.count - 1, self.stop, values)

    @property
    def values(self) -> np.ndarray:
        return self.at(np.arange(len(self)))

    @property
    def names(self) -> tuple[str, ...]:
        return (self.name,)

    def take(self, index: np.ndarray) -> dict[str, np.ndarray]:
        return {self.name: self.at(index)}

    def describe(self) -> dict:
        return {self.name: self.text}


@dataclass(frozen=True)
class TableAxis:
    """A table of runs (``--table FILE``, CSV or Parquet): row ``i`` gives every named column's
    value to one run, the columns together one axis (crossed with the grids)."""

    text: str
    sha256: str
    columns: tuple[tuple[str, tuple[float, ...]], ...]

    def __len__(self) -> int:
        return len(self.columns[0][1]) if self.columns else 0

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.columns)

    @property
    def name(self) -> str:
        return ", ".join(self.names)

    def take(self, index: np.ndarray) -> dict[str, np.ndarray]:
        return {name: np.asarray(values, dtype=float)[index] for name, values in self.columns}

    def describe(self) -> dict:
        return {f"table {self.text}": {"sha256": self.sha256, "columns": list(self.names), "rows": len(self)}}


MAX_TABLE_BYTES = 1 << 30  # a table of runs larger than this is a dataset to split into sweeps


def read_table(path: str, problems: list[Problem]) -> TableAxis | None:
    """``--table FILE``: a CSV file (a header row, then numbers) or Parquet (a file or a folder);
    every column a name swept, every row a run."""
    import hashlib
    from pathlib import Path

    where = Location(f"--table {path}")
    file = Path(path)
    try:
        import pyarrow as pa

        if file.suffix.lower() == ".csv":
            import pyarrow.csv as pcsv

            if file.stat().st_size > MAX_TABLE_BYTES:
                problems.append(Problem(where, f"the table is larger than {MAX_TABLE_BYTES:,} bytes",
                                        "split it into several sweeps"))
                return None
            table = pcsv.read_csv(file)
            digest = hashlib.sha256(file.read_bytes()).hexdigest()
        else:
            import pyarrow.parquet as pq

            table = pq.read_table(file)
            digest = hashlib.sha256(repr(table.schema).encode() + str(table.to_pydict()).encode()).hexdigest()
    except (OSError, ValueError, pa.ArrowException) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        problems.append(Problem(where, f"cannot read the table: {first}",
                                "give a CSV file (a header row of names, then numbers) or a Parquet file"))
        return None
    if table.num_columns == 0 or table.num_rows == 0:
        problems.append(Problem(where, "the table has no rows" if table.num_columns else "the table has no columns",
                                "a header row of names, then a row of numbers per run"))
        return None
    names = [str(name) for name in table.column_names]
    unnamed = [k + 1 for k, name in enumerate(names) if not name.strip()]
    twice = sorted({name for name in names if names.count(name) > 1 and name.strip()})
    if unnamed or twice:
        problems.extend([Problem(where, f"column {k} has no name", "name every column in the header row")
                         for k in unnamed] +
                        [Problem(where, f"column {name} appears {names.count(name)} times",
                                 "give each name one column: a run has one value of it") for name in twice])
        return None
    columns = []
    for k, name in enumerate(names):
        try:
            values = table.column(k).cast(pa.float64()).to_numpy(zero_copy_only=False)
        except (pa.ArrowException, ValueError):
            cells = table.column(k).to_pylist()
            row = next((r for r, cell in enumerate(cells) if not _numeric(cell)), None)
            problems.append(Problem(where, f"column {name} is not numeric" +
                                    (f": row {row + 1} holds {cells[row]!r}" if row is not None else ""),
                                    "every column holds numbers"))
            continue
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            problems.append(Problem(where, f"column {name}, row {int(bad[0]) + 1}: not a finite number",
                                    "fill every cell with a number"))
            continue
        columns.append((str(name), tuple(float(v) for v in values)))
    if len(columns) < table.num_columns:
        return None
    return TableAxis(str(path), digest, tuple(columns))


def _numeric(cell) -> bool:
    """Whether a table's cell reads as a number."""
    try:
        float(cell)
    except (TypeError, ValueError):
        return False
    return True


@dataclass(frozen=True)
class SampleAxis:
    """A distribution over one name: ``kind`` of :data:`DISTRIBUTIONS` with its arguments."""

    name: str
    kind: str
    args: tuple[float, ...]
    text: str

    def transform(self, u: np.ndarray) -> np.ndarray:
        """Values of the distribution at the uniform numbers ``u`` in (0, 1) (its inverse CDF)."""
        if self.kind == "uniform":
            a, b = self.args
            return a + (b - a) * u
        if self.kind == "loguniform":
            a, b = self.args
            return np.exp(math.log(a) + (math.log(b) - math.log(a)) * u)
        from scipy.special import ndtri

        mu, sd = self.args
        return mu + sd * ndtri(u)


def _split(text: str, sep: str) -> list[str]:
    """``text`` split at ``sep`` outside parentheses and brackets."""
    parts, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        if ch in "([":
            depth += 1
        elif ch in ")]":
            depth -= 1
        elif ch == sep and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts]


def _constant(text: str, where: Location, what: str, problems: list[Problem]) -> float | None:
    try:
        value = constant_value(parse_expression(text, {}, where, what=what), where, what=what)
    except ModelError as exc:
        problems.extend(exc.problems)
        return None
    if not math.isfinite(value):
        problems.append(Problem(where, f"{what} is not finite ({text})", "give a finite number"))
        return None
    return value


def _assignment(kind: str, item: str, example: str, problems: list[Problem]) -> tuple[str, str, Location] | None:
    """``NAME=VALUES`` of the option ``kind`` (``grid``, ``sample``), placed as the caller gave it
    (``--grid m2=0.5:2:16``; from Python ``grid['m2']=0.5:2:16``)."""
    name, sep, value = item.partition("=")
    name, value = name.strip(), value.strip()
    where = Location(f"{option(kind, name)}={value}" if sep and name else f"{option(kind)} {item}")
    if not sep or not name or not value:
        problems.append(Problem(where, f"{option(kind)} takes NAME=VALUES", f"e.g. {option(kind)} {example}"))
        return None
    return name, value, where


GRID_HINT = "a grid is a:b:n (n values from a to b), log:a:b:n (logarithmic, 0 < a) or a list [v1, v2, ...]"


def parse_grid(item: str, problems: list[Problem]) -> GridAxis | None:
    """One ``--grid NAME=...``; its problems appended to ``problems``."""
    got = _assignment("grid", item, "m2=0.5:2:16", problems)
    if got is None:
        return None
    name, text, where = got
    before = len(problems)
    if text.startswith("[") and text.endswith("]") or ":" not in text:
        body = text[1:-1] if text.startswith("[") else text
        items = [p for p in _split(body, ",")]
        if not body.strip() or any(not p for p in items):
            problems.append(Problem(where, f"the list of {name} has an empty entry", GRID_HINT))
            return None
        values = [_constant(p, where, f"value of {name}", problems) for p in items]
        return None if len(problems) > before else GridAxis(name, text, listed=tuple(values))
    parts = _split(text, ":")
    log = parts[0] == "log"
    if log:
        parts = parts[1:]
    if len(parts) != 3:
        problems.append(Problem(where, f"the grid of {name} is not a:b:n", GRID_HINT))
        return None
    a = _constant(parts[0], where, f"start of {name}'s grid", problems)
    b = _constant(parts[1], where, f"end of {name}'s grid", problems)
    try:
        n = int(parts[2])
    except ValueError:
        n = None
    if n is None or n < 1 or n > MAX_GRID_POINTS:
        problems.append(Problem(where, f"the number of values of {name} must be a whole number from 1 to "
                                       f"{MAX_GRID_POINTS:,} (got {parts[2]!r})", GRID_HINT))
    if len(problems) > before:
        return None
    if a > b:
        problems.append(Problem(where, f"the grid of {name} is inverted: it starts at {a:g}, above its end {b:g}",
                                f"write {name}={parts[1]}:{parts[0]}:{n}"))
        return None
    if a == b and n > 1:
        problems.append(Problem(where, f"the grid of {name} is empty: {n} values from {a:g} to {b:g}",
                                "give two different ends, or one value"))
        return None
    if log and not a > 0:
        problems.append(Problem(where, f"a logarithmic grid of {name} needs a start above 0 (got {a:g})",
                                "use a linear grid a:b:n for ranges through 0"))
        return None
    return GridAxis(name, text, start=a, stop=b, count=n, log=log)


_CALL = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*\((.*)\)$", re.S)


def parse_sample(item: str, problems: list[Problem]) -> SampleAxis | None:
    """One ``--sample "NAME=dist(args)"``; its problems appended to ``problems``."""
    got = _assignment("sample", item, "k=uniform(90, 110)", problems)
    if got is None:
        return None
    name, text, where = got
    hint = "distributions: " + "; ".join(f"{k}({', '.join(a)}): {d}" for k, (a, d) in DISTRIBUTIONS.items())
    call = _CALL.match(text)
    if call is None or call.group(1) not in DISTRIBUTIONS:
        told = f"unknown distribution '{call.group(1)}'" if call is not None else f"'{text}' is not a distribution"
        problems.append(Problem(where, f"{told} for {name}", hint))
        return None
    kind, body = call.group(1), call.group(2)
    names = DISTRIBUTIONS[kind][0]
    items = _split(body, ",") if body.strip() else []
    if len(items) != len(names):
        problems.append(Problem(where, f"{kind} takes {len(names)} arguments ({', '.join(names)}), got {len(items)}",
                                hint))
        return None
    before = len(problems)
    args = [_constant(p, where, f"{a} of {name}'s {kind}", problems) for p, a in zip(items, names)]
    if len(problems) > before:
        return None
    if kind == "normal" and not args[1] > 0:
        problems.append(Problem(where, f"the standard deviation of {name} must be above 0 (got {args[1]:g})", hint))
    elif kind != "normal" and not args[0] < args[1]:
        problems.append(Problem(where, f"{kind}({args[0]:g}, {args[1]:g}) of {name} is empty or inverted: "
                                       "it needs a < b", hint))
    elif kind == "loguniform" and not args[0] > 0:
        problems.append(Problem(where, f"loguniform of {name} needs a > 0 (got {args[0]:g})", hint))
    if len(problems) > before:
        return None
    return SampleAxis(name, kind, tuple(args), text)


def read_axes(grids: tuple[str, ...], samples: tuple[str, ...],
              tables: tuple[str, ...] = ()) -> tuple[list, list[SampleAxis]]:
    """Every ``--table``, ``--grid`` and ``--sample``, each name once; raises :class:`ModelError`
    with every problem."""
    problems: list[Problem] = []
    grid_axes = [a for a in (read_table(item, problems) for item in tables) if a is not None]
    grid_axes += [a for a in (parse_grid(item, problems) for item in grids) if a is not None]
    sample_axes = [a for a in (parse_sample(item, problems) for item in samples) if a is not None]
    seen: dict[str, str] = {}

    def said(axis, name) -> str:
        return f"{option('table')} {axis.text}" if isinstance(axis, TableAxis) else \
            f"{option('sample' if isinstance(axis, SampleAxis) else 'grid', name)}={axis.text}"

    for axis in [*grid_axes, *sample_axes]:
        for name in getattr(axis, "names", (axis.name,)):
            if name in seen:
                problems.append(Problem(Location(said(axis, name)), f"{name} is swept twice (also by {seen[name]})",
                                        "sweep each name once"))
            seen.setdefault(name, said(axis, name))
    if problems:
        raise ModelError(problems)
    return grid_axes, sample_axes
