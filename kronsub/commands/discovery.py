"""Discovery: ``kronsub components [TYPE]``, ``kronsub new NAME``, ``kronsub check MODEL``."""
from __future__ import annotations

import os
import shlex
import tempfile
from pathlib import Path

import click

from ..atomic import cannot_create, umask
from ..emitters.escape import json_document
from .common import USAGE_ERROR, budget_option, fail, run_command, say
from .starters import STARTERS


@click.command()
@click.argument("type_name", metavar="[TYPE]", required=False)
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True,
              help="Output format.")
def components(type_name: str | None, fmt: str):
    """The component library, the effect types and the joints of constraints; with TYPE, the
    details of one (coordinates, parameters with defaults and units, named points,
    conventions; or an effect's or a joint's keys)."""
    from ..errors import KronsubError, close_matches
    from . import catalogue

    def job():
        if type_name is None:
            text = (json_document(catalogue.catalogue(), indent=2) + "\n") if fmt == "json" else catalogue.overview_text()
        elif type_name not in catalogue.names():
            raise KronsubError(f"no component type, effect type or joint '{type_name}'\n  hint: "
                               + close_matches(type_name, catalogue.names()))
        elif fmt == "json":
            text = json_document(catalogue.details(type_name), indent=2) + "\n"
        else:
            text = catalogue.detail_text(type_name)
        click.echo(text, nl=False)

    run_command(job)


def _create(path: Path, text: str) -> None:
    """Write a new file atomically; an existing file is never replaced (FileExistsError)."""
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise cannot_create(exc, path) from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
        os.chmod(tmp, 0o666 & ~umask())
        os.link(tmp, path)  # fails when path exists: no overwrite, no race
    except FileExistsError:
        raise
    except OSError as exc:  # named after the user's path, not the temporary file
        raise cannot_create(exc, path) from None
    finally:
        os.unlink(tmp)


@click.command()
@click.argument("name")
@click.option("--from", "kind", type=click.Choice(sorted(STARTERS)), default="pendulum", show_default=True,
              help="The starter model.")
@click.option("--links", type=click.IntRange(1, 50), default=3, show_default=True,
              help="Number of rods (--from chain).")
def new(name: str, kind: str, links: int):
    """Write a starter model NAME.yaml that derives (never overwrites a file)."""
    from ..errors import printable
    from .starters import starter

    def job():
        path = Path(name if name.endswith((".yaml", ".yml")) else name + ".yaml")
        stem = path.name[:-len(path.suffix)]
        if not stem.strip() or stem.startswith(".") or not name.isprintable() or "/" in stem:
            fail(f"Error: NAME {printable(repr(name))} gives no usable file name ({printable(str(path))})\n"
                  "  hint: a name of printable characters not starting with '.', e.g. kronsub new my_pendulum",
                  USAGE_ERROR)
        if kind != "chain" and click.get_current_context().get_parameter_source("links") \
                is not click.core.ParameterSource.DEFAULT:
            fail(f"Error: --links is for --from chain (not {kind})\n  hint: add --from chain, or drop --links",
                  USAGE_ERROR)
        if not path.resolve().parent.is_dir():
            fail(f"Error: {path}: the directory {path.resolve().parent} does not exist\n"
                  "  hint: create it first, or choose another NAME")
        if path.exists():
            fail(f"Error: {path} exists; kronsub new never overwrites a file\n  hint: choose another NAME")
        try:
            _create(path, starter(kind, path.stem, links))
        except FileExistsError:
            fail(f"Error: {path} exists; kronsub new never overwrites a file\n  hint: choose another NAME")
        shown = shlex.quote(str(path))  # a command to copy: the name quoted for the shell
        say(f"wrote {path} (from {kind}); next: kronsub check {shown} && kronsub derive {shown}")

    run_command(job)


@click.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@budget_option
def check(model: Path):
    """Validate MODEL without deriving it: every problem at once, exit 1 when there are any."""
    from ..budget import cpu_backstop
    from ..model.loader import load_model

    def job():
        with cpu_backstop():
            loaded = load_model(model)
            _check_rank(loaded)
        counts = [(len(loaded.coordinates), "generalized coordinate"), (len(loaded.primitive.parts), "component"),
                  (len(loaded.effects), "effect"), (len(getattr(loaded, "scenes", ())), "scene")]
        shown = [f"{n} {what}{'s' if n != 1 else ''}" for n, what in counts if n or what != "scene"]
        say(f"{model}: OK ({', '.join(shown)})", err=False)

    run_command(job)


def _check_rank(model) -> None:
    """Warn, as deriving would, when ``C = dx/dxbar`` (21) loses rank at sample configurations."""
    from ..model.derive import check_rank

    check_rank(model, [model.connection.get(c, c) for c in model.primitive.coordinates])


__all__ = ["check", "components", "new"]
