#!/usr/bin/env python
"""Benchmark: closed loops (issue 7), ratios against peers measured in the same run.

Usage::

    python benchmarks/closed_loops.py [--quick]

a. Deriving (load, constraint analysis and projection; the known-system cache off) the
   four-bar and System III, min and median of repeats after a warm-up, against deriving
   System I in the same run. Target: each <= 1 s.
b. One evaluation of the generated C right-hand side ``ks_rhs_pre`` of ``system2_implicit``
   (the dependent coordinate phi by Newton's method, warm-started from the previous call, then
   lambda and gamma), and of the same model with its closed form (26), against ``system2``
   (the paper's parametric form, closed form throughout), called in a loop by a small C harness
   over states along a slow sweep of theta (neighbouring calls close, as in an integration).
   Target: Newton <= 3x system2.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
os.environ["KRONSUB_CACHE_DIR"] = "off"

import kronsub  # noqa: E402
from kronsub.emitters.code import emit_c  # noqa: E402
from kronsub.simulation.native import host_flags  # noqa: E402

DERIVE_TARGET_S = 1.0
RHS_TARGET_RATIO = 3.0

HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "model.h"

#define K 1024

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv) {
    static double ys[K][KS_NY], param[KS_NPARAM + 1], pre[KS_NPRE + 1], ydot[KS_NY];
    long calls = atol(argv[1]), failed = 0;
    int repeats = atoi(argv[2]);
    double best = 1e300, sink = 0.0;
    for (int i = 0; i < KS_NPARAM; i++) param[i] = atof(argv[3 + i]);
    ks_prepare(param, pre);
    for (int k = 0; k < K; k++) {  /* a slow sweep: theta in [0.35, 1.15], theta_dot in [-1, 1] */
        ys[k][0] = 0.75 + 0.4 * sin(6.283185307179586 * k / K);
        ys[k][1] = cos(6.283185307179586 * k / K);
    }
    for (int r = 0; r < repeats; r++) {
        double t0 = now();
        for (long c = 0; c < calls; c++) {
            failed += ks_rhs_pre(0.0, ys[c & (K - 1)], pre, ydot);
            sink += ydot[KS_NY - 1];
        }
        double dt = now() - t0;
        if (dt < best) best = dt;
    }
    printf("%.6g %ld %.6g\n", 1e9 * best / calls, failed, sink);
    return 0;
}
"""


def derive_times(path: Path, repeats: int) -> list[float]:
    kronsub.load(path, cache=False).derive(cache=False)  # warm-up (imports, sympy caches)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        kronsub.load(path, cache=False).derive(cache=False)
        times.append(time.perf_counter() - t0)
    return times


def rhs_ns(system, calls: int, repeats: int, folder: Path, name: str) -> float:
    work = folder / name
    work.mkdir()
    for generated in emit_c(system, "model"):
        (work / generated.name).write_text(generated.text)
    (work / "harness.c").write_text(HARNESS)
    subprocess.run(["gcc", "-std=c99", "-O2", *host_flags(), "-o", "harness", "harness.c", "model.c", "-lm"],
                   cwd=work, check=True)
    params = [str(float(p.value)) for p in system.parameters]
    out = subprocess.run([str(work / "harness"), str(calls), str(repeats), *params], capture_output=True,
                         text=True, check=True).stdout.split()
    if int(out[1]):
        raise RuntimeError(f"{name}: {out[1]} failed evaluations")
    return float(out[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    args = parser.parse_args()
    repeats = 3 if args.quick else 7
    print("a. deriving (cache off), seconds: min / median of", repeats)
    peer = derive_times(REPO / "models/hoffmann/system1.yaml", repeats)
    print(f"   {'System I (peer)':<24} {min(peer):.3f} / {statistics.median(peer):.3f}")
    for label, path in (("four-bar", "models/examples/four_bar.yaml"), ("System III", "models/hoffmann/system3.yaml")):
        times = derive_times(REPO / path, repeats)
        verdict = "ok" if min(times) <= DERIVE_TARGET_S else "OVER TARGET"
        print(f"   {label:<24} {min(times):.3f} / {statistics.median(times):.3f}   "
              f"x{min(times) / min(peer):.2f} System I; target <= {DERIVE_TARGET_S} s: {verdict}")

    calls = 200_000 if args.quick else 2_000_000
    explicit = kronsub.load(REPO / "models/hoffmann/system2.yaml").derive()
    implicit = kronsub.load(REPO / "models/hoffmann/system2_implicit.yaml").derive()
    newton = dataclasses.replace(implicit, implicit=dataclasses.replace(implicit.implicit, closed_form=()))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        base = rhs_ns(explicit, calls, repeats, folder, "system2")
        closed = rhs_ns(implicit, calls, repeats, folder, "closed")
        solved = rhs_ns(newton, calls, repeats, folder, "newton")
    print(f"b. right-hand side, ns per call (best of {repeats} x {calls} calls)")
    print(f"   {'system2 (26), peer':<34} {base:8.1f}")
    print(f"   {'system2_implicit, closed form':<34} {closed:8.1f}   x{closed / base:.2f}")
    verdict = "ok" if solved / base <= RHS_TARGET_RATIO else "OVER TARGET"
    print(f"   {'system2_implicit, Newton inside':<34} {solved:8.1f}   x{solved / base:.2f}; "
          f"target <= {RHS_TARGET_RATIO}x: {verdict}")


if __name__ == "__main__":
    main()
