"""docs/cli.md stays true: its tables are the commands' ``--help``.

Every command has a ``## `kronsub ...` `` section; every option of it (``-h, --help`` apart) is a
row ``| option | value | default | meaning |``, and no row names an option that does not exist.
The value is the metavar ``--help`` shows (with its range, as ``(1<=x<=120)``); the default is
``--help``'s ``[default: X]`` written `` `X` ``, ``off`` for a flag, ``required`` for a required
option, else words that ``--help`` says after "default" in the option's text, or ``—`` when
there is none.
"""
from __future__ import annotations

import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from kronsub.cli import main

PAGE = Path(__file__).resolve().parent.parent / "docs" / "cli.md"
HEADING = re.compile(r"^## `(kronsub[^`]*)`\n", re.M)
CELL = re.compile(r"(?<!\\)\|")


def commands(group: click.Command = main, path: tuple[str, ...] = ("kronsub",)):
    """``{("kronsub", "cache", "info"): command}`` for the group and every command under it."""
    out = {path: group}
    if isinstance(group, click.Group):  # through list_commands: the group imports its commands when used
        ctx = click.Context(group, info_name=path[-1])
        for name in group.list_commands(ctx):
            out.update(commands(group.get_command(ctx, name), path + (name,)))
    return out


def documented() -> dict[tuple[str, ...], dict[str, tuple[str, str]]]:
    """Per command path, ``{option names: (value, default)}`` of its table in the page."""
    text = PAGE.read_text(encoding="utf-8")
    parts = HEADING.split(text)
    out = {}
    for title, body in zip(parts[1::2], parts[2::2]):
        body = body.split("\n## ")[0]
        path = tuple(word for word in title.split() if re.fullmatch(r"[a-z][a-z-]*", word))
        rows = {}
        for line in body.splitlines():
            if not line.startswith("| `-"):
                continue
            cells = [c.strip().replace("\\|", "|") for c in CELL.split(line)[1:-1]]
            assert len(cells) == 4, line
            names = cells[0].strip("`")
            assert names not in rows, f"{title}: {names} documented twice"
            rows[names] = (cells[1], cells[2])
        assert path not in out, f"{title} documented twice"
        out[path] = rows
    return out


def from_help(command: click.Command, name: str) -> dict[str, tuple[str, str, str]]:
    """``{option names: (value, default, text)}`` as ``--help`` shows them."""
    ctx = click.Context(command, info_name=name)
    out = {}
    for param in command.params:
        if not isinstance(param, click.Option) or param.name == "help" or param.hidden:
            continue
        first, text = param.get_help_record(ctx)
        match = re.fullmatch(r"((?:-{1,2}[\w-]+(?:, )?)+)\s*(.*)", first)
        names, value = match.group(1).strip().rstrip(","), match.group(2)
        extras: dict[str, str] = {}
        bracket = re.search(r"\s*\[([^\[\]]*)\]$", text)
        if bracket and any(k in bracket.group(1) for k in ("default: ", "required", "<=", ">=")):
            for item in bracket.group(1).split("; "):
                key = "default" if item.startswith("default: ") else "required" if item == "required" else "range"
                extras[key] = item.removeprefix("default: ")
            text = text[:bracket.start()]
        value = f"`{value}`" if value else ""
        if "range" in extras:
            value += f" ({extras['range']})"
        if param.is_flag:
            default = "off"
        elif "default" in extras:
            default = f"`{extras['default']}`"
        elif "required" in extras:
            default = "required"
        else:
            default = None  # words of the text, checked below
        out[names] = (value.strip(), default, " ".join(text.split()))
    return out


def test_every_command_is_documented_and_nothing_else():
    assert set(documented()) == set(commands())


@pytest.mark.parametrize("path", sorted(commands()), ids=lambda p: " ".join(p))
def test_options_are_the_help(path):
    command = commands()[path]
    shown = from_help(command, path[-1])
    doc = documented()[path]
    assert set(doc) == set(shown), f"documented {sorted(doc)}, --help has {sorted(shown)}"
    for names, (value, default) in doc.items():
        want_value, want_default, text = shown[names]
        assert value == want_value, f"{' '.join(path)} {names}: value {value!r}, --help {want_value!r}"
        if want_default is not None:
            assert default == want_default, f"{' '.join(path)} {names}: default {default!r}, --help {want_default!r}"
        elif default == "—":
            assert "default" not in text.lower(), f"{' '.join(path)} {names}: --help names a default: {text}"
        else:
            assert "default" in text.lower() and default in text, \
                f"{' '.join(path)} {names}: default {default!r} is not what --help says: {text}"
    # and the help printed by the command names each option
    result = CliRunner().invoke(main, [*path[1:], "--help"], terminal_width=200)
    assert result.exit_code == 0, result.output
    for names in shown:
        assert names in result.output, names
