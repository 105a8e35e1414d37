"""``kronsub derive MODEL``: the equations of motion in Markdown, LaTeX or JSON."""
from __future__ import annotations

import difflib
from pathlib import Path

import click
from click.core import ParameterSource

from .. import budget
from ..errors import Location
from ..model import kept
from ..model.file_reading import read_user_text
from .common import (USAGE_ERROR, budget_option, budget_units, emit_text, fail, note_choice, output_option,
                     run_command, said_advice, say, scene_option, scene_system, separate_outputs)


@click.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["markdown", "latex", "json"]), default="markdown",
              show_default=True, help="Output format.")
@output_option()
@click.option("--check", type=click.Path(dir_okay=False, path_type=Path),
              help="Compare with FILE (in the format of its extension .md, .tex or .json, or of its "
                   "text, unless --format is given); exit 1 with a unified diff when they differ.")
@click.option("--no-cache", is_flag=True, help="Derive from scratch, ignoring the known-system cache.")
@scene_option
@budget_option
@click.option("--reactions", "with_reactions", is_flag=True,
              help="Add the workless reactions (viewpoint (alpha)) as functions of the state.")
def derive(model: Path, fmt: str, output: Path | None, check: Path | None, no_cache: bool, scene_name: str | None,
           with_reactions: bool):
    """Derive the equations of motion of MODEL (a YAML file)."""

    def job():
        separate_outputs(model, ("--output", output, "output"))
        expected = None
        chosen = fmt
        if check is not None:
            if not check.exists():
                fail(f"Error: {check}: No such file or directory\n  hint: write it first with --output {check}")
            expected = read_user_text(check, "file of derived equations (--check)")
            chosen = _check_format(check, expected, fmt, click.get_current_context().get_parameter_source("fmt")
                                   is not ParameterSource.DEFAULT)
        if output is not None and not output.resolve().parent.is_dir():
            fail(f"Error: {output}: the directory {output.resolve().parent} does not exist\n"
                  "  hint: create it first, or choose another --output path")
        text = _derived_text(model, chosen, scene_name, no_cache, with_reactions)
        if expected is not None:
            if expected != text:
                diff = difflib.unified_diff(expected.splitlines(True), text.splitlines(True),
                                            fromfile=str(check), tofile=f"derived from {model}")
                say("".join(diff).rstrip("\n"), err=False)
                fail(f"Error: {check} differs from the derived equations")
            say(f"{check}: up to date")
            return
        emit_text(text, output)

    run_command(job)


def _derived_text(model: Path, fmt: str, scene_name: str | None, no_cache: bool, with_reactions: bool) -> str:
    """The equations of ``model`` as text: kept from the same command before (no SymPy,
    :mod:`kronsub.model.kept`) unless ``--no-cache``, else derived (and kept when nothing was
    said about them on the way)."""
    options = dict(format=fmt, scene=scene_name, reactions=with_reactions, budget=budget_units())
    key = None if no_cache else kept.key("derive", model, options)
    payload = kept.load(key) if key is not None else None
    if payload is not None and isinstance(payload.get("text"), str):
        return payload["text"]
    from ..emitters import EMITTERS
    from ..emitters.reactions import with_reactions as add_reactions

    with budget.cpu_backstop():  # one CPU-time backstop for reading, deriving and printing
        try:
            loaded, _, system = scene_system(model, scene_name, cache=not no_cache)
            note_choice(system)
            text = EMITTERS[fmt](system)
            if with_reactions:
                text = add_reactions(text, system, fmt)
        except budget.WorkBudgetExceeded as exc:  # (what the printing derives: a drive's terms, reactions)
            raise exc.at(Location(str(model))) from None
    if key is not None and not said_advice() and loaded.source is not None:  # (note_choice's note too)
        kept.record(key, {"text": text}, (loaded.source, *loaded.uses))
    return text


SUFFIXES = {".md": "markdown", ".markdown": "markdown", ".tex": "latex", ".json": "json"}
"""The format of a ``--check`` file by its extension."""
SHOWN = {"markdown": "Markdown", "latex": "LaTeX", "json": "JSON"}


def format_of(path: Path, text: str) -> str | None:
    """The format ``derive`` wrote ``text`` in: by the extension of ``path``, else by its first
    character (JSON an object, LaTeX a command, Markdown a heading); None when it says none."""
    if path.suffix.lower() in SUFFIXES:
        return SUFFIXES[path.suffix.lower()]
    start = text.lstrip()[:1]
    return {"{": "json", "\\": "latex", "#": "markdown"}.get(start)


def _check_format(check: Path, text: str, fmt: str, given: bool) -> str:
    """The format to compare ``check`` in: ``--format`` when given (refused when the file is in
    another), else the file's own."""
    found = format_of(check, text)
    if not given:
        return found or fmt
    if found is not None and found != fmt:
        fail(f"Error: --check {check} holds {SHOWN[found]}, "
             f"but --format is {fmt}\n  hint: drop --format (the file's format is used) or give --format {found}",
             USAGE_ERROR)
    return fmt


__all__ = ["SHOWN", "SUFFIXES", "derive", "format_of"]
