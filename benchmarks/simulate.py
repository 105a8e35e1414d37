#!/usr/bin/env python
"""Benchmark: the cost of kronsub's generated right-hand side, and of simulating with it.

Usage::

    python benchmarks/simulate.py [--quick]

a. One evaluation of ``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` for the 2-, 5- and 10-link rod
   chains (``models/chain/generate.py``) at varying random states, by

   * ``C from C``: the generated C, called in a loop by a small C harness compiled with it at
     ``-O2`` and the flags kronsub builds its libraries with for this processor
     (``native.host_flags()``; written and built at run time);
   * ``C circle state``: the same harness calling the right-hand side of the circle state
     ``[q; qdot; cos q; sin q]`` (``ks_rhs_circle_pre``, ``kronsub/emitters/circle.py``), which
     ``dop853`` and ``rk4`` integrate: no sine or cosine evaluated;
   * ``C from Python``: the same C through ctypes (``NativeModel.scipy_rhs``, what scipy calls);
   * ``numpy module``: the generated numpy module (``emit_python``);
   * ``lambdify``: ``sympy.lambdify(cse=True)`` of ``Mbar`` and ``fbar - hbar`` with
     ``numpy.linalg.solve`` (the peer every ratio is taken against);
   * ``PyDy cython``: PyDy's cython backend on the same ``Mbar``, ``fbar - hbar``, if it installs.

   Targets: the C at n = 10 in <= 0.5 us and >= 100x faster than lambdify; issue 9: the
   right-hand side the integrators call at n = 10 in <= 0.3 us.

b. The double pendulum of two uniform rods (System I with its defaults: masses 1, lengths 1,
   g = 9.81; initial angles 120 and -10 degrees, at rest) to t = 10: wall time of the
   integration alone (compilation and setup excluded, best of several runs) and the largest
   error of the state at t = 10 against the 40-digit reference
   ``../shared/reference/double-pendulum-rods.json``, for kronsub's C ``dop853`` (in the circle
   state, as ``simulate`` runs it, and in ``[q; qdot]``) and ``gauss4``,
   scipy's methods calling the compiled C right-hand side, and heyoka (if installed; its
   compile time apart). Target: error <= 1e-8 in <= 0.5 ms. The rows of ``taylor`` and of
   heyoka (0.1-1 ms each) are timed interleaved, 200 rounds of every tolerance in turn, so a
   slow phase of the machine (they come in bursts of seconds) falls on all of them alike.

c. Where the C ``dop853`` time goes: the same integration called from C, from Python through
   ctypes, and the right-hand side's share.

d. The two routes of the generated C per call, the 10- to 30-link chains: ``Mbar``, ``hbar`` and
   ``fbar`` from the derived expressions (``expanded``, the route of every size when issue 34 was
   filed) and formed at run time (``projected``, ``kronsub/emitters/projected.py``, what ``auto``
   takes from ``PROJECTED_FROM`` coordinates on), each in the circle state's right-hand side
   called by the C harness of a.; min and median over 5 rounds (each the best of 3 loops), and
   projected / expanded. Goal (issue 34): projected no slower per call than expanded at 20 links.
   ``--routes`` runs this section alone.

``--quick`` shortens every loop (and builds PyDy only for n = 2) to finish within a minute.
"""
from __future__ import annotations

import argparse
import ctypes
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy

REPO = Path(__file__).resolve().parent.parent
REFERENCE = REPO.parent / "shared" / "reference" / "double-pendulum-rods.json"
if not REFERENCE.exists():  # the repository's own copy (tests/data/double_pendulum_reference.py)
    REFERENCE = REPO / "tests" / "data" / "double_pendulum_rods.json"
SIZES = (2, 5, 10)
RHS_TARGET_NS = 500.0
RHS_TARGET_RATIO = 100.0
ISSUE9_RHS_NS = 300.0  # issue 9: the right-hand side the integrators call, n = 10
ERROR_TARGET = 1e-8
TIME_TARGET_MS = 0.5
FRONTIER = ((2.5e-9, None), (1e-6, 0.15))  # issue 9: (error, ms): faster than heyoka's best there / within ms

sys.path.insert(0, str(REPO / "models" / "chain"))

import kronsub  # noqa: E402
from generate import chain_yaml  # noqa: E402
from kronsub.emitters.code import emit_c, emit_python  # noqa: E402
from kronsub.simulation.native import (CSRC, INTEGRATOR_FILES, NativeModel, _CResult,  # noqa: E402
                                      compile_library, compiler_command, host_flags)
from kronsub.simulation.values import resolve  # noqa: E402

HARNESS = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "model.h"
#include "integrators.h"

#define K 256 /* distinct states, cycled */

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* usage: harness rhs CALLS REPEATS p0 p1 ...     (circle: the circle state's ks_rhs_circle_pre)
          harness dop853 RUNS REPEATS TOL T_END y0_0 .. y0_{ny-1} p0 p1 ... */
int main(int argc, char **argv) {
    static double ys[K][KS_NZ], param[KS_NPARAM + 1], pre[KS_NPRE + 1], ydot[KS_NZ];
    int circle = argv[1][0] == 'c', rhs = argv[1][0] == 'r' || circle;
    long calls = atol(argv[2]);
    int repeats = atoi(argv[3]), first = rhs ? 4 : 6 + KS_NY;
    for (int i = 0; i < KS_NPARAM; i++) param[i] = atof(argv[first + i]);
    ks_prepare(param, pre);  /* once per parameter set, as the integrators do */
    double best = 1e300, sink = 0.0;
    long failed = 0;
    if (rhs) {
        unsigned long s = 12345;
        for (int k = 0; k < K; k++)
            for (int i = 0; i < KS_NY; i++) {
                s = s * 6364136223846793005UL + 1442695040888963407UL;
                double u = (double)(s >> 11) / 9007199254740992.0;
                ys[k][i] = i < KS_NQ ? 6.283185307179586 * (u - 0.5) : 4 * (u - 0.5);
            }
#if KS_NC > 0
        for (int k = 0; k < K && circle; k++) {
            double y[KS_NY];
            for (int i = 0; i < KS_NY; i++) y[i] = ys[k][i];
            ks_circle_state(y, ys[k]);
        }
#endif
        for (int r = 0; r < repeats; r++) {
            double t0 = now();
            for (long c = 0; c < calls; c++) {
#if KS_NC > 0
                failed += circle ? ks_rhs_circle_pre(0.0, ys[c & (K - 1)], pre, ydot)
                                 : ks_rhs_pre(0.0, ys[c & (K - 1)], pre, ydot);
#else
                failed += ks_rhs_pre(0.0, ys[c & (K - 1)], pre, ydot);
#endif
                sink += ydot[KS_NY - 1];
            }
            double dt = now() - t0;
            if (dt < best) best = dt;
        }
        printf("%.6g %ld %.6g\n", 1e9 * best / calls, failed, sink);
    } else {
        double tol = atof(argv[4]), t_end = atof(argv[5]), y0[KS_NY], out[3 * (KS_NY + 1)];
        static double work[27 * KS_NY];
        ks_result res;
        for (int i = 0; i < KS_NY; i++) y0[i] = atof(argv[6 + i]);
        for (int r = 0; r < repeats; r++) {
            double t0 = now();
            for (long c = 0; c < calls; c++) {
                ks_dop853(ks_rhs_pre, KS_NY, pre, 0.0, y0, t_end, t_end, tol, tol, 0.0, 0, out, 3,
                          work, &res);
                sink += out[KS_NY + 1];
            }
            double dt = now() - t0;
            if (dt < best) best = dt;
        }
        printf("%.6g %d %ld %ld", 1e9 * best / calls, res.status, res.n_steps, res.n_evals);
        for (int i = 0; i < KS_NY; i++) printf(" %.17g", out[KS_NY + 2 + i]);
        printf("\n");
    }
    return 0;
}
"""


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------

def interleaved(fns: dict, rounds: int) -> tuple[dict, dict]:
    """The shortest and the median wall time of each of ``fns`` (seconds) over ``rounds`` rounds
    that call every one in turn, and each one's last result. The machine's slow phases come in
    bursts of seconds, longer than a row's repeats: measured one after another, a burst can slow one
    row alone; in turn, it falls on every row alike."""
    times = {key: [] for key in fns}
    results = {}
    for _ in range(rounds):
        for key, fn in fns.items():
            t0 = time.perf_counter()
            results[key] = fn()
            times[key].append(time.perf_counter() - t0)
    return {key: (min(v), sorted(v)[len(v) // 2]) for key, v in times.items()}, results


def best_of(fn, repeats: int) -> float:
    """The shortest wall time of ``repeats`` calls of ``fn()``, in seconds."""
    return min_median(fn, repeats)[0]


def min_median(fn, repeats: int) -> tuple[float, float]:
    """The shortest and the median wall time of ``repeats`` calls of ``fn()``, in seconds."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    times.sort()
    return times[0], times[len(times) // 2]


def chain(n: int):
    model = kronsub.load(f"chain{n}.yaml", text=chain_yaml(n))
    system = model.derive()
    return system, np.array(resolve(system, dict(model.initial), {}).parameters)


def random_states(n: int, count: int, seed: int = 1) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [np.concatenate([rng.uniform(-math.pi, math.pi, n), rng.uniform(-2, 2, n)])
            for _ in range(count)]


class Harness:
    """The generated C of a system compiled with the integrators and the C timing harness."""

    def __init__(self, system, folder: Path, route: str = "auto"):
        folder.mkdir(parents=True, exist_ok=True)
        for g in emit_c(system, "model", route=route):
            (folder / g.name).write_text(g.text)
        for name in INTEGRATOR_FILES:
            (folder / name).write_text((CSRC / name).read_text())
        (folder / "harness.c").write_text(HARNESS)
        self.exe = folder / "harness"
        proc = subprocess.run([*compiler_command(), "-std=c99", "-D_POSIX_C_SOURCE=199309L", "-O2", *host_flags(),
                               "-o", str(self.exe), "harness.c", "model.c", "integrators.c", "-lm"],
                              cwd=folder, capture_output=True, text=True)
        if proc.returncode:
            raise RuntimeError(f"compiling the C harness failed:\n{proc.stderr}")

    def _run(self, *args) -> list[str]:
        text = [a if isinstance(a, str) else repr(float(a)) for a in args]
        return subprocess.run([str(self.exe), *text], check=True, capture_output=True,
                              text=True).stdout.split()

    def rhs_ns(self, param, calls: int, repeats: int = 5, circle: bool = False) -> float:
        ns, failed = self._run("circle" if circle else "rhs", str(calls), str(repeats), *param)[:2]
        if int(failed):
            raise RuntimeError(f"ks_rhs failed in {failed} of the timed calls")
        return float(ns)

    def dop853(self, param, y0, t_end: float, tol: float, runs: int, repeats: int = 5):
        """(ns per integration, steps, evaluations, final state)."""
        out = self._run("dop853", str(runs), str(repeats), tol, t_end, *y0, *param)
        if int(out[1]):
            raise RuntimeError(f"ks_dop853 failed with status {out[1]}")
        return float(out[0]), int(out[2]), int(out[3]), np.array([float(v) for v in out[4:]])


def native_model(system) -> NativeModel:
    files = {g.name: g.text for g in emit_c(system, "model")}
    library = compile_library([("model.h", files["model.h"]), ("model.c", files["model.c"])], "bench")
    return NativeModel(library, len(system.coordinates), len(system.parameters))


# ---------------------------------------------------------------------------------------------
# a. one right-hand side evaluation
# ---------------------------------------------------------------------------------------------

def numpy_rhs(system, param):
    (generated,) = emit_python(system, "model")
    namespace: dict = {}
    exec(compile(generated.text, "<kronsub numpy module>", "exec"), namespace)
    rhs = namespace["rhs"]
    return lambda t, y: rhs(t, y, param)


def lambdify_rhs(system, param):
    n = len(system.coordinates)
    fn = sympy.lambdify([list(system.coordinates), list(system.velocities),
                         [p.symbol for p in system.parameters]],
                        [system.mass_matrix, system.forces - system.velocity_terms],
                        cse=True, modules="numpy")

    def rhs(t, y):
        M, r = fn(y[:n], y[n:], param)
        return np.concatenate([y[n:], np.linalg.solve(M, np.ravel(r))])

    return rhs


def pydy_rhs(system, param, folder: Path):
    """PyDy's cython backend (form [3]: minimal mass matrix, q' = u) and its build time."""
    import sympy.physics.mechanics as me
    from pydy.codegen.ode_function_generators import generate_ode_function

    n = len(system.coordinates)
    qs, us = me.dynamicsymbols(f"q:{n}"), me.dynamicsymbols(f"u:{n}")
    swap = {**dict(zip(system.coordinates, qs)), **dict(zip(system.velocities, us))}
    here = os.getcwd()
    folder.mkdir(parents=True, exist_ok=True)
    os.chdir(folder)  # cython writes its build files into the working folder
    try:
        t0 = time.perf_counter()
        fn = generate_ode_function((system.forces - system.velocity_terms).xreplace(swap), qs, us,
                                   [p.symbol for p in system.parameters],
                                   mass_matrix=system.mass_matrix.xreplace(swap),
                                   coordinate_derivatives=sympy.Matrix(us), generator="cython",
                                   constants_arg_type="array")
        built = time.perf_counter() - t0
    finally:
        os.chdir(here)
    return (lambda t, y: fn(y, t, param)), built


def per_call_ns(rhs, states, calls: int, repeats: int = 3) -> float:
    ys = [states[i % len(states)] for i in range(calls)]

    def loop():
        for y in ys:
            rhs(0.0, y)

    return 1e9 * best_of(loop, repeats) / calls


def section_rhs(quick: bool, scratch: Path) -> None:
    c_calls = 100_000 if quick else 1_000_000
    py_calls = {"C from Python": 20_000, "numpy module": 3_000, "lambdify": 3_000, "PyDy cython": 3_000}
    if quick:
        py_calls = {k: max(300, v // 10) for k, v in py_calls.items()}
    try:
        import pydy  # noqa: F401

        pydy_state = None
    except ImportError as exc:
        pydy_state = f"not available ({exc})"

    print("a. One right-hand side evaluation ydot = [qdot; Mbar^-1 (fbar - hbar)], n-link rod chain,")
    print(f"   {256} random states cycled; ns per call (best of repeats); speed-up = lambdify / row")
    print(f"   target: C at n = 10 <= {RHS_TARGET_NS:.0f} ns and >= {RHS_TARGET_RATIO:.0f}x faster than lambdify")
    print()
    header = f"{'n':>3}  {'backend':<14} {'ns/call':>11} {'speed-up':>9}  {'max |diff|':>10}  note"
    print(header)
    print("-" * len(header))
    for n in SIZES:
        system, param = chain(n)
        states = random_states(n, 256)
        rows = []
        harness = Harness(system, scratch / f"chain{n}")
        rows.append(("C from C", harness.rhs_ns(param, c_calls), None, ""))
        rows.append(("C circle state", harness.rhs_ns(param, c_calls, circle=True), None, ""))
        native = native_model(system)
        backends = {"C from Python": native.scipy_rhs(param),
                    "numpy module": numpy_rhs(system, param),
                    "lambdify": lambdify_rhs(system, param)}
        note = {}
        if pydy_state is None and (not quick or n == 2):
            try:
                backends["PyDy cython"], built = pydy_rhs(system, param, scratch / f"pydy{n}")
                note["PyDy cython"] = f"build {built:.1f} s"
            except Exception as exc:  # noqa: BLE001 - any build failure means "not available"
                pydy_state = f"not available ({type(exc).__name__}: {str(exc).splitlines()[0][:80]})"
        expected = backends["C from Python"](0.0, states[0])
        for name, rhs in backends.items():
            diff = float(np.max(np.abs(rhs(0.0, states[0]) - expected)))
            rows.append((name, per_call_ns(rhs, states, py_calls[name]), diff, note.get(name, "")))
        lam = dict((r[0], r[1]) for r in rows)["lambdify"]
        for name, ns, diff, extra in rows:
            ratio = lam / ns
            if name in ("C from C", "C circle state") and n == 10:
                ok = ns <= RHS_TARGET_NS and ratio >= RHS_TARGET_RATIO
                extra = (f"target <= {RHS_TARGET_NS:.0f} ns, >= {RHS_TARGET_RATIO:.0f}x: "
                         + ("MET" if ok else "missed"))
                if name == "C circle state":
                    extra += f"; <= {ISSUE9_RHS_NS:.0f} ns: " + ("MET" if ns <= ISSUE9_RHS_NS else "missed")
            shown = "" if diff is None else f"{diff:.1e}"
            print(f"{n:>3}  {name:<14} {ns:>11,.0f} {ratio:>8.1f}x  {shown:>10}  {extra}")
        if pydy_state is not None:
            print(f"{n:>3}  {'PyDy cython':<14} {pydy_state}")
        elif quick and n > 2:
            print(f"{n:>3}  {'PyDy cython':<14} skipped (--quick)")
        print()


# ---------------------------------------------------------------------------------------------
# b. the double pendulum to t = 10
# ---------------------------------------------------------------------------------------------

def print_frontier(points) -> None:
    """The cheapest row (least min time) of kronsub's own methods, of scipy's and of heyoka at or
    below each error of :data:`FRONTIER`, the ratios, and whether issue 9's goals are met. As
    ``kronsub accuracy --target`` does, a row counts only when every tighter setting (tolerance or
    step) of its method meets the error too: the chaotic error scatters from one to the next."""
    def tighter(p, q):  # q is the same method as p at a tighter setting ("tol 1e-10", "h 0.001")
        return q[0] == p[0] and float(q[1].split()[1]) < float(p[1].split()[1])

    def best(prefix, err):
        rows = [p for p in points if p[0].startswith(prefix) and p[3] <= err
                and all(q[3] <= err for q in points if tighter(p, q))]
        return min(rows, key=lambda p: p[2]) if rows else None

    print()
    print("   frontier: the fastest row (min time) at or below each error, and at every tighter setting of its method;")
    print("   ratio = peer time / kronsub's")
    for err, goal_ms in FRONTIER:
        own = best("kronsub", err)
        peers = {name: best(prefix, err) for name, prefix in (("heyoka", "heyoka"), ("scipy", "scipy"),
                                                               ("MuJoCo", "MuJoCo"))}
        shown = (f"kronsub {own[0][8:]} {own[1]} {own[2]:.3f} ms ({own[3]:.1e})" if own else "kronsub: none")
        for name, p in peers.items():
            if p is not None:
                ratio = f", {p[2] / own[2]:.2f}x" if own else ""
                shown += f"; {name} {p[1]} {p[2]:.3f} ms ({p[3]:.1e}{ratio})"
        if goal_ms is not None:
            met = own is not None and own[2] <= goal_ms
            goal = f"goal <= {goal_ms} ms: " + ("MET" if met else "missed")
            if own is not None:  # how far under (or over) the goal, by the min and the median
                spread = [f"{abs(100 * (1 - t / goal_ms)):.1f} % {'under' if t <= goal_ms else 'over'} ({what})"
                          for t, what in ((own[2], "min"), (own[4], "median")) if t is not None]
                goal += ", " + ", ".join(spread)
        elif peers["heyoka"] is not None:
            met = own is not None and own[2] < peers["heyoka"][2]
            goal = "goal faster than heyoka: " + ("MET" if met else "missed")
        else:
            goal = "goal faster than heyoka: not measured (no heyoka)"
        print(f"   error <= {err:.1e}: {shown}; {goal}")


def section_pendulum(quick: bool, scratch: Path) -> None:
    from scipy.integrate import solve_ivp

    if not REFERENCE.exists():
        print(f"b. skipped: the reference {REFERENCE} is missing")
        return
    data = json.loads(REFERENCE.read_text())
    want = np.array([float(data["state_at_t_end"][k]) for k in ("q1", "q2", "u1", "u2")])
    system = kronsub.load(REPO / "models" / "hoffmann" / "system1.yaml").derive()
    values = resolve(system, {}, {"theta": "2*pi/3", "phi": "-pi/18"})
    param, y0, t_end = np.array(values.parameters), np.array(values.y0), 10.0
    native = native_model(system)
    c_repeats, py_repeats = (5, 1) if quick else (30, 3)
    rounds = 20 if quick else 200  # of the interleaved rows (taylor, heyoka): 0.1-1 ms each

    print(f"b. Double pendulum of two uniform rods (System I defaults), 120 / -10 deg at rest, to t = {t_end:g};")
    print("   wall time of the integration alone (min and median of repeats), max |error| of [q; qdot] at t = 10")
    print("   against the 40-digit reference (float64 floor 1.3e-11: the inputs rounded to float64 alone)")
    print(f"   target: error <= {ERROR_TARGET:.0e} in <= {TIME_TARGET_MS} ms   (* = meets it)")
    print()
    header = (f"  {'method':<22} {'setting':<13} {'min [ms]':>10} {'median':>8} {'error':>9} {'f evals':>8}  note")
    print(header)
    print("-" * len(header))
    points = []  # (method, setting, min ms, error, median ms or None)

    def row(method, setting, seconds, final, evals, note=""):
        err = float(np.max(np.abs(np.asarray(final) - want)))
        low, median = seconds if isinstance(seconds, tuple) else (seconds, None)
        ms = 1e3 * low
        points.append((method, setting, ms, err, None if median is None else 1e3 * median))
        mark = "*" if err <= ERROR_TARGET and ms <= TIME_TARGET_MS else " "
        shown = "" if median is None else f"{1e3 * median:.3f}"
        print(f"{mark} {method:<22} {setting:<13} {ms:>10.3f} {shown:>8} {err:>9.1e} {evals:>8}  {note}")

    for circle in (True, False):
        for tol in (1e-6, 1e-8, 1e-10, 1e-12, 1e-13, 1e-14):
            out = {}

            def run():
                out["r"] = native.integrate("dop853", 0.0, y0, t_end, t_end, param, rtol=tol, atol=tol,
                                            circle=circle)

            seconds = min_median(run, c_repeats)
            _, Y, res = out["r"]
            row("kronsub C dop853" if circle else "kronsub C dop853 in q", f"tol {tol:.0e}", seconds, Y[-1],
                res.n_evals, f"{res.n_steps} steps" + ("; circle state" if circle else ""))
    for h in ((1e-2, 2e-3) if quick else (1e-2, 5e-3, 2e-3, 1e-3)):
        out = {}

        def run():
            out["r"] = native.integrate("gauss4", 0.0, y0, t_end, t_end, param, h=h)

        seconds = best_of(run, max(1, c_repeats // 5))
        _, Y, res = out["r"]
        row("kronsub C gauss4", f"h {h:g}", seconds, Y[-1], res.n_evals, f"{res.n_steps} steps")

    from kronsub.simulation.taylor_c import TaylorC, order_for

    taylor = TaylorC(system)
    taylor_tols = (1e-6, 1e-9, 1e-10, 3e-11, 1e-12, 3e-13, 1e-15) if quick else \
        (1e-6, 1e-9, 1e-10, 3e-11, 1e-12, 3e-13, 1e-13, 1e-14, 1e-15)
    built = {}
    for tol in taylor_tols:
        t0 = time.perf_counter()
        taylor.build(order_for(tol))
        built[tol] = time.perf_counter() - t0
    seconds, results = interleaved({tol: (lambda tol=tol: taylor.integrate(param, y0, t_end, tol))
                                    for tol in taylor_tols}, rounds)
    for tol in taylor_tols:
        final, _, steps, order = results[tol]
        row("kronsub C taylor", f"tol {tol:.0e}", seconds[tol], final, "-",
            f"{steps} steps, order {order}; generated C, build {built[tol]:.1f} s")

    rhs = native.scipy_rhs(param)
    scipy_runs = [("RK45", 1e-6), ("RK45", 1e-9), ("DOP853", 1e-9), ("DOP853", 1e-12),
                  ("LSODA", 1e-6), ("LSODA", 1e-9), ("Radau", 1e-6), ("Radau", 1e-9)]
    if quick:
        scipy_runs = [r for r in scipy_runs if r[1] == 1e-6 or r[0] == "DOP853"]
    for method, tol in scipy_runs:
        out = {}

        def run():
            out["s"] = solve_ivp(rhs, (0.0, t_end), y0, method=method, rtol=tol, atol=tol)

        seconds = best_of(run, py_repeats)
        sol = out["s"]
        row(f"scipy {method} + C rhs", f"tol {tol:.0e}", seconds, sol.y[:, -1], sol.nfev)

    try:
        import heyoka

        from kronsub.simulation.heyoka_backend import HeyokaIntegrator
    except ImportError as exc:
        print(f"  {'heyoka':<22} not available ({exc})")
    else:
        heyoka.llvm_state.set_diskcache_enabled(False)  # this process only: cold compile times
        grid = np.array([0.0, t_end])
        heyoka_tols = (1e-9, 1e-12, 1e-13, 1e-15) if quick else (1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15)
        tas, compiled = {}, {}
        for tol in heyoka_tols:
            t0 = time.perf_counter()
            tas[tol] = HeyokaIntegrator(system, tol).ta
            compiled[tol] = time.perf_counter() - t0

        def run(ta):
            ta.time, ta.state[:], ta.pars[:] = 0.0, y0, param
            return ta.propagate_grid(grid)

        seconds, results = interleaved({tol: (lambda tol=tol: run(tas[tol])) for tol in heyoka_tols}, rounds)
        for tol in heyoka_tols:
            outcome, _, _, steps, _, Y = results[tol]
            row("heyoka " + heyoka.__version__, f"tol {tol:.0e}", seconds[tol], Y[-1], "-",
                f"{steps} steps, order {tas[tol].order}; compile {compiled[tol]:.2f} s")

    import peer_mujoco  # MuJoCo's Euler and RK4 at several steps, where mujoco installs (benchmarks/peer_mujoco.py)

    peer_mujoco.table_rows(row, native, system, values, y0, t_end, c_repeats, quick)
    print_frontier(points)

    # extended precision: extrapolation in the generated C in long double and _Float128
    from kronsub.simulation.extended import ExtendedError, ExtendedModel

    exact_param = [sympy.Integer(1), sympy.Integer(1), sympy.Rational(1, 2), sympy.Rational(1, 2),
                   sympy.Rational(1, 12), sympy.Rational(1, 12), sympy.Rational(981, 100), sympy.Integer(0)]
    exact_y0 = [2 * sympy.pi / 3, -sympy.pi / 18, 0, 0]
    import mpmath

    with mpmath.workdps(50):
        want_mp = [mpmath.mpf(data["state_at_t_end"][k]) for k in ("q1", "q2", "u1", "u2")]
    for precision, tols in (("long", (1e-12, 1e-16)), ("quad", (1e-20, 1e-24, 1e-28))):
        try:
            t0 = time.perf_counter()
            ext = ExtendedModel(system, precision)
            built = time.perf_counter() - t0
        except ExtendedError as exc:
            print(f"  {'kronsub C gbs-' + precision:<22} not available ({exc})")
            continue
        for tol in tols:
            out = {}

            def run():
                out["r"] = ext.integrate(exact_param, exact_y0, t_end, tol=tol)

            seconds = best_of(run, 1 if quick or precision == "quad" else 3)
            r = out["r"]
            with mpmath.workdps(50):
                err = float(max(abs(a - b) for a, b in zip(r.state, want_mp)))
            print(f"  {'kronsub C gbs-' + precision:<22} {'tol ' + format(tol, '.0e'):<13} {1e3 * seconds:>10.3f} "
                  f"{'':>8} {err:>9.1e} {r.evaluations:>8}  {r.steps} steps, exact inputs; build {built:.1f} s")

    # c. where the dop853 time goes
    print()
    print("c. Where the C dop853 time goes (same problem, in [q; qdot]):")
    harness = Harness(system, scratch / "system1")
    rhs_ns = harness.rhs_ns(param, 200_000 if quick else 2_000_000)
    runs = 20 if quick else 200
    header = f"   {'tol':<7} {'C->C [ms]':>10} {'ctypes [ms]':>11} {'integrate() [ms]':>16} {'evals':>6} {'ns/eval':>8} {'rhs share':>9}"
    print(header)
    dop = native._fn["ks_dop853"]  # the bare ctypes call, without integrate()'s Python around it
    for tol in (1e-8, 1e-13, 1e-14):
        c_ns, steps, evals, final = harness.dop853(param, y0, t_end, tol, runs)
        out_rows = np.empty((3, 5))
        work = np.empty(27 * 4)
        res = _CResult()
        pre, rhs = native._prepared(param, "ks_rhs")
        address = ctypes.cast(rhs, ctypes.c_void_p).value
        args = (address, 4, pre.ctypes.data, 0.0, y0.ctypes.data, t_end, t_end, tol, tol, 0.0, 0,
                out_rows.ctypes.data, 3, work.ctypes.data, ctypes.byref(res))
        raw = best_of(lambda: dop(*args), c_repeats)
        api = best_of(lambda: native.integrate("dop853", 0.0, y0, t_end, t_end, param, rtol=tol, atol=tol,
                                               circle=False), c_repeats)
        print(f"   {tol:<7.0e} {c_ns / 1e6:>10.3f} {raw * 1e3:>11.3f} {api * 1e3:>16.3f} {evals:>6} "
              f"{c_ns / evals:>8.1f} {rhs_ns * evals / c_ns:>8.0%}")
    print(f"   one ks_rhs call from C: {rhs_ns:.1f} ns (n = 2)")


ROUTE_SIZES = (10, 12, 16, 20, 30)


def section_routes(quick: bool, scratch: Path) -> None:
    print("d. The right-hand side per call by route, n-link rod chain, circle state, C harness;")
    print("   ns per call min/median of 5 rounds; goal: projected <= expanded at n = 20")
    print()
    header = f"{'n':>3}  {'expanded':>15}  {'projected':>15}  {'projected/expanded':>19}  build s (exp./proj.)"
    print(header)
    print("-" * len(header))
    for n in ROUTE_SIZES[::2] if quick else ROUTE_SIZES:
        system, param = chain(n)
        calls = max(1000, (200_000 if quick else 2_000_000) * 10 // n ** 2)
        cells, builds = {}, {}
        for route in ("expanded", "projected"):
            start = time.perf_counter()
            harness = Harness(system, scratch / f"route-{route}{n}", route=route)
            builds[route] = time.perf_counter() - start
            rounds = sorted(harness.rhs_ns(param, calls, repeats=3, circle=True) for _ in range(5))
            cells[route] = (rounds[0], rounds[len(rounds) // 2])
        (e_min, e_med), (p_min, p_med) = cells["expanded"], cells["projected"]
        verdict = ""
        if n == 20:
            verdict = "  met" if p_min <= e_min and p_med <= e_med else "  missed"
        print(f"{n:>3}  {e_min:>7,.0f}/{e_med:<7,.0f}  {p_min:>7,.0f}/{p_med:<7,.0f}  "
              f"{p_min / e_min:>9.2f}/{p_med / e_med:<9.2f}  {builds['expanded']:.1f}/{builds['projected']:.1f}{verdict}")
    print()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="short loops: finishes within a minute")
    parser.add_argument("--routes", action="store_true", help="section d alone: the routes per call")
    args = parser.parse_args(argv)
    print(f"kronsub {kronsub.__version__}, Python {platform.python_version()}, numpy {np.__version__}, "
          f"sympy {sympy.__version__}, {platform.machine()}, {os.cpu_count()} cores"
          + (", --quick" if args.quick else ""))
    print()
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="kronsub-bench-") as tmp:
        if not args.routes:
            section_rhs(args.quick, Path(tmp))
            section_pendulum(args.quick, Path(tmp))
        section_routes(args.quick, Path(tmp))
    print()
    print(f"total {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
