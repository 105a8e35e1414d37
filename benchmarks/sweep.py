"""kronsub sweep against its peers: 10^4 double-pendulum runs (System I's defaults, initial angles
uniform in [-2, 2], at rest, t = 10) through `kronsub sweep`'s driver on 1 and 2 local workers,
the compiled ensemble called directly in this process (on one thread, and on two threads each
given half the runs: what the machine gives two workers at the time), heyoka's `ensemble_propagate_until`
(threads, 1 and 2) and a Python loop over `system.simulate()`; each at the loosest tolerance whose
error at t = 10 is <= 1e-8 on a sample of runs against the Taylor integrator at 1e-15. The routes
are timed round by round (interleaved). The sweep rows time the driver writing every chunk as its
Parquet part (as the command does) on the command's local cluster, started before the clock;
the share of the wall time each worker spent in the ensemble's calls (what the engine leaves to
the runs: a thread that waits for a core while in a call still counts, so the load of other jobs
moves it little) is printed beside them; the whole command, cluster start included, is timed apart (with the sweep's C kept from the
run before; the emission that saves is timed in this process). Then the engine's share of the wall
time at --overhead-runs (one worker: the wall time less the time the worker spent in the
ensemble's calls, timed over the same interval) and the client's peak memory (the peak resident
set, ``VmHWM``, of the process running `kronsub sweep`, its worker threads included) at 10^4,
10^5 and 10^6 runs of a cheap sweep (rk4, t = 0.1, dt = 0.05, 10^4 runs a chunk). Prints runs
per second, the ratios the issue sets as goals, min and median of --repeats.

    python benchmarks/sweep.py [--runs 10000] [--repeats 3] [--overhead-runs 100000] [--memory 4,5,6] [--quick]
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "models" / "hoffmann" / "system1.yaml"
T_END, DT = 10.0, 0.01
ERROR = 1e-8  # at t = 10, on the sample, against the tight run
SAMPLE = 20
ANGLES = ("theta=uniform(-2, 2)", "phi=uniform(-2, 2)")
LOOP = "Python loop over system.simulate(method='taylor')"
DIRECT2 = "Taylor ensemble directly, 2 threads, half the runs each"
CHEAP = ("--method", "rk4", "--t", "0.1", "--dt", "0.05", "--chunk", "10000")  # the memory runs: the engine, not the model


def timed(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--overhead-runs", type=int, default=100_000)
    parser.add_argument("--memory", default="4,5,6", help="powers of ten of the memory runs ('' for none)")
    parser.add_argument("--quick", action="store_true", help="2,000 runs, one repeat, overhead at 10^4, memory at 10^4, 10^5")
    parser.add_argument("--memory-child", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.memory_child is not None:
        return memory_child(args.memory_child)
    runs, repeats = (2000, 1) if args.quick else (args.runs, args.repeats)
    overhead_runs = 10_000 if args.quick else args.overhead_runs
    powers = [4, 5] if args.quick else [int(p) for p in args.memory.split(",") if p.strip()]

    import kronsub
    from kronsub.commands.common import scene_system
    from kronsub.model.scenes import initial_values
    from kronsub.sweep.axes import read_axes
    from kronsub.sweep.chunk import inputs_of
    from kronsub.sweep.driver import execute, local_cluster
    from kronsub.sweep.ensemble import load, pieces
    from kronsub.sweep.study import make_job, make_plan

    loaded, _, system = scene_system(MODEL, None)
    plan = make_plan(*read_axes((), ANGLES), runs, 1)

    def job_at(tol, chunk=1000):  # noqa: D401
        return make_job(system, plan, initial_values(loaded, None), {}, method="dop853", t_end=T_END, dt=DT,
                        rtol=tol, atol=tol, chunk=chunk)

    from kronsub.simulation.grid import Grid
    from kronsub.sweep.ensemble import load_taylor, taylor_sources

    base = job_at(1e-10)
    _, param, y0 = inputs_of(base, 0, runs)
    ensemble = load(base.sources)
    cuts = pieces(T_END, DT, "dop853")
    times = Grid(T_END, DT)[0:len(Grid(T_END, DT))]
    reference = load_taylor(taylor_sources(system, 1e-15)).run(times, 1e-15, param[:SAMPLE], y0[:SAMPLE], None)[:, 5:9]

    def loosest(errors):
        return next((t for t, e in errors.items() if e <= ERROR), min(errors))

    dop = {t: float(np.max(np.abs(ensemble.run("dop853", cuts, DT, t, t, param[:SAMPLE], y0[:SAMPLE], False)[:, 5:9]
                                  - reference))) for t in (1e-10, 1e-11, 1e-12, 1e-13, 1e-14)}
    tay = {t: float(np.max(np.abs(load_taylor(taylor_sources(system, t)).run(times, t, param[:SAMPLE], y0[:SAMPLE],
                                                                             None)[:, 5:9] - reference)))
           for t in (1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14)}
    print(f"load average {', '.join(f'{x:.1f}' for x in os.getloadavg())} on {os.cpu_count()} cores at the start")
    print(f"{runs:,} runs of System I to t = {T_END:g}, rows every {DT:g}; error at t = {T_END:g} on {SAMPLE} runs "
          "against the Taylor integrator at 1e-15:")
    print("  dop853: " + ", ".join(f"{t:.0e}: {e:.1e}" for t, e in dop.items()))
    print("  taylor: " + ", ".join(f"{t:.0e}: {e:.1e}" for t, e in tay.items()))
    dop_tol, tol = loosest(dop), loosest(tay)
    print(f"  the loosest at <= {ERROR:g}: dop853 {dop_tol:.0e}, taylor {tol:.0e}")
    rates, medians, per_cpu = {}, {}, {}

    def report(name, seconds, count=runs):
        low, med = seconds
        rates[name], medians[name] = count / low, count / med
        print(f"  {name:<52} {count / low:>10,.0f} runs/s (best)   {count / med:>10,.0f} (median)")

    taylor = load_taylor(taylor_sources(system, tol))
    job = make_job(system, plan, initial_values(loaded, None), {}, method="taylor", t_end=T_END, dt=DT,
                   rtol=tol, atol=tol, chunk=1000)
    from kronsub.sweep.chunk import columns
    from kronsub.sweep.dataset import Dataset

    scratch = tempfile.TemporaryDirectory(prefix="kronsub-sweep-bench-")

    def written(job_, name):
        """``done`` as the command's: each chunk's rows written as its Parquet part."""
        dataset = Dataset(Path(scratch.name) / name, columns(job_))
        dataset.prepare({}, resume=False, force=True)
        return lambda index, rows: dataset.write(index, rows)

    tenth = max(1, runs // 10)
    from concurrent.futures import ThreadPoolExecutor

    halves = ThreadPoolExecutor(2)

    def direct_on_two():
        cut = (0, runs // 2, runs)
        list(halves.map(lambda k: taylor.run(times, tol, param[cut[k]:cut[k + 1]], y0[cut[k]:cut[k + 1]], None),
                        (0, 1)))

    routes = {"Taylor ensemble directly, this process": (lambda: taylor.run(times, tol, param, y0, None), runs),
              DIRECT2: (direct_on_two, runs),
              f"dop853 ensemble directly, this process ({tenth:,} runs)": (
                  lambda: ensemble.run("dop853", cuts, DT, dop_tol, dop_tol, param[:tenth], y0[:tenth], False), tenth)}

    def sweep_on(cluster, workers):
        return lambda: execute(job, range(job.chunks), written(job, f"w{workers}"), scheduler=cluster.scheduler_address)

    with contextlib.ExitStack() as stack:
        for workers in (1, 2):  # the clusters started (and the workers' library loaded) before the clock
            t0 = time.perf_counter()
            cluster = stack.enter_context(local_cluster(workers, threads=True))  # the command's, for compiled runs
            execute(job, range(workers), written(job, "warm"), scheduler=cluster.scheduler_address)
            print(f"  (a local cluster of {workers} started and warmed in {time.perf_counter() - t0:.1f} s)")
            routes[f"kronsub sweep (taylor), {workers} local worker(s)"] = (sweep_on(cluster, workers), runs)
        try:
            import heyoka

            from kronsub.simulation.heyoka_backend import HeyokaIntegrator
        except ImportError as exc:
            print(f"  heyoka not available ({exc})")
        else:
            errors = {}
            for t in (1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15):
                integ = HeyokaIntegrator(system, t)
                worst = 0.0
                for r in range(SAMPLE):
                    integ.start(0.0, y0[r], param[r])
                    integ.ta.propagate_until(T_END)
                    worst = max(worst, float(np.max(np.abs(integ.ta.state - reference[r]))))
                errors[t] = worst
                if worst <= ERROR:
                    break
            hy_tol = loosest(errors)
            print("  heyoka: " + ", ".join(f"{t:.0e}: {e:.1e}" for t, e in errors.items()))
            integ = HeyokaIntegrator(system, hy_tol)
            used = integ.used

            def gen(ta, i):
                ta.time = 0.0
                ta.state[:] = y0[i]
                ta.pars[:] = param[i, :used]
                return ta

            for threads in (1, 2):
                routes[f"heyoka ensemble, {threads} thread(s), tol {hy_tol:.0e}"] = (
                    lambda threads=threads: heyoka.ensemble_propagate_until(
                        integ.ta, T_END, runs, gen, algorithm="thread", max_workers=threads), runs)
        seconds = {name: [] for name in routes}
        cpu = {name: [] for name in routes}
        busy = {name: [] for name in routes}  # the workers' time in the ensemble's calls / (workers x wall)
        with in_calls() as spent:
            for _ in range(repeats):  # interleaved: each route once a round, so that a change of load hits them all
                for name, (fn, _count) in routes.items():
                    spent.clear()
                    t0, c0 = time.perf_counter(), time.process_time()
                    fn()
                    seconds[name].append(time.perf_counter() - t0)
                    cpu[name].append(time.process_time() - c0)
                    busy[name].append(sum(spent) / (seconds[name][-1] * (2 if "2 local" in name else 1)))
    for name, (_, count) in routes.items():
        report(name, (min(seconds[name]), statistics.median(seconds[name])), count)
    print("  the share of the wall time each worker spent in the ensemble's calls (what the engine leaves to the "
          "runs, whatever the load), best and median:")
    for name in routes:
        if name.startswith("kronsub sweep"):
            print(f"    {name:<50} {max(busy[name]):>10.1%} {statistics.median(busy[name]):>10.1%}")
    print("  per second of this process's CPU time (all its threads: the sweep's client, scheduler and worker; "
          "heyoka's threads), best and median:")
    for name, (_, count) in routes.items():
        per_cpu[name] = count / min(cpu[name])
        print(f"    {name:<50} {count / min(cpu[name]):>10,.0f} {count / statistics.median(cpu[name]):>10,.0f}")
    command_seconds(runs, tol, Path(scratch.name) / "whole")  # (the sweep's C kept, if it was not)
    whole = [command_seconds(runs, tol, Path(scratch.name) / f"whole{k}") for k in range(repeats)]
    report("the whole `kronsub sweep` command, 1 worker", (min(whole), statistics.median(whole)))
    emitting = []
    for _ in range(repeats):
        from kronsub.emitters.code import emit_c
        from kronsub.simulation.taylor_c import generated_c, order_for

        t0 = time.perf_counter()
        emit_c(system, "model")
        generated_c(system, order_for(tol))
        emitting.append(time.perf_counter() - t0)
    print(f"  emitting the sweep's C, which a sweep of a model whose C is kept leaves out: {min(emitting):.2f} s "
          f"(best), {statistics.median(emitting):.2f} s (median)")
    api = kronsub.load(MODEL).derive()
    loop = min(runs, 200)

    def python_loop():
        for r in range(loop):
            api.simulate(t=T_END, dt=DT, method="taylor", set={"theta": y0[r, 0], "phi": y0[r, 1]}, rtol=tol,
                         atol=tol, dataframe=False)

    report(LOOP, timed(python_loop, 1), loop)
    share = overhead(system, loaded, tol, overhead_runs, repeats, written)
    memory = {10 ** p: memory_mb(10 ** p, Path(scratch.name) / f"memory{p}") for p in powers}
    for count, mb in memory.items():
        print(f"  client peak memory, {count:>9,} runs (rk4, t = 0.1): {mb:6.0f} MB")
    print("ratios (of the best; of the medians):")
    sweep1, sweep2 = "kronsub sweep (taylor), 1 local worker(s)", "kronsub sweep (taylor), 2 local worker(s)"
    hey = next((k for k in rates if k.startswith("heyoka ensemble, 1")), None)

    def ratio(a, b):
        return f"{rates[a] / rates[b]:.2f}; {medians[a] / medians[b]:.2f}"

    print(f"  sweep on 1 worker / compiled ensemble directly: {ratio(sweep1, 'Taylor ensemble directly, this process')} "
          "(goal >= 0.8)")
    print(f"  sweep on 2 workers / 1 worker: {ratio(sweep2, sweep1)} (goal >= 1.8); per CPU second "
          f"{per_cpu[sweep2] / per_cpu[sweep1]:.2f}")
    direct1 = "Taylor ensemble directly, this process"
    print(f"  the machine at the time, ensemble directly on 2 threads / 1: {ratio(DIRECT2, direct1)}; the sweep's "
          f"share of it: {rates[sweep2] / rates[sweep1] / (rates[DIRECT2] / rates[direct1]):.2f}; "
          f"{medians[sweep2] / medians[sweep1] / (medians[DIRECT2] / medians[direct1]):.2f}")
    if hey:
        print(f"  sweep on 1 worker / heyoka ensemble on 1 thread: {ratio(sweep1, hey)} (goal >= 5)")
    print(f"  sweep on 1 worker / Python loop: {ratio(sweep1, LOOP)}")
    print(f"  per core: {rates[sweep1]:,.0f}; {medians[sweep1]:,.0f} runs/s through kronsub sweep (goal >= 5,000); "
          f"{per_cpu[sweep1]:,.0f} per CPU second")
    if hey:
        print(f"  per CPU second, sweep on 1 worker / heyoka on 1 thread: {per_cpu[sweep1] / per_cpu[hey]:.2f} (goal >= 5)")
    print(f"  engine's share of the wall time at {overhead_runs:,} runs: {share[0]:.1%} (best), {share[1]:.1%} "
          "(median) (goal <= 5 %)")
    if memory:
        low = min(memory.values())
        print("  client memory / the smallest run's: " + ", ".join(f"{c:,}: {m / low:.2f}" for c, m in memory.items())
              + " (goal: flat)")
    print(f"load average {', '.join(f'{x:.1f}' for x in os.getloadavg())} at the end")
    scratch.cleanup()


@contextlib.contextmanager
def in_calls():
    """The seconds of each call of the Taylor ensemble made meanwhile, by any thread of this
    process (the local cluster's workers are its threads)."""
    from kronsub.sweep.ensemble import TaylorEnsemble

    spent, original = [], TaylorEnsemble.run

    def timed_run(self, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            return original(self, *args, **kwargs)
        finally:
            spent.append(time.perf_counter() - t0)

    TaylorEnsemble.run = timed_run
    try:
        yield spent
    finally:
        TaylorEnsemble.run = original


def overhead(system, loaded, tol, count, repeats, written):
    """The engine's share of a sweep's wall time on one worker, ``1 - compute / wall``: ``compute``
    the time its worker spent in the compiled ensemble's calls, timed in the worker (a thread of
    this process, as the command's local cluster) over the same interval as the wall, so that a
    change of load moves both; (best, median) of ``max(2, repeats)``."""
    from kronsub.model.scenes import initial_values
    from kronsub.sweep.axes import read_axes
    from kronsub.sweep.driver import execute, local_cluster
    from kronsub.sweep.study import make_job, make_plan

    plan = make_plan(*read_axes((), ANGLES), count, 2)
    job = make_job(system, plan, initial_values(loaded, None), {}, method="taylor", t_end=T_END, dt=DT, rtol=tol,
                   atol=tol, chunk=1000)
    shares = []
    with in_calls() as spent, local_cluster(1, threads=True) as cluster:
        execute(job, range(1), lambda i, rows: None, scheduler=cluster.scheduler_address)
        for k in range(max(2, repeats)):
            spent.clear()
            t0 = time.perf_counter()
            execute(job, range(job.chunks), written(job, f"overhead{k}"), scheduler=cluster.scheduler_address)
            wall = time.perf_counter() - t0
            shares.append(1 - sum(spent) / wall)
            print(f"  {count:,} runs on 1 worker: {wall:.2f} s, of which {sum(spent):.2f} s in the ensemble's calls")
    return min(shares), statistics.median(shares)


def command_seconds(runs, tol, out) -> float:
    """Wall time of the whole command (a fresh process: import, model, local cluster, Parquet)."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "kronsub", "sweep", str(MODEL), *(a for s in ANGLES for a in ("--sample", s)),
                    "--runs", str(runs), "--seed", "1", "--method", "taylor", "--rtol", repr(tol), "--atol", repr(tol),
                    "--t", repr(T_END), "--dt", repr(DT), "--workers", "1", "-o", str(out)], check=True,
                   capture_output=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    return time.perf_counter() - t0


def memory_mb(count, out) -> float:
    """Peak resident memory of the client of a cheap sweep of ``count`` runs (a fresh process)."""
    done = subprocess.run([sys.executable, __file__, "--memory-child", str(count), "--runs", "1", "--memory", str(out)],
                          check=True, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    return json.loads(done.stdout.strip().splitlines()[-1])["maxrss_mb"]


def memory_child(count) -> None:
    """In the child: `kronsub sweep` of ``count`` cheap runs in this process, then its peak memory
    (``VmHWM``: ``ru_maxrss`` keeps the parent's peak across ``exec`` on Linux)."""
    from kronsub.cli import main

    out = sys.argv[sys.argv.index("--memory") + 1]
    try:
        main(["sweep", str(MODEL), *(a for s in ANGLES for a in ("--sample", s)), "--runs", str(count), *CHEAP,
              "--workers", "1", "-o", out], standalone_mode=False)
    except SystemExit as exc:
        if exc.code:
            raise
    peak = next(line for line in Path("/proc/self/status").read_text().splitlines() if line.startswith("VmHWM:"))
    print(json.dumps({"maxrss_mb": int(peak.split()[1]) / 1024}))


if __name__ == "__main__":
    main()
