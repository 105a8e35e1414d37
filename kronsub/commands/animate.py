"""``kronsub animate MODEL|TRAJ.csv --output motion.gif``: the mechanism drawn over time."""
from __future__ import annotations

from pathlib import Path

import click

from .common import (T_END, USAGE_ERROR, budget_option, check_times, fail, output_option, run_command, say,
                     separate_outputs, set_option, writable)


@click.command()
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@output_option("The animation: a .gif (pillow) or .mp4 (ffmpeg).", required=True)
@click.option("--t", "t_end", type=float, default=T_END, show_default=True,
              help="End time (MODEL only; the same default as simulate).")
@click.option("--dt", type=float, default=0.02, show_default=True, help="Output interval (MODEL only).")
@click.option("--method", default="dop853", show_default=True, help="Integration method (MODEL only).")
@set_option("Set a parameter or an initial coordinate/velocity (MODEL only; repeatable).")
@click.option("--fps", type=click.IntRange(1, 120), default=30, show_default=True,
              help="Frames per second; rows are skipped so that the animation plays in real time.")
@click.option("--size", type=click.IntRange(64, 4096), default=480, show_default=True,
              help="Width and height of the frames in pixels.")
@budget_option
def animate(source: Path, output: Path, t_end: float, dt: float, method: str, settings: tuple[str, ...],
            fps: int, size: int):
    """Draw the mechanism of SOURCE over time: a MODEL (simulated first) or a trajectory CSV
    written with `kronsub simulate --points`. Bodies are segments between their named
    points, discs are circles; needs matplotlib (pip install 'kronsub[plot]')."""
    from ..simulation.methods import SIMULATE
    from ..simulation.run import SimulationError, row_count

    def job():
        separate_outputs(source, ("--output", output, "animation"))
        from_csv = source.suffix.lower() == ".csv"
        ctx = click.get_current_context()
        if from_csv:  # a trajectory has its times and values: the options that make one do not apply
            given = [f"--{name.replace('t_end', 't').replace('settings', 'set')}" for name in
                     ("t_end", "dt", "method", "settings")
                     if ctx.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT]
            if given:
                fail(f"Error: {', '.join(given)} {'applies' if len(given) == 1 else 'apply'} to a MODEL, not to "
                      f"the trajectory {source}\n  hint: drop {', '.join(given)}, or animate the model itself",
                      USAGE_ERROR)
        else:
            check_times(t_end, dt)
            if method not in SIMULATE:
                fail(f"Error: unknown method '{method}'\n  hint: choose one of {', '.join(SIMULATE)}", USAGE_ERROR)
            try:
                row_count(t_end, dt)
            except SimulationError as exc:
                fail(f"Error: {exc}", USAGE_ERROR)
        writable(output, "--output")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            fail("Error: animate needs matplotlib\n  hint: pip install 'kronsub[plot]'")
        from ..simulation.animate import animate as draw
        from ..simulation.animate import read_points_csv

        if from_csv:
            t, names, values = read_points_csv(source)
            title = ""
        else:
            t, names, values, title = _simulate(source, t_end, dt, method, settings)
        frames = draw(t, names, values, output, fps=fps, size=size, title=title)
        say(f"wrote {output} ({frames} frames)")

    run_command(job)


def _simulate(model: Path, t_end: float, dt: float, method: str, settings):
    import numpy as np

    from ..model.loader import load_model
    from ..simulation.run import simulate
    from ..simulation.table import point_columns
    from ..simulation.values import parse_assignments, resolve

    loaded = load_model(model)
    system = loaded.derive()
    values = resolve(system, dict(loaded.initial), parse_assignments(settings))
    traj = simulate(system, values, t_end, dt, method)
    if not traj.complete:
        say(f"Warning: the run stopped at t = {traj.t_fail:.6g}: {traj.message}; "
            f"animating the {len(traj.t)} rows computed")
    names, pts = point_columns(system, traj, np.array(values.parameters))
    return traj.t, names, pts, system.name
