"""The command line: the ``kronsub`` group and its commands, each from a module of
:mod:`kronsub.commands`. Exit codes: :data:`EXIT_CODES` (`kronsub.commands.common`)."""
from __future__ import annotations

import os

import click

from .commands.accuracy import accuracy
from .commands.animate import animate
from .commands.cache import cache
from .commands.codegen import codegen
from .commands.common import DEBUG_ENV, EXIT_CODES
from .commands.derive import derive
from .commands.discovery import check, components, new
from .commands.linearize import linearize
from .commands.simulate import simulate
from .commands.sweep import sweep
from .version import __version__

__all__ = ["EXIT_CODES", "main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="kronsub")
@click.option("--debug", is_flag=True, help=f"Show the traceback of an internal error (as {DEBUG_ENV}=1 does).")
def main(debug: bool):
    """Equations of motion of interconnected systems by Kron's method of subspaces."""
    if debug:
        os.environ[DEBUG_ENV] = "1"


for _command in (derive, codegen, simulate, accuracy, cache, components, new, check, linearize, animate, sweep):
    main.add_command(_command)

if __name__ == "__main__":
    main()
