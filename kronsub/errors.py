"""Problems found in a model, collected and reported together.

Every user-facing error names the file, line and column, says what is wrong,
and gives a hint. The CLI prints them as ``Error: FILE:LINE:COL: message``
and exits with code 1; nothing here ever leaks a traceback.
"""
from __future__ import annotations

import difflib
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Location:
    """A place in a model file; line and column are 1-based."""

    file: str
    line: int = 0
    column: int = 0

    def shifted(self, columns: int) -> "Location":
        """The location ``columns`` characters further on the same line."""
        return Location(self.file, self.line, self.column + columns)

    def __str__(self) -> str:
        if self.line:
            return f"{self.file}:{self.line}:{self.column}"
        return self.file


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a model: where, what, and how to fix it."""

    location: Location | None
    message: str
    hint: str | None = None

    def format(self) -> str:
        """``where: message`` and ``  hint: ...``, each on one line (see `printable`)."""
        where = f"{self.location}: " if self.location is not None else ""
        text = printable(f"{where}{self.message}")
        if self.hint:
            text += f"\n  hint: {printable(self.hint)}"
        return text


def printable(text: str) -> str:
    """``text`` with control and direction characters escaped (``\\n``, ``\\u202e``), so
    that text quoted from a model cannot break a message into lines or reorder it."""
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() or ch == " " else ch.encode("unicode_escape").decode("ascii")
                   for ch in text)


_COMMAND_LINE: ContextVar[bool] = ContextVar("kronsub_command_line", default=False)


@contextmanager
def command_line():
    """Within it, messages name options as the command line takes them (``--t``); outside, as
    the Python API's keyword arguments of the same names (``t``)."""
    token = _COMMAND_LINE.set(True)
    try:
        yield
    finally:
        _COMMAND_LINE.reset(token)


def on_command_line() -> bool:
    """Whether messages are made for the command line (:func:`command_line`), not for Python."""
    return _COMMAND_LINE.get()


def option(name: str, key: str | None = None) -> str:
    """The option ``name`` (and an entry ``key`` of it) as the caller gave it: ``--t``, ``--set m1``
    on the command line (:func:`command_line`), ``t``, ``set['m1']`` from Python."""
    if _COMMAND_LINE.get():
        return f"--{name}" + (f" {key}" if key is not None else "")
    return name + (f"[{key!r}]" if key is not None else "")


def given(name: str, value) -> str:
    """The option ``name`` with its ``value`` as the caller gave it: ``--scene pushed`` on the
    command line, ``scene='pushed'`` from Python."""
    return f"--{name} {value}" if _COMMAND_LINE.get() else f"{name}={value!r}"


def assignment(name: str, key: str = "NAME", value: str = "VALUE", text: bool = False) -> str:
    """How to give ``key`` the value ``value`` by the option ``name``: ``--at NAME=VALUE`` on the
    command line, ``at={'NAME': VALUE}`` from Python (``text``: a string there, ``'VALUE'``)."""
    if _COMMAND_LINE.get():
        return f"--{name} {key}={value}"
    shown = repr(value) if text else value
    return f"{name}={{{key!r}: {shown}}}"


class KronsubError(Exception):
    """Base class of the errors kronsub reports to users."""


class ModelError(KronsubError):
    """One or more problems in a model; raised once with all of them."""

    def __init__(self, problems: list[Problem]):
        self.problems = list(problems)
        super().__init__(self.format())

    def format(self) -> str:
        return "\n".join(p.format() for p in self.problems)


@dataclass
class ProblemCollector:
    """Collects problems while validating a whole model, then raises once."""

    problems: list[Problem] = field(default_factory=list)

    def add(self, location: Location | None, message: str, hint: str | None = None) -> None:
        self.problems.append(Problem(location, message, hint))

    def extend(self, error: ModelError) -> None:
        self.problems.extend(error.problems)

    def __bool__(self) -> bool:
        return bool(self.problems)

    def raise_if_any(self) -> None:
        if self.problems:
            raise ModelError(self.problems)


def _one_edit(a: str, b: str) -> bool:
    """Whether ``b`` is ``a`` with one character changed, added, removed, or two neighbours swapped."""
    if a == b or abs(len(a) - len(b)) > 1:
        return False
    if len(a) == len(b):
        diff = [i for i, (x, y) in enumerate(zip(a, b)) if x != y]
        return len(diff) == 1 or (len(diff) == 2 and diff[1] == diff[0] + 1
                                  and a[diff[0]] == b[diff[1]] and a[diff[1]] == b[diff[0]])
    short, long = (a, b) if len(a) < len(b) else (b, a)
    i = next((k for k, (x, y) in enumerate(zip(short, long)) if x != y), len(short))
    return short[i:] == long[i + 1:]


def near_names(name: str, options, n: int = 3) -> list[str]:
    """The valid names nearest to ``name``: difflib's close matches, then the names one edit
    away (``q2`` for ``q1``, which difflib's ratio misses in short names); at most ``n``."""
    options = sorted(set(options))
    near = difflib.get_close_matches(name, options, n=n)
    if len(name) >= 2:
        near += [o for o in options if o not in near and _one_edit(name, o)]
    return near[:n]


def close_matches(name: str, options) -> str:
    """A hint for an unknown name: the nearest valid ones, else all of them (each once)."""
    options = list(dict.fromkeys(options))
    near = near_names(name, options)
    if near:
        return "did you mean " + ", ".join(f"'{n}'" for n in near) + "?"
    return "valid names: " + ", ".join(sorted(options)) if options else "none are defined"


__all__ = ["KronsubError", "Location", "ModelError", "Problem", "ProblemCollector", "assignment", "close_matches",
           "command_line", "given", "near_names", "on_command_line", "option", "printable"]
