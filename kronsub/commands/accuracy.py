"""``kronsub accuracy MODEL``: error against a high-precision reference, per method and tolerance."""
from __future__ import annotations

import math
from pathlib import Path

import click
from click.core import ParameterSource

from ..atomic import write_atomically
from ..simulation.methods import MEASURED
from ..simulation.methods import help_text as method_help
from .common import (T_END, budget_option, check_times, coincident_at_start, default_sidecar, fail,
                     interrupted_by, meta_option, output_option, plot_option, run_command, say, scene_option,
                     scene_system, separate_outputs, set_option, writable, writable_outputs)

__all__ = ["accuracy"]


@click.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--t", "t_end", type=float, default=T_END, show_default=True, help="End time.")
@click.option("--methods", default="all", show_default=True,
              help="Comma-separated (all: every one but the extended-precision ones, see --precision): "
                   + method_help(MEASURED))
@click.option("--tolerances", default="1e-4:1e-14", show_default=True,
              help="Every decade of a range (1e-4:1e-14, or 1e-4:1e-14:2 for every second) or a list "
                   "(1e-6,1e-9). Fixed-step methods take the step tol^(1/4).")
@click.option("--target", type=float, help="Name the cheapest method and tolerance reaching this error (and at every "
                                           "tighter tolerance of that method).")
@output_option("Write the CSV (a header row, one row per method and tolerance) to FILE; its metadata goes "
                   "beside it as JSON (wp.csv -> wp.json).")
@meta_option("Write the metadata (JSON: model, reference routes and estimated error, t_end, skipped methods, "
                   "failures, target) to FILE (default: beside --output).")
@plot_option("Write the work-precision plot (error against time, log-log; PNG, PDF or SVG by the name).")
@click.option("--quick", is_flag=True,
              help="A coarse grid (every third tolerance of the default --tolerances; tolerances given are kept), "
                   "few repeats, a cheaper reference.")
@click.option("--digits", type=click.IntRange(12, 200), default=None,
              help="Digits of the reference's cross-check run (default 20; --quick 16); the reference runs at 8 more.")
@click.option("--precision", type=click.Choice(["double", "long", "quad"]), default="double", show_default=True,
              help="long / quad: add extrapolation in the generated C in long double (gbs-long) or _Float128 "
                   "(gbs-quad); quad raises the reference's default --digits to 34.")
@set_option()
@scene_option
@budget_option
def accuracy(model: Path, t_end: float, methods: str, tolerances: str, target: float | None,
             output: Path | None, meta: Path | None, plot: Path | None, quick: bool, digits: int | None,
             precision: str, settings: tuple[str, ...], scene_name: str | None):
    """What accuracy costs in time: error against a high-precision reference, per method and tolerance."""
    from ..api import System, accuracy_plan
    from ..api import accuracy as experiment
    from ..simulation import accuracy as acc
    from ..simulation.table import metadata_json
    from ..simulation.values import parse_assignments

    thin = click.get_current_context().get_parameter_source("tolerances") is ParameterSource.DEFAULT

    def job():
        check_times(t_end, None)
        given = None if thin else tolerances  # --quick thins the default grid only; tolerances given are kept
        accuracy_plan(methods, given, quick=quick, precision=precision)  # before deriving
        if target is not None and not (target > 0 and math.isfinite(target)):
            fail("Error: --target must be a positive finite error, e.g. --target 1e-8")
        meta_path = meta if meta is not None else default_sidecar(output)
        separate_outputs(model, ("--output", output, "CSV"), ("--meta", meta_path, "metadata"),
                          ("--plot", plot, "plot"))
        writable_outputs(output, plot)
        writable(meta_path, "--meta")
        loaded, scene, system = scene_system(model, scene_name)
        assignments = parse_assignments(settings)
        say(f"computing the reference to t = {t_end:g} ...")
        try:
            result = experiment(System.of(system, loaded, scene), t_end, methods, given, quick=quick,
                                digits=digits, precision=precision, set=assignments, keep_interrupted=True)
        except acc.AccuracyError:
            coincident_at_start(loaded, system, assignments)
            raise
        wp = result.measurement
        for note in result.notes:
            say(f"note: initial conditions projected onto the constraints: {note}")
        click.echo(result.markdown(target), nl=False)
        if output is not None:
            write_atomically(output, result.to_csv())
            say(f"wrote {output} ({len(wp.points)} points)")
        if meta_path is not None:
            csv_name = None if output is None else (
                output.name if output.parent.resolve() == meta_path.parent.resolve() else str(output))
            info = result.metadata(target, csv_name)
            write_atomically(meta_path, metadata_json(info))
            say(f"wrote {meta_path}")
        if wp.interrupted is not None:
            count = f"{len(wp.points)} point{'s' if len(wp.points) != 1 else ''}"
            kept = f": the {count} measured so far kept in {output}" if output is not None else f" after {count}"
            marked = f" (marked interrupted in {meta_path})" if meta_path is not None else ""
            fail(f"Interrupted{interrupted_by(wp.interrupted)}{kept}{marked}",
                 128 + int(wp.interrupted))  # (as kronsub.interrupts.exit_code)
        if wp.points and wp.best_error() is None:
            first = next((p for p in wp.points if p.status), wp.points[0])
            fail(f"Error: every point failed ({len(wp.points)} of {len(wp.points)}); the first, "
                  f"{first.method} at {first.setting}: {first.status or 'a non-finite error'}"
                  + (", so no plot was written" if plot is not None else "")
                  + "\n  hint: the table above (and the CSV) has each point's status; try a shorter "
                    "--t or other --set values")
        if not wp.reference_sufficient():
            fail(f"Error: the reference's estimated error {wp.reference.error:.1e} is not "
                  f"{acc.REFERENCE_MARGIN:g}x below the best point's error {wp.best_error():.1e}: the errors "
                  "near it are not measured" + (", so no plot was written" if plot is not None else "")
                  + "\n  hint: raise --digits")
        if plot is not None:
            result.plot(plot, target)
            say(f"wrote {plot}")

    run_command(job)
