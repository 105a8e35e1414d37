"""The Taylor integrator generated as C for the model (:mod:`..emitters.taylor_c`), compiled per
order and run: ``ks_taylor_io``, whose one argument holds every input and output. The order is
``2 ceil(ln(1/tol) / 4) + 4`` (:func:`order_for`); systems with implicit constraints are refused
(:class:`TaylorUnavailable`)."""
from __future__ import annotations

import ctypes
import threading

import numpy as np

from ..core.known_system import KnownSystem
from ..emitters.taylor_c import MIN_ORDER, Skeleton, TaylorEmitter, TaylorUnavailable, emit_taylor_c, order_for
from .native import CSRC, compile_library, data_address

__all__ = ["SKELETON", "STATUS", "TaylorC", "TaylorUnavailable", "generated_c", "order_for"]


STATUS = {0: "", 1: "the mass matrix is not positive definite, or the state became NaN or infinite",
          4: "the step limit was reached", 6: "bad arguments"}


def _csrc(name: str) -> str:
    """A hand-written C file of ``csrc/`` (the one home of hand-written C), as text."""
    return (CSRC / name).read_text(encoding="utf-8")


SKELETON = Skeleton(template=_csrc("taylor.c.in"), step_root=_csrc("taylor_step_root.h"),
                    rotate=_csrc("taylor_rotate.c.in"), lanes=_csrc("taylor_lanes.h"), loop=_csrc("taylor_loop.h"))
"""The hand-written C of the generated Taylor integrator, from ``csrc/`` (the one home of hand-written C)."""


def generated_c(system: KnownSystem, order: int) -> str:
    """The C source of the Taylor integrator of order ``order`` for ``system``
    (:func:`..emitters.taylor_c.emit_taylor_c` in :data:`SKELETON`)."""
    return emit_taylor_c(system, order, SKELETON)


class TaylorC:
    """The generated Taylor integrator of one system, compiled per order when first used."""

    def __init__(self, system: KnownSystem):
        self.system = system
        self.ny = 2 * len(system.coordinates)
        self.nparam = len(system.parameters)
        self._fns: dict[int, object] = {}
        self._local = threading.local()  # integrate's io buffer, one per thread (the call releases the GIL)
        self.last_steps = 0
        TaylorEmitter(system, MIN_ORDER)  # refuse an unsupported system now

    def build(self, order: int):
        """The compiled ``ks_taylor_io`` of ``order`` (built and cached on first use)."""
        if order not in self._fns:
            library = compile_library([("taylor.c", generated_c(self.system, order))], f"taylor{order}")
            fn = ctypes.CDLL(str(library)).ks_taylor_io
            fn.restype = ctypes.c_int
            fn.argtypes = [ctypes.c_void_p]
            self._fns[order] = fn
        return self._fns[order]

    def run(self, param, y0, times, tol: float, order: int = 0, max_steps: int = 10_000_000, t0: float = 0.0,
            y0_lo=None):
        """``(Y, status, steps, rows, t_last)``: the states at the increasing ``times`` (>= t0)
        from ``y0`` at ``t0``; rows after a failure are NaN (``rows`` says how many were
        written; ``t_last`` is the time of the last state reached). ``y0_lo``: a low part of the
        initial state (the state is ``y0 + y0_lo``), carried to first order."""
        order = order or order_for(tol)
        fn = self._fns.get(order) or self.build(order)
        p, y = self._inputs(param, y0)
        ts = np.asarray(times, dtype=float).ravel()
        npar, ny, m = max(1, self.nparam), self.ny, len(ts)
        lo = None if y0_lo is None else np.asarray(y0_lo, dtype=float)
        if lo is not None and lo.size != ny:
            raise ValueError(f"expected {ny} low parts of the initial values (got {lo.size})")
        # one array and one argument (ks_taylor_io): the header, parameters, y0, y0_lo, times, rows
        at = 8 + npar + 2 * ny
        io = np.empty(at + m + m * ny)
        io[:8] = (t0, tol, max_steps, m, lo is not None, 0, 0, t0)
        if p is not None:
            io[8:8 + self.nparam] = p.ravel()
        io[8 + npar:8 + npar + ny] = y.ravel()
        if lo is not None:
            io[8 + npar + ny:at] = lo.ravel()
        io[at:at + m] = ts
        status = fn(data_address(io))
        return io[at + m:].reshape(-1, ny), status, int(io[5]), int(io[6]), float(io[7])

    def _inputs(self, param, y0) -> tuple:
        """``(param, y0)`` as float arrays, their sizes checked (param None: a model without
        parameters, which ``ks_taylor`` does not read)."""
        p = np.asarray(param, dtype=float) if self.nparam else None
        y = np.asarray(y0, dtype=float)
        if (p is not None and p.size != self.nparam) or y.size != self.ny:
            raise ValueError(f"expected {self.nparam} parameters and {self.ny} initial values "
                             f"(got {0 if p is None else p.size} and {y.size})")
        return p, y

    def solve(self, param, y0, grid, tol: float) -> tuple[np.ndarray, np.ndarray, bool, str]:
        """``(t, Y, complete, message)`` as :meth:`.heyoka_backend.HeyokaIntegrator.run`: rows
        ``Y = [q; qdot]`` at the ``grid`` times from ``y0`` at ``grid[0]``; on a failure, the
        rows before it. The steps taken are left in ``last_steps``."""
        grid = np.asarray(grid, dtype=float).ravel()
        if grid.size < 1 or not np.all(np.isfinite(grid)) or np.any(np.diff(grid) < 0):
            raise ValueError("grid must be a non-empty, finite, non-decreasing array of times")
        if not np.all(np.isfinite(np.asarray(y0, dtype=float))):
            raise ValueError(f"y0 must be finite (got {y0})")
        Y, status, self.last_steps, rows, t_last = self.run(param, y0, grid, tol, t0=float(grid[0]))
        if status == 0:
            return grid.copy(), Y, True, ""
        return grid[:rows].copy(), Y[:rows], False, f"{STATUS.get(status, f'status {status}')} at t = {t_last:.17g}"

    def integrate(self, param, y0, t_end: float, tol: float, order: int = 0, max_steps: int = 10_000_000):
        """``(y_end, status, steps, order)`` from ``y0`` at t = 0. The quick path of :meth:`run` for
        one end state: the io array (header, parameters, y0, t_end, the row) is kept per thread
        with its address, so a call writes five entries and reads four."""
        order = order or order_for(tol)
        fn = self._fns.get(order) or self.build(order)
        p, y = self._inputs(param, y0)
        buffer = getattr(self._local, "io", None)
        if buffer is None:  # {t0 = 0, tol, max_steps, n_out = 1, has_lo = 0, steps, rows, t_last, param, y0, lo, t, row}
            io = np.zeros(8 + max(1, self.nparam) + 3 * self.ny + 1)
            io[3] = 1
            buffer = self._local.io = (io, data_address(io), 8 + max(1, self.nparam))
        io, address, at = buffer
        io[1] = tol
        io[2] = max_steps
        if p is not None:
            io[8:8 + self.nparam] = p.ravel()
        io[at:at + self.ny] = y.ravel()
        io[at + 2 * self.ny] = t_end
        status = fn(address)
        return io[-self.ny:].copy(), status, int(io[5]), order
