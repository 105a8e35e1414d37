"""What ``accuracy`` measures, from its options: the methods (from the method table,
:mod:`.methods`), the tolerances, and the setting of a method at a tolerance (an adaptive
method takes ``rtol = atol = tol``; a fixed-step method of order p the step ``h = tol^(1/p)``,
at most ``t_end / 8``, so that its error also scales like ``tol``)."""
from __future__ import annotations

import math

from ..errors import KronsubError
from .methods import MEASURED, METHODS

__all__ = ["ALL_METHODS", "AccuracyError", "CLOSED_LOOP", "KNOWN_METHODS", "fixed_step", "parse_methods",
           "parse_tolerances", "quick_tolerances", "setting"]

KNOWN_METHODS = MEASURED
ALL_METHODS = tuple(name for name in MEASURED if METHODS[name].precision == "double")  # "all"; extended ones by name
CLOSED_LOOP = tuple(name for name in MEASURED if METHODS[name].closed_loops)  # Newton's method finds y_d


class AccuracyError(KronsubError):
    """A work-precision measurement that could not be made."""


def parse_tolerances(text: str) -> tuple[float, ...]:
    """``1e-4:1e-14`` (every decade between, both ends included), ``1e-4:1e-14:2`` (every
    second decade) or a list ``1e-6,1e-9``."""
    hint = "write e.g. --tolerances 1e-4:1e-14, 1e-4:1e-14:2 or 1e-6,1e-9,1e-12"
    try:
        if ":" in text:
            parts = text.split(":")
            if len(parts) not in (2, 3):
                raise ValueError
            first, last = float(parts[0]), float(parts[1])
            every = int(parts[2]) if len(parts) == 3 else 1
            if not (0 < first < 1 and 0 < last < 1 and every >= 1):
                raise ValueError
            a, b = math.log10(first), math.log10(last)
            count = int(math.floor(abs(b - a) / every + 1e-9)) + 1
            sign = -1 if b < a else 1
            values = [first * 10.0 ** (sign * every * i) for i in range(count)]
        else:
            values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise AccuracyError(f"--tolerances '{text}' is not a range or list of positive numbers below 1\n"
                            f"  hint: {hint}") \
            from None
    if not values or not all(0 < v < 1 for v in values):
        raise AccuracyError(f"--tolerances '{text}' must give positive numbers below 1 (relative tolerances)\n"
                            f"  hint: {hint}")
    return tuple(dict.fromkeys(float(f"{v:.6g}") for v in values))


def quick_tolerances(tolerances: tuple[float, ...]) -> tuple[float, ...]:
    """A coarse grid: every third tolerance, and the last."""
    picked = list(tolerances[::3])
    if tolerances[-1] not in picked:
        picked.append(tolerances[-1])
    return tuple(picked)


def fixed_step(method: str, tol: float, t_end: float) -> float:
    """The step of a fixed-step method of order p at tolerance ``tol``: ``tol^(1/p)``."""
    return min(tol ** (1.0 / METHODS[method].order), t_end / 8)


def setting(method: str, tol: float, t_end: float) -> str:
    """How ``method`` runs at ``tol``, as the table says it: ``h 0.0178`` or ``tol 1e-08``."""
    return f"h {fixed_step(method, tol, t_end):.3g}" if METHODS[method].fixed_step else f"tol {tol:.0e}"


def parse_methods(text: str | None) -> tuple[str, ...]:
    """``dop853,RK45`` or ``all`` (the default)."""
    if text is None or text.strip() == "all":
        return ALL_METHODS
    names = [m.strip() for m in text.split(",") if m.strip()]
    unknown = [m for m in names if m not in KNOWN_METHODS]
    if unknown or not names:
        raise AccuracyError(f"unknown method{'s' if len(unknown) > 1 else ''} {', '.join(unknown) or '(none)'}\n"
                            f"  hint: choose from {', '.join(KNOWN_METHODS)} (comma-separated), or all")
    return tuple(dict.fromkeys(names))
