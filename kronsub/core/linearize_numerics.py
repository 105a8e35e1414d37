"""What the two linearisations share (:mod:`.linearize`, and :mod:`.linearize_implicit` for
implicit constraints): the result and its error, and the numerics of ``Mbar qddot = r``,
``r = fbar - hbar`` (10'): evaluating the matrices, solving with ``Mbar``, the least-squares
search for an equilibrium ``r(q, 0) = 0``, and the eigenvalues of ``A``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
import sympy

from ..errors import KronsubError, assignment, option
from .finite import describe_rank_loss, nonfinite_cause
from .known_system import KnownSystem

EQUILIBRIUM_TOLERANCE = 1e-8  # largest |qddot| at a point called an equilibrium


class LinearizationError(KronsubError):
    """The operating point cannot be found or the system cannot be linearised there."""


@dataclass(frozen=True)
class Linearization:
    """``ydot ~ A (y - y*) + B (u - u*)`` about the operating point, ``y = [q; qdot]``.

    ``A`` and ``B`` are numpy arrays, or sympy matrices in the parameters when
    ``symbolic``; ``eigenvalues`` are those of ``A`` with the parameters' values
    (None when some parameter has no value).
    """

    state: tuple[sympy.Symbol, ...]
    inputs: tuple[sympy.Symbol, ...]
    point: tuple[tuple[sympy.Symbol, sympy.Expr], ...]  # q*, qdot*, then u*
    time: sympy.Expr
    parameters: tuple[tuple[sympy.Symbol, sympy.Expr], ...]  # values substituted
    A: np.ndarray | sympy.Matrix
    B: np.ndarray | sympy.Matrix
    eigenvalues: tuple[complex, ...] | None
    acceleration: tuple[float, ...]  # qddot at the point (zero at an equilibrium)
    equilibrium: bool
    found: tuple[sympy.Symbol, ...]  # coordinates solved for (not given)
    symbolic: bool = False
    notes: tuple[str, ...] = ()  # caveats to show with the result
    dependent: tuple[tuple[sympy.Symbol, float], ...] = ()  # implicit constraints: y_d at the point
    in_speeds: bool = False  # under velocity constraints: y = [kept coordinates; speeds], about a steady motion
    printed: Mapping[sympy.Symbol, str] = field(default_factory=dict)  # a charge's velocity: its current's name

    def name_of(self, s: sympy.Symbol) -> str:
        """The printed name of ``s`` (a charge's velocity and acceleration: its current and the rate)."""
        return self.printed.get(s, s.name)

    @property
    def stable(self) -> bool | None:
        """Every eigenvalue in the open left half plane (None when unknown)."""
        if self.eigenvalues is None:
            return None
        return all(e.real < 0 for e in self.eigenvalues)


def residual(system: KnownSystem) -> sympy.Matrix:
    """``r = fbar - hbar`` (10')."""
    return system.forces - system.velocity_terms


def numeric_value(expr: sympy.Expr, values: Mapping[sympy.Symbol, float]) -> float:
    """``expr`` at ``values`` as a float: NaN where a symbol is left or the value is complex."""
    value = sympy.sympify(expr).xreplace(values)
    try:
        return float(value.evalf(30)) if value.free_symbols == set() else float("nan")
    except TypeError:  # complex: outside the expression's real domain
        return float("nan")


class Evaluator:
    """Numeric matrices of symbolic ones at given values (lambdified once)."""

    def __init__(self, matrices: Sequence[sympy.Matrix], symbols: Sequence[sympy.Symbol]):
        self.matrices = list(matrices)
        self.shapes = [m.shape for m in matrices]
        flat = [e for m in matrices for e in m]
        self.symbols = list(symbols)
        self.fn = sympy.lambdify([self.symbols], flat, modules=["numpy"])

    def __call__(self, values: Mapping[sympy.Symbol, float]) -> list[np.ndarray]:
        with np.errstate(all="ignore"):  # numpy's doubles: (-1.0)**0.5 is NaN, not a Python complex
            flat = np.array(self.fn([np.float64(values[s]) for s in self.symbols]), dtype=float).ravel()
        out, start = [], 0
        for rows, cols in self.shapes:
            out.append(flat[start:start + rows * cols].reshape(rows, cols))
            start += rows * cols
        return out


def checked_inputs(system: KnownSystem, inputs) -> tuple:
    """The inputs, each one a parameter of ``system`` (else a :class:`LinearizationError`)."""
    inputs = tuple(inputs)
    known = {p.symbol for p in system.parameters}
    for u in inputs:
        if u not in known:
            raise LinearizationError(f"input '{u}' is not a parameter of {system.name}")
    return inputs


def parameter_defaults(system: KnownSystem) -> dict:
    """The parameters' default values, where they have one."""
    return {p.symbol: p.value for p in system.parameters if p.value is not None}


def parameter_numbers(system: KnownSystem, values: Mapping) -> tuple[dict, list[str]]:
    """Every parameter's value (``values`` over the defaults) as a float, NaN where none is
    known; and the names of those without one."""
    defaults = parameter_defaults(system)
    numbers: dict[sympy.Symbol, float] = {}
    missing = []
    for p in system.parameters:
        given = values.get(p.symbol, defaults.get(p.symbol))
        numbers[p.symbol] = numeric_value(given, {}) if given is not None else float("nan")
        if not np.isfinite(numbers[p.symbol]):
            missing.append(p.name)
    return numbers, missing


def solve_mass(Mn: np.ndarray, rhs: np.ndarray, values, q) -> np.ndarray:
    """``Mbar^-1 rhs`` at the state ``values`` of the coordinates ``q``; a :class:`LinearizationError`
    where ``Mbar`` is not positive definite or is singular there."""
    where = ", ".join(f"{s}={values[s]:.6g}" for s in q)
    try:
        np.linalg.cholesky(Mn)
    except np.linalg.LinAlgError:
        why = describe_rank_loss(Mn, [s.name for s in q])
        raise LinearizationError(f"the mass matrix is not positive definite at {where}"
                                 + (f"; {why}" if why else "")) from None
    try:  # Cholesky passes a matrix singular to round-off (Euler angles at their singularity)
        return np.linalg.solve(Mn, rhs)
    except np.linalg.LinAlgError:
        raise LinearizationError(f"the mass matrix is singular at {where} (a coordinate singularity, such as "
                                 "Euler angles where two axes line up)\n  hint: give another operating point "
                                 "with " + assignment("at") + ", or other coordinates") from None


def at_equilibrium(Mn: np.ndarray, rn: np.ndarray) -> bool:
    """Whether ``qddot = Mbar^-1 r`` is 0 to :data:`EQUILIBRIUM_TOLERANCE` (False where it has no
    value, or ``Mbar`` is singular)."""
    with np.errstate(all="ignore"):
        try:
            a = np.linalg.solve(Mn, rn)
        except np.linalg.LinAlgError:
            return False
    return bool(np.all(np.isfinite(a)) and np.max(np.abs(a), initial=0.0) <= EQUILIBRIUM_TOLERANCE)


def least_squares_equilibrium(fun, jac, x0: np.ndarray, settled, warm=None) -> np.ndarray:
    """The free coordinates where ``r(q, 0) = 0``, by least squares from ``x0``: first
    Levenberg-Marquardt; where it stalls short of an equilibrium (``settled`` false: near a
    turning point of the residual, where ``(dr/dq)^T r`` is small with ``r`` not, its steps
    shrink to nothing), the trust-region reflective method from the same start, whose trust
    region takes other steps; its answer is taken only where it settles. A point where
    Levenberg-Marquardt settles is kept as it is (the second method is not run), and so is the
    point where both stall (the one reported). ``warm = (get, put)`` reads and sets what ``fun``
    keeps between calls (a warm start): the second method starts from the first's start, and
    the first's answer comes back with its own."""
    from scipy.optimize import least_squares

    start = warm[0]() if warm is not None else None
    # unit scaling: scaled by the Jacobian's column norms (scipy's default for "lm"), a coordinate the
    # equilibrium does not fix, whose column is round-off (~1e-16) rather than 0, takes steps of ~1e15
    first = least_squares(fun, x0, jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, x_scale=1.0)
    if settled(first.x):
        return first.x
    kept = warm[0]() if warm is not None else None
    if warm is not None:
        warm[1](start)
    try:
        second = least_squares(fun, x0, jac=jac, method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15, x_scale=1.0)
        if settled(second.x):
            return second.x
    except (ValueError, np.linalg.LinAlgError, LinearizationError):  # a state without a value: the first stands
        pass
    if warm is not None:
        warm[1](kept)
    return first.x


def unevaluable(r, q, values, M, where: str = "at the initial values") -> str:
    """Why ``Mbar`` or ``r = fbar - hbar`` has no finite value at ``values``: an overflow (then
    another operating point does not help) or a function outside its domain (:mod:`.finite`)."""
    n = len(q)
    quantities = [(f"Mbar[{q[i].name}, {q[j].name}]", M[i, j]) for i in range(n) for j in range(i + 1)]
    cause = nonfinite_cause(quantities + [(f"(fbar - hbar)[{s.name}]", e) for s, e in zip(q, r)], values)
    if cause is None:
        return f"the equations cannot be evaluated {where}; give the operating point with " + assignment("at")
    hint = cause.hint if cause.overflow else f"{cause.hint}, or give the operating point with " + assignment("at")
    return f"the equations cannot be evaluated {where}: {cause.what}\n  hint: {hint}"


def sorted_eigenvalues(A: np.ndarray) -> tuple[complex, ...]:
    """Eigenvalues of ``A`` in a fixed order (by real part, then imaginary part)."""
    if A.size == 0:
        return ()
    if not np.all(np.isfinite(A)):
        raise LinearizationError("A is not finite at the operating point: the equations overflow a double "
                                 "there\n  hint: check the values given with " + option("at") + " and the parameters' values")
    values = np.linalg.eigvals(A)
    scale = max(1.0, float(np.max(np.abs(values))))
    cleaned = [complex(v.real if abs(v.real) > 1e-12 * scale else 0.0,
                       v.imag if abs(v.imag) > 1e-12 * scale else 0.0) for v in values]
    return tuple(sorted(cleaned, key=lambda c: (round(c.real, 9), round(c.imag, 9))))


__all__ = ["EQUILIBRIUM_TOLERANCE", "Evaluator", "Linearization", "LinearizationError", "at_equilibrium",
           "checked_inputs", "least_squares_equilibrium", "numeric_value", "parameter_defaults",
           "parameter_numbers", "residual", "solve_mass", "sorted_eigenvalues", "unevaluable"]
