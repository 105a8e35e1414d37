"""What the commands share: exit codes, messages, the run of a command body, the options
declared once, and the model with its scene derived. Imported by every module of
:mod:`kronsub.commands`; imports none of them.

Problems in a model print as ``Error: FILE:LINE:COL: message`` with a hint;
never a traceback. Exit codes (see :data:`EXIT_CODES`): 0 success, 1 model or
input error, 2 usage error, 3 numerical failure (rows so far kept), 4 internal
error, 130 interrupted (rows so far kept); 143 and 129 for SIGTERM and SIGHUP, which
interrupt a run as Ctrl-C does.
"""
from __future__ import annotations

import os
import signal
import sys
import warnings
from pathlib import Path

import click

from .. import budget
from ..atomic import STREAM, output_target, write_atomically
from ..collector import frozen_at_exit, released
from ..errors import KronsubError, Location, ModelError, command_line
from ..interrupts import exit_code, signal_name, signal_of, signals_as_interrupts
from ..simulation.span import T_END
from ..version import __version__

__all__ = ["DEBUG_ENV", "EXIT_CODES", "FILE", "HANGUP", "INPUT_ERROR", "INTERNAL_ERROR", "INTERRUPTED",
           "NUMERICAL_FAILURE", "OK", "OUTPUT_HELP", "SCENE_HELP", "SET_HELP", "T_END", "TERMINATED", "USAGE_ERROR",
           "budget_option", "budget_units", "check_times", "coincident_at_start", "coincident_ends",
           "default_sidecar", "emit_text", "fail", "interrupted_by", "meta_option", "note_choice", "note_safely",
           "output_option", "plot_option", "run_command", "said_advice", "say", "scene_option", "scene_system",
           "separate_outputs", "set_option", "writable", "writable_outputs"]

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


def writable_outputs(output: Path | None, plot: Path | None) -> None:
    """Before a long run: ``--output`` and ``--plot`` can be written, ``--plot`` is named for a
    format it writes (a FIFO or a device without one gets PNG), and matplotlib is there for a
    plot."""
    if plot is not None:
        plot_formats(plot)
    writable(output, "--output")
    writable(plot, "--plot")
    if plot is not None:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            fail("Error: --plot needs matplotlib\n  hint: pip install 'kronsub[plot]'")


def plot_formats(plot: Path) -> None:
    """A usage error unless ``--plot`` ends in a suffix it writes (or is a FIFO or a device)."""
    from ..simulation.plot import FORMATS, plot_format

    if plot_format(plot) is not None:
        return
    try:
        if output_target(plot)[0] == STREAM:
            return
    except OSError:
        pass
    suffix = f"'{plot.suffix}'" if plot.suffix else "suffix-less"
    names = ", ".join(FORMATS)
    fail(f"Error: --plot {plot}: cannot write {suffix} plots\n  hint: end the name in one of {names}", USAGE_ERROR)


def _same_file(a: Path, b: Path) -> bool:
    """Whether the paths name one file (an existing one by inode, through links; else by path)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def separate_outputs(model: Path | None, *outputs: tuple[str, Path | None, str],
                     inputs: tuple[tuple[str, Path | None, str], ...] = ()) -> None:
    """Fail (a usage error) before any work when an output ``(flag, path, what)`` (or ``(flag, path,
    what, option)``: the option the hint asks to change) would replace the model file, a model
    file it uses (``model:``, :func:`~kronsub.model.uses.model_files`), another of the command's
    ``inputs`` or another output of the same command."""
    from ..model.uses import model_files

    seen = [("MODEL", model, "model")] if model is not None else []
    if model is not None:
        seen += [("MODEL", used, "used model") for used in model_files(model)[1:]]
    seen += [entry for entry in inputs if entry[1] is not None]
    for flag, path, what, *option in outputs:
        if path is None:
            continue
        for _, other, other_what, *_ in seen:
            if _same_file(path, other):
                itself = f"the {other_what} file itself" if other_what != "used model" else \
                    f"a model file that {model} uses ({other})"
                fail(f"Error: {flag} {path} is {itself}\n  hint: choose another {(option or [flag])[0]}",
                     USAGE_ERROR)
        seen.append((flag, path, what))


_ADVICE = [0]  # warnings and notes said since the command began (see :func:`said_advice`)


def say(message: str, err: bool = True) -> None:
    """A message for the terminal (standard error unless ``err`` is false), through
    :func:`~.emitters.escape.terminal_text`: whatever a model, a path or an exception put in it,
    no control or direction character reaches the terminal."""
    from ..emitters.escape import terminal_text  # not at import: the emitters bring sympy

    if message.startswith(("Warning:", "note:")):
        _ADVICE[0] += 1
    click.echo(terminal_text(message), err=err)


def said_advice() -> bool:
    """Whether this command has said a warning or a note: its outputs are then not kept
    (:mod:`kronsub.model.kept`), since the same command again, served from them, would not say it."""
    return _ADVICE[0] > 0


def fail(message: str, code: int = INPUT_ERROR) -> None:
    say(message)
    sys.exit(code)


def _report_model_error(exc: ModelError) -> None:
    lines = []
    for problem in exc.problems:
        lines.append("Error: " + problem.format())
    count = len(exc.problems)
    if count > 1:
        lines.append(f"{count} problems found.")
    fail("\n".join(lines))


def _show_warning(message, category, filename, lineno, file=None, line=None):
    say(f"Warning: {message}")  # matplotlib's missing-glyph warnings quote the character


def run_command(job):
    """Run a command body, turning known errors into messages and exit codes; its work is
    bounded by the command's ``--budget`` (`kronsub.budget`); what its preparation set aside goes
    back to the collector at its end (:func:`kronsub.collector.released`), and its objects are not
    collected again while the process exits (:func:`kronsub.collector.frozen_at_exit`)."""
    frozen_at_exit()
    warnings.showwarning = _show_warning
    _ADVICE[0] = 0
    context = click.get_current_context(silent=True)
    units = context.meta.get(_BUDGET_KEY) if context is not None else None
    try:
        with signals_as_interrupts(), budget.limited(units), command_line():  # SIGTERM and SIGHUP stop a run as Ctrl-C does
            return job()
    except budget.WorkBudgetExceeded as exc:  # placed at the model file when no layer placed it
        source = context.params.get("model") or context.params.get("source") if context is not None else None
        _report_model_error(exc.at(Location(str(source))) if source is not None else exc)
    except ModelError as exc:
        _report_model_error(exc)
    except KronsubError as exc:
        fail(f"Error: {exc}")
    except BrokenPipeError:  # the reader of standard output went away (`| head`): nothing to say
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        sys.exit(INPUT_ERROR)
    except OSError as exc:
        fail(f"Error: {exc.filename or ''}: {exc.strerror or exc}\n  hint: check the path and its permissions")
    except RecursionError:
        fail("Error: the model is nested too deeply to derive\n  hint: split it into known systems")
    except KeyboardInterrupt as exc:
        fail(f"Interrupted{interrupted_by(signal_of(exc))}.", exit_code(exc))
    except Exception as exc:  # never a traceback for users
        if os.environ.get(DEBUG_ENV):
            raise
        text = str(exc).splitlines()[0][:200] if str(exc) else ""
        fail(f"Error: internal error ({type(exc).__name__}{': ' + text if text else ''})\n"
              f"  hint: this is a bug in kronsub {__version__}; please report it to the kronsub developers "
              f"with the command and the model file; {DEBUG_ENV}=1 prints the traceback", INTERNAL_ERROR)
    finally:
        released()  # what a command's preparation set aside (kronsub.collector.preparation)


def note_safely(text: str) -> None:
    """A line on standard error that cannot stop the command (a terminal gone after SIGHUP)."""
    try:
        say(text)
    except OSError:
        pass


def interrupted_by(signum: int) -> str:
    """`` by SIGTERM`` (nothing for Ctrl-C, which the user pressed)."""
    return "" if signum == signal.SIGINT else f" by {signal_name(signum)}"


_BUDGET_KEY = "kronsub.budget"


def _budget_units(ctx, param, value):
    """Keep ``--budget`` for `run_command` (read there, so every command body runs under it)."""
    if value is not None:
        ctx.meta[_BUDGET_KEY] = value
    return value


def budget_units() -> int | None:
    """The running command's ``--budget`` (None: the default)."""
    context = click.get_current_context(silent=True)
    return context.meta.get(_BUDGET_KEY) if context is not None else None


def budget_option(command):
    """``--budget UNITS`` for every command that reads or derives a model (`kronsub.budget`)."""
    return click.option("--budget", type=click.IntRange(min=1), metavar="UNITS", default=None,
                        expose_value=False, callback=_budget_units, is_eager=True,
                        help=f"Work budget of reading and deriving the model, in units of about a term "
                             f"formed each (default {budget.DEFAULT_UNITS:,}): a model that needs more stops "
                             "with an error naming what grew.")(command)


SCENE_HELP = ("Use the model's scene NAME: only its effects are derived and computed "
              "(default: the model's only scene if it has exactly one, else every effect).")
SET_HELP = "Set a parameter or an initial coordinate/velocity (repeatable)."
OUTPUT_HELP = "Write to FILE (atomically) instead of standard output."
FILE = click.Path(dir_okay=False, path_type=Path)


def scene_option(command=None, *, help: str = SCENE_HELP):
    """``--scene NAME`` for every command that derives a model (see :func:`scene_system`);
    ``@scene_option`` or ``@scene_option(help=...)``."""
    option = click.option("--scene", "scene_name", metavar="NAME", default=None, help=help)
    return option if command is None else option(command)


def set_option(help: str = SET_HELP):
    """``--set NAME=VALUE`` (repeatable): parameters and initial values of a run."""
    return click.option("--set", "settings", multiple=True, metavar="NAME=VALUE", help=help)


def output_option(help: str = OUTPUT_HELP, **kwargs):
    """``--output FILE`` / ``-o FILE``: a command's output file."""
    return click.option("--output", "-o", type=FILE, help=help, **kwargs)


def meta_option(help: str):
    """``--meta FILE``: a run's metadata (JSON)."""
    return click.option("--meta", type=FILE, help=help)


def plot_option(help: str):
    """``--plot FILE``: a plot of the run, PNG, PDF or SVG by the name (:func:`plot_formats`)."""
    return click.option("--plot", type=FILE, help=help)


def scene_system(model: Path, scene_name: str | None, *, cache: bool = True, all_points: bool = False):
    """``(model, scene, system)``: the model loaded, its scene chosen (None: the whole model)
    and the scene's equations derived. ``all_points`` asks the scene for every named point."""
    from ..model.loader import load_model
    from ..model.scenes import scene_system as chosen_scene

    with budget.cpu_backstop():
        loaded = load_model(model, cache=cache)
        scene, system = chosen_scene(loaded, scene_name, cache=cache, all_points=all_points)
        return loaded, scene, system


def note_choice(system) -> None:
    """Say on stderr which coordinates `coordinates: auto` picked as independent."""
    imp = getattr(system, "implicit", None)
    if imp is not None and imp.choice == "auto":
        say(f"note: coordinates: auto picked {', '.join(q.name for q in imp.independent)} as independent "
            f"({', '.join(q.name for q in imp.dependent)} dependent; pivoted QR of dg/dy at the initial "
            "configuration)")


def default_sidecar(output: Path | None) -> Path | None:
    """The metadata file beside ``--output``: none for standard output, a FIFO or a device
    (nothing is beside ``/dev/null``)."""
    from ..simulation.trajectory_file import sidecar_path

    if output is None:
        return None
    try:
        how, _ = output_target(output)
    except OSError:
        how = None
    return sidecar_path(output) if how != STREAM else None


def writable(path: Path | None, what: str) -> None:
    """Fail before any work when an output file could not be written."""
    if path is None:
        return
    try:
        how, where = output_target(path)
    except OSError as exc:
        fail(f"Error: {path}: {exc.strerror}\n  hint: choose another {what}")
    if how == STREAM:  # a FIFO or a device, written directly
        if not os.access(where, os.W_OK):
            fail(f"Error: {path}: not writable\n  hint: choose another {what}")
        return
    parent = where.resolve().parent
    if not parent.is_dir():
        fail(f"Error: {path}: the directory {parent} does not exist\n  hint: create it first, or choose another {what}")
    if where.exists() and not os.access(where, os.W_OK) or not where.exists() and not os.access(parent, os.W_OK):
        fail(f"Error: {path}: not writable\n  hint: choose another {what}")


def check_times(t_end: float | None, dt: float | None) -> None:
    """``--t`` and ``--dt``, when given, are positive finite normal numbers (a usage error else)."""
    from ..simulation.run import time_problem

    for name, given in (("t", t_end), ("dt", dt)):
        why = time_problem(name, given) if given is not None else None
        if why is not None:
            fail(f"Error: {why}", USAGE_ERROR)


def coincident_ends(loaded, system, t, y, param):
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


def coincident_at_start(loaded, system, settings) -> None:
    """Raise the :func:`coincident_ends` problem at the initial state (``settings``: ``--set`` or
    ``--at`` values, a ``t`` among them) when there is one: ``linearize`` and ``accuracy`` found
    equations without a value there, and this names the spring or damper why."""
    from ..simulation.start import starting_values

    t = settings.get("t", "0")
    try:
        values = starting_values(system, {k: v for k, v in settings.items() if k != "t"}).values
        t = float(t)
    except (KronsubError, ValueError):
        return  # the values are reported as they are
    ends = coincident_ends(loaded, system, t, values.y0, values.parameters)
    if ends is not None:
        raise ModelError([ends])
