#!/usr/bin/env python
"""Benchmark: writing an animation, kronsub's blitted frames against matplotlib redrawing each one.

Usage::

    python benchmarks/animate.py [--repeats 3] [--models cart_pole,four_bar,system1]

For each model (``models/examples/*.yaml``, ``models/hoffmann/*.yaml``), a 5 s run (dt 0.02)
is simulated once and its shapes placed (:mod:`kronsub.simulation.mechanism`); then, measured
in turn in this one process with the same shapes, frames (30 per second: 167 GIF frames at
0.03 s), size (480 px) and GIF file:

a. ``kronsub``: :func:`kronsub.simulation.animate.animate` (the fixed shapes drawn once, the
   moving artists updated in place and blitted over that background, each picture quantized
   to one palette and written by Pillow's GIF writer).
b. ``peer``: plain ``matplotlib.animation.FuncAnimation`` (``blit=False``) with
   ``PillowWriter``, redrawing the whole figure at every frame, each shape one ``Line2D``
   through its places (a spring's zigzag and a damper's dashpot made by the same functions).

Wall time, min and median of ``--repeats`` runs each, with the median processor time (user
+ system, which other jobs on the machine move far less), and the ratio of the wall medians
(target: kronsub at least 5x faster). Then the whole command, ``python -m kronsub animate
models/examples/cart_pole.yaml --output X.gif`` (the derivation cached, the run, the drawing),
in fresh processes: min and median wall time and the median processor time (target: under 3 s).
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

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from kronsub.model.loader import load_model  # noqa: E402
from kronsub.simulation.animate import animate, at_frames, dashpot, frame_times, zigzag  # noqa: E402
from kronsub.simulation.mechanism import describe, place  # noqa: E402
from kronsub.simulation.plot import plane  # noqa: E402
from kronsub.simulation.run import simulate  # noqa: E402
from kronsub.simulation.values import parse_assignments, resolve  # noqa: E402

FOLDERS = ("examples", "hoffmann")
SPEEDUP, COMMAND_SECONDS = 5.0, 3.0


def shapes_of(name: str, t_end: float = 5.0, dt: float = 0.02):
    path = next(REPO / "models" / folder / f"{name}.yaml" for folder in FOLDERS
                if (REPO / "models" / folder / f"{name}.yaml").exists())
    model = load_model(path)
    system = model.derive()
    values = resolve(system, dict(model.initial), parse_assignments(()))
    traj = simulate(system, values, t_end, dt, "dop853")
    return traj.t, place(describe(model, system), system, traj, np.array(values.parameters)), system.name


def peer(t, shapes, path: Path, fps: int = 30, size: int = 480) -> int:
    """matplotlib's FuncAnimation redrawing everything each frame, PillowWriter."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import animation

    times, interval = frame_times(t, fps, gif=True)
    frames = [plane(at_frames(t, times, s.places)) for s in shapes if s.kind != "dial"]
    kinds = [s.kind for s in shapes if s.kind != "dial"]
    everything = np.vstack([f.reshape(-1, 2) for f in frames])
    low, high = everything.min(axis=0), everything.max(axis=0)
    centre, half = (low + high) / 2, max(float(np.max(high - low)) / 2, 1e-9) * 1.15
    fig = plt.figure(figsize=(size / 80, size / 80), dpi=80)
    ax = fig.add_axes((0.13, 0.1, 0.82, 0.8))
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
    lines = [ax.plot([], [], "-o", lw=2)[0] for _ in frames]
    clock = ax.set_title("")

    def draw(k):
        for line, xy, kind in zip(lines, frames, kinds):
            if kind == "spring":
                xy_k = zigzag(xy[k, 0], xy[k, 1], 0.035 * half)
            elif kind == "damper":
                xy_k = dashpot(xy[k, 0], xy[k, 1], 0.035 * half)
            else:
                xy_k = xy[k]
            line.set_data(xy_k[:, 0], xy_k[:, 1])
        clock.set_text(f"t = {times[k]:.2f} s")
        return lines + [clock]

    movie = animation.FuncAnimation(fig, draw, frames=len(times), blit=False)
    movie.save(str(path), writer=animation.PillowWriter(fps=1000.0 / (1000.0 * interval + 1e-6)), dpi=80)
    plt.close(fig)
    return len(times)


def _cpu() -> float:
    """Processor seconds of this process and of its finished children (user + system)."""
    me, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + children.ru_utime + children.ru_stime


def timed(job, repeats: int) -> tuple[float, float, float, object]:
    """Wall seconds (min, median), processor seconds (median) and the job's result."""
    times, cpu, result = [], [], None
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), _cpu()
        result = job()
        times.append(time.perf_counter() - start)
        cpu.append(_cpu() - start_cpu)
    return min(times), statistics.median(times), statistics.median(cpu), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--models", default="cart_pole,four_bar,system1")
    args = parser.parse_args()
    print(f"{'model':<12} {'frames':>6}  {'kronsub [s] min/med (cpu)':>26}  {'peer [s] min/med (cpu)':>24}  "
          f"{'peer/kronsub':>12}  target >= {SPEEDUP:g}x")
    with tempfile.TemporaryDirectory() as folder:
        gif = Path(folder) / "motion.gif"
        for name in args.models.split(","):
            t, shapes, title = shapes_of(name)
            k_min, k_med, k_cpu, frames = timed(lambda: animate(t, shapes, gif, title=title, progress=False),
                                                args.repeats)
            p_min, p_med, p_cpu, _ = timed(lambda: peer(t, shapes, gif), args.repeats)
            ratio = p_med / k_med
            print(f"{name:<12} {frames:>6}  {k_min:>8.3f}/{k_med:<6.3f} ({k_cpu:6.3f})  "
                  f"{p_min:>8.3f}/{p_med:<6.3f} ({p_cpu:6.3f})  {ratio:>11.1f}x  {'OK' if ratio >= SPEEDUP else 'MISS'}")
        env = dict(os.environ, PYTHONPATH=str(REPO))
        command = [sys.executable, "-m", "kronsub", "animate", str(REPO / "models" / "examples" / "cart_pole.yaml"),
                   "--output", str(gif), "--no-progress"]
        subprocess.run(command, env=env, check=True, capture_output=True)  # the derivation cached
        c_min, c_med, c_cpu, _ = timed(lambda: subprocess.run(command, env=env, check=True, capture_output=True),
                                       args.repeats)
        print(f"\nkronsub animate cart_pole.yaml (5 s, 167 frames), whole command [s] min/med: "
              f"{c_min:.3f}/{c_med:.3f}, processor {c_cpu:.3f}  target < {COMMAND_SECONDS:g} s -> "
              f"{'OK' if c_med < COMMAND_SECONDS else 'MISS'} (processor time: "
              f"{'OK' if c_cpu < COMMAND_SECONDS else 'MISS'}; the wall time waits for other jobs on a loaded machine)")


if __name__ == "__main__":
    main()
