"""The command line: ``kronsub derive MODEL``.

Problems in a model print as ``Error: FILE:LINE:COL: message`` with a hint
and exit with code 1 (usage errors: 2); never a traceback.
"""
from __future__ import annotations

import difflib
import os
import sys
import tempfile
import warnings
from pathlib import Path

import click

from . import __version__
from .errors import KronsubError, ModelError


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent or Path("."), prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _fail(message: str) -> None:
    click.echo(message, err=True)
    sys.exit(1)


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
    except OSError as exc:
        _fail(f"Error: {exc.filename or ''}: {exc.strerror or exc}\n  hint: check the path and its permissions")
    except RecursionError:
        _fail("Error: the model is nested too deeply to derive\n  hint: split it into known systems")
    except KeyboardInterrupt:
        _fail("Interrupted.")
    except Exception as exc:  # never a traceback for users
        if os.environ.get("KRONSUB_DEBUG"):
            raise
        _fail(f"Error: internal error: {type(exc).__name__}: {exc}\n"
              "  hint: this is a bug in kronsub; run with KRONSUB_DEBUG=1 for the traceback and report it")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="kronsub")
def main():
    """Equations of motion of interconnected systems by Kron's method of subspaces."""


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
@click.option("--precision", type=click.Choice(["double", "long", "quad"]), default="double", show_default=True,
              help="The C's real type: double, long double, or _Float128 (glibc's libm; typedef ks_real).")
def codegen(model: Path, lang: str, outdir: Path, name: str | None, prefix: str, precision: str):
    """Generate C (header + source) or a numpy module for MODEL."""
    from .emitters.code import LANGUAGES
    from .model.loader import load_model

    def job():
        if not outdir.is_dir():
            _fail(f"Error: {outdir}: no such directory\n  hint: create it first, or choose another --output")
        if precision != "double" and lang != "c":
            _fail("Error: --precision long|quad is for --lang c\n  hint: drop --precision, or use --lang c")
        system = load_model(model).derive()
        stem = name or model.stem
        for generated in LANGUAGES[lang](system, stem, source=model.as_posix(), prefix=prefix):
            text = generated.text
            if precision != "double":
                from .simulation.extended import prelude, retype

                text = prelude(precision) + retype(text, precision)
            write_atomically(outdir / generated.name, text)
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
    from .simulation.run import METHODS
    from .simulation.run import simulate as run
    from .simulation.table import to_csv
    from .simulation.values import parse_assignments, resolve

    def job():
        if method not in METHODS:
            _fail(f"Error: unknown method '{method}'\n  hint: choose one of {', '.join(METHODS)}")
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
        traj = run(system, values, t_end, dt, method, rtol, atol)
        text = to_csv(system, model.as_posix(), traj, values, rtol, atol, with_points)
        if output is not None:
            write_atomically(output, text)
            click.echo(f"wrote {output} ({len(traj.t)} rows)", err=True)
        else:
            click.echo(text, nl=False)
        if plot is not None:
            from .simulation.plot import plot_trajectory

            plot_trajectory(system, traj, values, plot)
            click.echo(f"wrote {plot}", err=True)
        if not traj.complete:
            _fail(f"Error: the run stopped at t = {traj.t_fail:.6g}: {traj.message}; "
                  f"the {len(traj.t)} rows computed so far are kept (marked incomplete)")

    _run(job)


@main.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--t", "t_end", type=float, default=10.0, show_default=True, help="End time.")
@click.option("--methods", default="all", show_default=True,
              help="Comma-separated: dop853, gauss4, rk4, taylor (C), RK45, DOP853, Radau, LSODA (scipy), heyoka; "
                   "gbs-long, gbs-quad (extended precision, see --precision).")
@click.option("--tolerances", default="1e-4:1e-14", show_default=True,
              help="Every decade of a range (1e-4:1e-14, or 1e-4:1e-14:2 for every second) or a list "
                   "(1e-6,1e-9). Fixed-step methods take the step tol^(1/4).")
@click.option("--target", type=float, help="Name the cheapest method and tolerance reaching this error.")
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path), help="Write the CSV to FILE.")
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
def accuracy(model: Path, t_end: float, methods: str, tolerances: str, target: float | None,
             output: Path | None, plot: Path | None, quick: bool, digits: int | None, precision: str,
             settings: tuple[str, ...]):
    """What accuracy costs in time: error against a high-precision reference, per method and tolerance."""
    from .model.loader import load_model
    from .simulation import accuracy as acc
    from .simulation.values import parse_assignments, resolve

    def job():
        chosen = acc.parse_methods(methods)
        if precision != "double" and f"gbs-{precision}" not in chosen:
            chosen = chosen + (f"gbs-{precision}",)
        grid = acc.parse_tolerances(tolerances)
        if quick:
            grid = acc.quick_tolerances(grid)
        if target is not None and not target > 0:
            _fail("Error: --target must be a positive error, e.g. --target 1e-8")
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
        click.echo(f"computing the reference to t = {t_end:g} ...", err=True)
        default_digits = 34 if "gbs-quad" in chosen else (16 if quick else 20)
        wp = acc.measure(system, values, t_end, chosen, grid, digits=digits or default_digits, quick=quick)
        click.echo(acc.markdown(wp, target), nl=False)
        if output is not None:
            write_atomically(output, acc.to_csv(wp))
            click.echo(f"wrote {output} ({len(wp.points)} points)", err=True)
        if not wp.reference_sufficient():
            _fail(f"Error: the reference's estimated error {wp.reference.error:.1e} is not "
                  f"{acc.REFERENCE_MARGIN:g}x below the best point's error {wp.best_error():.1e}: the errors "
                  "near it are not measured" + (", so no plot was written" if plot is not None else "")
                  + "\n  hint: raise --digits")
        if plot is not None:
            acc.plot(wp, plot, target)
            click.echo(f"wrote {plot}", err=True)

    _run(job)


if __name__ == "__main__":
    main()
