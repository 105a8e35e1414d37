#!/usr/bin/env python
"""Benchmark: the Whipple bicycle of the benchmark, derived and linearised (issue 37).

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
* ``sympy``: sympy's own ``test_bicycle`` (``sympy/physics/mechanics/tests/test_kane3.py``):
  ``KanesMethod`` on the same benchmark bicycle, its ``linearize`` and the check of ``A`` at
  v = 0..5, the peer this project's derivation is set beside.

Reported: min and median seconds (the two kronsub routes interleaved, repeat by repeat), the
CPU seconds, the ratios, and the targets (each route's derive + linearise <= 10 s).
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TARGET_S = 10.0

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


def row(name: str, runs: list) -> str:
    """min and median to v = 5, the least CPU, the least to v = 0..10."""
    done = [t for t in runs if t]
    if not done:
        return f"{name:<9} {'timed out':>8}"
    firsts = [t[0] for t in done]
    return (f"{name:<9} {min(firsts):>8.2f} {statistics.median(firsts):>10.2f} {min(t[2] for t in done):>11.2f} "
            f"{min(t[1] for t in done):>14.2f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--peer-timeout", type=float, default=1800.0)
    parser.add_argument("--no-peer", action="store_true")
    args = parser.parse_args(argv)
    ours, files = [], []
    for _ in range(args.repeats):  # interleaved: the load of the machine falls on both alike
        ours.append(timed(KRONSUB, 600))
        files.append(timed(YAML, 600))
    print(f"{'tool':<9} {'min [s]':>8} {'median [s]':>10} {'cpu min [s]':>11} {'v = 0..10 [s]':>14}")
    print(row("kronsub", ours))
    print(row("yaml", files))
    firsts = [t[0] for t in ours if t]
    from_file = [t[0] for t in files if t]
    if firsts and from_file:
        print(f"ratio yaml / kronsub (min): {min(from_file) / min(firsts):.1f}")
    if not args.no_peer:
        peer = timed(SYMPY, args.peer_timeout)
        if peer is None:
            print(f"{'sympy':<9} {'> ' + format(args.peer_timeout, '.0f'):>8}  (timed out)")
        else:
            print(f"{'sympy':<9} {peer[0]:>8.2f} {peer[0]:>10.2f} {peer[2]:>11.2f} {'':>14}   ratio sympy / "
                  f"kronsub {peer[0] / min(firsts):.1f}, sympy / yaml {peer[0] / min(from_file):.1f}")
    for name, times in (("derive + linearise", firsts), ("the model file's derive + linearise", from_file)):
        best = min(times) if times else float("inf")
        print(f"target: {name} <= {TARGET_S:.0f} s: {best:.2f} s {'OK' if best <= TARGET_S else 'MISS'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
