"""Integrating the equations of motion: the method table and the run driver.

The right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` is the generated
C, compiled once and cached by content hash; without a C compiler the
generated numpy module stands in (with a one-line warning). A run is split
into chunks so long runs can show progress; a non-finite state or a mass
matrix that is not positive definite stops it, keeping the rows so far.
"""
from __future__ import annotations

import sys
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..core.known_system import KnownSystem
from ..emitters.code import emit_c, emit_python
from ..errors import KronsubError
from .native import CompilerNotFound, NativeModel, compile_library
from .values import RunValues


@dataclass(frozen=True)
class Method:
    name: str
    engine: str  # "c" (wholly in compiled C) or "scipy"
    summary: str


METHODS = {
    m.name: m
    for m in (
        Method("dop853", "c", "Dormand-Prince 8(5,3), adaptive, dense output at --dt; wholly in C (default: "
                              "accurate and fast for smooth non-stiff problems)"),
        Method("gauss4", "c", "2-stage Gauss-Legendre, fixed step --dt, symplectic in (q, p = Mbar qdot); for "
                              "long conservative runs: energy error stays bounded instead of drifting"),
        Method("RK45", "scipy", "scipy's Dormand-Prince 5(4) calling the compiled right-hand side"),
        Method("DOP853", "scipy", "scipy's DOP853 calling the compiled right-hand side"),
        Method("Radau", "scipy", "scipy's implicit Radau IIA (order 5): stiff problems (stiff springs, dampers)"),
        Method("LSODA", "scipy", "scipy's LSODA: switches between stiff and non-stiff automatically"),
        Method("heyoka", "heyoka", "heyoka's Taylor integrator (optional extra kronsub[heyoka]): the "
                                   "high-accuracy end, for small systems; tolerance --rtol"),
    )
}


class StiffnessWarning(UserWarning):
    """An explicit method found the problem stiff (Hairer's test): an implicit one would be cheaper."""


class SimulationError(KronsubError):
    """A run that could not start."""


@dataclass
class Trajectory:
    """Rows of a run: times, states ``[q; qdot]``, and how the run ended."""

    t: np.ndarray
    y: np.ndarray
    method: str
    complete: bool = True
    message: str = ""
    t_fail: float | None = None
    stats: dict = field(default_factory=dict)
    backend: str = ""
    energies: tuple[np.ndarray, np.ndarray] | None = None  # (T, V) per row, when computed in C


def _numpy_module(system: KnownSystem):
    """The generated numpy module, loaded from its text (our own generated code)."""
    namespace: dict = {}
    (generated,) = emit_python(system, "model")
    exec(compile(generated.text, f"<kronsub model {system.name}>", "exec"), namespace)
    return namespace


class _Progress:
    """A progress bar on stderr for runs longer than a second, only on a terminal."""

    def __init__(self, total: float, enabled: bool | None = None):
        self.total = total
        self.start = time.perf_counter()
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.shown = False

    def update(self, t: float) -> None:
        if not self.enabled or time.perf_counter() - self.start < 1.0:
            return
        frac = min(1.0, t / self.total) if self.total > 0 else 1.0
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r[{bar:<30}] t = {t:.4g} / {self.total:.4g}")
        sys.stderr.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown:
            sys.stderr.write("\n")


def simulate(system: KnownSystem, values: RunValues, t_end: float, dt: float, method: str = "dop853",
             rtol: float = 1e-10, atol: float = 1e-10, chunks: int = 20, progress: bool | None = None) -> Trajectory:
    """Integrate from t = 0 to ``t_end`` with rows every ``dt``."""
    if method not in METHODS:
        raise SimulationError(f"unknown method '{method}'; choose one of: {', '.join(METHODS)}")
    if not (t_end > 0 and dt > 0):
        raise SimulationError("--t and --dt must be positive")
    param = np.array(values.parameters, dtype=float)
    y0 = np.array(values.y0, dtype=float)
    grid = _grid(t_end, dt)
    if METHODS[method].engine == "heyoka":
        return _run_heyoka(system, param, y0, grid, rtol)
    native = None
    try:
        generated = [(g.name, g.text) for g in emit_c(system, "model")]
        native = NativeModel(compile_library(generated, "model"), len(system.coordinates), len(system.parameters))
    except CompilerNotFound:
        warnings.warn("no C compiler found: using the generated numpy module (slower)")
    spec = METHODS[method]
    if native is None and spec.engine == "c":
        fallback = "DOP853"
        warnings.warn(f"method '{method}' runs in compiled C; using scipy's {fallback} instead")
        spec = METHODS[fallback]
    bar = _Progress(t_end, progress)
    if not bar.enabled:
        chunks = 1  # one call: no restarts of the step-size control
    try:
        if spec.engine == "c":
            traj = _run_native(native, spec.name, grid, y0, param, rtol, atol, dt, chunks, bar, system)
        else:
            rhs = _native_rhs(native, param) if native is not None else _numpy_rhs(system, param)
            traj = _run_scipy(rhs, spec.name, grid, y0, rtol, atol, chunks, bar, system)
    finally:
        bar.close()
    traj.backend = "C" if native is not None else "numpy"
    if native is not None and _stiffness(traj.stats) and len(traj.t):
        warnings.warn(StiffnessWarning(_stiffness_advice(native, param, traj, method)))
    if native is not None and len(traj.t):
        traj.energies = native.energies(traj.t, traj.y, param)
    return traj


def _stiffness(stats: dict) -> bool:
    """Whether an explicit adaptive run's step size was held by stability: Hairer's test fired, or
    the step size bounced on the stability boundary (a large share of rejected steps over many)."""
    steps, rejected = stats.get("steps", 0), stats.get("rejected", 0)
    return "stiff_from" in stats or (steps + rejected >= STIFF_MIN_STEPS
                                     and rejected >= STIFF_REJECTED_SHARE * (steps + rejected))


def _fastest_mode(native, param, t: float, y: np.ndarray) -> complex:
    """The eigenvalue of largest modulus of the Jacobian of the right-hand side at ``y``
    (central differences)."""
    n = len(y)
    J = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1e-6 * max(1.0, abs(y[j]))
        J[:, j] = (native.rhs(t, y + e, param) - native.rhs(t, y - e, param)) / (2 * e[j])
    lam = np.linalg.eigvals(J)
    return complex(lam[np.argmax(np.abs(lam))])


def _stiffness_advice(native, param, traj, method: str) -> str:
    """What to do about a stiff run: an implicit method when its fastest mode is damped; when
    it is an undamped oscillation, every method has to follow it, so say that instead."""
    steps, rejected = traj.stats["steps"], traj.stats["rejected"]
    cost = f"{steps} steps, {rejected} rejected, mean step {(traj.t[-1] - traj.t[0]) / max(steps, 1):.3g}"
    try:
        lam = _fastest_mode(native, param, float(traj.t[-1]), np.asarray(traj.y[-1], dtype=float))
    except Exception:  # noqa: BLE001 - the advice is a courtesy; a failed evaluation must not stop the run
        lam = complex("nan")
    mode = f"fastest mode lambda = {lam.real:.3g}{lam.imag:+.3g}i"
    if np.isfinite(lam.real) and -lam.real >= STIFF_DAMPED_SHARE * abs(lam):
        return (f"the problem is stiff: {method}'s step size is held by stability, not accuracy ({cost}; {mode}); "
                "an implicit method is far cheaper here: use --method Radau")
    return (f"a fast oscillation holds {method}'s step size ({cost}; {mode}, period "
            f"{2 * np.pi / max(abs(lam.imag), 1e-300):.3g}): it is undamped, so every method must follow it; "
            "an implicit method (--method Radau) pays off only where the fast mode is damped")


STIFF_MIN_STEPS = 5000        # fewer steps are cheap whatever the cause
STIFF_REJECTED_SHARE = 0.25   # accuracy-limited smooth runs reject a few per cent
STIFF_DAMPED_SHARE = 0.05     # a fast mode that decays by e within 20 radians counts as damped


def _grid(t_end: float, dt: float) -> np.ndarray:
    """Output times 0, dt, 2 dt, ... and exactly t_end."""
    grid = np.arange(0.0, t_end + 0.5 * dt, dt)
    if abs(grid[-1] - t_end) < 0.5 * dt:
        grid[-1] = t_end
    if grid[-1] < t_end:
        grid = np.append(grid, t_end)
    return grid


def _run_heyoka(system, param, y0, grid, tol) -> Trajectory:
    try:
        from . import heyoka_backend
    except ImportError:
        heyoka_backend = None
    if heyoka_backend is None or not heyoka_backend.available():
        raise SimulationError("method 'heyoka' needs heyoka: pip install 'kronsub[heyoka]'")
    t, Y, complete, message = heyoka_backend.integrate(system, param, y0, grid, tol)
    return Trajectory(t, Y, "heyoka", complete, message, None if complete else float(t[-1]), {}, "heyoka")


def _native_rhs(native, param):
    from .native import SingularMassMatrix

    rhs = native.scipy_rhs(param)

    def f(t, y):
        try:
            return rhs(t, y)
        except SingularMassMatrix as exc:
            raise _Singular(t, y) from exc

    return f


def _numpy_rhs(system, param):
    module = _numpy_module(system)
    rhs = module["rhs"]

    def f(t, y):
        try:
            return rhs(t, y, param)
        except np.linalg.LinAlgError as exc:
            raise _Singular(t, y) from exc

    return f


class _Singular(Exception):
    def __init__(self, t, y):
        super().__init__(t)
        self.t, self.y = t, y


def _chunks(grid: np.ndarray, count: int):
    """Index ranges of the output grid, one per chunk."""
    edges = np.unique(np.linspace(0, len(grid) - 1, min(count, len(grid) - 1) + 1).astype(int))
    return list(zip(edges[:-1], edges[1:]))


def _where(system, y) -> str:
    """The configuration at a failure, for the message."""
    if y is None:
        return ""
    return " at " + ", ".join(f"{q.name}={v:.6g}" for q, v in zip(system.coordinates, y))


def _run_native(native, method, grid, y0, param, rtol, atol, dt, chunks, bar, system) -> Trajectory:
    times, rows = [grid[0]], [y0]
    stats = {"steps": 0, "rejected": 0, "evaluations": 0}
    y = y0
    for a, b in _chunks(grid, chunks):
        t, Y, result = native.integrate(method, grid[a], y, grid[b], dt, param, rtol=rtol, atol=atol,
                                        h=dt if method == "gauss4" else None)
        stats["steps"] += result.n_steps
        stats["rejected"] += result.n_rejected
        stats["evaluations"] += result.n_evals
        if result.t_stiff is not None and "stiff_from" not in stats:
            stats["stiff_from"] = result.t_stiff
        keep = t > times[-1] + 1e-12 * max(1.0, abs(times[-1]))
        times.extend(t[keep])
        rows.extend(Y[keep])
        if result.status != 0:
            message = result.message + (_where(system, result.y_fail) if result.status in (1, 2) else "")
            return Trajectory(np.array(times), np.array(rows), method, False, message, result.t_fail, stats)
        y = Y[-1]
        bar.update(grid[b])
    return Trajectory(np.array(times), np.array(rows), method, True, "", None, stats)


def _run_scipy(rhs, method, grid, y0, rtol, atol, chunks, bar, system) -> Trajectory:
    from scipy.integrate import solve_ivp

    times, rows = [grid[0]], [y0]
    stats = {"evaluations": 0}
    y = y0
    for a, b in _chunks(grid, chunks):
        try:
            with np.errstate(all="ignore"):
                sol = solve_ivp(rhs, (grid[a], grid[b]), y, method=method, t_eval=grid[a:b + 1],
                                rtol=rtol, atol=atol)
        except _Singular as exc:
            return Trajectory(np.array(times), np.array(rows), method, False,
                              "the mass matrix is singular or not positive definite" + _where(system, exc.y), exc.t, stats)
        except (ValueError, RuntimeError) as exc:
            return Trajectory(np.array(times), np.array(rows), method, False, str(exc), times[-1], stats)
        stats["evaluations"] += int(sol.nfev)
        good = np.all(np.isfinite(sol.y), axis=0)
        t_new, y_new = sol.t[1:], sol.y.T[1:]
        finite = good[1:]
        if not np.all(finite) or sol.status < 0:
            stop = int(np.argmin(finite)) if not np.all(finite) else len(t_new)
            times.extend(t_new[:stop])
            rows.extend(y_new[:stop])
            cause = "the state became NaN or infinite" if not np.all(finite) else sol.message
            t_fail = float(t_new[stop]) if stop < len(t_new) else float(sol.t[-1])
            return Trajectory(np.array(times), np.array(rows), method, False, cause, t_fail, stats)
        times.extend(t_new)
        rows.extend(y_new)
        y = y_new[-1]
        bar.update(grid[b])
    return Trajectory(np.array(times), np.array(rows), method, True, "", None, stats)
