"""``kronsub simulate MODEL``: the trajectory as CSV, its metadata as JSON."""
from __future__ import annotations

import os
import signal
import sys
from pathlib import Path
from types import SimpleNamespace

import click

from ..atomic import atomic_file, write_atomically
from ..collector import preparation
from ..simulation.methods import SIMULATE
from ..simulation.methods import help_text as method_help
from .common import (INTERRUPTED, NUMERICAL_FAILURE, T_END, USAGE_ERROR, budget_option, budget_units, check_times,
                     coincident_ends, default_sidecar, fail, interrupted_by, meta_option, note_choice, note_safely,
                     output_option, plot_option, run_command, said_advice, say, scene_option, scene_system,
                     separate_outputs, set_option, writable, writable_outputs)

__all__ = ["simulate"]


@click.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--t", "t_end", type=float, default=None, help=f"End time (default: the scene's, else {T_END:g}).")
@click.option("--dt", type=float, default=None,
              help="Output interval (and step of fixed-step methods; default: the scene's, else 0.01).")
@click.option("--method", default=None,
              help="Default: the scene's, else dop853. " + method_help())
@click.option("--rtol", type=float, default=1e-10, show_default=True, help="Relative tolerance (adaptive methods).")
@click.option("--atol", type=float, default=1e-10, show_default=True, help="Absolute tolerance (adaptive methods).")
@click.option("--jacobian", type=click.Choice(["differences", "exact"]), default="differences", show_default=True,
              help="The Jacobian of Radau and LSODA: by finite differences, or the generated exact d ydot/dy.")
@set_option()
@output_option("Write the CSV to FILE (atomically) instead of standard output; the run's metadata "
                   "goes beside it as JSON (out.csv -> out.json).")
@meta_option("Write the run's metadata (JSON: model and hash, method, tolerances, parameters, initial "
                   "state, cost, complete or where it stopped) to FILE (default: beside --output; none for "
                   "standard output).")
@click.option("--points", "with_points", is_flag=True, help="Add the named points' positions to the CSV.")
@plot_option("Write a plot of coordinates, velocities and energy (PNG, PDF or SVG by the name).")
@scene_option
@budget_option
@click.option("--reactions", "with_reactions", is_flag=True,
              help="Add the workless reactions (viewpoint (alpha)) to the CSV.")
def simulate(model: Path, t_end: float | None, dt: float | None, method: str | None, rtol: float, atol: float,
             settings: tuple[str, ...], output: Path | None, meta: Path | None, with_points: bool,
             plot: Path | None, scene_name: str | None, with_reactions: bool = False, jacobian: str = "differences"):
    """Simulate MODEL from t = 0 to --t; the trajectory is plain CSV (a header row, then numbers),
    its metadata JSON (--meta, or beside --output)."""
    options = dict(t=t_end, dt=dt, method=method, rtol=rtol, atol=atol, set=list(settings), scene=scene_name,
                   budget=budget_units(), jacobian=jacobian)

    def job():
        # the same command run before, from its compiled model (no SymPy); else derived
        key = None
        if not (with_points or plot is not None or with_reactions):
            from ..simulation import prepared

            key = prepared.run_key(model, options)
            found = prepared.load(key) if key is not None else None
            if found is not None and _served(found, model, output, meta):
                return
        _simulate(model, t_end, dt, method, rtol, atol, settings, output, meta, with_points, plot, scene_name,
                  with_reactions, key, jacobian)

    run_command(job)


def _served(found, model: Path, output: Path | None, meta: Path | None) -> bool:
    """Run the prepared run ``found`` and write its outputs as a derived run writes them; False
    (nothing written) when it did not complete as recorded."""
    from ..simulation.prepared import runs
    from ..simulation.trajectory_file import RowWriter

    meta_path = _outputs_checked(model, output, meta, None)
    run = runs(found)
    if run is None:
        return False

    def stream(out):
        writer = RowWriter(out, list(found.columns), found.start_metadata(), found.want)
        try:
            writer.stream(run)
        except KeyboardInterrupt:
            pass  # the file is kept, its metadata says interrupted (writer.stopped)
        return writer

    _written(output, meta_path, stream, run)
    return True


def _outputs_checked(model: Path, output: Path | None, meta: Path | None, plot: Path | None) -> Path | None:
    """The metadata file (--meta, or beside --output), once every output can be written and none
    is the model or another output."""
    meta_path = meta if meta is not None else default_sidecar(output)
    separate_outputs(model, ("--output", output, "CSV"), ("--meta", meta_path, "metadata"),
                      ("--plot", plot, "plot"))
    writable_outputs(output, plot)
    writable(meta_path, "--meta")
    return meta_path


def _written(output: Path | None, meta_path: Path | None, stream, run):
    """Write the CSV (``stream(out)`` to --output atomically, else to standard output) and the
    metadata; fail when the reader went away or the run was interrupted. Returns the writer,
    where the CSV went and how the metadata is named in messages."""
    if output is not None:
        with atomic_file(output) as fh:
            writer = stream(fh)
        where = str(output)
        note_safely(f"wrote {output} ({_rows(writer.rows)})")  # a terminal gone (SIGHUP) keeps no metadata back
    else:
        writer = stream(sys.stdout)
        if writer.reader_gone:  # nothing more goes to standard output
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        else:
            sys.stdout.flush()
        where = "standard output"
    if meta_path is not None:
        from ..simulation.trajectory_file import metadata_json

        info = writer.metadata()
        info["csv"] = output.name if output is not None and output.parent.resolve() == meta_path.parent.resolve() \
            else (str(output) if output is not None else None)
        write_atomically(meta_path, metadata_json(info))
        say(f"wrote {meta_path}")
    state = "stopped" if writer.reader_gone else "interrupted" if writer.stopped else "incomplete"
    marked = f" (marked {state} in {meta_path})" \
        if meta_path is not None else ""
    for _, what in run.switches:
        say(f"note: coordinates: auto switched at {what}")
    if writer.reader_gone:
        fail(f"Stopped after t = {writer.last_t!r}: the reader of {where} closed it after "
              f"{_rows(writer.rows)}{marked}", INTERRUPTED)
    if writer.stopped:
        signum = writer.signum or signal.SIGINT
        fail(f"Interrupted{interrupted_by(signum)} after t = {writer.last_t!r}: {_kept(writer.rows)} in "
             f"{where}{marked}", 128 + signum)
    return writer, where, marked


def _simulate(model: Path, t_end: float | None, dt: float | None, method: str | None, rtol: float, atol: float,
              settings: tuple[str, ...], output: Path | None, meta: Path | None, with_points: bool,
              plot: Path | None, scene_name: str | None, with_reactions: bool, key: str | None,
              jacobian: str = "differences"):
    """The run of a derived model (recorded as a prepared run under ``key`` when it can be one)."""
    with preparation():  # the collector paused, what it leaves set aside (kronsub.collector)
        from ..api import System, run_span
        from ..simulation.constrained import newton_tolerance
        from ..simulation.power import energy_split
        from ..simulation.run import SimulationError, check_tolerances, collect, explicit_only, row_count, start
        from ..simulation.start import starting_values
        from ..simulation.table import CsvWriter, trajectory_csv
        from ..simulation.values import parse_assignments

        if method is not None and method not in SIMULATE:
            fail(f"Error: unknown method '{method}'\n  hint: choose one of {', '.join(SIMULATE)}", USAGE_ERROR)
        check_times(t_end, dt)  # before deriving; the row count once both are known
        try:
            check_tolerances(rtol, atol)
        except SimulationError as exc:
            fail(f"Error: {exc}", USAGE_ERROR)
        meta_path = _outputs_checked(model, output, meta, plot)
        loaded, scene, system = scene_system(model, scene_name, all_points=with_points)
        note_choice(system)
        outputs = scene.outputs if scene is not None else None
        span, step, chosen = run_span(System.of(system, loaded, scene), t_end, dt, method)
        try:
            row_count(span, step)
        except SimulationError as exc:
            fail(f"Error: {exc}", USAGE_ERROR)
        try:  # before the initial values are projected onto the constraints
            explicit_only(system, chosen)
        except SimulationError as exc:
            fail(f"Error: {exc}")
        begin = starting_values(system, parse_assignments(settings), tolerance=newton_tolerance(rtol, atol))
        for note in begin.notes:
            say(f"note: initial conditions projected onto the constraints: {note}")
        values, constrained = begin.values, begin.constrained
        run = start(system, values, span, step, chosen, rtol, atol,
                    outputs=outputs, constrained=constrained, jacobian=jacobian == "exact")
    kept = [] if plot is not None or with_reactions else None
    run_info = dict(t_end=span, dt=step, scene=scene.name if scene is not None else None,
                    source=loaded.source, uses=loaded.uses, split=energy_split(loaded, system))

    def stream(out):
        """Write the CSV; what is returned tells ``rows``, ``last_t``, ``stopped`` and the metadata."""
        if with_reactions:  # the reactions need the whole run: computed, then written at once
            import numpy as np

            from ..simulation.reactions import reaction_columns

            traj = collect(run, list(run), len(system.coordinates))
            kept.append(traj)
            extra = reaction_columns(system, traj, np.array(values.parameters), constrained=constrained)
            text, info = trajectory_csv(system, model.as_posix(), traj, values, rtol, atol, with_points,
                                        outputs, extra, **run_info)
            out.write(text)
            return SimpleNamespace(rows=len(traj.t), last_t=float(traj.t[-1]) if len(traj.t) else None,
                                   stopped=False, reader_gone=False, metadata=lambda: info)
        writer = CsvWriter(out, system, model.as_posix(), values, run.method, run.backend, rtol, atol,
                           with_points, outputs, **run_info)
        try:
            writer.stream(run, kept.append if kept is not None else None)
        except KeyboardInterrupt:
            pass  # the file is kept, its metadata says interrupted (writer.stopped)
        return writer

    writer, where, marked = _written(output, meta_path, stream, run)
    if plot is not None:
        from ..simulation.plot import plot_trajectory

        traj = kept[0] if with_reactions else collect(run, kept, len(system.coordinates))
        plot_trajectory(system, traj, values, plot, with_points)
        say(f"wrote {plot}")
    if not run.complete:
        ends = coincident_ends(loaded, system, run.t_fail, getattr(run, "y_fail", None), values.parameters)
        at, message, hint = (f"{ends.location}: ", ends.message, f"\n  hint: {ends.hint}") if ends is not None \
            else ("", run.message, "")
        fail(f"Error: {at}the run stopped at t = {run.t_fail:.6g}: {message}; "
              f"{_kept(writer.rows)} in {where}{marked}"
              + hint + _constraint_hints(system, run, step), NUMERICAL_FAILURE)
    if key is not None and kept is None and isinstance(writer, CsvWriter) and writer.plain and not said_advice():
        _record(key, loaded, system, run, values, writer, span, step, rtol, atol)


def _record(key: str, loaded, system, run, values, writer, span: float, step: float, rtol: float,
            atol: float) -> None:
    """Keep a completed run as a prepared run (:mod:`kronsub.simulation.prepared`) when its rows
    came from the compiled model alone: a method wholly in C, no closed loop, a run in one block."""
    from ..core.first_order import zero_rows
    from ..simulation import native
    from ..simulation.grid import Grid
    from ..simulation.methods import METHODS
    from ..simulation.prepared import Prepared, record
    from ..simulation import rows

    if run.library is None or system.implicit is not None or run.switches or METHODS[run.method].engine != "c" \
            or len(Grid(span, step)) > rows.BLOCK_ROWS or zero_rows(system) or system.speeds is not None:
        return  # (first-order velocities filled in by the derived run; a state [q; u] of other size)
    digest = native.recorded_digest(run.library)
    if digest is None or loaded.source is None or run.library.parent.parent != native.build_root():
        return  # (a library in the process's temporary folder is gone at its exit)
    prepared = Prepared(library=run.library, sha256=digest, nq=len(system.coordinates),
                        nparam=len(system.parameters), method=run.method, rtol=rtol, atol=atol, t_end=span, dt=step,
                        param=tuple(map(float, values.parameters)), y0=tuple(map(float, values.y0)),
                        columns=tuple(writer.columns), want=dict(writer.want), meta=writer.metadata())
    record(key, prepared, (loaded.source, *loaded.uses))


def _rows(count: int) -> str:
    return f"{count} row" if count == 1 else f"{count} rows"


def _kept(count: int) -> str:
    return f"the {_rows(count)} computed so far {'is' if count == 1 else 'are'} kept"


def _constraint_hints(system, run, step: float) -> str:
    """Hints after a closed-loop run stopped: a fixed step too coarse for the mechanism, a toggle
    position that another choice of independent coordinates passes."""
    if system.implicit is None:
        return ""
    hints = []
    from ..simulation.run import FIXED_STEP

    if run.method in FIXED_STEP:
        hints.append(f"{run.method} takes fixed steps of --dt {step:g}: a smaller --dt keeps each step "
                     "within the mechanism's reach")
    if "toggle position" in run.message and system.implicit.choice != "auto":
        hints.append("only the independent coordinates chosen are singular there: with `coordinates: auto` "
                     "kronsub changes them where dg/dy_d of its choice goes singular, and the run goes on")
    return "".join(f"\n  hint: {h}" for h in hints)
