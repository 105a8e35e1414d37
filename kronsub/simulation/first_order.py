"""The velocities of first-order coordinates in a run's rows.

A first-order coordinate (:mod:`kronsub.core.first_order`, a loop without inductance) has no
velocity of its own in the integrated state: the right-hand side solves it from the
coordinate's equation, ``qdot_J = D^-1 (fbar - hbar)_J``, and returns it as the rate of the
coordinate, while the state's slot ``y[n + j]`` is not integrated. The rows written are the
state with that slot set to the solved velocity (the branch current), so every column derived
from a row (energies, dissipated power) sees it.
"""
from __future__ import annotations

from typing import Callable, Iterable, Iterator

import numpy as np


def first_order_rows(rows: Iterable, rhs: Callable[[float, np.ndarray], np.ndarray], indices, nq: int) -> Iterator:
    """``rows`` (``(t, y)`` blocks) with ``y[n + j] = qdot_j`` for the first-order coordinates ``j``."""
    columns = [nq + j for j in indices]
    for t, y in rows:
        y = np.array(y, dtype=float).reshape(len(t), -1)
        for k, (ti, yi) in enumerate(zip(t, y)):
            yi[columns] = 0.0  # the slot is not read by the right-hand side: any value gives the same rates
            try:
                rates = rhs(float(ti), yi)
            except Exception:  # noqa: BLE001 - a row where the rates fail (a singular metric) keeps NaN there
                y[k, columns] = np.nan
                continue
            y[k, columns] = np.asarray(rates)[list(indices)]
        yield t, y


__all__ = ["first_order_rows"]
