"""The command line: ``kronsub derive MODEL``.

Problems in a model print as ``Error: FILE:LINE:COL: message`` with a hint;
never a traceback. Exit codes (see :data:`EXIT_CODES`): 0 success, 1 model or
input error, 2 usage error, 3 numerical failure (rows so far kept), 4 internal
error, 130 interrupted (rows so far kept); 143 and 129 for SIGTERM and SIGHUP, which
interrupt a run as Ctrl-C does.
"""
from __future__ import annotations

import difflib
import math
import os
import re
import signal
import sys
from pathlib import Path
from types import SimpleNamespace

import click

from .atomic import atomic_file, write_atomically
from .commands.common import (DEBUG_ENV, EXIT_CODES, INPUT_ERROR, INTERNAL_ERROR, INTERRUPTED,  # noqa: F401
                              NUMERICAL_FAILURE, OK, USAGE_ERROR, budget_option, check_times, coincident_at_start,
                              coincident_ends, default_sidecar, emit_text, fail, interrupted_by, meta_option,
                              note_choice, note_safely, output_option, plot_option, run_command, say,
                              scene_option, set_option, scene_system, separate_outputs, writable,
                              writable_outputs)
from .simulation.methods import MEASURED, SIMULATE
from .simulation.methods import help_text as method_help
from .version import __version__


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="kronsub")
@click.option("--debug", is_flag=True, help=f"Show the traceback of an internal error (as {DEBUG_ENV}=1 does).")
def main(debug: bool):
    """Equations of motion of interconnected systems by Kron's method of subspaces."""
    if debug:
        os.environ[DEBUG_ENV] = "1"


@main.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["markdown", "latex", "json"]), default="markdown",
              show_default=True, help="Output format.")
@output_option()
@click.option("--check", type=click.Path(dir_okay=False, path_type=Path),
              help="Compare with FILE; exit 1 with a unified diff when they differ.")
@click.option("--no-cache", is_flag=True, help="Derive from scratch, ignoring the known-system cache.")
@scene_option
@budget_option
@click.option("--reactions", "with_reactions", is_flag=True,
              help="Add the workless reactions (viewpoint (alpha)) as functions of the state.")
def derive(model: Path, fmt: str, output: Path | None, check: Path | None, no_cache: bool, scene_name: str | None,
           with_reactions: bool):
    """Derive the equations of motion of MODEL (a YAML file)."""
    from .emitters import EMITTERS

    def job():
        separate_outputs(model, ("--output", output, "output"))
        if output is not None and not output.resolve().parent.is_dir():
            fail(f"Error: {output}: the directory {output.resolve().parent} does not exist\n"
                  "  hint: create it first, or choose another --output path")
        _, _, system = scene_system(model, scene_name, cache=not no_cache)
        note_choice(system)
        text = EMITTERS[fmt](system)
        if with_reactions:
            from .emitters.reactions import with_reactions as add_reactions

            text = add_reactions(text, system, fmt)
        if check is not None:
            from .model.source import read_user_text

            if not check.exists():
                fail(f"Error: {check}: No such file or directory\n  hint: write it first with --output {check}")
            expected = read_user_text(check, "file of derived equations (--check)")
            if expected != text:
                diff = difflib.unified_diff(expected.splitlines(True), text.splitlines(True),
                                            fromfile=str(check), tofile=f"derived from {model}")
                say("".join(diff).rstrip("\n"), err=False)
                fail(f"Error: {check} differs from the derived equations")
            say(f"{check}: up to date")
            return
        emit_text(text, output)

    run_command(job)


@main.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--lang", type=click.Choice(["c", "python"]), default="c", show_default=True,
              help="Language of the generated code.")
@click.option("--output", "-o", "outdir", type=click.Path(file_okay=False, path_type=Path), default=Path("."),
              show_default=True, help="Directory to write the files into.")
@click.option("--name", help="Stem of the file names (default: the model file's stem).")
@click.option("--prefix", default="ks", show_default=True,
              help="Prefix of the C functions and macros, so several models can share a program.")
@scene_option
@budget_option
@click.option("--precision", type=click.Choice(["double", "long", "quad"]), default="double", show_default=True,
              help="The C's real type: double, long double, or _Float128 (glibc's libm; typedef ks_real).")
def codegen(model: Path, lang: str, outdir: Path, name: str | None, prefix: str, scene_name: str | None,
            precision: str):
    """Generate C (header + source) or a numpy module for MODEL."""
    from .emitters.code import LANGUAGES
    from .emitters.numeric import identifier

    def job():
        if not _C_IDENTIFIER.fullmatch(prefix):
            fail(f"Error: --prefix {prefix!r} is not a C identifier (letters, digits and _, not starting "
                  f"with a digit)\n  hint: e.g. --prefix {identifier(prefix)}", USAGE_ERROR)
        if outdir.exists() and not outdir.is_dir():
            fail(f"Error: {outdir}: not a directory\n  hint: choose a directory for --output")
        try:
            outdir.mkdir(parents=True, exist_ok=True)  # the README's `--output build/` in a fresh clone
        except OSError as exc:
            fail(f"Error: {outdir}: cannot create the directory ({exc.strerror})\n"
                  "  hint: choose another --output")
        if precision != "double" and lang != "c":
            fail("Error: --precision long|quad is for --lang c\n  hint: drop --precision, or use --lang c")
        _, scene, system = scene_system(model, scene_name)
        stem = name or model.stem
        outputs = scene.outputs if scene is not None else None
        files = list(LANGUAGES[lang](system, stem, source=model.as_posix(), prefix=prefix, outputs=outputs))
        separate_outputs(model, *((f"--output {outdir} --name {stem}", outdir / g.name, "generated") for g in files))
        for generated in files:
            text = generated.text
            if precision != "double":
                from .simulation.extended import prelude, retype

                text = prelude(precision) + retype(text, precision)
            write_atomically(outdir / generated.name, text)
            say(f"wrote {outdir / generated.name}")

    run_command(job)


_C_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")

@main.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--t", "t_end", type=float, default=None, help="End time (default: the scene's, else 10).")
@click.option("--dt", type=float, default=None,
              help="Output interval (and step of fixed-step methods; default: the scene's, else 0.01).")
@click.option("--method", default=None,
              help="Default: the scene's, else dop853. " + method_help())
@click.option("--rtol", type=float, default=1e-10, show_default=True, help="Relative tolerance (adaptive methods).")
@click.option("--atol", type=float, default=1e-10, show_default=True, help="Absolute tolerance (adaptive methods).")
@set_option()
@output_option("Write the CSV to FILE (atomically) instead of standard output; the run's metadata "
                   "goes beside it as JSON (out.csv -> out.json).")
@meta_option("Write the run's metadata (JSON: model and hash, method, tolerances, parameters, initial "
                   "state, cost, complete or where it stopped) to FILE (default: beside --output; none for "
                   "standard output).")
@click.option("--points", "with_points", is_flag=True, help="Add the named points' positions to the CSV.")
@plot_option("Write a PNG of coordinates and energy.")
@scene_option
@budget_option
@click.option("--reactions", "with_reactions", is_flag=True,
              help="Add the workless reactions (viewpoint (alpha)) to the CSV.")
def simulate(model: Path, t_end: float | None, dt: float | None, method: str | None, rtol: float, atol: float,
             settings: tuple[str, ...], output: Path | None, meta: Path | None, with_points: bool,
             plot: Path | None, scene_name: str | None, with_reactions: bool = False):
    """Simulate MODEL from t = 0 to --t; the trajectory is plain CSV (a header row, then numbers),
    its metadata JSON (--meta, or beside --output)."""
    from .model.scenes import initial_values
    from .simulation.run import SimulationError, check_tolerances, collect, explicit_only, row_count, start
    from .simulation.table import CsvWriter, metadata_json, trajectory_csv
    from .simulation.values import parse_assignments, resolve

    def job():
        if method is not None and method not in SIMULATE:
            fail(f"Error: unknown method '{method}'\n  hint: choose one of {', '.join(SIMULATE)}", USAGE_ERROR)
        check_times(t_end, dt)  # before deriving; the row count once both are known
        try:
            check_tolerances(rtol, atol)
        except SimulationError as exc:
            fail(f"Error: {exc}", USAGE_ERROR)
        meta_path = meta if meta is not None else default_sidecar(output)
        separate_outputs(model, ("--output", output, "CSV"), ("--meta", meta_path, "metadata"),
                          ("--plot", plot, "plot"))
        writable_outputs(output, plot)
        writable(meta_path, "--meta")
        loaded, scene, system = scene_system(model, scene_name, all_points=with_points)
        note_choice(system)
        outputs = scene.outputs if scene is not None else None
        span = _pick(t_end, scene and scene.t_end, 10.0)
        step = _pick(dt, scene and scene.dt, 0.01)
        try:
            row_count(span, step)
        except SimulationError as exc:
            fail(f"Error: {exc}", USAGE_ERROR)
        try:  # before the initial values are projected onto the constraints
            explicit_only(system, _pick(method, scene and scene.method, "dop853"))
        except SimulationError as exc:
            fail(f"Error: {exc}")
        initial = initial_values(loaded, scene)
        assignments = parse_assignments(settings)
        constrained = None
        if system.implicit is not None:  # initial conditions onto the constraints (simulation/constrained.py)
            from .simulation.constrained import newton_tolerance, project_initial, split_settings

            assignments, dependent_settings = split_settings(system, assignments)
            values = resolve(system, initial, assignments)
            values, notes, constrained = project_initial(system, initial, dependent_settings, values,
                                                         newton_tolerance(rtol, atol))
            for note in notes:
                say(f"note: initial conditions projected onto the constraints: {note}")
        else:
            values = resolve(system, initial, assignments)
        run = start(system, values, span, step, _pick(method, scene and scene.method, "dop853"), rtol, atol,
                    outputs=outputs, constrained=constrained)
        kept = [] if plot is not None or with_reactions else None
        run_info = dict(t_end=span, dt=step, scene=scene.name if scene is not None else None,
                        source=loaded.source, uses=loaded.uses)

        def stream(out):
            """Write the CSV; what is returned tells ``rows``, ``last_t``, ``stopped`` and the metadata."""
            if with_reactions:  # the reactions need the whole run: computed, then written at once
                import numpy as np

                from .simulation.reactions import reaction_columns
                from .simulation.fallback import numpy_module

                traj = collect(run, list(run), len(system.coordinates))
                kept.append(traj)
                extra = reaction_columns(system, traj, np.array(values.parameters), numpy_module(system), constrained)
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
            fail(f"Interrupted{interrupted_by(signum)} after t = {writer.last_t!r}: {_kept(writer.rows)} in {where}{marked}",
                  128 + signum)
        if plot is not None:
            from .simulation.plot import plot_trajectory

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

    run_command(job)


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
    from .simulation.run import FIXED_STEP

    if run.method in FIXED_STEP:
        hints.append(f"{run.method} takes fixed steps of --dt {step:g}: a smaller --dt keeps each step "
                     "within the mechanism's reach")
    if "toggle position" in run.message and system.implicit.choice != "auto":
        hints.append("`coordinates: auto` changes the independent coordinates where this choice's dg/dy_d "
                     "goes singular, and the run goes on")
    return "".join(f"\n  hint: {h}" for h in hints)


@main.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--t", "t_end", type=float, default=10.0, show_default=True, help="End time.")
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
@plot_option("Write the work-precision PNG (error against time, log-log) to FILE.")
@click.option("--quick", is_flag=True, help="A coarse grid (every third tolerance), few repeats, a cheaper reference.")
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
    from .model.scenes import initial_values
    from .simulation import accuracy as acc
    from .simulation import accuracy_report as report
    from .simulation.table import metadata_json
    from .simulation.values import parse_assignments, resolve

    def job():
        check_times(t_end, None)
        chosen = acc.parse_methods(methods)
        if precision != "double" and f"gbs-{precision}" not in chosen:
            chosen = chosen + (f"gbs-{precision}",)
        grid = acc.parse_tolerances(tolerances)
        if quick:
            grid = acc.quick_tolerances(grid)
        if target is not None and not (target > 0 and math.isfinite(target)):
            fail("Error: --target must be a positive finite error, e.g. --target 1e-8")
        meta_path = meta if meta is not None else default_sidecar(output)
        separate_outputs(model, ("--output", output, "CSV"), ("--meta", meta_path, "metadata"),
                          ("--plot", plot, "plot"))
        writable_outputs(output, plot)
        writable(meta_path, "--meta")
        loaded, scene, system = scene_system(model, scene_name)
        initial, assignments = initial_values(loaded, scene), parse_assignments(settings)
        dependent = None
        if system.implicit is not None:  # initial conditions onto the constraints, as simulate does
            from .simulation.constrained import project_initial, split_settings

            assignments, dependent_settings = split_settings(system, assignments)
            values = resolve(system, initial, assignments)
            values, notes, closure = project_initial(system, initial, dependent_settings, values, 1e-14)
            dependent = closure.guess
            for note in notes:
                say(f"note: initial conditions projected onto the constraints: {note}")
        else:
            values = resolve(system, initial, assignments)
        say(f"computing the reference to t = {t_end:g} ...")
        default_digits = 34 if "gbs-quad" in chosen else (16 if quick else 20)
        try:
            wp = acc.measure(system, values, t_end, chosen, grid, digits=digits or default_digits, quick=quick,
                             dependent=dependent)
        except acc.AccuracyError:
            coincident_at_start(loaded, system, initial, assignments)
            raise
        click.echo(report.markdown(wp, target), nl=False)
        if output is not None:
            write_atomically(output, report.to_csv(wp))
            say(f"wrote {output} ({len(wp.points)} points)")
        if meta_path is not None:
            csv_name = None if output is None else (
                output.name if output.parent.resolve() == meta_path.parent.resolve() else str(output))
            info = report.metadata(wp, model_file=model.as_posix(), source=loaded.source, uses=loaded.uses,
                                scene=scene.name if scene is not None else None, methods=chosen, tolerances=grid,
                                target=target, csv=csv_name)
            write_atomically(meta_path, metadata_json(info))
            say(f"wrote {meta_path}")
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
            report.plot(wp, plot, target)
            say(f"wrote {plot}")

    run_command(job)


@main.group()
def cache():
    """Show or clear kronsub's caches (derived known systems, compiled models)."""


def _size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return ""


@cache.command("info")
def cache_info():
    """Where the cache is, how many entries it holds and their sizes."""
    from . import cache as store

    def job():
        found = store.info()
        if found.folder is None:
            say(f"cache: off ({store.CACHE_ENV}=off)", err=False)
            return
        exists = found.folder.exists()
        reason = store.unsafe_reason(found.folder) if exists else store.missing_reason(found.folder)
        say(f"cache: {found.folder}" + (f" (not used: {reason})" if reason else "")
            + ("" if exists or reason else " (empty)"), err=False)
        say(f"derived known systems: {found.systems} ({_size(found.systems_bytes)})", err=False)
        say(f"compiled models: {found.libraries} ({_size(found.libraries_bytes)})", err=False)

    run_command(job)


@cache.command("clear")
def cache_clear():
    """Remove kronsub's own entries from the cache (nothing else in the folder)."""
    from . import cache as store

    def job():
        removed = store.clear()
        if removed.folder is None:
            say(f"cache: off ({store.CACHE_ENV}=off)", err=False)
            return
        say(f"removed from {removed.folder}: derived known systems: {removed.systems} "
            f"({_size(removed.systems_bytes)}), compiled models: {removed.libraries} "
            f"({_size(removed.libraries_bytes)})", err=False)

    run_command(job)


def _pick(given, from_scene, default):
    """A command-line value, else the scene's, else the default."""
    if given is not None:
        return given
    return from_scene if from_scene is not None else default


def _register_commands() -> None:
    """Commands kept in modules of their own (kronsub/commands/)."""
    from .commands.animate import animate
    from .commands.discovery import check, components, new
    from .commands.linearize import linearize

    for command in (check, linearize, animate):
        budget_option(command)
    for command in (components, new, check, linearize, animate):
        main.add_command(command)


_register_commands()

if __name__ == "__main__":
    main()
