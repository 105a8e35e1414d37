"""The command line: the ``kronsub`` group and its commands, each from a module of
:mod:`kronsub.commands`. Exit codes: :data:`EXIT_CODES` (`kronsub.commands.common`).

A command's module is imported when the command runs, so ``kronsub --help`` and a command
that needs no SymPy do not pay for SymPy, NumPy, SciPy or Jinja; the listing of ``--help``
reads :data:`COMMANDS`, whose summaries a test keeps equal to the commands' own."""
from __future__ import annotations

import importlib
import os

import click

from .commands.common import DEBUG_ENV, EXIT_CODES
from .version import __version__

__all__ = ["BLAS_THREADS", "COMMANDS", "EXIT_CODES", "main"]

BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""One BLAS thread for a command: its matrices are small (a metric, a Jacobian, a rank of ``C``),
where BLAS's threads only wait on busy cores, and a sweep's workers are its parallelism."""

# command name: (its module in kronsub.commands, its summary in the listing of --help)
COMMANDS = {
    "accuracy": ("accuracy", "What accuracy costs in time: error against a high-precision reference, "
                             "per method and tolerance."),
    "animate": ("animate", "Draw the mechanism of SOURCE over time: a MODEL (simulated first) or a trajectory CSV "
                           "written with `kronsub simulate --points`."),
    "cache": ("cache", "Show or clear kronsub's caches (derived known systems, compiled models)."),
    "check": ("discovery", "Validate MODEL without deriving it: every problem at once, exit 1 when there are any."),
    "codegen": ("codegen", "Generate C (header + source) or a numpy module for MODEL."),
    "components": ("discovery", "The component library, the effect types and the joints of constraints; with "
                                "TYPE, the details of one (coordinates, parameters with defaults and units, named "
                                "points, conventions; or an effect's or a joint's keys)."),
    "derive": ("derive", "Derive the equations of motion of MODEL (a YAML file)."),
    "linearize": ("linearize", "Linearise MODEL: ydot ~ A (y - y*) + B (u - u*), y = [q; qdot], "
                               "with the eigenvalues of A."),
    "new": ("discovery", "Write a starter model NAME.yaml that derives (never overwrites a file)."),
    "simulate": ("simulate", "Simulate MODEL from t = 0 to --t; the trajectory is plain CSV (a header row, then "
                             "numbers), its metadata JSON (--meta, or beside --output)."),
    "sweep": ("sweep", "Run MODEL over a grid or a sample of its parameters and initial values: a row per run "
                       "(inputs, status, final state, min and max of each coordinate, energy drift, cost)."),
}


def short_help(text: str, limit: int) -> str:
    """A command's line in ``kronsub --help``: the first sentence of ``text`` when it fits in
    ``limit`` characters, else as many of its first words as fit with ``...`` after them."""
    words = text.split("\n\n")[0].split()
    shown: list[str] = []
    for word in words:
        if len(" ".join([*shown, word])) > limit:
            break
        shown.append(word)
        if word.endswith("."):
            return " ".join(shown)
    else:
        return " ".join(shown)
    while shown and len(" ".join(shown)) + 3 > limit:
        shown.pop()
    return " ".join(shown) + "..."


class CommandTable(click.Group):
    """A click group whose commands are imported from :data:`COMMANDS` when first used."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(COMMANDS) | set(self.commands))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in COMMANDS:
            for name in BLAS_THREADS:  # before the command imports NumPy; a value the user set stands
                os.environ.setdefault(name, "1")
            module = importlib.import_module(f"{__package__}.commands.{COMMANDS[cmd_name][0]}")
            self.add_command(getattr(module, cmd_name.replace("-", "_")), cmd_name)
        return self.commands.get(cmd_name)

    def resolve_command(self, ctx: click.Context, args: list[str]):
        if self.get_command(ctx, click.utils.make_str(args[0])) is None:
            for name in COMMANDS:  # an unknown name: click's "Did you mean" looks among them all
                self.get_command(ctx, name)
        return super().resolve_command(ctx, args)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        names = self.list_commands(ctx)
        if not names:
            return
        limit = formatter.width - 6 - max(len(name) for name in names)
        rows = []
        for name in names:
            if name in COMMANDS:
                summary = short_help(COMMANDS[name][1], limit)
            else:
                summary = self.commands[name].get_short_help_str(limit)
            rows.append((name, summary))
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=CommandTable, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="kronsub")
@click.option("--debug", is_flag=True, help=f"Show the traceback of an internal error (as {DEBUG_ENV}=1 does).")
def main(debug: bool):
    """Equations of motion of interconnected systems by Kron's method of subspaces."""
    if debug:
        os.environ[DEBUG_ENV] = "1"


if __name__ == "__main__":
    main()
