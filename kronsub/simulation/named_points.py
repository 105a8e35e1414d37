"""A run's named points in numbers, each compiled from its own expressions.

A named point is an expression of the coordinates (and ``t``): it needs no projection. For a
system whose projection onto the speeds is made in numbers at run time
(:func:`~kronsub.core.projection_work.projected_in_numbers`) a run does not make the generated
numpy module, the usual home of its points (its ``points``), which is long to write for such a
system; this gives it the same names and values, each point lambdified apart, the printed size
charged to the work budget as generated code's is.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import sympy

from ..budget import PER_OPERATION, charge, scope
from ..core.known_system import KnownSystem
from ..core.operations import count_ops
from ..core.symbols import TIME
from ..errors import KronsubError

POINT_NAMES = ("POINTS", "points", "TIMED")
"""What the generated numpy module names its points by: their labels and dimensions, the function,
and whether it takes ``t``."""

__all__ = ["POINT_NAMES", "point_namespace"]


def point_namespace(system: KnownSystem) -> dict[str, object]:
    """``POINTS`` (label and dimension of each named point, sorted by label), ``points(t, y, param)``
    (their positions concatenated in that order at the state ``y = [q; ...]`` and the parameter
    values ``param``, in the order of ``system.parameters``) and ``TIMED`` (True: ``points`` takes ``t``)."""
    coordinates = list(system.coordinates)
    parameters = [p.symbol for p in system.parameters]
    labels = sorted(system.points)
    compiled: list[Callable] = []
    known = {TIME, *coordinates, *parameters}
    with scope():
        for label in labels:
            exprs = [sympy.sympify(e) for e in system.points[label]]
            unknown = set().union(*(e.free_symbols for e in exprs)) - known
            if unknown:
                names = ", ".join(sorted(s.name for s in unknown))
                raise KronsubError(f"cannot evaluate the named point '{label}': {names} is neither a parameter, a "
                                   "coordinate nor t")
            charge(PER_OPERATION["print"] * sum(count_ops(e) for e in exprs), f"the named point '{label}'")
            compiled.append(sympy.lambdify([TIME, coordinates, parameters], exprs, "numpy", cse=True))
    n = len(coordinates)
    size = sum(len(system.points[label]) for label in labels)

    def points(t, y, param) -> np.ndarray:
        q, p = [float(v) for v in np.asarray(y, dtype=float)[:n]], [float(v) for v in param]
        out = [float(v) for fn in compiled for v in fn(float(t), q, p)]
        return np.array(out, dtype=float).reshape(size)

    return {"POINTS": [(label, len(system.points[label])) for label in labels], "points": points, "TIMED": True}
