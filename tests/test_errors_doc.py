"""docs/errors.md stays true: every example in it is run and must print exactly what it shows.

Each ``### `` section of the page is one example, run in a fresh directory:
its ```` ```yaml ```` blocks whose first line is ``# NAME`` are written to NAME
(that comment line included, so the line numbers shown are those of the block),
then its ```` ```console ```` blocks are replayed: ``$ kronsub ...`` runs the CLI
in-process, ``$ echo $?`` prints the exit code of the last command, and a few
plain commands (``mkfifo``, ``ln -s``, ``truncate``, ``mkdir``) prepare special files. The
lines after each command are its exact output (standard output, then error),
where ``<number>`` stands for any number (:data:`NUMBER`): digits that depend on the
machine's BLAS kernel, instruction set or thread count are never pinned.

``python tests/test_errors_doc.py --update`` rewrites the outputs from a run
(then read the diff: the page is documentation, the run is the check).
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from click.testing import CliRunner

from kronsub.cli import main

PAGE = Path(__file__).resolve().parent.parent / "docs" / "errors.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\n", re.M | re.S)
PLAIN_COMMANDS = {"mkfifo", "ln", "truncate", "mkdir"}
PLACEHOLDER = "<number>"
NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)"
"""What :data:`PLACEHOLDER` stands for in a documented output: a number as Python prints it."""


def matches(documented: str, actual: str) -> bool:
    """Whether ``actual`` is the ``documented`` output, each placeholder a number."""
    if PLACEHOLDER not in documented:
        return actual == documented
    pattern = f"(?:{NUMBER})".join(re.escape(part) for part in documented.split(PLACEHOLDER))
    return re.fullmatch(pattern, actual) is not None


def sections(text: str) -> list[tuple[str, str]]:
    """(title, body) of every ``### `` section."""
    parts = re.split(r"^### (.+)\n", text, flags=re.M)
    return [(parts[i].strip(), parts[i + 1]) for i in range(1, len(parts), 2)]


def replay(body: str, folder: Path) -> list[tuple[str, str]]:
    """Write the section's files, run its commands; (documented, actual) console blocks."""
    blocks = []
    for match in FENCE.finditer(body):
        kind, content = match.group(1), match.group(2)
        if kind == "yaml":
            first, _, _ = content.partition("\n")
            assert first.startswith("# "), f"a yaml example starts with `# FILE NAME`: {first!r}"
            (folder / first[2:].strip()).write_text(content, encoding="utf-8")
        elif kind == "console":
            blocks.append((content, run_console(content, folder)))
    return blocks


def run_console(content: str, folder: Path) -> str:
    out, code = [], 0
    for line in content.splitlines():
        if not line.startswith("$ "):
            continue
        out.append(line)
        command = line[2:]
        if command == "echo $?":
            out.append(str(code))
            continue
        words = shlex.split(command)
        if words[0] == "kronsub":
            result = CliRunner().invoke(main, words[1:], prog_name="kronsub")
            code = result.exit_code
            text = result.stdout + result.stderr
            assert "Traceback" not in text, text
            out.extend(text.splitlines())
        else:
            assert words[0] in PLAIN_COMMANDS, f"unknown command in docs/errors.md: {command}"
            code = subprocess.run(words, cwd=folder, check=True).returncode
    return "\n".join(out) + "\n"


def run_section(body: str, monkeypatch) -> list[tuple[str, str]]:
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        monkeypatch.chdir(folder)
        monkeypatch.setenv("KRONSUB_CACHE_DIR", str(folder / ".cache"))
        monkeypatch.setenv("COLUMNS", "100")
        return replay(body, folder)


EXAMPLES = sections(PAGE.read_text(encoding="utf-8"))


def test_the_page_has_examples():
    assert len(EXAMPLES) >= 40
    assert len({title for title, _ in EXAMPLES}) == len(EXAMPLES), "titles are unique"


@pytest.mark.parametrize("body", [body for _, body in EXAMPLES], ids=[title for title, _ in EXAMPLES])
def test_example_prints_what_the_page_shows(body, monkeypatch):
    blocks = run_section(body, monkeypatch)
    assert blocks, "every example runs a command"
    for documented, actual in blocks:
        assert matches(documented, actual), (documented, actual)
        if PLACEHOLDER not in documented:
            assert actual == documented


@pytest.mark.parametrize("documented, actual, expected", [
    ("residual <number> in 'B.x'\n", "residual 5.96 in 'B.x'\n", True),
    ("residual <number> in 'B.x'\n", "residual 1e-05 in 'B.x'\n", True),
    ("residual <number> in 'B.x'\n", "residual 4.71 in 'B.y'\n", False),
    ("residual <number> in 'B.x'\n", "residual  in 'B.x'\n", False),
    ("residual 4.71 in 'B.x'\n", "residual 5.96 in 'B.x'\n", False),
])
def test_a_placeholder_stands_for_a_number_only(documented, actual, expected):
    assert matches(documented, actual) is expected


def test_every_exit_code_is_documented():
    text = PAGE.read_text(encoding="utf-8")
    table = text[text.index("## Exit codes"):text.index("## ", text.index("## Exit codes") + 3)]
    for code in ("0", "1", "2", "3", "4", "130"):
        assert re.search(rf"^\| `{code}` \|", table, re.M), code


def _update() -> None:
    """Rewrite every console block of the page with the output of a run."""
    text = PAGE.read_text(encoding="utf-8")

    class Patch:  # a minimal stand-in for pytest's monkeypatch
        def __init__(self):
            self.cwd, self.env = os.getcwd(), dict(os.environ)

        def chdir(self, path):
            os.chdir(path)

        def setenv(self, key, value):
            os.environ[key] = value

    patch = Patch()
    for _, body in sections(text):
        new_body = body
        for documented, actual in run_section(body, patch):
            if not matches(documented, actual):  # a placeholder that still matches is kept
                new_body = new_body.replace(documented, actual, 1)
        text = text.replace(body, new_body, 1)
    os.chdir(patch.cwd)
    PAGE.write_text(text, encoding="utf-8")


if __name__ == "__main__" and "--update" in sys.argv:
    _update()
