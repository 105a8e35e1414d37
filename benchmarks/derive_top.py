#!/usr/bin/env python
"""Benchmark: a heavy top written through ``atan2``/``asin`` (issue 10, hard case 6).

Usage::

    python benchmarks/derive_top.py [--repeats 3]

Derives (load and projection; the known-system cache off) the three tops of
``tests/hard/models``: Z-X-Z angles converted to ``rigid_body3d``'s Z-Y-X ones through
``atan2``/``asin`` in the connection, the same top with ``euler: ZXZ``, and the top in its
Z-Y-X angles directly (the peer). Reported: min and median seconds of the repeats after a
warm-up, the ratio to the peer, and the longest and total characters of the ``Mbar`` and
``hbar`` entries. Targets: the ``atan2`` top derives in <= 10 s, with mass-matrix entries no
longer than the peer's.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
os.environ["KRONSUB_CACHE_DIR"] = "off"

import kronsub  # noqa: E402

MODELS = REPO / "tests" / "hard" / "models"
TOPS = ("top_zyx", "top_zxz_euler", "top_zxz_atan2")
TARGET_S = 10.0


def derive(name: str):
    return kronsub.load(MODELS / f"{name}.yaml", cache=False).derive(cache=False)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    derive("top_zyx")  # warm-up: imports and sympy's caches
    rows = {}
    for name in TOPS:
        times, system = [], None
        for _ in range(args.repeats):
            start = time.perf_counter()
            system = derive(name)
            times.append(time.perf_counter() - start)
        m = [len(str(e)) for e in system.mass_matrix]
        h = [len(str(e)) for e in system.velocity_terms]
        rows[name] = (min(times), statistics.median(times), max(m), sum(m), max(h), sum(h))
    peer = rows["top_zyx"]
    print(f"{'model':<15} {'min [s]':>8} {'median [s]':>10} {'ratio':>6} {'M max/total chars':>18} "
          f"{'h max/total chars':>18}")
    for name, (tmin, tmed, mmax, msum, hmax, hsum) in rows.items():
        print(f"{name:<15} {tmin:>8.2f} {tmed:>10.2f} {tmin / peer[0]:>6.2f} {mmax:>8}/{msum:<9} {hmax:>8}/{hsum:<9}")
    tmin, _, mmax, msum = rows["top_zxz_atan2"][:4]
    ok = tmin <= TARGET_S and mmax <= peer[2] and msum <= peer[3]
    print(f"target: atan2 top <= {TARGET_S:g} s, M entries no longer than top_zyx's -> {'OK' if ok else 'MISS'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
