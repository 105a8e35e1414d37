#!/usr/bin/env python
"""Benchmark: the Whipple bicycle of the benchmark, derived and linearised, and simulated (issue 37).

Usage::

    python benchmarks/whipple_bicycle.py [--repeats 3] [--peer-timeout 1800] [--no-peer]

Each repeat runs in a fresh Python process (cold: sympy's caches empty), and times from the
first line of the build to the eigenvalues at v = 5 m/s:

* ``kronsub``: ``models/benchmarks/whipple_bicycle.py`` (four placed bodies, the contact-height
  constraint, the rolling constraints) and ``core/nonholonomic_linearize.py``
  (``SteadyMotionRates`` + ``linearize``, the roll and steer torques as inputs), then the eigenvalues at v = 0..10 too;
* ``yaml``: the model file ``models/benchmarks/whipple_bicycle.yaml`` through the API,
  ``kronsub.load(...).derive().linearize(at={"rear_dot": v / rR})`` (what ``kronsub linearize``
  does), in the default work budget and an empty cache folder, then v = 0..10 too;
* ``simulate``: ``kronsub simulate models/benchmarks/whipple_bicycle.yaml --t 10`` as a command in a
  fresh process with an empty cache folder (the model's own initial state, at rest), and the same
  from upright running at 5 m/s rolled by 1e-3 rad (``--set roll=0.001 --set rear_dot=5/rR``):
  the equations in the speeds projected in numbers at every evaluation by the generated C
  (``emitters/projected_speeds.py``; emitted and compiled within the command), timed from the
  command's start to its exit;
* ``per call``: one evaluation of the right-hand side ``[qdot; udot]`` at the rolled state, the
  generated C's (through the library scipy calls, ``NativeModel.scipy_rhs``) beside the numpy
  route's (``simulation/numeric_speeds.py``, what a run without a C compiler takes), min over
  five batches, in the same process;
* ``sympy``: sympy's own ``test_bicycle`` (``sympy/physics/mechanics/tests/test_kane3.py``):
  ``KanesMethod`` on the same benchmark bicycle, its ``linearize`` and the check of ``A`` at
  v = 0..5, the peer this project's derivation is set beside.

Reported: min and median seconds (the two kronsub routes interleaved, repeat by repeat), the
CPU seconds, the ratios (numpy / C per call), and the targets (each route's derive + linearise <= 10 s; the model
file's ``simulate --t 10`` cold <= 15 s).
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TARGET_S = 10.0
SIMULATE_TARGET_S = 15.0
BICYCLE = REPO / "models" / "benchmarks" / "whipple_bicycle.yaml"
SIMULATE = {"simulate": [], "simulate 5 m/s": ["--set", "roll=0.001", "--set", f"rear_dot={5.0 / 0.3!r}"]}

KRONSUB = f"""
import sys, time
start = time.perf_counter()
sys.path.insert(0, {str(REPO)!r}); sys.path.insert(0, {str(REPO / 'models' / 'benchmarks')!r})
import whipple_bicycle as bicycle
rates = bicycle.rates_of()
bicycle.linearized(rates, 5.0).eigenvalues
first, cpu = time.perf_counter() - start, time.process_time()
for v in range(11):
    bicycle.linearized(rates, float(v)).eigenvalues
print(cpu, first, time.perf_counter() - start)
"""

YAML = f"""
import sys, time
start = time.perf_counter()
sys.path.insert(0, {str(REPO)!r})
import kronsub
system = kronsub.load({str(REPO / 'models' / 'benchmarks' / 'whipple_bicycle.yaml')!r}).derive()
system.linearize(at={{"rear_dot": 5.0 / 0.3}}).eigenvalues
first, cpu = time.perf_counter() - start, time.process_time()
for v in range(11):
    system.linearize(at={{"rear_dot": v / 0.3}}).eigenvalues
print(cpu, first, time.perf_counter() - start)
"""

PER_CALL = f"""
import sys, time
sys.path.insert(0, {str(REPO)!r})
import numpy as np
import kronsub
from kronsub.simulation.compiled import native_model
from kronsub.simulation.numeric_speeds import NumericSpeeds
system = kronsub.load({str(BICYCLE)!r}).derive()
param = np.array([float(p.value) for p in system.parameters])
names = [q.name for q in system.coordinates] + [u.name for u in system.speeds.speeds]
y = np.zeros(len(names))
y[names.index("roll")], y[names.index("rear_dot")] = 1e-3, 5.0 / 0.3
routes = {{"C": native_model(system, canonical=False).scipy_rhs(param), "numpy": NumericSpeeds(system, param).rhs}}
for name, f in routes.items():
    count = 20000 if name == "C" else 200
    best = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(count):
            f(0.0, y)
        best = min(best, (time.perf_counter() - start) / count)
    print(name, best)
"""

SYMPY = """
import time
start = time.perf_counter()
from sympy.physics.mechanics.tests.test_kane3 import test_bicycle
test_bicycle()
t = time.perf_counter() - start
print(time.process_time(), t, t)
"""


def timed(code: str, timeout: float) -> tuple[float, float, float] | None:
    """Seconds to v = 5 and to all speeds, and the CPU seconds to v = 5 (the process's, imports
    included), from a fresh process with an empty cache folder (None past ``timeout``)."""
    with tempfile.TemporaryDirectory() as cache:
        try:
            out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                                 check=True, cwd=REPO, env={**os.environ, "KRONSUB_CACHE_DIR": cache}).stdout.split()
        except subprocess.TimeoutExpired:
            return None
    return float(out[-2]), float(out[-1]), float(out[-3])


def simulated(extra: list[str], timeout: float) -> tuple[float, float, float] | None:
    """Wall seconds of ``kronsub simulate BICYCLE --t 10`` in a fresh process with an empty cache
    folder (twice: the first and the whole run are one), and its CPU seconds (None past ``timeout``)."""
    with tempfile.TemporaryDirectory() as cache:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        try:
            subprocess.run([sys.executable, "-m", "kronsub", "simulate", str(BICYCLE), "--t", "10", *extra,
                            "-o", str(Path(cache) / "run.csv")], capture_output=True, timeout=timeout, check=True,
                           cwd=REPO, env={**os.environ, "KRONSUB_CACHE_DIR": cache,
                                          "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])})
        except subprocess.TimeoutExpired:
            return None
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, wall, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def per_call(timeout: float) -> dict[str, float] | None:
    """Seconds per call of each route's right-hand side (in a fresh process, the cache folder empty)."""
    with tempfile.TemporaryDirectory() as cache:
        try:
            out = subprocess.run([sys.executable, "-c", PER_CALL], capture_output=True, text=True, timeout=timeout,
                                 check=True, cwd=REPO, env={**os.environ, "KRONSUB_CACHE_DIR": cache}).stdout
        except subprocess.TimeoutExpired:
            return None
    return {line.split()[0]: float(line.split()[1]) for line in out.splitlines() if line.strip()}


def row(name: str, runs: list) -> str:
    """min and median to v = 5, the least CPU, the least to v = 0..10."""
    done = [t for t in runs if t]
    if not done:
        return f"{name:<15} {'timed out':>8}"
    firsts = [t[0] for t in done]
    return (f"{name:<15} {min(firsts):>8.2f} {statistics.median(firsts):>10.2f} {min(t[2] for t in done):>11.2f} "
            f"{min(t[1] for t in done):>14.2f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--peer-timeout", type=float, default=1800.0)
    parser.add_argument("--no-peer", action="store_true")
    args = parser.parse_args(argv)
    ours, files = [], []
    runs = {name: [] for name in SIMULATE}
    for _ in range(args.repeats):  # interleaved: the load of the machine falls on all alike
        ours.append(timed(KRONSUB, 600))
        files.append(timed(YAML, 600))
        for name, extra in SIMULATE.items():
            runs[name].append(simulated(extra, 600))
    print(f"{'tool':<15} {'min [s]':>8} {'median [s]':>10} {'cpu min [s]':>11} {'v = 0..10 [s]':>14}")
    print(row("kronsub", ours))
    print(row("yaml", files))
    for name, times in runs.items():
        print(row(name, times))
    calls = per_call(600)
    if calls:
        print(f"per call: C {calls['C'] * 1e6:.1f} us, numpy {calls['numpy'] * 1e6:.0f} us, "
              f"ratio numpy / C {calls['numpy'] / calls['C']:.0f}")
    firsts = [t[0] for t in ours if t]
    from_file = [t[0] for t in files if t]
    if firsts and from_file:
        print(f"ratio yaml / kronsub (min): {min(from_file) / min(firsts):.1f}")
    if not args.no_peer:
        peer = timed(SYMPY, args.peer_timeout)
        if peer is None:
            print(f"{'sympy':<15} {'> ' + format(args.peer_timeout, '.0f'):>8}  (timed out)")
        else:
            print(f"{'sympy':<15} {peer[0]:>8.2f} {peer[0]:>10.2f} {peer[2]:>11.2f} {'':>14}   ratio sympy / "
                  f"kronsub {peer[0] / min(firsts):.1f}, sympy / yaml {peer[0] / min(from_file):.1f}")
    for name, times in (("derive + linearise", firsts), ("the model file's derive + linearise", from_file)):
        best = min(times) if times else float("inf")
        print(f"target: {name} <= {TARGET_S:.0f} s: {best:.2f} s {'OK' if best <= TARGET_S else 'MISS'}")
    for name, times in runs.items():
        best = min((t[0] for t in times if t), default=float("inf"))
        print(f"target: the model file's {name} --t 10 cold <= {SIMULATE_TARGET_S:.0f} s: {best:.2f} s "
              f"{'OK' if best <= SIMULATE_TARGET_S else 'MISS'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
