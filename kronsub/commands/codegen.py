"""``kronsub codegen MODEL``: C (header + source) or a numpy module of the equations."""
from __future__ import annotations

from pathlib import Path

import click

from ..atomic import write_atomically
from ..model import kept
from .common import (USAGE_ERROR, budget_option, budget_units, fail, run_command, said_advice, say, scene_option,
                     scene_system, separate_outputs)


@click.command()
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
@click.option("--jacobian", "with_jacobian", is_flag=True,
              help="C: add <prefix>_jacobian, the exact Jacobian d ydot/dy of the right-hand side.")
def codegen(model: Path, lang: str, outdir: Path, name: str | None, prefix: str, scene_name: str | None,
            precision: str, with_jacobian: bool = False):
    """Generate C (header + source) or a numpy module for MODEL."""

    def job():
        # the same command before: its files kept (no SymPy); else derived and emitted
        key = kept.key("codegen", model, dict(lang=lang, name=name, prefix=prefix, precision=precision,
                                              scene=scene_name, budget=budget_units(), jacobian=with_jacobian))
        files = _kept_files(key) if key is not None else None
        if files is None:
            from ..api import C_IDENTIFIER
            from ..emitters.numeric import identifier

            if not C_IDENTIFIER.fullmatch(prefix):
                fail(f"Error: --prefix {prefix!r} is not a C identifier (letters, digits and _, not starting "
                      f"with a digit)\n  hint: e.g. --prefix {identifier(prefix)}", USAGE_ERROR)
        if outdir.exists() and not outdir.is_dir():
            fail(f"Error: {outdir}: not a directory\n  hint: choose a directory for --output")
        try:
            outdir.mkdir(parents=True, exist_ok=True)  # the README's `--output build/` in a fresh clone
        except OSError as exc:
            fail(f"Error: {outdir}: cannot create the directory ({exc.strerror})\n"
                  "  hint: choose another --output")
        stem = name or model.stem
        if with_jacobian and lang != "c":
            fail("Error: --jacobian is for --lang c\n  hint: drop --jacobian, or use --lang c", USAGE_ERROR)
        if files is None:
            from ..api import System, code_files

            if precision != "double" and lang != "c":
                fail("Error: --precision long|quad is for --lang c\n  hint: drop --precision, or use --lang c")
            loaded, scene, system = scene_system(model, scene_name)
            files = code_files(System.of(system, loaded, scene), stem, lang, prefix=prefix, precision=precision,
                               source=model.as_posix(), jacobian=with_jacobian)
            if key is not None and not said_advice() and loaded.source is not None:
                kept.record(key, {"files": [list(f) for f in files]}, (loaded.source, *loaded.uses))
        separate_outputs(model, *((f"--output {outdir} --name {stem}", outdir / n, "generated") for n, _ in files))
        for file_name, text in files:
            write_atomically(outdir / file_name, text)
            say(f"wrote {outdir / file_name}")

    run_command(job)


def _kept_files(key: str) -> list[tuple[str, str]] | None:
    """The files kept under ``key`` (:mod:`kronsub.model.kept`), each a plain name and its text."""
    payload = kept.load(key)
    try:
        files = [(str(n), str(t)) for n, t in payload["files"]]
    except (KeyError, TypeError, ValueError):
        return None
    return files if files and all(n and Path(n).name == n for n, _ in files) else None


__all__ = ["codegen"]
