"""A run in the speeds that crossed a configuration where the speeds are singular.

Under velocity constraints the state is ``[x; u]`` and ``xdot = C u + d`` solves
``S xdot = r0 + [0; u]`` with ``S = [G; A; Y]``: the configuration constraints' rates, the
velocity constraints' rows and the speeds ``u = Y xdot`` (Kron's non-holonomic frame). Where
``S`` is singular the frame fails, as a chart fails at its edge, and ``xdot`` has no value. The
model's start is checked when it is read; along a run, an adaptive integrator can step over such
a configuration without noticing (its error estimate sees only the rows on either side), and the
rows after it are then not accurate. ``det S`` is continuous along the motion, so a change of its
sign between two rows says the motion crossed ``det S = 0`` between them; a smallest singular
value of ``S`` (its rows on their own scale, :mod:`kronsub.core.scales`) below
:data:`NEAR_SINGULAR` of its largest says it came that close.
"""
from __future__ import annotations

import numpy as np
import sympy

from ..core.linearize_numerics import LinearizationError
from ..core.nonholonomic import generic_values
from ..core.nonholonomic_linearize import frame_matrix, velocity_rows
from ..core.scales import row_sizes, rows_scaled
from ..model.nonholonomic import regular_speeds

__all__ = ["NEAR_SINGULAR", "SHOWN", "FrameWatch", "SingularSpeedsWarning", "frame_watch"]

NEAR_SINGULAR = 1e-9
"""Smallest over largest singular value of ``S`` (rows scaled) below which a row is called singular:
``xdot = C u + d`` there is lost to rounding in all but a few digits."""

SHOWN = 4
"""Most coordinates a warning names (those ``S`` depends on)."""


class SingularSpeedsWarning(UserWarning):
    """A run in the speeds crossed, or came within rounding of, a configuration where the speeds are singular."""


class FrameWatch:
    """``S = [G; A; Y]`` of ``system`` (a system in its speeds) at the parameter values ``param``,
    watched along the rows of a run (:meth:`see`) for the first crossing of ``det S = 0``."""

    def __init__(self, system, param):
        s = system.speeds
        x = self.x = list(system.coordinates)
        values = {p.symbol: sympy.Float(float(v), 17) for p, v in zip(system.parameters, param)}
        g = sympy.Matrix([c.expression for c in s.holonomic]) if s.holonomic else sympy.zeros(0, 1)
        S = frame_matrix(g, velocity_rows(system), [e for _, e in s.definitions], x)[0]
        self.constraint_rows = S.rows - len(s.speeds)  # those of [G; A]
        self.sizes = row_sizes(generic_values(S, x, values))
        self.shown = [q for q in x if any(q in e.free_symbols for e in S)][:SHOWN]
        self.index = [x.index(q) for q in self.shown]
        self.param = [float(v) for v in param]
        symbols = [p.symbol for p in system.parameters]
        varying = S.free_symbols - set(symbols)  # params as arguments: cse on their symbols is quicker than on numbers
        self.frame = sympy.lambdify([x, symbols], S, "numpy", cse=True) if varying else None
        self.constant = None if varying else np.array(S.xreplace(values), dtype=float)
        self.last = None  # (t, y, sign of det S) of the last row seen
        self.found = None  # (t0, y0, t1, y1, crossed): the rows about the first crossing or near approach

    def _at(self, y) -> tuple[float, float, np.ndarray] | None:
        """(sign of det S, smallest over largest singular value, S) at the coordinates of ``y``;
        None where ``S`` has no finite value."""
        with np.errstate(all="ignore"):
            try:
                S = self.constant if self.frame is None else np.array(self.frame(list(y[:len(self.x)]), self.param),
                                                                     dtype=float)
            except (TypeError, ValueError, ZeroDivisionError, OverflowError):
                return None
        if not np.all(np.isfinite(S)):
            return None
        scaled = rows_scaled(S, self.sizes)
        sigma = np.linalg.svd(scaled, compute_uv=False)
        return float(np.sign(np.linalg.det(scaled))), float(sigma[-1] / sigma[0]) if sigma[0] > 0 else 0.0, S

    def see(self, times, states) -> None:
        """The rows ``(t, [x; u])`` of a block, in order, after those already seen."""
        if self.found is not None or self.frame is None:
            return
        for t, y in zip(np.asarray(times, dtype=float), np.asarray(states, dtype=float)):
            at = self._at(y)
            if at is None:
                self.last = None
                continue
            sign, ratio, _ = at
            if ratio < NEAR_SINGULAR:
                previous = self.last if self.last is not None else (t, y, sign)
                self.found = (previous[0], previous[1], t, y.copy(), False)
                return
            if self.last is not None and sign * self.last[2] < 0:
                self.found = (self.last[0], self.last[1], t, y.copy(), True)
                return
            self.last = (t, y.copy(), sign)

    def advice(self) -> str:
        """What the run crossed, where, and which speeds would serve there ("" when nothing was found)."""
        if self.found is None:
            return ""
        t0, y0, t1, y1, crossed = self.found
        moved = ", ".join(f"{q.name} from {y0[i]:.6g} to {y1[i]:.6g}" for q, i in zip(self.shown, self.index))
        where = (f"between t = {t0:.6g} and t = {t1:.6g}" + (f" ({moved})" if moved else "") if crossed else
                 f"at t = {t1:.6g}" + (" (" + ", ".join(f"{q.name} = {y1[i]:.6g}" for q, i in
                                                        zip(self.shown, self.index)) + ")" if self.shown else ""))
        what = "crossed" if crossed else "came within rounding of"
        hint = "choose speeds that stay independent along the motion"
        at = self._at(y1)
        if at is not None and self.constraint_rows:
            serving = regular_speeds(at[2][:self.constraint_rows], self.x,
                                     None if self.sizes is None else self.sizes[:self.constraint_rows], best=True)
            if serving:
                hint += ", e.g. `speeds: [" + ", ".join(serving) + "]`, independent there"
        return (f"the run {what} a configuration where the speeds are singular, {where}: [G; A; Y] xdot = "
                f"[-dg/dt; -b; u] has no solution there, so xdot = C u + d has no value, and the rows from "
                f"t = {t0:.6g} on are not accurate; {hint}")


def frame_watch(system, param) -> FrameWatch | None:
    """A :class:`FrameWatch` for a run of ``system`` in its speeds; None for a system not in its
    speeds, or whose ``S`` depends on time (no linear rows to watch)."""
    if getattr(system, "speeds", None) is None:
        return None
    try:
        return FrameWatch(system, param)
    except LinearizationError:
        return None

