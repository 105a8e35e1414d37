"""kronsub sweep against its peers: 10^4 double-pendulum runs (System I's defaults, initial angles
uniform in [-2, 2], at rest, t = 10) through `kronsub sweep`'s driver on 1 and 2 local workers,
the compiled ensemble called directly in this process, heyoka's `ensemble_propagate_until`
(threads, 1 and 2) and a Python loop over `system.simulate()`; each at a tolerance whose error
at t = 10 is <= 1e-8 on a sample of runs against a run at 1e-14. Prints runs per second, the
ratios the issue sets as goals, min and median of --repeats.

    python benchmarks/sweep.py [--runs 10000] [--repeats 3] [--quick]
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "models" / "hoffmann" / "system1.yaml"
T_END, DT = 10.0, 0.01
ERROR = 1e-8  # at t = 10, on the sample, against the tight run
SAMPLE = 20


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
    parser.add_argument("--quick", action="store_true", help="2,000 runs, one repeat")
    args = parser.parse_args()
    runs, repeats = (2000, 1) if args.quick else (args.runs, args.repeats)

    import kronsub
    from kronsub.commands.common import scene_system
    from kronsub.model.scenes import initial_values
    from kronsub.sweep.axes import read_axes
    from kronsub.sweep.chunk import _values  # noqa: PLC2701 - the benchmark reads the same inputs
    from kronsub.sweep.driver import execute
    from kronsub.sweep.ensemble import load, pieces
    from kronsub.sweep.study import make_job, make_plan

    loaded, _, system = scene_system(MODEL, None)
    plan = make_plan(*read_axes((), ("theta=uniform(-2, 2)", "phi=uniform(-2, 2)")), runs, 1)

    def job_at(tol, chunk=1000):
        return make_job(system, plan, initial_values(loaded, None), {}, method="dop853", t_end=T_END, dt=DT,
                        rtol=tol, atol=tol, chunk=chunk)

    tight = job_at(1e-14)
    _, param, y0 = _values(tight, 0, runs)
    ensemble = load(tight.sources)
    cuts = pieces(T_END, DT, "dop853")
    reference = ensemble.run("dop853", cuts, DT, 1e-14, 1e-14, param[:SAMPLE], y0[:SAMPLE], False)[:, 5:9]
    errors = {t: float(np.max(np.abs(ensemble.run("dop853", cuts, DT, t, t, param[:SAMPLE], y0[:SAMPLE], False)[:, 5:9]
                                      - reference))) for t in (1e-9, 1e-10, 1e-11, 1e-12, 1e-13)}
    print("  dop853 error at t = 10 by tolerance: " + ", ".join(f"{t:.0e}: {e:.1e}" for t, e in errors.items()))
    tol = next((t for t, e in errors.items() if e <= ERROR), 1e-13)
    print(f"{runs:,} runs of System I to t = {T_END:g}; dop853 at rtol = atol = {tol:.0e} (error <= {ERROR:g} at "
          f"t = {T_END:g} on {SAMPLE} runs against 1e-14)")
    rates = {}

    def report(name, seconds, count=runs):
        low, med = seconds
        rates[name] = count / low
        print(f"  {name:<40} {count / low:>10,.0f} runs/s (best)   {count / med:>10,.0f} (median)")

    report("compiled ensemble, this process", timed(
        lambda: ensemble.run("dop853", cuts, DT, tol, tol, param, y0, False), repeats))
    job = job_at(tol)
    for workers in (1, 2):
        report(f"kronsub sweep, {workers} local worker(s)", timed(
            lambda: execute(job, range(job.chunks), lambda i, rows: None, workers=workers), repeats))
    try:
        import heyoka

        from kronsub.simulation.heyoka_backend import HeyokaIntegrator
    except ImportError as exc:
        print(f"  heyoka not available ({exc})")
    else:
        hy_tol = next(t for t in (1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14) if True)
        for t in (1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14):
            integ = HeyokaIntegrator(system, t)
            worst = 0.0
            for r in range(SAMPLE):
                integ.start(0.0, y0[r], param[r])
                integ.ta.propagate_until(T_END)
                worst = max(worst, float(np.max(np.abs(integ.ta.state - reference[r]))))
            if worst <= ERROR:
                hy_tol = t
                break
        integ = HeyokaIntegrator(system, hy_tol)
        used = integ.used

        def gen(ta, i):
            ta.time = 0.0
            ta.state[:] = y0[i]
            ta.pars[:] = param[i, :used]
            return ta

        for threads in (1, 2):
            report(f"heyoka ensemble, {threads} thread(s), tol {hy_tol:.0e}", timed(
                lambda: heyoka.ensemble_propagate_until(integ.ta, T_END, runs, gen, algorithm="thread",
                                                        max_workers=threads), repeats))
    api = kronsub.load(MODEL).derive()
    loop = min(runs, 200)

    def python_loop():
        for r in range(loop):
            api.simulate(t=T_END, dt=DT, set={"theta": y0[r, 0], "phi": y0[r, 1]}, rtol=tol, atol=tol,
                         dataframe=False)

    report("Python loop over system.simulate()", timed(python_loop, 1), loop)
    print("ratios:")
    direct = rates["compiled ensemble, this process"]
    one, two = rates["kronsub sweep, 1 local worker(s)"], rates["kronsub sweep, 2 local worker(s)"]
    print(f"  sweep on 1 worker / compiled ensemble directly: {one / direct:.2f} (goal >= 0.8)")
    print(f"  sweep on 2 workers / 1 worker: {two / one:.2f} (goal >= 1.8)")
    heyoka_one = next((v for k, v in rates.items() if k.startswith("heyoka ensemble, 1")), None)
    if heyoka_one:
        print(f"  sweep on 1 worker / heyoka ensemble on 1 thread: {one / heyoka_one:.2f} (goal >= 5)")
    print(f"  sweep on 1 worker / Python loop: {one / rates['Python loop over system.simulate()']:.0f}")
    print(f"  per core: {one:,.0f} runs/s through kronsub sweep (goal >= 5,000)")


if __name__ == "__main__":
    main()
