"""A prepared run: a ``simulate`` command run once, kept so that the same command runs again
from its compiled model, without reading or deriving the model (no SymPy).

A run whose rows come from the compiled model alone (a method wholly in C, no closed loop, no
drive power, circuit energies, points or reactions) and that completed records what it ran
(:func:`record`): the compiled library (its folder, name and sha256), the parameters and the
initial state as numbers, the columns and the metadata, kept (:mod:`kronsub.model.kept`) under
the key of what decided all of that (:func:`run_key`: kronsub's source, the model file, the
command's options, the compiler, the build and the integrators' C) with the model files it was
derived from. The same command then finds the record (:func:`load`: the files unchanged, the
library's bytes those recorded), integrates in C on the pieces of the output grid the C engine
walks (:mod:`.engines.c`), computes ``T`` and ``V`` (24) per row in C, and writes through the
same :class:`~.trajectory_file.RowWriter` as a derived run.

Anything else is not served and the command runs as usual: no record, a record damaged, not
private or not this user's (:func:`kronsub.cache.load_entry`), a file changed, a library whose
digest differs, a run that does not complete as recorded (it stopped, was held by stiffness, or
did not keep the energy of a conservative model: the usual run says why).
"""
from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..cache import LIBRARY_FILE, NATIVE_DIR
from ..errors import KronsubError
from ..model import kept
from . import native
from . import rows
from .advice import energy_advice, is_stiff
from .grid import Grid, integrated_pieces
from .methods import METHODS
from .progress import Progress
from .rows import Block, RunInProgress

__all__ = ["Prepared", "load", "record", "run_key", "runs"]


def run_key(model: Path, options: dict) -> str | None:
    """The key of a ``simulate`` of ``model`` with ``options`` (:func:`kronsub.model.kept.key`,
    with the compiler, the build and the integrators' C): None when the cache is off, the model
    file cannot be read, or no compiler is there."""
    try:
        command = native.compiler_command()
        integrators = [hashlib.sha256((native.CSRC / name).read_bytes()).hexdigest()
                       for name in native.INTEGRATOR_FILES]
    except (KronsubError, OSError):
        return None
    return kept.key("simulate", model, options, compiler=[shutil.which(command[0]) or command[0], *command[1:]],
                    build=native.build_identity(), integrators=integrators)


@dataclass(frozen=True)
class Prepared:
    """What a recorded run ran: the library and its sha256, the numbers of coordinates and
    parameters, the method, tolerances, span and output interval, the parameters and initial
    state ``y0 = [q; qdot]``, and the CSV's columns (``want``: which of coordinates, velocities,
    energies) and metadata as the run began."""

    library: Path
    sha256: str
    nq: int
    nparam: int
    method: str
    rtol: float
    atol: float
    t_end: float
    dt: float
    param: tuple[float, ...]
    y0: tuple[float, ...]
    columns: tuple[str, ...]
    want: dict
    meta: dict

    def start_metadata(self) -> dict:
        """The metadata as a run begins (a copy): running, no rows, no cost yet."""
        meta = json.loads(json.dumps(self.meta))
        meta.update(status="running", complete=False, rows=0, last_t=None, cost={})
        return meta


def record(key: str, prepared: Prepared, files) -> None:
    """Keep ``prepared`` under ``key`` with the model files it was derived from
    (:func:`kronsub.model.kept.record`)."""
    library = prepared.library
    kept.record(key, {"library": {"folder": library.parent.name, "name": library.name, "sha256": prepared.sha256},
                      "nq": prepared.nq, "nparam": prepared.nparam, "method": prepared.method,
                      "rtol": prepared.rtol, "atol": prepared.atol, "t_end": prepared.t_end, "dt": prepared.dt,
                      "param": list(prepared.param), "y0": list(prepared.y0), "columns": list(prepared.columns),
                      "want": prepared.want, "meta": prepared.meta}, files)


def load(key: str) -> Prepared | None:
    """The run kept under ``key`` (:func:`kronsub.model.kept.load`: its model files unchanged)
    when its library is the one recorded (:func:`.native.verified`); else None."""
    entry = kept.load(key)
    if entry is None:
        return None
    try:
        lib = entry["library"]
        folder, name = lib["folder"], lib["name"]
        if not (NATIVE_DIR.fullmatch(folder) and LIBRARY_FILE.fullmatch(name)):
            return None
        library = native.build_root() / folder / name
        if native.recorded_digest(library) != lib["sha256"] or not native.verified(library):
            return None
        prepared = Prepared(
            library=library, sha256=lib["sha256"], nq=int(entry["nq"]), nparam=int(entry["nparam"]),
            method=str(entry["method"]), rtol=float(entry["rtol"]), atol=float(entry["atol"]),
            t_end=float(entry["t_end"]), dt=float(entry["dt"]), param=tuple(map(float, entry["param"])),
            y0=tuple(map(float, entry["y0"])), columns=tuple(map(str, entry["columns"])),
            want={k: bool(entry["want"][k]) for k in ("coordinates", "velocities", "energies")},
            meta=dict(entry["meta"]))
    except (AttributeError, KeyError, TypeError, ValueError, KronsubError, OSError):
        return None
    method = METHODS.get(prepared.method)
    if method is None or method.engine != "c" or len(prepared.y0) != 2 * prepared.nq \
            or len(prepared.param) != prepared.nparam:
        return None
    return prepared


def runs(prepared: Prepared, progress: bool | None = None) -> RunInProgress | None:
    """The run of ``prepared``, computed now (its blocks kept to be written): None when it did
    not complete as recorded (the usual run then says why) or has more rows than a streamed run
    keeps in one block (:data:`.rows.BLOCK_ROWS`). An interrupt keeps the blocks so far,
    the run's blocks raise it again after them (the writer records it as a streamed run's)."""
    try:
        model = native.NativeModel(prepared.library, prepared.nq, prepared.nparam)
    except (OSError, KronsubError, ValueError):
        return None
    method = METHODS[prepared.method]
    param, y0 = np.array(prepared.param, dtype=float), np.array(prepared.y0, dtype=float)
    grid = Grid(prepared.t_end, prepared.dt)
    if len(grid) > rows.BLOCK_ROWS:  # computed at once: a run of one block only (a streamed run's memory)
        return None
    bar = Progress(prepared.t_end, progress)
    chunks = 20 if bar.enabled else 1  # as run.start: one call unless a bar moves
    run = RunInProgress(method.name, "C")
    done: list[Block] = []
    stopped = None
    energy = None  # (t0, y0, E0, largest T, last E), as run._finish keeps it for energy_advice
    dt = prepared.dt

    def add(t, Y):
        nonlocal energy
        energies = model.energies(t, Y, param) if prepared.want["energies"] else None
        if energies is not None:
            T, V = energies
            if energy is None:
                energy = (float(t[0]), np.asarray(Y)[0].copy(), float(T[0] + V[0]), 0.0, 0.0)
            energy = (*energy[:3], max(energy[3], float(np.max(np.abs(T)))), float(T[-1] + V[-1]))
        done.append(Block(grid.snap(t), np.asarray(Y), energies))

    try:
        add(np.array([grid[0]]), np.array([y0]))
        stats = run.stats = {"steps": 0, "rejected": 0, "evaluations": 0}

        def integrate(t0, y, t1):
            return model.integrate(method.name, t0, y, t1, dt, param, rtol=prepared.rtol, atol=prepared.atol,
                                   h=dt if method.fixed_step else None, interruptible=True)

        for _, _, t1, t, Y, result in integrated_pieces(integrate, grid, y0, dt, chunks, method.fixed_step, stats):
            if result.status != 0:
                return None
            if len(t):
                add(t, Y)
            bar.update(t1)
    except KeyboardInterrupt as exc:
        stopped = exc
    finally:
        bar.close()
    if stopped is None:
        if is_stiff(run.stats):
            return None
        if energy is not None and energy_advice(model, param, prepared.nq, method.name, *energy):
            return None

    def blocks():
        yield from done
        if stopped is not None:
            raise stopped

    run.blocks = blocks()
    return run
