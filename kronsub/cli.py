"""The command line: ``kronsub derive MODEL``.

Problems in a model print as ``Error: FILE:LINE:COL: message`` with a hint;
never a traceback. Exit codes (see :data:`EXIT_CODES`): 0 success, 1 model or
input error, 2 usage error, 3 numerical failure (rows so far kept), 4 internal
error, 130 interrupted (rows so far kept).
"""
from __future__ import annotations

import difflib
import os
import sys
import warnings
from pathlib import Path

import click

from . import __version__
from .atomic import atomic_file, write_atomically
from .errors import KronsubError, ModelError

OK, INPUT_ERROR, USAGE_ERROR, NUMERICAL_FAILURE, INTERNAL_ERROR, INTERRUPTED = 0, 1, 2, 3, 4, 130
EXIT_CODES = {
    OK: "success",
    INPUT_ERROR: "model or input error (the message names the file, line and column)",
    USAGE_ERROR: "usage error (an unknown command or option, an option value out of range)",
    NUMERICAL_FAILURE: "numerical failure: the run stopped early; the rows so far are kept, marked incomplete",
    INTERNAL_ERROR: "internal error: a bug in kronsub (KRONSUB_DEBUG=1 shows the traceback)",
    INTERRUPTED: "interrupted (Ctrl-C); the rows so far are kept, marked incomplete",
}
DEBUG_ENV = "KRONSUB_DEBUG"


def _fail(message: str, code: int = INPUT_ERROR) -> None:
    click.echo(message, err=True)
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
    click.echo(f"Warning: {message}", err=True)


def _run(job):
    """Run a command body, turning known errors into messages and exit codes."""
    warnings.showwarning = _show_warning
    try:
        return job()
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
    except KeyboardInterrupt:
        _fail("Interrupted.", INTERRUPTED)
    except Exception as exc:  # never a traceback for users
        if os.environ.get(DEBUG_ENV):
            raise
        text = str(exc).splitlines()[0][:200] if str(exc) else ""
        _fail(f"Error: internal error ({type(exc).__name__}{': ' + text if text else ''})\n"
              f"  hint: this is a bug in kronsub {__version__}; please report it to the kronsub developers "
              f"with the command and the model file; {DEBUG_ENV}=1 prints the traceback", INTERNAL_ERROR)


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
def derive(model: Path, fmt: str, output: Path | None, check: Path | None, no_cache: bool):
    """Derive the equations of motion of MODEL (a YAML file)."""
    from .emitters import EMITTERS
    from .model.loader import load_model

    def job():
        if output is not None and not output.resolve().parent.is_dir():
            _fail(f"Error: {output}: the directory {output.resolve().parent} does not exist\n"
                  "  hint: create it first, or choose another --output path")
        system = load_model(model, cache=not no_cache).derive(cache=not no_cache)
        text = EMITTERS[fmt](system)
        if check is not None:
            try:
                expected = check.read_text(encoding="utf-8")
            except OSError as exc:
                _fail(f"Error: {check}: {exc.strerror}\n  hint: write it first with --output {check}")
            if expected != text:
                diff = difflib.unified_diff(expected.splitlines(True), text.splitlines(True),
                                            fromfile=str(check), tofile=f"derived from {model}")
                click.echo("".join(diff), nl=False)
                _fail(f"Error: {check} differs from the derived equations")
            click.echo(f"{check}: up to date", err=True)
            return
        if output is not None:
            write_atomically(output, text)
            click.echo(f"wrote {output}", err=True)
        else:
            click.echo(text, nl=False)

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
def codegen(model: Path, lang: str, outdir: Path, name: str | None, prefix: str):
    """Generate C (header + source) or a numpy module for MODEL."""
    from .emitters.code import LANGUAGES
    from .model.loader import load_model

    def job():
        if not outdir.is_dir():
            _fail(f"Error: {outdir}: no such directory\n  hint: create it first, or choose another --output")
        system = load_model(model).derive()
        stem = name or model.stem
        for generated in LANGUAGES[lang](system, stem, source=model.as_posix(), prefix=prefix):
            write_atomically(outdir / generated.name, generated.text)
            click.echo(f"wrote {outdir / generated.name}", err=True)

    _run(job)


def _writable(path: Path | None, what: str) -> None:
    """Fail before any work when an output file could not be written."""
    if path is None:
        return
    parent = path.resolve().parent
    if not parent.is_dir():
        _fail(f"Error: {path}: the directory {parent} does not exist\n  hint: create it first, or choose another {what}")
    if not os.access(parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        _fail(f"Error: {path}: not writable\n  hint: choose another {what}")


@main.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--t", "t_end", type=float, default=10.0, show_default=True, help="End time.")
@click.option("--dt", type=float, default=0.01, show_default=True, help="Output interval (and step of fixed-step methods).")
@click.option("--method", default="dop853", show_default=True,
              help="dop853 (C, adaptive), gauss4 (C, symplectic, fixed step), RK45, DOP853, Radau, LSODA "
                   "(scipy), heyoka (optional extra).")
@click.option("--rtol", type=float, default=1e-10, show_default=True, help="Relative tolerance (adaptive methods).")
@click.option("--atol", type=float, default=1e-10, show_default=True, help="Absolute tolerance (adaptive methods).")
@click.option("--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="Set a parameter or an initial coordinate/velocity (repeatable).")
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the CSV to FILE (atomically) instead of standard output.")
@click.option("--points", "with_points", is_flag=True, help="Add the named points' positions to the CSV.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), help="Write a PNG of coordinates and energy.")
def simulate(model: Path, t_end: float, dt: float, method: str, rtol: float, atol: float,
             settings: tuple[str, ...], output: Path | None, with_points: bool, plot: Path | None):
    """Simulate MODEL from t = 0 to --t; the trajectory is CSV."""
    from .model.loader import load_model
    from .simulation.run import METHODS, SimulationError, collect, row_count, start
    from .simulation.table import CsvWriter
    from .simulation.values import parse_assignments, resolve

    def job():
        if method not in METHODS:
            _fail(f"Error: unknown method '{method}'\n  hint: choose one of {', '.join(METHODS)}", USAGE_ERROR)
        try:
            row_count(t_end, dt)
        except SimulationError as exc:
            _fail(f"Error: {exc}", USAGE_ERROR)
        _writable(output, "--output")
        _writable(plot, "--plot")
        if plot is not None:
            try:
                import matplotlib  # noqa: F401
            except ImportError:
                _fail("Error: --plot needs matplotlib\n  hint: pip install 'kronsub[plot]'")
        loaded = load_model(model)
        system = loaded.derive()
        values = resolve(system, dict(loaded.initial), parse_assignments(settings))
        run = start(system, values, t_end, dt, method, rtol, atol)
        kept = [] if plot is not None else None

        def stream(out) -> CsvWriter:
            writer = CsvWriter(out, system, model.as_posix(), values, run.method, run.backend, rtol, atol,
                               with_points)
            try:
                writer.stream(run, kept.append if kept is not None else None)
            except KeyboardInterrupt:
                pass  # the file is kept, marked incomplete (writer.stopped)
            return writer

        if output is not None:
            with atomic_file(output) as fh:
                writer = stream(fh)
            where = str(output)
            click.echo(f"wrote {output} ({writer.rows} rows)", err=True)
        else:
            writer = stream(sys.stdout)
            sys.stdout.flush()
            where = "standard output"
        if writer.stopped:
            _fail(f"Interrupted after t = {writer.last_t!r}: the {writer.rows} rows computed so far are kept "
                  f"in {where} (marked incomplete)", INTERRUPTED)
        if plot is not None:
            from .simulation.plot import plot_trajectory

            plot_trajectory(system, collect(run, kept, len(system.coordinates)), values, plot)
            click.echo(f"wrote {plot}", err=True)
        if not run.complete:
            _fail(f"Error: the run stopped at t = {run.t_fail:.6g}: {run.message}; "
                  f"the {writer.rows} rows computed so far are kept in {where} (marked incomplete)",
                  NUMERICAL_FAILURE)

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
            click.echo(f"cache: off ({store.CACHE_ENV}=off)")
            return
        reason = store.unsafe_reason(found.folder) if found.folder.exists() else None
        click.echo(f"cache: {found.folder}" + (f" (not used: {reason})" if reason else "")
                   + ("" if found.folder.exists() else " (empty)"))
        click.echo(f"derived known systems: {found.systems} ({_size(found.systems_bytes)})")
        click.echo(f"compiled models: {found.libraries} ({_size(found.libraries_bytes)})")

    _run(job)


@cache.command("clear")
def cache_clear():
    """Remove kronsub's own entries from the cache (nothing else in the folder)."""
    from . import cache as store

    def job():
        folder = store.cache_dir()
        removed = store.clear()
        click.echo(f"removed {removed} entries from {folder}" if folder is not None else "cache: off")

    _run(job)


if __name__ == "__main__":
    main()
