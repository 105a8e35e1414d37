"""``kronsub linearize MODEL``: ``A``, ``B`` and eigenvalues about an operating point."""
from __future__ import annotations

from pathlib import Path

import click

from .common import (USAGE_ERROR, budget_option, coincident_at_start, emit_text, fail, output_option, run_command,
                     say, scene_option, scene_system, separate_outputs, writable)


@click.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--at", "at", multiple=True, metavar="NAME=VALUE",
              help="Fix a coordinate, velocity, speed, t or parameter value at the operating point (repeatable); "
                   "coordinates not given are solved for an equilibrium from the model's initial values "
                   "(under velocity constraints: they keep their initial values, speeds not given are 0).")
@click.option("--inputs", default="", metavar="NAME,...", help="Parameters that are inputs u (columns of B).")
@click.option("--symbolic", is_flag=True,
              help="A and B in the parameters' symbols (those not fixed with --at) instead of numbers.")
@click.option("--format", "fmt", type=click.Choice(["markdown", "json", "latex"]), default="markdown",
              show_default=True, help="Output format.")
@output_option()
@scene_option(help="Use the model's scene NAME: only its effects, its values and initial values.")
@budget_option
def linearize(model: Path, at: tuple[str, ...], inputs: str, symbolic: bool, fmt: str, output: Path | None,
              scene_name: str | None):
    """Linearise MODEL: ydot ~ A (y - y*) + B (u - u*), y = [q; qdot], with the eigenvalues of A.

    The operating point is an equilibrium (qdot = 0, qddot = 0), found numerically from the
    model's initial values, or checked when given with --at; a point that is not an
    equilibrium is linearised about anyway and reported as such. Under velocity constraints
    it is a steady motion given by coordinates and speeds, y = [kept coordinates; speeds].
    """
    from ..api import linearize as linearize_system
    from ..core.linearize import LinearizationError
    from ..emitters.linearization import EMITTERS
    from ..simulation.values import parse_assignments

    def job():
        writable(output, "--output")
        separate_outputs(model, ("--output", output, "output"))
        assignments = parse_assignments(at, "--at")
        names = [n.strip() for n in inputs.split(",") if n.strip()]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            fail(f"Error: --inputs names {', '.join(twice)} more than once\n  hint: name each input once", USAGE_ERROR)
        loaded, _, system = scene_system(model, scene_name)
        try:
            lin = linearize_system(system, assignments, names, symbolic=symbolic, option="--at",
                                   drive=loaded.locations.get("drive"))
        except LinearizationError:
            coincident_at_start(loaded, system, assignments)
            raise
        if not lin.equilibrium and not lin.in_speeds:  # about a steady motion: the core's note says it
            moving = [f"{system.name_of(s)}={v}" for s, v in lin.point
                      if s in set(system.velocities) and v.is_zero is not True]
            why = ("qddot = " + ", ".join(f"{a:.6g}" for a in lin.acceleration)
                   + (f"; {', '.join(moving)}" if moving else "")) if not _at_rest(lin.acceleration) \
                else "qdot is not 0: " + ", ".join(moving)
            say(f"Warning: the operating point is not an equilibrium ({why}): A describes the motion "
                "near it, not about a rest state")
        for note in lin.notes:
            say(f"Warning: {note}")
        text = EMITTERS[fmt](lin, system.name)
        emit_text(text, output)

    run_command(job)


def _at_rest(acceleration) -> bool:
    """Whether every qddot is 0 to the tolerance of an equilibrium (NaN: not known, so not)."""
    from ..core.linearize import EQUILIBRIUM_TOLERANCE

    return all(abs(a) <= EQUILIBRIUM_TOLERANCE for a in acceleration)


__all__ = ["linearize"]
