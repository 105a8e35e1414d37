#!/usr/bin/env python
"""Benchmark: a large chain's report (``kronsub derive --format markdown|json``) against its derivation.

Usage::

    python benchmarks/derive_report.py [--sizes 50,100] [--formats markdown,json] [--repeats 3]
                                       [--baseline /path/to/another/kronsub/tree]

For every n the n-rod chain (``models/chain/generate.py``) is loaded and derived
(``kronsub.load(chainN.yaml, cache=False).derive(cache=False)``) and then printed
(``kronsub.emitters.text.EMITTERS[format]``), in a fresh process each repeat, under a
work budget of 10^13; the CPU seconds (``time.process_time``) of the derivation and of
the report, the report's size and a hash of its text, and the peak RSS are read from the
process. The ratio is (derive + report) / derive, the goal of issue 34 being at most 2.
With ``--baseline`` the same runs are made with that tree first on ``sys.path``
(interleaved: baseline, this tree, baseline, ...), and the reports' hashes are compared.
Columns: min/median over the repeats.
"""
from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
GOAL = 2.0


def worker(tree: str, n: int, fmt: str) -> None:
    sys.path.insert(0, tree)
    import kronsub
    from kronsub.budget import limited
    from kronsub.emitters.text import EMITTERS

    spec = importlib.util.spec_from_file_location("_chain_generate", REPO / "models" / "chain" / "generate.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"chain{n}.yaml"
        path.write_text(gen.chain_yaml(n))
        with limited(10**13):
            start = time.process_time()
            system = kronsub.load(str(path), cache=False).derive(cache=False)
            derived = time.process_time()
            text = EMITTERS[fmt](system)
            reported = time.process_time()
    print(json.dumps({"derive": derived - start, "report": reported - derived, "bytes": len(text.encode()),
                      "sha": hashlib.sha256(text.encode()).hexdigest()[:12],
                      "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024,
                      "kronsub": kronsub.__file__}))


def run(tree: str, n: int, fmt: str) -> dict:
    env = {**os.environ, "PYTHONPATH": tree}
    out = subprocess.run([sys.executable, __file__, "--worker", tree, str(n), fmt], env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _span(values) -> str:
    return f"{min(values):.2f}/{statistics.median(values):.2f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="50,100")
    ap.add_argument("--formats", default="markdown,json")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--baseline", help="another kronsub source tree, run interleaved")
    ap.add_argument("--worker", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        worker(args.worker[0], int(args.worker[1]), args.worker[2])
        return 0
    trees = ([("baseline", args.baseline)] if args.baseline else []) + [("this tree", str(REPO))]
    print(f"load average at start: {os.getloadavg()[0]:.1f}; CPU seconds, min/median of {args.repeats}")
    print(f"{'n':>4} {'format':<9} {'tree':<10} {'derive':>11} {'report':>11} {'ratio':>11} "
          f"{'MB out':>7} {'peak RSS':>9}  sha")
    for n in [int(s) for s in args.sizes.split(",")]:
        for fmt in args.formats.split(","):
            results = {name: [] for name, _ in trees}
            for _ in range(args.repeats):
                for name, tree in trees:
                    results[name].append(run(tree, n, fmt))
            for name, _ in trees:
                rows = results[name]
                ratios = [(r["derive"] + r["report"]) / r["derive"] for r in rows]
                shas = sorted({r["sha"] for r in rows})
                print(f"{n:>4} {fmt:<9} {name:<10} {_span([r['derive'] for r in rows]):>11} "
                      f"{_span([r['report'] for r in rows]):>11} {_span(ratios):>11} "
                      f"{rows[0]['bytes'] / 1e6:>7.1f} {max(r['rss'] for r in rows):>6} MB  {','.join(shas)}"
                      + (f"  goal <= {GOAL:g}: {'OK' if statistics.median(ratios) <= GOAL else 'MISS'}"
                         if name == "this tree" else ""), flush=True)
            if args.baseline:
                same = {r["sha"] for rows in results.values() for r in rows}
                print(f"{'':>4} {'':<9} reports {'the same' if len(same) == 1 else 'DIFFER'}", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
