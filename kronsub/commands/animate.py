"""``kronsub animate MODEL|TRAJ.csv --output motion.gif``: the mechanism drawn over time."""
from __future__ import annotations

from pathlib import Path

import click

from .common import (T_END, USAGE_ERROR, budget_option, check_times, fail, output_option, run_command, say, scene_option,
                     scene_system, separate_outputs, set_option, writable)

__all__ = ["animate"]

_MODEL_ONLY = {"t_end": "--t", "dt": "--dt", "method": "--method", "settings": "--set", "scene_name": "--scene"}


@click.command()
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@output_option("The animation: a .gif (pillow) or .mp4 (ffmpeg).", required=True)
@click.option("--t", "t_end", type=float, default=None, help=f"End time (MODEL only; default: the scene's, else {T_END:g}, as simulate).")
@click.option("--dt", type=float, default=None,
              help="Output interval (MODEL only; default: the scene's, else 0.02).")
@click.option("--method", default=None, help="Integration method (MODEL only; default: the scene's, else dop853).")
@set_option("Set a parameter or an initial coordinate/velocity (MODEL only; repeatable).")
@click.option("--fps", type=click.IntRange(1, 120), default=30, show_default=True,
              help="Frames per second; the places between the rows are interpolated so that the animation "
                   "plays in real time.")
@click.option("--size", type=click.IntRange(64, 4096), default=480, show_default=True,
              help="Width and height of the frames in pixels.")
@scene_option(help="Use the model's scene NAME (MODEL only): its effects, values, initial values, span, step "
                   "and method (default: the model's only scene if it has exactly one, else every effect).")
@click.option("--progress/--no-progress", default=None,
              help="A bar counting the frames on stderr (default: on a terminal only).")
@budget_option
def animate(source: Path, output: Path, t_end: float | None, dt: float | None, method: str | None,
            settings: tuple[str, ...], fps: int, size: int, scene_name: str | None, progress: bool | None):
    """Draw the mechanism of SOURCE over time: a MODEL (simulated first) or a trajectory CSV
    written with `kronsub simulate --points`. From a MODEL: rods, discs with a mark at their
    angle, flywheels as dials, bodies' axes, springs (zigzag) and dampers (dashpot), fixed
    pivots on hatched ground, walls, rails and sliders, joints; from a CSV: the named
    points. Needs matplotlib and Pillow (pip install 'kronsub[plot]')."""
    from ..simulation.methods import SIMULATE

    def job():
        separate_outputs(source, ("--output", output, "animation"))
        from ..simulation.animate import FORMATS

        if output.suffix.lower() not in FORMATS:  # before the run
            suffix = f"'{output.suffix}'" if output.suffix else "suffix-less"
            fail(f"Error: --output {output}: cannot write {suffix} animations\n  hint: end the name in .gif or .mp4",
                 USAGE_ERROR)
        from_csv = source.suffix.lower() == ".csv"
        ctx = click.get_current_context()
        if from_csv:  # a trajectory has its times and values: the options that make one do not apply
            given = [flag for name, flag in _MODEL_ONLY.items()
                     if ctx.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT]
            if given:
                fail(f"Error: {', '.join(given)} {'applies' if len(given) == 1 else 'apply'} to a MODEL, not to "
                      f"the trajectory {source}\n  hint: drop {', '.join(given)}, or animate the model itself",
                      USAGE_ERROR)
        else:
            check_times(t_end, dt)
            if method is not None and method not in SIMULATE:
                fail(f"Error: unknown method '{method}'\n  hint: choose one of {', '.join(SIMULATE)}", USAGE_ERROR)
        writable(output, "--output")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            fail("Error: animate needs matplotlib\n  hint: pip install 'kronsub[plot]'")
        from ..simulation.animate import animate as draw
        from ..simulation.animate import read_points_csv
        from ..simulation.mechanism import from_points

        if from_csv:
            t, names, values = read_points_csv(source)
            frames = draw(t, from_points(names, values), output, fps=fps, size=size, title="", progress=progress)
        else:
            frames = _animate_model(source, output, t_end, dt, method, settings, fps, size, scene_name, progress)
        say(f"wrote {output} ({frames} frames)")

    run_command(job)


def _animate_model(model: Path, output: Path, t_end, dt, method, settings, fps: int, size: int, scene_name,
                   progress: bool | None):
    """Derive MODEL's scene with every named point, then :func:`kronsub.api.animate`."""
    from ..api import ANIMATION_DEFAULTS, System, run_span
    from ..api import animate as animate_system
    from ..simulation.run import SimulationError, row_count
    from ..simulation.values import parse_assignments

    loaded, scene, system = scene_system(model, scene_name, all_points=True)
    system = System.of(system, loaded, scene)
    span, step, chosen = run_span(system, t_end, dt, method, ANIMATION_DEFAULTS)
    try:
        row_count(span, step)
    except SimulationError as exc:
        fail(f"Error: {exc}", USAGE_ERROR)
    return animate_system(system, output, span, step, chosen, parse_assignments(settings), fps=fps, size=size,
                          progress=progress)
