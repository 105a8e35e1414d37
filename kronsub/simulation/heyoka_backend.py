"""Optional backend: heyoka's adaptive Taylor integrator, for the high-accuracy end.

heyoka (https://bluescarni.github.io/heyoka.py/) compiles an explicit ODE with LLVM and
integrates it by a Taylor method of the order its tolerance asks for. We give it

    qdot  = qdot
    qddot = Mbar^-1 (fbar - hbar)                      from Mbar qddot + hbar = fbar  (10')

on the state ``y = [q; qdot]``. ``Mbar^-1`` is not formed: ``Mbar = L D L^T`` is factored
symbolically on heyoka expressions (``Mbar`` is symmetric positive definite, so no pivoting),
followed by the two triangular solves; heyoka's decomposition shares the repeated
subexpressions, so the ODE stays ``O(n^3)`` operations instead of sympy's expanding inverse.
The parameters become heyoka's runtime parameters ``par[i]`` (in ``system.parameters`` order),
so one compiled integrator serves any parameter values. Above three coordinates heyoka's
compact mode is used: it compiles in seconds where the unrolled code takes minutes (n = 10:
2 s against > 4 min), for steps a few times slower. kronsub caches nothing on disk; heyoka
keeps its own cache of compiled code (``heyoka.llvm_state.set_diskcache_enabled``).

Install with ``pip install 'kronsub[heyoka]'``.
"""
from __future__ import annotations

import numpy as np
import sympy

from ..core.known_system import KnownSystem
from ..core.symbols import TIME
from ..errors import KronsubError

__all__ = ["INSTALL_HINT", "HeyokaIntegrator", "available", "integrate", "ode"]

INSTALL_HINT = "pip install 'kronsub[heyoka]'"


def available() -> bool:
    """Whether heyoka can be imported."""
    try:
        _heyoka()
    except KronsubError:
        return False
    return True


def _heyoka():
    try:
        import heyoka
    except ImportError as exc:
        raise KronsubError(f"the heyoka backend needs the heyoka package ({exc}); "
                           f"install it with: {INSTALL_HINT}") from None
    return heyoka


def _float_rationals(expr: sympy.Expr) -> sympy.Expr:
    """Rationals as doubles: heyoka converts only those with a power-of-2 denominator."""
    swap = {r: sympy.Float(r, precision=53) for r in expr.atoms(sympy.Rational)
            if not r.is_Integer and r.q & (r.q - 1)}
    return expr.xreplace(swap) if swap else expr


def _without_abs(hy, expr: sympy.Expr, names: dict) -> tuple[sympy.Expr, dict]:
    """``expr`` and the names for ``hy.from_sympy`` with ``Abs(x)`` and ``sign(x)`` standing for
    heyoka's ``relu(x) + relu(-x)`` and ``relup(x) - relup(-x)`` (heyoka has no ``abs``; a spring
    whose length is a coordinate brings ``Abs``), innermost first: exact at ``x = 0`` (``sign(0)
    = 0``, where ``x / sqrt(x**2)`` is NaN), and differentiated as kronsub does (``d sign/dx = 0``,
    ``d |x|/dx = sign(x)``: :mod:`kronsub.core.derivative`)."""
    names = dict(names)
    while True:
        found = sorted(expr.atoms(sympy.Abs, sympy.sign), key=sympy.default_sort_key)
        inner = [a for a in found if not a.args[0].has(sympy.Abs, sympy.sign)]
        if not inner:
            return expr, names
        swap = {}
        for k, atom in enumerate(inner):
            x = hy.from_sympy(atom.args[0], names)
            stand_in = sympy.Dummy(f"abs{len(names)}_{k}")
            names[stand_in] = (hy.relu(x) + hy.relu(-x) if isinstance(atom, sympy.Abs)
                                else hy.relup(x) - hy.relup(-x))
            swap[atom] = stand_in
        expr = expr.xreplace(swap)


def ode(system: KnownSystem) -> list:
    """heyoka's ``[(y_i, ydot_i), ...]`` for ``y = [q; qdot]``, ``qddot = Mbar^-1 (fbar - hbar)``."""
    hy = _heyoka()
    n = len(system.coordinates)
    q = [hy.expression(s.name) for s in system.coordinates]
    qd = [hy.expression(s.name) for s in system.velocities]
    names = {**dict(zip(system.coordinates, q)), **dict(zip(system.velocities, qd)),
             **{p.symbol: hy.par[i] for i, p in enumerate(system.parameters)}, TIME: hy.time}

    def convert(expr):
        """A heyoka expression, or None for an exact zero (so sparse terms are skipped)."""
        expr = sympy.sympify(expr)
        if expr == 0:
            return None
        unknown = expr.free_symbols - set(names)
        if unknown:
            raise KronsubError("heyoka backend: " + ", ".join(sorted(s.name for s in unknown))
                               + " is neither a parameter, a coordinate, a velocity nor t")
        try:
            return hy.from_sympy(*_without_abs(hy, _float_rationals(expr), names))
        except (TypeError, ValueError) as exc:
            raise KronsubError(f"heyoka backend cannot convert {expr}: {exc}") from None

    def minus(a, terms):
        """``a - sum(terms)`` with None as zero."""
        terms = [t for t in terms if t is not None]
        if not terms:
            return a
        s = terms[0] if len(terms) == 1 else hy.sum(terms)
        return -s if a is None else a - s

    def times(*factors):
        return None if any(f is None for f in factors) else hy.prod(list(factors))

    M = system.mass_matrix
    r = system.forces - system.velocity_terms
    # Mbar = L D L^T, L unit lower triangular
    L = [[None] * n for _ in range(n)]
    D = [None] * n
    for j in range(n):
        D[j] = minus(convert(M[j, j]), [times(L[j][k], L[j][k], D[k]) for k in range(j)])
        if D[j] is None:
            raise KronsubError(f"heyoka backend: Mbar is singular (pivot {j} is identically zero)")
        for i in range(j + 1, n):
            num = minus(convert(M[i, j]), [times(L[i][k], L[j][k], D[k]) for k in range(j)])
            L[i][j] = None if num is None else num / D[j]
    # L z = r, then L^T x = D^-1 z
    z = [None] * n
    for i in range(n):
        z[i] = minus(convert(r[i]), [times(L[i][k], z[k]) for k in range(i)])
    x = [None] * n
    for i in reversed(range(n)):
        w = None if z[i] is None else z[i] / D[i]
        x[i] = minus(w, [times(L[k][i], x[k]) for k in range(i + 1, n)])
    zero = hy.expression(0.0)
    return list(zip(q, qd)) + [(v, a if a is not None else zero) for v, a in zip(qd, x)]


class HeyokaIntegrator:
    """A compiled heyoka integrator of one system at one tolerance, reusable for any
    parameters, initial state and output grid."""

    def __init__(self, system: KnownSystem, tol: float, compact: bool | None = None):
        hy = _heyoka()
        if not tol > 0:
            raise ValueError(f"tol must be positive (got {tol})")
        self.ny = 2 * len(system.coordinates)
        self.nparam = len(system.parameters)
        compact = len(system.coordinates) > 3 if compact is None else compact
        equations = ode(system)
        # heyoka takes as many values as the highest parameter the equations use (none when they
        # cancel, as in m*sign(q)**2*qddot = 0): the others it does not see
        used = [int(str(p)[1:]) for p in hy.get_params([rhs for _, rhs in equations])]
        self.used = max(used) + 1 if used else 0
        self.ta = hy.taylor_adaptive(equations, np.zeros(self.ny), tol=tol,
                                     pars=np.zeros(self.used), compact_mode=compact)
        self.finished = hy.taylor_outcome.time_limit  # the outcome of a propagation that reached its end
        self._nonfinite = hy.taylor_outcome.err_nf_state

    def start(self, t0: float, y0, param) -> None:
        """Set the time, the state and the parameters (those the equations use) of :attr:`ta`."""
        self.ta.time = t0
        self.ta.state[:] = y0
        self.ta.pars[:] = np.asarray(param, dtype=float).ravel()[:self.used]

    def run(self, param, y0, grid) -> tuple[np.ndarray, np.ndarray, bool, str]:
        """``(t, Y, complete, message)``: rows ``Y = [q; qdot]`` at the ``grid`` times from
        ``y0`` at ``grid[0]``. On a failure, the rows before it and ``complete = False``."""
        param = np.asarray(param, dtype=float).ravel()
        y0 = np.asarray(y0, dtype=float).ravel()
        grid = np.asarray(grid, dtype=float).ravel()
        if param.size != self.nparam:
            raise ValueError(f"param must have {self.nparam} entries (got {param.size})")
        if y0.size != self.ny or not np.all(np.isfinite(y0)):
            raise ValueError(f"y0 must have {self.ny} finite entries (got {y0})")
        if grid.size < 1 or not np.all(np.isfinite(grid)) or np.any(np.diff(grid) < 0):
            raise ValueError("grid must be a non-empty, finite, non-decreasing array of times")
        ta = self.ta
        self.start(grid[0], y0, param)
        outcome, *_, Y = ta.propagate_grid(grid)
        if outcome == self.finished:
            return grid.copy(), np.asarray(Y), True, ""
        Y = np.asarray(Y).reshape(-1, self.ny)  # only the rows reached
        good = np.all(np.isfinite(Y), axis=1)
        keep = int(np.argmin(good)) if not np.all(good) else len(Y)
        cause = ("the state became NaN or infinite" if outcome == self._nonfinite
                 else f"heyoka outcome {outcome.name}")
        when = ta.time if np.isfinite(ta.time) else grid[min(keep, len(grid) - 1)]
        return grid[:keep].copy(), Y[:keep], False, f"{cause} at t = {when:.17g}"


def integrate(system: KnownSystem, param: np.ndarray, y0: np.ndarray, grid: np.ndarray,
              tol: float) -> tuple[np.ndarray, np.ndarray, bool, str]:
    """Compile heyoka's integrator of ``system`` at ``tol`` and run it over ``grid``:
    ``(t, Y, complete, message)`` with rows ``Y = [q; qdot]`` (see :class:`HeyokaIntegrator`)."""
    return HeyokaIntegrator(system, tol).run(param, y0, grid)
