#!/usr/bin/env python
"""Benchmark: what a scene saves by leaving its switched-off effects out.

Usage::

    python benchmarks/scenes.py [--quick]

For System I (scene ``free``: gravity only), the Watt governor (scene ``idle``:
no engine load) and a 10-link rod chain with a torsional spring and damper at
every hinge (``models/chain/generate.py 10 --hinges``, scene ``gravity_only``),
measured in one run:

a. The generated right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` of the full
   model and of the gravity-only scene, the one ``simulate``'s ``dop853`` and ``rk4`` call:
   in the circle state ``[q; qdot; cos q; sin q]`` when the model or scene has circle
   coordinates (``ks_rhs_circle_pre``, ``kronsub/emitters/circle.py``: angles that enter only
   through sines and cosines; a torsional spring's angle enters as itself), else in
   ``[q; qdot]`` (``ks_rhs_pre``). ``sympy.count_ops`` of its body (common subexpressions
   and outputs, the per-parameter constants apart, a guarded angle counted as its
   single-angle products), and the cost of one call of the compiled C (``-O2`` and kronsub's
   host flags) from a small C harness cycling through random states, the full model and
   the scene timed in turn in one program (so both see the same machine load): min and
   median over repeats, and the scene/full ratio. The ``state`` column gives each state's
   size. Target: the 10-link gravity-only scene costs at most 70 % of the full model per call.

b. Whole runs: ``dop853`` (tol 1e-10) from the model's initial state to t = 10 through
   ``NativeModel.integrate``, the full model and the gravity-only scene, the scene also
   in ``[q; qdot]`` (``circle=False``): time per right-hand-side evaluation, the
   integrator's own arithmetic on the longer circle state included (min over repeats).
   The full model and the scene move differently (the scene's hinges turn freely), so
   their evaluation counts differ; the time per evaluation is what compares.

c. Deriving: the whole model from an empty cache, then a scene of it (sharing the
   cached inertia and effects); and, from an empty cache, the gravity-only scene
   first and then the full scene (which derives only the effects the first lacked).
   Each in a fresh process (imports, a warm-up and the cache's set-up excluded: kronsub's
   source hashed and the cache folder probed, once per process), loading the file and
   deriving timed apart; medians over repeats, each second scene's derivation as a
   share of the model's. Target: a second scene costs at most 20 % of deriving the model.

``--quick`` shortens every loop.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "models" / "chain"))

from generate import chain_yaml  # noqa: E402
from kronsub.emitters.code import emit_c  # noqa: E402
from kronsub.emitters.circle import circle_equations  # noqa: E402
from kronsub.emitters.numeric import NearAxis, prepare  # noqa: E402
from kronsub.cache import usable_cache_dir  # noqa: E402
from kronsub.model.derive import content_key  # noqa: E402
from kronsub.model.loader import load_model  # noqa: E402
from kronsub.model.scenes import derive_scene, select_scene  # noqa: E402
from kronsub.simulation.native import compiler_command, host_flags  # noqa: E402
from kronsub.simulation.values import resolve  # noqa: E402

RHS_TARGET = 0.70
DERIVE_TARGET = 0.20

HARNESS = r"""#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "full.h"
#include "scene.h"

#define K 256 /* distinct states, cycled */
#define NY (KF_NY > KG_NY ? KF_NY : KG_NY)
#define NZ (KF_NZ > KG_NZ ? KF_NZ : KG_NZ)

/* the right-hand side the integrators call: in the circle state when there is one */
static int full_rhs(const double *z, const double *pre, double *zdot)
{
#if KF_NC > 0
    return kf_rhs_circle_pre(0.0, z, pre, zdot);
#else
    return kf_rhs_pre(0.0, z, pre, zdot);
#endif
}

static int scene_rhs(const double *z, const double *pre, double *zdot)
{
#if KG_NC > 0
    return kg_rhs_circle_pre(0.0, z, pre, zdot);
#else
    return kg_rhs_pre(0.0, z, pre, zdot);
#endif
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* usage: harness CALLS REPEATS NF f0 f1 ... g0 g1 ...: the full model's and the scene's
   right-hand sides timed in turn (so both see the same load); ns per call, one line each */
int main(int argc, char **argv) {
    static double ys[K][NY], zf[K][NZ], zg[K][NZ], pf[KF_NPARAM + 1], pg[KG_NPARAM + 1];
    static double pre_f[KF_NPRE + 1], pre_g[KG_NPRE + 1], ydot[NZ], tf[1000], tg[1000];
    long calls = atol(argv[1]), failed = 0;
    int repeats = atoi(argv[2]);
    double sink = 0.0;
    unsigned long s = 12345;
    (void)argc;
    for (int i = 0; i < KF_NPARAM; i++) pf[i] = atof(argv[3 + i]);
    for (int i = 0; i < KG_NPARAM; i++) pg[i] = atof(argv[3 + KF_NPARAM + i]);
    kf_prepare(pf, pre_f);
    kg_prepare(pg, pre_g);
    for (int k = 0; k < K; k++)
        for (int i = 0; i < NY; i++) {
            s = s * 6364136223846793005UL + 1442695040888963407UL;
            double u = (double)(s >> 11) / 9007199254740992.0;
            ys[k][i] = i < NY / 2 ? 6.283185307179586 * (u - 0.5) : 4 * (u - 0.5);
        }
    for (int k = 0; k < K; k++) {
        for (int i = 0; i < NY; i++) zf[k][i] = zg[k][i] = ys[k][i];
#if KF_NC > 0
        kf_circle_state(ys[k], zf[k]);
#endif
#if KG_NC > 0
        kg_circle_state(ys[k], zg[k]);
#endif
    }
    for (int r = 0; r < repeats && r < 1000; r++) {
        double t0 = now();
        for (long c = 0; c < calls; c++) {
            failed += full_rhs(zf[c & (K - 1)], pre_f, ydot);
            sink += ydot[0];
        }
        double t1 = now();
        for (long c = 0; c < calls; c++) {
            failed += scene_rhs(zg[c & (K - 1)], pre_g, ydot);
            sink += ydot[0];
        }
        double t2 = now();
        tf[r] = 1e9 * (t1 - t0) / calls;
        tg[r] = 1e9 * (t2 - t1) / calls;
    }
    for (int r = 0; r < repeats; r++) printf("%.6g ", tf[r]);
    printf("\n");
    for (int r = 0; r < repeats; r++) printf("%.6g ", tg[r]);
    printf("\n%ld %.6g\n", failed, sink);
    return 0;
}
"""


def _cases(folder: Path) -> list[tuple[str, Path, str | None, str]]:
    """(label, model file, full scene or None, gravity-only scene)."""
    chain = folder / "chain10_hinges.yaml"
    chain.write_text(chain_yaml(10, hinges=True), encoding="utf-8")
    return [
        ("System I", REPO / "models" / "hoffmann" / "system1.yaml", None, "free"),
        ("Watt governor", REPO / "models" / "examples" / "watt_governor.yaml", None, "idle"),
        ("10-link chain, hinges", chain, "full", "gravity_only"),
    ]


def _system(path: Path, scene: str | None):
    model = load_model(path)
    chosen = select_scene(model, scene)
    return model, chosen, derive_scene(model, chosen)


def rhs_ops(system) -> tuple[int, int]:
    """Operations in the body of the right-hand side the integrators call (its cse temporaries
    and outputs; a guarded angle as its products), and the size of its state."""
    block = prepare(system, guarded_angles=True).equations
    n = len(system.coordinates)
    circle, on_circle = circle_equations(block, [sympy.Symbol(f"q[{i}]") for i in range(n)])
    block = on_circle or block
    products = lambda e: e.replace(NearAxis, lambda angle, kind, p, again: p)  # noqa: E731
    return (int(sum(sympy.count_ops(products(e)) for _, e in block.temporaries) +
                sum(sympy.count_ops(products(e)) for _, e in block.outputs)), 2 * n + 2 * len(circle))


def rhs_costs(pair, folder: Path, calls: int, repeats: int) -> tuple[list[float], list[float]]:
    """ns per call of the compiled ``ks_rhs_pre`` of the full model and of the scene, one value
    per repeat, timed in turn in one program. The states are the same: the scene has the
    model's coordinates."""
    work = Path(tempfile.mkdtemp(dir=folder))
    args = []
    for (model, scene, system), stem in zip(pair, ("full", "scene")):
        outputs = scene.outputs if scene is not None else None
        for g in emit_c(system, stem, outputs=outputs, prefix="kf" if stem == "full" else "kg"):
            (work / g.name).write_text(g.text, encoding="utf-8")
        args += map(repr, resolve(system, dict(model.initial), {}).parameters)
    (work / "harness.c").write_text(HARNESS, encoding="utf-8")
    subprocess.run([*compiler_command(), "-std=c99", "-O2", *host_flags(), "-o", "harness", "harness.c", "full.c", "scene.c",
                    "-lm"], cwd=work, check=True, capture_output=True)
    out = subprocess.run([str(work / "harness"), str(calls), str(repeats), *args],
                         cwd=work, check=True, capture_output=True, text=True).stdout.split("\n")
    return [float(v) for v in out[0].split()], [float(v) for v in out[1].split()]


def run_costs(pair, repeats: int) -> list[tuple[str, float, int]]:
    """(label, ns per evaluation, evaluations) of a dop853 run to t = 10 of the full model, the
    scene, and the scene in ``[q; qdot]``: the best of ``repeats``."""
    from kronsub.simulation.compiled import compiled_library
    from kronsub.simulation.native import NativeModel

    rows = []
    for (model, scene, system), label in zip(pair, ("full", "scene")):
        native = NativeModel(compiled_library(system, scene.outputs if scene else None), len(system.coordinates),
                             len(system.parameters))
        values = resolve(system, dict(model.initial), {})
        y0, param = np.array(values.y0), np.array(values.parameters)
        for circle in ((None, False) if label == "scene" else (None,)):
            best, evals = float("inf"), 0
            for _ in range(repeats):
                t0 = time.perf_counter()
                _, _, result = native.integrate("dop853", 0.0, y0, 10.0, 10.0, param, rtol=1e-10, atol=1e-10,
                                                circle=circle)
                best = min(best, time.perf_counter() - t0)
                evals = result.n_evals
            state = "circle state" if native.nc and circle is None else "[q; qdot]"
            rows.append((f"{label}, {state}", 1e9 * best / evals, evals))
    return rows


def _child(path: str, scene: str) -> None:
    """Time ``load + derive`` of one scene (``-``: the whole model) in this fresh process,
    after a warm-up (imports, sympy's lazily loaded simplifiers) that writes no cache."""
    cache = os.environ.get("KRONSUB_CACHE_DIR", "")
    os.environ["KRONSUB_CACHE_DIR"] = "off"
    x = sympy.Symbol("x")
    sympy.simplify(sympy.expand(sympy.sin(x) ** 2 + sympy.cos(x) ** 2))
    load_model(REPO / "models" / "examples" / "double_pendulum.yaml", cache=False).derive(cache=False)
    os.environ["KRONSUB_CACHE_DIR"] = cache
    # what a process sets up once for its cache, as it imports once: kronsub's own source hashed
    # (every cache key holds it) and the cache folder probed for writing
    content_key()
    usable_cache_dir()
    t0 = time.perf_counter()
    model = load_model(Path(path))
    t1 = time.perf_counter()
    derive_scene(model, select_scene(model, None if scene == "-" else scene))
    print(t1 - t0, time.perf_counter() - t1)


def _timed(path: Path, scene: str | None, cache: str) -> tuple[float, float]:
    """(load, derive) seconds in a fresh process."""
    env = dict(os.environ, KRONSUB_CACHE_DIR=cache)
    out = subprocess.run([sys.executable, __file__, "--child", str(path), scene or "-"], env=env, check=True,
                         capture_output=True, text=True).stdout.split()
    return float(out[-2]), float(out[-1])


def derive_costs(path: Path, full: str | None, gravity: str, repeats: int) -> dict[str, list]:
    """(load, derive) seconds, each in a fresh process (imports excluded), the first of each
    pair from an empty cache."""
    times: dict[str, list] = {"model": [], "scene after model": [], "first scene": [], "second scene": []}
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as cache:
            times["model"].append(_timed(path, full, cache))
            times["scene after model"].append(_timed(path, gravity, cache))
        with tempfile.TemporaryDirectory() as cache:
            times["first scene"].append(_timed(path, gravity, cache))
            times["second scene"].append(_timed(path, full, cache))
    return times


def _fmt_ns(values: list[float]) -> str:
    return f"{min(values):8.1f} {statistics.median(values):8.1f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="shorter loops")
    parser.add_argument("--child", nargs=2, metavar=("MODEL", "SCENE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(*args.child)
        return
    calls, repeats, derive_repeats = (20_000, 5, 1) if args.quick else (200_000, 15, 3)
    saved = os.environ.get("KRONSUB_CACHE_DIR")
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        cases = _cases(folder)
        print("a. Right-hand side: full model and gravity-only scene "
              f"(C, -O2; ns per call over {calls} calls, {repeats} repeats)\n")
        print(f"{'model':24s} {'scene':14s} {'state':>5s} {'ops':>6s} {'min ns':>8s} {'median':>8s}  "
              f"{'scene/full (min, median)':s}")
        verdicts = []
        for label, path, full, gravity in cases:
            os.environ["KRONSUB_CACHE_DIR"] = str(folder / "cache")
            pair = [_system(path, name) for name in (full, gravity)]
            fcost, gcost = rhs_costs(pair, folder, calls, repeats)
            (fname, (fops, fdim)), (gname, (gops, gdim)) = [(name or "(all effects)", rhs_ops(system))
                                                            for name, (_, _, system) in zip((full, gravity), pair)]
            ratio_min = min(gcost) / min(fcost)
            ratio_med = statistics.median(g / f for f, g in zip(fcost, gcost))  # repeat by repeat
            print(f"{label:24s} {fname:14s} {fdim:5d} {fops:6d} {_fmt_ns(fcost)}")
            print(f"{'':24s} {gname:14s} {gdim:5d} {gops:6d} {_fmt_ns(gcost)}  "
                  f"{ratio_min:.2f}, {ratio_med:.2f}   ops {gops / fops:.2f}")
            if label.startswith("10-link"):
                verdicts.append(f"10-link gravity-only scene / full model per call: {ratio_med:.2f} (median), "
                                f"target <= {RHS_TARGET:.2f}: {'met' if ratio_med <= RHS_TARGET else 'NOT met'}")
        print("\nb. Whole runs: dop853 (tol 1e-10) to t = 10; ns per right-hand-side evaluation, the "
              "integrator's arithmetic included\n")
        for label, path, full, gravity in cases:
            os.environ["KRONSUB_CACHE_DIR"] = str(folder / "cache")
            rows = run_costs([_system(path, name) for name in (full, gravity)], 3 if args.quick else 15)
            for k, (what, ns, evals) in enumerate(rows):
                ratio = f"  {ns / rows[0][1]:.2f} of the full model" if k else ""
                print(f"{label if k == 0 else '':24s} {what:26s} {ns:8.1f} ns  {evals:6d} evaluations{ratio}")
            if label.startswith("10-link"):
                verdicts.append(f"10-link gravity-only scene / full model per evaluation of a whole run: "
                                f"{rows[1][1] / rows[0][1]:.2f}")
        print("\nc. Deriving: median s of load + derive, each in a fresh process (imports excluded);\n"
              "   the shares are of the derivation alone (loading the file is the same for every command)\n")
        print(f"{'model':24s} {'model':>13s} {'scene after':>13s} {'first scene':>13s} {'second scene':>13s}"
              "  after/model  second/model")
        for label, path, full, gravity in cases:
            t = derive_costs(path, full, gravity, derive_repeats)
            load = {k: statistics.median(a for a, _ in v) for k, v in t.items()}
            work = {k: statistics.median(b for _, b in v) for k, v in t.items()}
            cells = [f"{load[k]:5.2f} + {work[k]:5.2f}" for k in t]
            share = work["scene after model"] / work["model"]
            new = work["second scene"] / work["model"]
            print(f"{label:24s} {cells[0]:>13s} {cells[1]:>13s} {cells[2]:>13s} {cells[3]:>13s}"
                  f"  {share:11.2f}  {new:12.2f}")
            verdicts.append(f"{label}: deriving a scene after the model / deriving the model {share:.2f}, target "
                            f"<= {DERIVE_TARGET:.2f}: {'met' if share <= DERIVE_TARGET else 'NOT met'}")
        print()
        for v in verdicts:
            print(v)
    if saved is None:
        os.environ.pop("KRONSUB_CACHE_DIR", None)
    else:
        os.environ["KRONSUB_CACHE_DIR"] = saved


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
