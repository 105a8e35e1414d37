"""The compiled ensemble: one library for a whole sweep, a block of runs a call.

The library is the model's generated C (parameters are arguments: never recompiled for new
values), kronsub's integrators and ``csrc/ensemble.c``, whose ``ks_ensemble_run`` integrates each
run exactly as one run of ``kronsub simulate`` does (the same integrator on the same pieces of
the output grid) and writes its summary. The client ships the sources with their sha256
(:class:`Sources`; the generated C kept for the next sweep of the same system,
:mod:`.emitted`); a worker checks the digest, builds them once (cached by content,
:func:`kronsub.simulation.native.compile_library`) and keeps the loaded library per process."""
from __future__ import annotations

import ctypes
import hashlib
import math
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import KronsubError
from ..simulation.compiled import fingerprint, identity_source
from ..simulation.grid import Grid, aligned_pieces, chunk_ranges, fixed_pieces
from ..simulation.methods import METHODS
from ..simulation.native import NativeModel, compile_library, data_address
from ..simulation.rows import BLOCK_ROWS
from .emitted import kept_files

__all__ = ["BATCH_METHODS", "Ensemble", "EnsembleError", "EnsembleStopped", "Sources", "TaylorEnsemble",
           "ensemble_sources", "load", "load_taylor", "pieces", "stop", "summary_width", "taylor_sources"]

ENSEMBLE_C = Path(__file__).resolve().parent / "csrc" / "ensemble.c"
BATCH_METHODS = {"dop853": 0, "gauss4": 1, "rk4": 2}  # the methods wholly in C, as ensemble.c numbers them
MAX_STEPS = 10_000_000  # as a run of simulate (NativeModel.integrate's bound on step attempts)


class EnsembleError(KronsubError):
    """Shipped sources that do not match their digest, or a library without the ensemble."""


class EnsembleStopped(KronsubError):
    """A block of runs left unfinished because the sweep was stopped (:func:`stop`)."""


_STOPPED = [False]  # whether this process's sweep was stopped: the libraries loaded later start stopped


def stop(stopped: bool = True) -> None:
    """Stop (or, ``False``, allow again) the blocks of runs of every library this process has
    loaded: once set, no further run of a block starts (the runs under way finish), and the block
    raises :class:`EnsembleStopped`. An interrupted client stops its threads' blocks so, rather
    than waiting for whole chunks."""
    _STOPPED[0] = stopped  # (before the libraries are listed: one loaded meanwhile reads it after it is listed)
    for loaded in (*list(_LOADED.values()), *list(_LOADED_TAYLOR.values())):
        _stop_flag(loaded.lib).value = int(stopped)


def _stop_flag(lib) -> ctypes.c_int:
    return ctypes.c_int.in_dll(lib, "ks_ensemble_stop")


def _finished(done: int, runs: int) -> None:
    if done < runs:
        raise EnsembleStopped(f"the sweep was stopped after {done} of a block's {runs} runs")


@dataclass(frozen=True)
class Sources:
    """The C files of a sweep's library, their sha256, and the model's sizes: ``ny`` the state's
    (``2 nq``, or ``nq`` and the speeds under velocity constraints), ``canonical`` whether gauss4
    integrates the canonical state ``[q; p]`` (not in the speeds)."""

    files: tuple[tuple[str, str], ...]
    sha256: str
    nq: int
    nparam: int
    ny: int = 0  # 0: 2 nq
    canonical: bool = True

    @property
    def state_width(self) -> int:
        return self.ny or 2 * self.nq


def _digest(files) -> str:
    digest = hashlib.sha256()
    for name, text in files:
        digest.update(name.encode() + b"\0" + text.encode() + b"\0")
    return digest.hexdigest()


def ensemble_sources(system, outputs=None) -> Sources:
    """The sources of ``system``'s sweep library: the generated C as ``simulate`` builds it
    (:func:`kronsub.simulation.compiled.compiled_library`) and the ensemble."""
    def emit():
        from ..emitters.code import emit_c  # heavy (jinja2, the C printer): only when the C is not kept

        return [(g.name, g.text) for g in emit_c(system, "model", outputs=outputs, mass_apart=False)]  # Mbar as simulate's

    nq, nparam = len(system.coordinates), len(system.parameters)
    files = kept_files("ensemble", system, repr(outputs), emit)
    key = fingerprint(system, outputs)
    if key is not None:
        files.append(identity_source(key, nq, nparam))
    files.append(("ks_ensemble.c", ENSEMBLE_C.read_text()))
    return Sources(tuple(files), _digest(files), nq, nparam, nq + len(system.state_velocities),
                   canonical=system.speeds is None)


def summary_width(nq: int, ny: int | None = None) -> int:
    """Doubles per run's summary (``ks_ensemble_nsum``): ``ny`` the state's (default ``2 nq``)."""
    return 7 + (2 * nq if ny is None else ny) + 2 * nq


def pieces(t_end: float, dt: float, method: str) -> np.ndarray:
    """The pieces ``[t0, t1]`` of the output grid a run of ``simulate`` integrates one call each
    (:func:`kronsub.simulation.engines.c.blocks` without a progress bar)."""
    grid = Grid(t_end, dt)
    chunks = max(1, math.ceil(len(grid) / BLOCK_ROWS))
    cut = fixed_pieces if METHODS[method].fixed_step else aligned_pieces
    return np.array([p for a, b in chunk_ranges(grid, chunks) for p in cut(grid[a], grid[b], dt)], dtype=float)


class _Settings(ctypes.Structure):
    """``ks_ensemble`` of ``csrc/ensemble.c``."""

    _fields_ = [(name, ctypes.c_void_p) for name in
                ("rhs", "rhs_circle", "circle_state", "prepare", "momentum", "velocity", "kinetic", "potential")] + [
        ("method", ctypes.c_int), ("canonical", ctypes.c_int), ("nq", ctypes.c_int), ("ny", ctypes.c_int),
        ("nc", ctypes.c_int), ("nfull", ctypes.c_int),
        ("npre", ctypes.c_int), ("n_pieces", ctypes.c_int), ("pieces", ctypes.c_void_p),
        ("dt", ctypes.c_double), ("rtol", ctypes.c_double), ("atol", ctypes.c_double),
        ("max_steps", ctypes.c_long), ("max_rows", ctypes.c_long), ("rows", ctypes.c_void_p),
        ("rows_per_run", ctypes.c_long), ("rows_written", ctypes.c_void_p)]


def _address(lib, name: str) -> int | None:
    try:
        return ctypes.cast(getattr(lib, name), ctypes.c_void_p).value
    except AttributeError:
        return None


class Ensemble:
    """A sweep's library, built from checked :class:`Sources` and loaded."""

    def __init__(self, sources: Sources):
        if _digest(sources.files) != sources.sha256:
            raise EnsembleError("the sweep's C sources do not match their sha256: not built")
        self.native = NativeModel(compile_library(list(sources.files), "sweep"), sources.nq, sources.nparam,
                                  sources.state_width, canonical=sources.canonical)
        lib = self.lib = ctypes.CDLL(str(self.native.path))  # the same library, for the ensemble's functions
        self.run_block = lib.ks_ensemble_run
        self.run_block.restype = ctypes.c_long
        self.run_block.argtypes = [ctypes.c_void_p, ctypes.c_long] + [ctypes.c_void_p] * 7
        self.addresses = {name: _address(lib, name) for name in (
            "ks_rhs_pre", "ks_rhs_canonical_pre", "ks_rhs_circle_pre", "ks_circle_state", "ks_prepare",
            "ks_momentum", "ks_velocity", "ks_kinetic_energy", "ks_potential_energy")}
        self.npre = int(lib.ks_npre())
        self.nq, self.nparam, self.ny = sources.nq, sources.nparam, sources.state_width

    def run(self, method: str, cuts: np.ndarray, dt: float, rtol: float, atol: float, param: np.ndarray,
            y0: np.ndarray, energies: bool, with_rows: bool = False):
        """Summaries (``runs x summary_width``) of the runs from the rows of ``y0`` with the rows
        of ``param`` (parameters, then a closed loop's Newton state); ``with_rows``: also each
        run's rows ``[t, y]`` on the output grid, ``(summary, rows, count per run)``."""
        a, native = self.addresses, self.native
        nq, ny, nc = self.nq, self.ny, native.nc
        canonical = method == "gauss4" and native.canonical and not native.nstate and not native.nfirst
        param = np.ascontiguousarray(param, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        runs = len(y0)
        nfull = self.nparam + native.nstate
        if param.shape != (runs, nfull) or y0.shape != (runs, ny):
            raise ValueError(f"param {param.shape} and y0 {y0.shape} do not match {runs} runs of "
                             f"{nfull} parameters and {ny} states")
        cuts = np.ascontiguousarray(cuts, dtype=float)
        nz = ny + 2 * nc
        longest = float(np.max(cuts[:, 1] - cuts[:, 0]))
        rows = math.floor(longest / dt) + 3 if method == "dop853" else max(1, math.ceil(longest / dt * (1 - 2e-7))) + 3
        s = _Settings(
            rhs=a["ks_rhs_canonical_pre"] if canonical else a["ks_rhs_pre"],
            rhs_circle=a["ks_rhs_circle_pre"] if nc else None, circle_state=a["ks_circle_state"] if nc else None,
            prepare=a["ks_prepare"], momentum=a["ks_momentum"], velocity=a["ks_velocity"],
            kinetic=a["ks_kinetic_energy"] if energies else None, potential=a["ks_potential_energy"],
            method=BATCH_METHODS[method], canonical=int(canonical), nq=nq, ny=ny, nc=nc, nfull=nfull, npre=self.npre, n_pieces=len(cuts),
            pieces=data_address(cuts), dt=dt, rtol=rtol, atol=atol, max_steps=MAX_STEPS, max_rows=rows)
        if with_rows:
            per_run = sum(math.floor((b - a) / dt) + 3 for a, b in cuts)
            kept = np.zeros((runs, per_run, ny + 1))
            written = np.zeros(runs, dtype=np.int64)
            s.rows, s.rows_per_run, s.rows_written = data_address(kept), per_run, data_address(written)
        summary = np.empty((runs, summary_width(nq, ny)))
        out = np.empty(rows * (nz + 1))
        work = np.empty(27 * nz)
        pre = np.empty(max(self.npre, nfull) + 1)
        start = np.empty(nz)
        if runs:
            _finished(self.run_block(ctypes.byref(s), runs, data_address(param), data_address(y0),
                                     data_address(summary), data_address(out), data_address(work), data_address(pre),
                                     data_address(start)), runs)
        return (summary, kept, written) if with_rows else summary

    def message(self, status: int) -> str:
        told = self.lib.ks_status_message
        told.restype, told.argtypes = ctypes.c_char_p, [ctypes.c_int]
        return told(int(status)).decode()


_LOADED: dict[str, Ensemble] = {}
_LOADING = threading.Lock()  # a worker's threads build and load a library once between them


def load(sources: Sources) -> Ensemble:
    """The :class:`Ensemble` of ``sources``, built and loaded once per process."""
    with _LOADING:
        if sources.sha256 not in _LOADED:
            _LOADED[sources.sha256] = Ensemble(sources)
            _stop_flag(_LOADED[sources.sha256].lib).value = int(_STOPPED[0])
        return _LOADED[sources.sha256]


TAYLOR_C = Path(__file__).resolve().parent / "csrc" / "taylor_ensemble.c"


def taylor_sources(system, tol: float) -> Sources:
    """The sources of ``system``'s Taylor integrator at the order for ``tol``, as ``simulate
    --method taylor`` builds it (:class:`kronsub.simulation.taylor_c.TaylorC`), and its ensemble."""
    from ..simulation.taylor_c import generated_c, order_for

    order = order_for(tol)
    files = kept_files("taylor", system, str(order), lambda: [("taylor.c", generated_c(system, order))])
    files.append(("ks_taylor_ensemble.c", TAYLOR_C.read_text()))
    return Sources(tuple(files), _digest(files), len(system.coordinates), len(system.parameters))


class TaylorEnsemble:
    """A sweep's Taylor library, built from checked :class:`Sources` and loaded."""

    def __init__(self, sources: Sources):
        if _digest(sources.files) != sources.sha256:
            raise EnsembleError("the sweep's C sources do not match their sha256: not built")
        order = re_order(sources.files[0][1])
        self.lib = ctypes.CDLL(str(compile_library(list(sources.files), f"taylor{order}")))
        self.run_block = self.lib.ks_taylor_ensemble
        self.run_block.restype = ctypes.c_long
        self.run_block.argtypes = [ctypes.c_long, ctypes.c_int, ctypes.c_int, ctypes.c_double, ctypes.c_double,
                                   ctypes.c_long] + [ctypes.c_void_p] * 9
        self.nq, self.nparam = sources.nq, sources.nparam

    def run(self, times: np.ndarray, tol: float, param: np.ndarray, y0: np.ndarray, energies: Ensemble | None,
            with_rows: bool = False, max_steps: int = MAX_STEPS):
        """As :meth:`Ensemble.run`, the rows at ``times`` (the output grid); ``energies``: the
        model's library whose ``T`` and ``V`` give the energy drift, or None."""
        nq, ny = self.nq, 2 * self.nq
        param = np.ascontiguousarray(param, dtype=float).reshape(len(y0), self.nparam)
        y0 = np.ascontiguousarray(y0, dtype=float)
        times = np.ascontiguousarray(times, dtype=float)
        runs, m = len(y0), len(times)
        summary = np.empty((runs, summary_width(nq)))
        io = np.empty(8 + max(1, self.nparam) + 2 * ny + m + m * ny)
        kept = np.zeros((runs, m, ny + 1)) if with_rows else None
        written = np.zeros(runs, dtype=np.int64) if with_rows else None
        kinetic = potential = None
        if energies is not None:
            kinetic, potential = energies.addresses["ks_kinetic_energy"], energies.addresses["ks_potential_energy"]
        if runs:
            _finished(self.run_block(runs, nq, self.nparam, tol, float(max_steps), m, data_address(times),
                                     data_address(param) if param.size else None, data_address(y0),
                                     data_address(summary), data_address(io), kinetic, potential,
                                     data_address(kept) if with_rows else None,
                                     data_address(written) if with_rows else None), runs)
        return (summary, kept, written) if with_rows else summary


def re_order(text: str) -> int:
    """The order a generated Taylor integrator's source declares (``#define TN_ORDER``)."""
    import re

    found = re.search(r"#define TN_ORDER (\d+)", text)
    if found is None:
        raise EnsembleError("the Taylor source does not declare its order")
    return int(found.group(1))


_LOADED_TAYLOR: dict[str, TaylorEnsemble] = {}


def load_taylor(sources: Sources) -> TaylorEnsemble:
    """The :class:`TaylorEnsemble` of ``sources``, built and loaded once per process."""
    with _LOADING:
        if sources.sha256 not in _LOADED_TAYLOR:
            _LOADED_TAYLOR[sources.sha256] = TaylorEnsemble(sources)
            _stop_flag(_LOADED_TAYLOR[sources.sha256].lib).value = int(_STOPPED[0])
        return _LOADED_TAYLOR[sources.sha256]
