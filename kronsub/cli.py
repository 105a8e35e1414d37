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


def scene_option(command):
    """``--scene NAME`` for every command that derives a model (see :func:`scene_system`)."""
    return click.option("--scene", "scene_name", metavar="NAME", default=None,
                        help="Use the model's scene NAME: only its effects are derived and computed "
                             "(default: the model's only scene if it has exactly one, else every effect).")(command)


def scene_system(model: Path, scene_name: str | None, *, cache: bool = True, all_points: bool = False):
    """``(model, scene, system)``: the model loaded, its scene chosen (None: the whole model)
    and the scene's equations derived. ``all_points`` asks the scene for every named point."""
    import dataclasses

    from .model.loader import load_model
    from .model.scenes import derive_scene, select_scene

    loaded = load_model(model, cache=cache)
    scene = select_scene(loaded, scene_name)
    if scene is not None and all_points:
        points = tuple(sorted(loaded.primitive.points()))
        scene = dataclasses.replace(scene, outputs=dataclasses.replace(scene.outputs, points=points))
    return loaded, scene, derive_scene(loaded, scene, cache=cache)


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
@scene_option
@click.option("--reactions", "with_reactions", is_flag=True,
              help="Add the workless reactions (viewpoint (alpha)) as functions of the state.")
def derive(model: Path, fmt: str, output: Path | None, check: Path | None, no_cache: bool, scene_name: str | None,
           with_reactions: bool):
    """Derive the equations of motion of MODEL (a YAML file)."""
    from .emitters import EMITTERS

    def job():
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
@scene_option
def codegen(model: Path, lang: str, outdir: Path, name: str | None, prefix: str, scene_name: str | None):
    """Generate C (header + source) or a numpy module for MODEL."""
    from .emitters.code import LANGUAGES

    def job():
        if not outdir.is_dir():
            _fail(f"Error: {outdir}: no such directory\n  hint: create it first, or choose another --output")
        _, scene, system = scene_system(model, scene_name)
        stem = name or model.stem
        outputs = scene.outputs if scene is not None else None
        for generated in LANGUAGES[lang](system, stem, source=model.as_posix(), prefix=prefix, outputs=outputs):
            write_atomically(outdir / generated.name, generated.text)
            click.echo(f"wrote {outdir / generated.name}", err=True)

    _run(job)


def _note_choice(system) -> None:
    """Say on stderr which coordinates `coordinates: auto` picked as independent."""
    imp = getattr(system, "implicit", None)
    if imp is not None and imp.choice == "auto":
        click.echo(f"note: coordinates: auto picked {', '.join(q.name for q in imp.independent)} as independent "
                   f"({', '.join(q.name for q in imp.dependent)} dependent; pivoted QR of dg/dy at the initial "
                   "configuration)", err=True)


def _reaction_csv(text: str, system, traj, values, constrained) -> str:
    """The CSV with the reaction columns appended to the header and to every row."""
    import io

    import numpy as np

    from .simulation.reactions import reaction_columns
    from .simulation.run import _numpy_module

    names, data = reaction_columns(system, traj, np.array(values.parameters), _numpy_module(system), constrained)
    out, row = [], 0
    header_done = False
    for line in text.splitlines():
        if line.startswith("#"):
            out.append(line)
        elif not header_done:
            out.append(line + "," + ",".join(names))
            header_done = True
        else:
            buf = io.StringIO()
            np.savetxt(buf, data[row:row + 1], fmt="%.17g", delimiter=",")
            out.append(line + "," + buf.getvalue().strip())
            row += 1
    return "\n".join(out) + "\n"


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
@click.option("--t", "t_end", type=float, default=None, help="End time (default: the scene's, else 10).")
@click.option("--dt", type=float, default=None,
              help="Output interval (and step of fixed-step methods; default: the scene's, else 0.01).")
@click.option("--method", default=None,
              help="Default: the scene's, else dop853. dop853 (C, adaptive), gauss4 (C, symplectic, fixed step), RK45, DOP853, Radau, LSODA "
                   "(scipy), heyoka (optional extra).")
@click.option("--rtol", type=float, default=1e-10, show_default=True, help="Relative tolerance (adaptive methods).")
@click.option("--atol", type=float, default=1e-10, show_default=True, help="Absolute tolerance (adaptive methods).")
@click.option("--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="Set a parameter or an initial coordinate/velocity (repeatable).")
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the CSV to FILE (atomically) instead of standard output.")
@click.option("--points", "with_points", is_flag=True, help="Add the named points' positions to the CSV.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), help="Write a PNG of coordinates and energy.")
@scene_option
@click.option("--reactions", "with_reactions", is_flag=True,
              help="Add the workless reactions (viewpoint (alpha)) to the CSV.")
def simulate(model: Path, t_end: float | None, dt: float | None, method: str | None, rtol: float, atol: float,
             settings: tuple[str, ...], output: Path | None, with_points: bool, plot: Path | None,
             scene_name: str | None, with_reactions: bool = False):
    """Simulate MODEL from t = 0 to --t; the trajectory is CSV."""
    from .model.scenes import initial_values
    from .simulation.run import METHODS
    from .simulation.run import simulate as run
    from .simulation.table import to_csv
    from .simulation.values import parse_assignments, resolve

    def job():
        if method is not None and method not in METHODS:
            _fail(f"Error: unknown method '{method}'\n  hint: choose one of {', '.join(METHODS)}")
        _writable(output, "--output")
        _writable(plot, "--plot")
        if plot is not None:
            try:
                import matplotlib  # noqa: F401
            except ImportError:
                _fail("Error: --plot needs matplotlib\n  hint: pip install 'kronsub[plot]'")
        loaded, scene, system = scene_system(model, scene_name, all_points=with_points)
        _note_choice(system)
        outputs = scene.outputs if scene is not None else None
        span = _pick(t_end, scene and scene.t_end, 10.0)
        step = _pick(dt, scene and scene.dt, 0.01)
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
                click.echo(f"note: initial conditions projected onto the constraints: {note}", err=True)
        else:
            values = resolve(system, initial, assignments)
        traj = run(system, values, span, step, _pick(method, scene and scene.method, "dop853"), rtol, atol,
                   outputs=outputs, constrained=constrained)
        text = to_csv(system, model.as_posix(), traj, values, rtol, atol, with_points, outputs=outputs)
        if with_reactions:
            text = _reaction_csv(text, system, traj, values, constrained)
        if output is not None:
            write_atomically(output, text)
            click.echo(f"wrote {output} ({len(traj.t)} rows)", err=True)
        else:
            click.echo(text, nl=False)
        if plot is not None:
            from .simulation.plot import plot_trajectory

            plot_trajectory(system, traj, values, plot, with_points)
            click.echo(f"wrote {plot}", err=True)
        if not traj.complete:
            _fail(f"Error: the run stopped at t = {traj.t_fail:.6g}: {traj.message}; "
                  f"the {len(traj.t)} rows computed so far are kept (marked incomplete)")

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

    for command in (components, new, check, linearize, animate):
        main.add_command(command)


_register_commands()

if __name__ == "__main__":
    main()
