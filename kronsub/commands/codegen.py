"""``kronsub codegen MODEL``: C (header + source) or a numpy module of the equations."""
from __future__ import annotations

from pathlib import Path

import click

from ..atomic import write_atomically
from .common import USAGE_ERROR, budget_option, fail, run_command, say, scene_option, scene_system, separate_outputs


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
def codegen(model: Path, lang: str, outdir: Path, name: str | None, prefix: str, scene_name: str | None,
            precision: str):
    """Generate C (header + source) or a numpy module for MODEL."""
    from ..api import C_IDENTIFIER, System, code_files
    from ..emitters.numeric import identifier

    def job():
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
        if precision != "double" and lang != "c":
            fail("Error: --precision long|quad is for --lang c\n  hint: drop --precision, or use --lang c")
        loaded, scene, system = scene_system(model, scene_name)
        stem = name or model.stem
        files = code_files(System.of(system, loaded, scene), stem, lang, prefix=prefix, precision=precision,
                           source=model.as_posix())
        separate_outputs(model, *((f"--output {outdir} --name {stem}", outdir / n, "generated") for n, _ in files))
        for file_name, text in files:
            write_atomically(outdir / file_name, text)
            say(f"wrote {outdir / file_name}")

    run_command(job)


__all__ = ["codegen"]
