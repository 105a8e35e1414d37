"""Why a run stopped: the state to explain, the configuration, and why the equations have no
finite value there (:mod:`..core.finite`) or ``Mbar`` is singular."""
from __future__ import annotations

import numpy as np

from ..core.projection_work import projected_in_numbers


__all__ = ["Singular", "at_configuration", "cause_of", "failed_state", "not_finite", "rank_loss_note", "real_at"]


class Singular(Exception):
    def __init__(self, t, y):
        super().__init__(t)
        self.t, self.y = t, y


def failed_state(run, last_row: np.ndarray) -> np.ndarray:
    """The state to explain a failure at: where the right-hand side failed when that is near the
    last row written (an integrator's trial stage can be far off: phi = -1e31), else that row."""
    y, last = run.y_fail, np.asarray(last_row, dtype=float)
    if y is None or y.shape != last.shape or not np.all(np.isfinite(y)):
        return last
    n = len(last) // 2
    return y if np.max(np.abs(y[:n] - last[:n])) <= 0.5 * (1.0 + np.max(np.abs(last[:n]))) else last


def rank_loss_note(system, t, y, param) -> str:
    """``; <why Mbar is singular at y>`` (:func:`..core.finite.rank_loss`), or nothing."""
    from ..core.finite import rank_loss

    if param is None or t is None or y is None or not np.all(np.isfinite(y)) or projected_in_numbers(system):
        return ""  # (with the projection onto the speeds made at run time, no symbolic Mbar to look at)
    why = rank_loss(system, t, y, param)
    return f"; {why}" if why else ""


def at_configuration(system, y) -> str:
    """The configuration at a failure, for the message."""
    if y is None:
        return ""
    return " at " + ", ".join(f"{q.name}={v:.6g}" for q, v in zip(system.coordinates, y))


def real_at(native, t: float, y, param) -> bool:
    """Whether the energies have a finite real value at ``(t, y)`` (a connection through sqrt, asin
    or acos has none outside its domain, where the mass matrix is NaN, not singular; huge values
    overflow)."""
    try:
        with np.errstate(all="ignore"):
            values = [native.kinetic_energy(y, param), native.potential_energy(t, y, param)]
    except Exception:  # noqa: BLE001 - a model without energies, or one that fails otherwise: no verdict
        return True
    return bool(np.all(np.isfinite(values)))


def cause_of(system, t: float, y, param, mass_only: bool = False):
    """The :class:`..core.finite.Cause` of :func:`not_finite`, or None (also when the projection
    onto the speeds is made at run time: its symbolic equations are not made to look into)."""
    from ..core.finite import at_state

    if projected_in_numbers(system):
        return None
    cause = at_state(system, t, y, param)
    if cause is not None and mass_only and not (cause.overflow or cause.label.startswith("Mbar")):
        return None
    return cause


def not_finite(system, t: float, y, param, otherwise: str | None = None, mass_only: bool = False) -> str:
    """Why the equations are NaN or infinite at ``(t, y)``, where the state is finite: a value
    beyond the range of doubles, or a function outside its domain (:mod:`..core.finite`); else
    ``otherwise`` (None: that the double values are not finite, though the exact ones are, or
    with implicit constraints, whose dependent coordinates are not known here, just that).
    ``mass_only``: only an overflow or a problem in ``Mbar`` (a singular one, as at a coordinate
    singularity, keeps ``otherwise``)."""
    cause = cause_of(system, t, y, param, mass_only)
    if cause is not None:
        return cause.stated()
    if otherwise is not None:
        return otherwise
    if system.implicit is not None:
        return "the equations have no finite value at this state"
    return ("the equations are NaN or infinite at this state in double precision, though finite when evaluated "
            "exactly (an intermediate value overflows or cancels: check for huge or tiny parameters and initial "
            "values)")
