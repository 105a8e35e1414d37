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
import warnings
from pathlib import Path
from types import SimpleNamespace

import click

from .atomic import STREAM, atomic_file, output_target, write_atomically
from .errors import KronsubError, Location, ModelError
from .simulation.methods import MEASURED, SIMULATE
from .simulation.methods import help_text as method_help
from .interrupts import exit_code, signal_name, signal_of, signals_as_interrupts
from .version import __version__

OK, INPUT_ERROR, USAGE_ERROR, NUMERICAL_FAILURE, INTERNAL_ERROR, INTERRUPTED = 0, 1, 2, 3, 4, 130
HANGUP, TERMINATED = 129, 143  # 128 + SIGHUP, 128 + SIGTERM (kronsub/interrupts.py)
EXIT_CODES = {
    OK: "success",
    INPUT_ERROR: "model or input error (the message names the file, line and column)",
    USAGE_ERROR: "usage error (an unknown command or option, an option value out of range)",
    NUMERICAL_FAILURE: "numerical failure: the run stopped early; the rows so far are kept, the metadata says where",
    INTERNAL_ERROR: "internal error: a bug in kronsub (KRONSUB_DEBUG=1 shows the traceback)",
    HANGUP: "hung up (SIGHUP); as for 130",
    INTERRUPTED: "interrupted (Ctrl-C); the rows so far are kept, the metadata says where",
    TERMINATED: "terminated (SIGTERM); as for 130",
}
DEBUG_ENV = "KRONSUB_DEBUG"


def emit_text(text: str, output: Path | None) -> None:
    """A command's text: to ``output`` (atomically), else to standard output."""
    if output is not None:
        write_atomically(output, text)
        say(f"wrote {output}")
    else:
        click.echo(text, nl=False)


def _writable_outputs(output: Path | None, plot: Path | None) -> None:
    """Before a long run: ``--output`` and ``--plot`` can be written, and matplotlib is there
    for a plot."""
    _writable(output, "--output")
    _writable(plot, "--plot")
    if plot is not None:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            _fail("Error: --plot needs matplotlib\n  hint: pip install 'kronsub[plot]'")


def _same_file(a: Path, b: Path) -> bool:
    """Whether the paths name one file (an existing one by inode, through links; else by path)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def _separate_outputs(model: Path | None, *outputs: tuple[str, Path | None, str]) -> None:
    """Fail (a usage error) before any work when an output ``(flag, path, what)`` would replace the
    model file or another output of the same command."""
    seen = [("MODEL", model, "model")] if model is not None else []
    for flag, path, what in outputs:
        if path is None:
            continue
        for _, other, other_what in seen:
            if _same_file(path, other):
                _fail(f"Error: {flag} {path} is the {other_what} file itself\n  hint: choose another {flag}",
                      USAGE_ERROR)
        seen.append((flag, path, what))


def say(message: str, err: bool = True) -> None:
    """A message for the terminal (standard error unless ``err`` is false), through
    :func:`~.emitters.escape.terminal_text`: whatever a model, a path or an exception put in it,
    no control or direction character reaches the terminal."""
    from .emitters.escape import terminal_text  # not at import: the emitters bring sympy

    click.echo(terminal_text(message), err=err)


def _fail(message: str, code: int = INPUT_ERROR) -> None:
    say(message)
    sys.exit(code)


def _report_model_error(exc: ModelError) -> None:
    lines = []
    for problem in exc.problems:
        lines.append("Error: " + problem.format())
    count = len(exc.problems)
    if count > 1:
        lines.append(f"{count} problems found.")
    _fail("\n".join(lines))


def _show_warning(message, category, filename, lineno, file=None, line=None):
    say(f"Warning: {message}")  # matplotlib's missing-glyph warnings quote the character


def _run(job):
    """Run a command body, turning known errors into messages and exit codes; its work is
    bounded by the command's ``--budget`` (`kronsub.budget`)."""
    from . import budget

    warnings.showwarning = _show_warning
    context = click.get_current_context(silent=True)
    units = context.meta.get(_BUDGET_KEY) if context is not None else None
    try:
        with signals_as_interrupts(), budget.limited(units):  # SIGTERM and SIGHUP stop a run as Ctrl-C does
            return job()
    except budget.WorkBudgetExceeded as exc:  # placed at the model file when no layer placed it
        source = context.params.get("model") or context.params.get("source") if context is not None else None
        _report_model_error(exc.at(Location(str(source))) if source is not None else exc)
    except ModelError as exc:
        _report_model_error(exc)
    except KronsubError as exc:
        _fail(f"Error: {exc}")
    except BrokenPipeError:  # the reader of standard output went away (`| head`): nothing to say
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        sys.exit(INPUT_ERROR)
    except OSError as exc:
        _fail(f"Error: {exc.filename or ''}: {exc.strerror or exc}\n  hint: check the path and its permissions")
    except RecursionError:
        _fail("Error: the model is nested too deeply to derive\n  hint: split it into known systems")
    except KeyboardInterrupt as exc:
        _fail(f"Interrupted{_by(signal_of(exc))}.", exit_code(exc))
    except Exception as exc:  # never a traceback for users
        if os.environ.get(DEBUG_ENV):
            raise
        text = str(exc).splitlines()[0][:200] if str(exc) else ""
        _fail(f"Error: internal error ({type(exc).__name__}{': ' + text if text else ''})\n"
              f"  hint: this is a bug in kronsub {__version__}; please report it to the kronsub developers "
              f"with the command and the model file; {DEBUG_ENV}=1 prints the traceback", INTERNAL_ERROR)


def _note(text: str) -> None:
    """A line on standard error that cannot stop the command (a terminal gone after SIGHUP)."""
    try:
        say(text)
    except OSError:
        pass


def _by(signum: int) -> str:
    """`` by SIGTERM`` (nothing for Ctrl-C, which the user pressed)."""
    return "" if signum == signal.SIGINT else f" by {signal_name(signum)}"


_BUDGET_KEY = "kronsub.budget"


def _budget_units(ctx, param, value):
    """Keep ``--budget`` for `_run` (read there, so every command body runs under it)."""
    if value is not None:
        ctx.meta[_BUDGET_KEY] = value
    return value


def budget_option(command):
    """``--budget UNITS`` for every command that reads or derives a model (`kronsub.budget`)."""
    from .budget import DEFAULT_UNITS

    return click.option("--budget", type=click.IntRange(min=1), metavar="UNITS", default=None,
                        expose_value=False, callback=_budget_units, is_eager=True,
                        help=f"Work budget of reading and deriving the model, in units of about a term "
                             f"formed each (default {DEFAULT_UNITS:,}): a model that needs more stops "
                             "with an error naming what grew.")(command)


def scene_option(command):
    """``--scene NAME`` for every command that derives a model (see :func:`scene_system`)."""
    return click.option("--scene", "scene_name", metavar="NAME", default=None,
                        help="Use the model's scene NAME: only its effects are derived and computed "
                             "(default: the model's only scene if it has exactly one, else every effect).")(command)


def scene_system(model: Path, scene_name: str | None, *, cache: bool = True, all_points: bool = False):
    """``(model, scene, system)``: the model loaded, its scene chosen (None: the whole model)
    and the scene's equations derived. ``all_points`` asks the scene for every named point."""
    import dataclasses

    from .budget import cpu_backstop
    from .model.loader import load_model
    from .model.scenes import derive_scene, select_scene

    with cpu_backstop():
        loaded = load_model(model, cache=cache)
        scene = select_scene(loaded, scene_name)
        if scene is not None and all_points:
            points = tuple(sorted(loaded.primitive.points()))
            scene = dataclasses.replace(scene, outputs=dataclasses.replace(scene.outputs, points=points))
        return loaded, scene, derive_scene(loaded, scene, cache=cache)


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
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path),
              help="Write to FILE (atomically) instead of standard output.")
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
        _separate_outputs(model, ("--output", output, "output"))
        if output is not None and not output.resolve().parent.is_dir():
            _fail(f"Error: {output}: the directory {output.resolve().parent} does not exist\n"
                  "  hint: create it first, or choose another --output path")
        _, _, system = scene_system(model, scene_name, cache=not no_cache)
        _note_choice(system)
        text = EMITTERS[fmt](system)
        if with_reactions:
            from .emitters.reactions import with_reactions as add_reactions

            text = add_reactions(text, system, fmt)
        if check is not None:
            from .model.source import read_user_text

            if not check.exists():
                _fail(f"Error: {check}: No such file or directory\n  hint: write it first with --output {check}")
            expected = read_user_text(check, "file of derived equations (--check)")
            if expected != text:
                diff = difflib.unified_diff(expected.splitlines(True), text.splitlines(True),
                                            fromfile=str(check), tofile=f"derived from {model}")
                say("".join(diff).rstrip("\n"), err=False)
                _fail(f"Error: {check} differs from the derived equations")
            say(f"{check}: up to date")
            return
        emit_text(text, output)

    _run(job)


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
            _fail(f"Error: --prefix {prefix!r} is not a C identifier (letters, digits and _, not starting "
                  f"with a digit)\n  hint: e.g. --prefix {identifier(prefix)}", USAGE_ERROR)
        if outdir.exists() and not outdir.is_dir():
            _fail(f"Error: {outdir}: not a directory\n  hint: choose a directory for --output")
        try:
            outdir.mkdir(parents=True, exist_ok=True)  # the README's `--output build/` in a fresh clone
        except OSError as exc:
            _fail(f"Error: {outdir}: cannot create the directory ({exc.strerror})\n"
                  "  hint: choose another --output")
        if precision != "double" and lang != "c":
            _fail("Error: --precision long|quad is for --lang c\n  hint: drop --precision, or use --lang c")
        _, scene, system = scene_system(model, scene_name)
        stem = name or model.stem
        outputs = scene.outputs if scene is not None else None
        files = list(LANGUAGES[lang](system, stem, source=model.as_posix(), prefix=prefix, outputs=outputs))
        _separate_outputs(model, *((f"--output {outdir} --name {stem}", outdir / g.name, "generated") for g in files))
        for generated in files:
            text = generated.text
            if precision != "double":
                from .simulation.extended import prelude, retype

                text = prelude(precision) + retype(text, precision)
            write_atomically(outdir / generated.name, text)
            say(f"wrote {outdir / generated.name}")

    _run(job)


_C_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _note_choice(system) -> None:
    """Say on stderr which coordinates `coordinates: auto` picked as independent."""
    imp = getattr(system, "implicit", None)
    if imp is not None and imp.choice == "auto":
        say(f"note: coordinates: auto picked {', '.join(q.name for q in imp.independent)} as independent "
            f"({', '.join(q.name for q in imp.dependent)} dependent; pivoted QR of dg/dy at the initial "
            "configuration)")


def _default_sidecar(output: Path | None) -> Path | None:
    """The metadata file beside ``--output``: none for standard output, a FIFO or a device
    (nothing is beside ``/dev/null``)."""
    from .simulation.table import sidecar_path

    if output is None:
        return None
    try:
        how, _ = output_target(output)
    except OSError:
        how = None
    return sidecar_path(output) if how != STREAM else None


def _writable(path: Path | None, what: str) -> None:
    """Fail before any work when an output file could not be written."""
    if path is None:
        return
    try:
        how, where = output_target(path)
    except OSError as exc:
        _fail(f"Error: {path}: {exc.strerror}\n  hint: choose another {what}")
    if how == STREAM:  # a FIFO or a device, written directly
        if not os.access(where, os.W_OK):
            _fail(f"Error: {path}: not writable\n  hint: choose another {what}")
        return
    parent = where.resolve().parent
    if not parent.is_dir():
        _fail(f"Error: {path}: the directory {parent} does not exist\n  hint: create it first, or choose another {what}")
    if where.exists() and not os.access(where, os.W_OK) or not where.exists() and not os.access(parent, os.W_OK):
        _fail(f"Error: {path}: not writable\n  hint: choose another {what}")


@main.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--t", "t_end", type=float, default=None, help="End time (default: the scene's, else 10).")
@click.option("--dt", type=float, default=None,
              help="Output interval (and step of fixed-step methods; default: the scene's, else 0.01).")
@click.option("--method", default=None,
              help="Default: the scene's, else dop853. " + method_help())
@click.option("--rtol", type=float, default=1e-10, show_default=True, help="Relative tolerance (adaptive methods).")
@click.option("--atol", type=float, default=1e-10, show_default=True, help="Absolute tolerance (adaptive methods).")
@click.option("--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="Set a parameter or an initial coordinate/velocity (repeatable).")
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the CSV to FILE (atomically) instead of standard output; the run's metadata "
                   "goes beside it as JSON (out.csv -> out.json).")
@click.option("--meta", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the run's metadata (JSON: model and hash, method, tolerances, parameters, initial "
                   "state, cost, complete or where it stopped) to FILE (default: beside --output; none for "
                   "standard output).")
@click.option("--points", "with_points", is_flag=True, help="Add the named points' positions to the CSV.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), help="Write a PNG of coordinates and energy.")
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
            _fail(f"Error: unknown method '{method}'\n  hint: choose one of {', '.join(SIMULATE)}", USAGE_ERROR)
        _check_times(t_end, dt)  # before deriving; the row count once both are known
        try:
            check_tolerances(rtol, atol)
        except SimulationError as exc:
            _fail(f"Error: {exc}", USAGE_ERROR)
        meta_path = meta if meta is not None else _default_sidecar(output)
        _separate_outputs(model, ("--output", output, "CSV"), ("--meta", meta_path, "metadata"),
                          ("--plot", plot, "plot"))
        _writable_outputs(output, plot)
        _writable(meta_path, "--meta")
        loaded, scene, system = scene_system(model, scene_name, all_points=with_points)
        _note_choice(system)
        outputs = scene.outputs if scene is not None else None
        span = _pick(t_end, scene and scene.t_end, 10.0)
        step = _pick(dt, scene and scene.dt, 0.01)
        try:
            row_count(span, step)
        except SimulationError as exc:
            _fail(f"Error: {exc}", USAGE_ERROR)
        try:  # before the initial values are projected onto the constraints
            explicit_only(system, _pick(method, scene and scene.method, "dop853"))
        except SimulationError as exc:
            _fail(f"Error: {exc}")
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
            _note(f"wrote {output} ({_rows(writer.rows)})")  # a terminal gone (SIGHUP) keeps no metadata back
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
            _fail(f"Stopped after t = {writer.last_t!r}: the reader of {where} closed it after "
                  f"{_rows(writer.rows)}{marked}", INTERRUPTED)
        if writer.stopped:
            signum = writer.signum or signal.SIGINT
            _fail(f"Interrupted{_by(signum)} after t = {writer.last_t!r}: {_kept(writer.rows)} in {where}{marked}",
                  128 + signum)
        if plot is not None:
            from .simulation.plot import plot_trajectory

            traj = kept[0] if with_reactions else collect(run, kept, len(system.coordinates))
            plot_trajectory(system, traj, values, plot, with_points)
            say(f"wrote {plot}")
        if not run.complete:
            ends = _coincident_ends(loaded, system, run.t_fail, getattr(run, "y_fail", None), values.parameters)
            at, message, hint = (f"{ends.location}: ", ends.message, f"\n  hint: {ends.hint}") if ends is not None \
                else ("", run.message, "")
            _fail(f"Error: {at}the run stopped at t = {run.t_fail:.6g}: {message}; "
                  f"{_kept(writer.rows)} in {where}{marked}"
                  + hint + _constraint_hints(system, run, step), NUMERICAL_FAILURE)

    _run(job)


def _check_times(t_end: float | None, dt: float | None) -> None:
    """``--t`` and ``--dt``, when given, are positive finite normal numbers (a usage error else)."""
    from .simulation.run import time_problem

    for flag, given in (("--t", t_end), ("--dt", dt)):
        why = time_problem(flag, given) if given is not None else None
        if why is not None:
            _fail(f"Error: {why}", USAGE_ERROR)


def _rows(count: int) -> str:
    return f"{count} row" if count == 1 else f"{count} rows"


def _kept(count: int) -> str:
    return f"the {_rows(count)} computed so far {'is' if count == 1 else 'are'} kept"


def _coincident_ends(loaded, system, t, y, param):
    """The spring or damper of ``loaded`` whose ends meet at ``(t, y)`` (where its force is 0/0),
    as a :class:`~.errors.Problem` at its entry; None when none does, or the state is not known."""
    import numpy as np

    if t is None or y is None or system.implicit is not None:
        return None
    y = np.asarray(y, dtype=float)
    n = len(system.coordinates)
    if len(y) < n or not np.all(np.isfinite(y[:n])):
        return None
    return loaded.coincident_ends(system, t, y[:n], param)


def _coincident_at_start(loaded, system, initial, settings) -> None:
    """Raise the :func:`_coincident_ends` problem at the initial state (``settings``: ``--set`` or
    ``--at`` values, a ``t`` among them) when there is one: ``linearize`` and ``accuracy`` found
    equations without a value there, and this names the spring or damper why."""
    from .simulation.values import resolve

    t = settings.get("t", "0")
    try:
        values = resolve(system, initial, {k: v for k, v in settings.items() if k != "t"})
        t = float(t)
    except (KronsubError, ValueError):
        return  # the values are reported as they are
    ends = _coincident_ends(loaded, system, t, values.y0, values.parameters)
    if ends is not None:
        raise ModelError([ends])


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
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the CSV (a header row, one row per method and tolerance) to FILE; its metadata goes "
                   "beside it as JSON (wp.csv -> wp.json).")
@click.option("--meta", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the metadata (JSON: model, reference routes and estimated error, t_end, skipped methods, "
                   "failures, target) to FILE (default: beside --output).")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the work-precision PNG (error against time, log-log) to FILE.")
@click.option("--quick", is_flag=True, help="A coarse grid (every third tolerance), few repeats, a cheaper reference.")
@click.option("--digits", type=click.IntRange(12, 200), default=None,
              help="Digits of the reference's cross-check run (default 20; --quick 16); the reference runs at 8 more.")
@click.option("--precision", type=click.Choice(["double", "long", "quad"]), default="double", show_default=True,
              help="long / quad: add extrapolation in the generated C in long double (gbs-long) or _Float128 "
                   "(gbs-quad); quad raises the reference's default --digits to 34.")
@click.option("--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="Set a parameter or an initial coordinate/velocity (repeatable).")
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
        _check_times(t_end, None)
        chosen = acc.parse_methods(methods)
        if precision != "double" and f"gbs-{precision}" not in chosen:
            chosen = chosen + (f"gbs-{precision}",)
        grid = acc.parse_tolerances(tolerances)
        if quick:
            grid = acc.quick_tolerances(grid)
        if target is not None and not (target > 0 and math.isfinite(target)):
            _fail("Error: --target must be a positive finite error, e.g. --target 1e-8")
        meta_path = meta if meta is not None else _default_sidecar(output)
        _separate_outputs(model, ("--output", output, "CSV"), ("--meta", meta_path, "metadata"),
                          ("--plot", plot, "plot"))
        _writable_outputs(output, plot)
        _writable(meta_path, "--meta")
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
            _coincident_at_start(loaded, system, initial, assignments)
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
            _fail(f"Error: every point failed ({len(wp.points)} of {len(wp.points)}); the first, "
                  f"{first.method} at {first.setting}: {first.status or 'a non-finite error'}"
                  + (", so no plot was written" if plot is not None else "")
                  + "\n  hint: the table above (and the CSV) has each point's status; try a shorter "
                    "--t or other --set values")
        if not wp.reference_sufficient():
            _fail(f"Error: the reference's estimated error {wp.reference.error:.1e} is not "
                  f"{acc.REFERENCE_MARGIN:g}x below the best point's error {wp.best_error():.1e}: the errors "
                  "near it are not measured" + (", so no plot was written" if plot is not None else "")
                  + "\n  hint: raise --digits")
        if plot is not None:
            report.plot(wp, plot, target)
            say(f"wrote {plot}")

    _run(job)


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

    _run(job)


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

    _run(job)


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
