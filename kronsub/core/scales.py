"""The size of each constraint's row, so that rank and regularity are judged on its own scale.

A constraint times a constant (written in other units) is the same constraint: its rows in the
coefficient matrices ``A`` (velocity constraints) or ``G = dg/dx`` (configuration ones) are
divided by their sizes over generic configurations before a rank, a singular value or a
Gram-Schmidt residual is compared with a tolerance, while a row that vanishes only at the
configuration in question stays small against its size elsewhere.
"""
from __future__ import annotations

import numpy as np


def row_sizes(samples) -> np.ndarray | None:
    """The size of each row of a matrix over ``samples`` (its values at several configurations,
    generic ones: :func:`kronsub.core.nonholonomic.generic_values`): the largest entry in size any of them has; None
    without samples."""
    samples = [np.abs(np.asarray(v)) for v in samples if np.asarray(v).size]
    return np.max([np.max(v, axis=1) for v in samples], axis=0) if samples else None


def rows_scaled(values: np.ndarray, sizes: np.ndarray | None) -> np.ndarray:
    """``values`` with each row divided by its size (:func:`row_sizes`; a row zero everywhere
    kept): a constraint written in other units, or times a constant, has the same rank and the
    same regularity, so tolerances on the result are relative to each row's own scale, while a
    row that only vanishes here (``cos(theta)`` at ``theta = pi/2``, a rounding's worth) stays
    small against its size elsewhere."""
    values = np.asarray(values)
    if not values.size or sizes is None:
        return values
    return values / np.where(sizes > 0, sizes, 1)[:, None]


__all__ = ["row_sizes", "rows_scaled"]
