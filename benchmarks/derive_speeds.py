#!/usr/bin/env python
"""Benchmark: ``kronsub derive`` of the Whipple bicycle's model file, its equations in the speeds
printed in Kron's implicit form (issue 37), beside ``kronsub linearize`` of the same file.

Usage::

    python benchmarks/derive_speeds.py [--repeats 3]

Each repeat runs each command in a fresh process with an empty cache folder (cold), the commands
interleaved repeat by repeat: ``kronsub derive models/benchmarks/whipple_bicycle.yaml --format F
--no-cache`` for F in markdown, json and latex, and the peer measured in the same run, ``kronsub
linearize`` of the same file at ``rear_dot = 5/rR`` (the derivation and the numbers the implicit
form describes). Reported: min and median wall seconds, the least CPU seconds of the process, the
ratio of each format to the peer, and the target: each format within the default work budget in
<= 10 s cold.
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
BICYCLE = REPO / "models" / "benchmarks" / "whipple_bicycle.yaml"
TARGET_S = 10.0
COMMANDS = {
    "derive markdown": ["derive", str(BICYCLE), "--format", "markdown", "--no-cache"],
    "derive json": ["derive", str(BICYCLE), "--format", "json", "--no-cache"],
    "derive latex": ["derive", str(BICYCLE), "--format", "latex", "--no-cache"],
    "linearize (peer)": ["linearize", str(BICYCLE), "--at", f"rear_dot={5.0 / 0.3!r}"],
}


def timed(arguments: list[str], timeout: float = 600.0) -> tuple[float, float] | None:
    """Wall and CPU seconds of ``kronsub ARGUMENTS`` in a fresh process with an empty cache folder
    (None when it fails or passes ``timeout``)."""
    with tempfile.TemporaryDirectory() as cache:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        try:
            subprocess.run([sys.executable, "-m", "kronsub", *arguments], capture_output=True, timeout=timeout,
                           check=True, cwd=REPO,
                           env={**os.environ, "KRONSUB_CACHE_DIR": cache,
                                "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])})
        except (subprocess.TimeoutExpired, subprocess.CalledProcessError):
            return None
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    runs: dict[str, list] = {name: [] for name in COMMANDS}
    for _ in range(args.repeats):  # interleaved: the load of the machine falls on all alike
        for name, arguments in COMMANDS.items():
            runs[name].append(timed(arguments))
    peer = [t[0] for t in runs["linearize (peer)"] if t]
    print(f"{'command':<18} {'min [s]':>8} {'median [s]':>10} {'cpu min [s]':>11} {'/ peer':>7}")
    for name, times in runs.items():
        done = [t for t in times if t]
        if not done:
            print(f"{name:<18} {'failed':>8}")
            continue
        walls = [t[0] for t in done]
        ratio = f"{min(walls) / min(peer):>7.2f}" if peer else f"{'':>7}"
        print(f"{name:<18} {min(walls):>8.2f} {statistics.median(walls):>10.2f} {min(t[1] for t in done):>11.2f} "
              f"{ratio}")
    for name, times in runs.items():
        if name.startswith("derive"):
            best = min((t[0] for t in times if t), default=float("inf"))
            print(f"target: {name} cold <= {TARGET_S:.0f} s: {best:.2f} s {'OK' if best <= TARGET_S else 'MISS'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
