#!/usr/bin/env python
"""Benchmark: derive the n-rod pendulum chain with kronsub and with sympy.physics.mechanics.

Usage::

    python benchmarks/derive_chain.py [--sizes 2,5,10,20,50] [--peer-timeout 300]

For every n the chain (n uniform rods pinned at the origin, absolute angles
q1..qn, gravity) is derived by

* ``kronsub``: ``kronsub.load(<tmp yaml from models/chain/generate.py>).derive()``
  (timed: load + derive + reading mass_matrix / velocity_terms / forces);
* ``kane``: sympy.physics.mechanics.KanesMethod;
* ``lagrange``: sympy.physics.mechanics.LagrangesMethod;

each in its own subprocess, killed after the timeout.  Reported per row:
wall time, operation counts (``sympy.count_ops``) of M, h and f entries after
``sympy.cse`` (replacement expressions + reduced expressions; each group
cse'd on its own, and the total of one joint cse over all entries), the raw
(pre-cse) counts, and kronsub/peer ratios of time and joint-cse ops.  The
peers do not split h and f: their ``forcing`` (= f - h, as returned, no extra
simplification) is reported in the f column and the h column shows "-".
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TOOLS = ("kronsub", "kane", "lagrange")
TARGETS = {20: (0.25, 2391), 50: (2.0, None), 100: (20.0, None)}  # n: (max seconds, max joint-cse ops), issue 11
CACHE_TARGET = 5.0  # % of deriving the chain, for a model whose only component is the cached chain


# ---------------------------------------------------------------------------
# Worker side (runs in a subprocess)
# ---------------------------------------------------------------------------


def _emit(**kw) -> None:
    print(json.dumps(kw), flush=True)


def _count_ops(exprs) -> int:
    import sympy

    return int(sum(sympy.count_ops(e) for e in exprs))


def _cse_ops(exprs) -> int:
    import sympy

    exprs = list(exprs)
    if not exprs:
        return 0
    repl, reduced = sympy.cse(exprs)
    return _count_ops([e for _, e in repl]) + _count_ops(reduced)


def _derive_kronsub(n: int):
    """Returns (seconds, {group: [entries]}) or raises _Unavailable."""
    sys.path.insert(0, str(REPO))
    try:
        import kronsub  # noqa: F401
    except Exception as exc:  # pragma: no cover - depends on project progress
        raise _Unavailable(f"import kronsub failed: {type(exc).__name__}: {exc}")
    if not hasattr(kronsub, "load"):
        raise _Unavailable("kronsub.load does not exist yet")
    gen_path = REPO / "models" / "chain" / "generate.py"
    if not gen_path.exists():
        raise _Unavailable(f"{gen_path.relative_to(REPO)} does not exist yet")
    try:
        spec = importlib.util.spec_from_file_location("_chain_generate", gen_path)
        gen = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(gen)
        text = gen.chain_yaml(n)
    except Exception as exc:
        raise _Unavailable(f"chain_yaml({n}) failed: {type(exc).__name__}: {exc}")
    import kronsub.model.loader  # noqa: F401  imports are not part of the timing (as for the peers)

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"chain{n}.yaml"
        path.write_text(text)
        start = time.perf_counter()
        try:
            system = kronsub.load(str(path), cache=False).derive(cache=False)
            M, h, f = system.mass_matrix, system.velocity_terms, system.forces
            coords = tuple(system.coordinates)
        except Exception as exc:
            raise _Unavailable(f"load/derive failed: {type(exc).__name__}: {exc}")
        seconds = time.perf_counter() - start
    if len(coords) != n:
        raise _Unavailable(f"derived {len(coords)} coordinates, expected {n}")
    return seconds, {"M": list(M), "h": list(h), "f": list(f)}


def _derive_peer(n: int, method: str):
    sys.path.insert(0, str(REPO / "tests"))
    from reference import mechanics as mr

    raw = mr.rod_chain(n, method, raw=True)
    M, forcing = raw.plain()  # conversion to plain symbols, not timed
    return raw.seconds, {"M": list(M), "h": None, "f": list(forcing)}


class _Unavailable(Exception):
    pass


def worker(tool: str, n: int, ops: bool = True) -> None:
    try:
        if tool == "kronsub":
            seconds, groups = _derive_kronsub(n)
        else:
            seconds, groups = _derive_peer(n, tool)
    except _Unavailable as exc:
        _emit(event="unavailable", reason=str(exc))
        return
    _emit(event="derived", seconds=seconds)
    if not ops:
        return
    present = {k: v for k, v in groups.items() if v is not None}
    raw = {k: _count_ops(v) for k, v in present.items()}
    _emit(event="raw_ops", ops=raw, total=sum(raw.values()))
    everything = [e for v in present.values() for e in v]
    _emit(event="cse_total", total=_cse_ops(everything))
    _emit(event="cse_ops", ops={k: _cse_ops(v) for k, v in present.items()})


# ---------------------------------------------------------------------------
# Driver side
# ---------------------------------------------------------------------------


def run_worker(tool: str, n: int, timeout: float, ops: bool = True) -> dict:
    """Run one derivation in a subprocess; collect whatever it reported."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", tool, str(n)] + ([] if ops else ["--no-ops"])
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    timed_out = False
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # the worker's own session only
        except ProcessLookupError:
            pass
        out, err = proc.communicate()
    result: dict = {"tool": tool, "n": n, "timed_out": timed_out}
    for line in out.splitlines():
        try:
            msg = json.loads(line)
        except json.JSONDecodeError:
            continue
        result[msg.pop("event")] = msg
    if not timed_out and proc.returncode != 0 and "derived" not in result and "unavailable" not in result:
        tail = (err.strip().splitlines() or ["?"])[-1]
        result["unavailable"] = {"reason": f"worker crashed: {tail}"}
    return result


def _fmt_groups(res: dict, key: str) -> str:
    if key == "cse":
        ops = res.get("cse_ops", {}).get("ops")
        total = res.get("cse_total", {}).get("total")
    else:
        ops = res.get("raw_ops", {}).get("ops")
        total = res.get("raw_ops", {}).get("total")
    if ops is None and total is None:
        return "timeout" if "derived" in res else "-"
    parts = "?, ?, ?" if ops is None else ", ".join(str(ops[k]) if k in ops else "-" for k in ("M", "h", "f"))
    return f"[{parts}] {total if total is not None else 'timeout'}"


def _row_time(res: dict) -> str:
    if "unavailable" in res:
        return "n/a"
    if "repeats" in res:
        return f"{min(res['repeats']):.3f}/{statistics.median(res['repeats']):.3f}"
    if "derived" in res:
        return f"{res['derived']['seconds']:.3f}"
    return "timeout"


def _targets_note(n: int, res: dict) -> str:
    if n not in TARGETS or res["tool"] != "kronsub":
        return ""
    max_s, max_ops = TARGETS[n]
    want = f"target: <= {max_s:g} s" + (f", <= {max_ops:,} ops" if max_ops else "")
    if "derived" not in res:
        return want
    ok_t = statistics.median(res.get("repeats", [res["derived"]["seconds"]])) <= max_s  # the median, not the best
    total = res.get("cse_total", {}).get("total")
    ok_ops = True if max_ops is None else (total is not None and total <= max_ops)
    return f"{want} -> {'OK' if ok_t and ok_ops else 'MISS'}"


def _ratio(a, b) -> str:
    if a is None or b is None or b == 0:
        return "-"
    return f"{a / b:.3g}"


HEADER = f"{'n':>3}  {'tool':<9} {'time [s]':>9}  {'cse ops [M, h, f] total':<34} {'raw ops [M, h, f] total':<40} {'t ks/peer':>9} {'ops ks/peer':>11}  note"


def print_row(res: dict, kron: dict | None) -> None:
    tool, n = res["tool"], res["n"]
    t_ratio = ops_ratio = ""
    note = ""
    if tool == "kronsub":
        if "unavailable" in res:
            note = f"kronsub: not available ({res['unavailable']['reason']})"
        else:
            note = _targets_note(n, res)
    elif kron is not None:
        kt = kron.get("derived", {}).get("seconds")
        pt = res.get("derived", {}).get("seconds")
        t_ratio = _ratio(kt, pt)
        ops_ratio = _ratio(kron.get("cse_total", {}).get("total"), res.get("cse_total", {}).get("total"))
    if tool != "kronsub" and "unavailable" in res:
        note = f"{tool}: failed ({res['unavailable']['reason']})"
    elif res["timed_out"]:
        killed = "killed at timeout" + (" (after deriving)" if "derived" in res else "")
        note = f"{killed}; {note}" if note else killed
    print(
        f"{n:>3}  {tool:<9} {_row_time(res):>9}  {_fmt_groups(res, 'cse'):<34} "
        f"{_fmt_groups(res, 'raw'):<40} {t_ratio:>9} {ops_ratio:>11}  {note}",
        flush=True,
    )


def cache_section(sizes, timeout) -> None:
    """Known-system cache: a model whose only component is the chain as a known system.

    Compares deriving the chain from scratch with deriving the wrapper model
    when the chain is already in the cache (target: <= CACHE_TARGET %), and with a
    wrapper that is itself cached; best of three runs each, after a warm-up.
    """
    print("\n== known-system cache (model whose component is the chain as a known system) ==")
    sys.path.insert(0, str(REPO))
    try:
        import kronsub
    except Exception as exc:  # pragma: no cover
        print(f"kronsub: not available ({exc})")
        return
    spec = importlib.util.spec_from_file_location("_chain_generate", REPO / "models" / "chain" / "generate.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    with tempfile.TemporaryDirectory() as tmp:  # warm up: imports and sympy's caches
        warm = Path(tmp) / "warm.yaml"
        warm.write_text(gen.chain_yaml(2))
        kronsub.load(warm, cache=False).derive(cache=False)
    print(f"{'n':>4} {'scratch [s] min/med':>20} {'sub cached [s] min/med':>23} {'ratio (med)':>11} "
          f"{'all cached [s]':>15}  target <= {CACHE_TARGET:g} %")
    for n in [k for k in sizes if k <= 20] or [5]:
        with tempfile.TemporaryDirectory() as tmp:
            os.environ["KRONSUB_CACHE_DIR"] = str(Path(tmp) / "cache")
            chain = Path(tmp) / "chain.yaml"
            chain.write_text(gen.chain_yaml(n))
            wrapper = Path(tmp) / "wrapper.yaml"
            wrapper.write_text("name: chain as a known system\ncomponents:\n  chain: {model: chain.yaml}\n"
                               "coordinates: [" + ", ".join(f"q{i}" for i in range(1, n + 1)) + "]\n")
            def best(job, repeats=5):
                times = []
                for _ in range(repeats):
                    gc.collect()  # each repeat from the same start: no collection left over from the last
                    start = time.perf_counter()
                    job()
                    times.append(time.perf_counter() - start)
                return min(times), statistics.median(times)

            scratch = best(lambda: kronsub.load(chain, cache=False).derive(cache=False))
            kronsub.load(chain).derive()  # fill the cache
            warm = best(lambda: kronsub.load(wrapper).derive(cache=False))
            kronsub.load(wrapper).derive()
            cached = best(lambda: kronsub.load(wrapper).derive())
            os.environ.pop("KRONSUB_CACHE_DIR", None)
        ratio = 100 * warm[1] / scratch[1]
        verdict = "OK" if ratio <= CACHE_TARGET else "MISS"
        print(f"{n:>4} {scratch[0]:>9.3f}/{scratch[1]:<10.3f} {warm[0]:>11.3f}/{warm[1]:<11.3f} {ratio:>10.1f}% "
              f"{cached[1]:>15.3f}  {verdict}", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="2,5,10,20,50", help="comma separated chain lengths")
    ap.add_argument("--peer-timeout", type=float, default=300.0, help="seconds per peer derivation")
    ap.add_argument("--kronsub-timeout", type=float, default=None, help="seconds for kronsub (default: peer timeout)")
    ap.add_argument("--tools", default=",".join(TOOLS), help="subset of kronsub,kane,lagrange")
    ap.add_argument("--repeats", type=int, default=3, help="kronsub derivations per size, each in a fresh process")
    ap.add_argument("--worker", nargs=2, metavar=("TOOL", "N"), help=argparse.SUPPRESS)
    ap.add_argument("--no-ops", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)

    if args.worker:
        worker(args.worker[0], int(args.worker[1]), ops=not args.no_ops)
        return 0

    sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
    tools = [t for t in args.tools.split(",") if t]
    kron_timeout = args.kronsub_timeout if args.kronsub_timeout is not None else args.peer_timeout
    print(f"== n-rod chain derivation (peer timeout {args.peer_timeout:g} s) ==")
    print("peers (kane, lagrange): h column '-', f column = mechanics' forcing (= f - h)")
    print("targets (median of the repeats): n=20 <= 0.25 s and <= 2,391 ops (joint cse total); n=50 <= 2 s; "
          "n=100 <= 20 s; kronsub time column: min/median of --repeats fresh processes")
    print(HEADER, flush=True)
    results = []
    for n in sizes:
        kron = None
        for tool in tools:
            res = run_worker(tool, n, kron_timeout if tool == "kronsub" else args.peer_timeout)
            if tool == "kronsub":
                kron = res if "derived" in res else None
                if kron is not None:
                    res["repeats"] = [res["derived"]["seconds"]]
                    for _ in range(args.repeats - 1):
                        again = run_worker(tool, n, kron_timeout, ops=False)
                        if "derived" in again:
                            res["repeats"].append(again["derived"]["seconds"])
            results.append(res)
            print_row(res, kron)
    cache_section(sizes, args.peer_timeout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
