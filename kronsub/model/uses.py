"""The files a model uses: the model file and, level by level, the model files its known
systems name (``model:`` of a component). Reading them builds nothing (no SymPy), so a command
can list them before any work, to keep its outputs off every one of them."""
from __future__ import annotations

import os
import re
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import ModelError
from .file_reading import read_model_file

if TYPE_CHECKING:
    from .source import Node

MAX_MODEL_DEPTH = 32
"""Most levels of model files, the model given first being level 1: a known system's own
``model:`` files are one level further down."""


def component_models(root: "Node", path: Path) -> list[Path]:
    """The files named by the ``model:`` of the components in ``root`` (the model at ``path``)."""
    out = []
    comps = root.get("components")
    if comps is not None and comps.is_mapping:
        for spec in comps.value.values():
            mnode = spec.get("model") if spec.is_mapping else None
            if mnode is not None and isinstance(mnode.value, str) and mnode.value and "\0" not in mnode.value:
                out.append(path.parent / mnode.value)
    return out


def names_no_model(text: str) -> bool:
    """Whether a model file plainly names no other model file: the word is nowhere in it, nor
    any escape (``"mod\\x65l"``) that could spell it."""
    return "model" not in text and "\\" not in text


_NAMED = re.compile(r"""(?:^|[\s{,])["']?model["']?[ \t]*:[ \t]*(?P<value>[^\n#,}]*)""")


def named_plainly(text: str) -> list[str] | None:
    """The values of the ``model:`` keys of ``text`` when each is a plain or quoted scalar on its
    line (``model: machine.yaml``, ``{model: "m.yaml"}``), read without YAML; None when one is
    not (an alias, a tag, a block, an escape): then YAML reads them."""
    if "\\" in text:
        return None
    values = []
    for found in _NAMED.finditer(text):
        value = found.group("value").strip()
        if len(value) >= 2 and value[0] == value[-1] and value[0] in "\"'":
            value = value[1:-1]
        elif not value or value[0] in "*&!|>[{\"'%@`":
            return None
        values.append(value)
    return values


def model_files(path: Path) -> list[Path]:
    """``path`` and every model file it uses, each once, in the order read; a file that cannot
    be read or parsed is listed and not looked into (loading the model reports it). YAML reads
    only a file whose ``model:`` values are not plain (:func:`named_plainly`)."""
    out: list[Path] = []
    seen: set[str] = set()

    def visit(file: Path, depth: int) -> None:
        resolved = os.path.realpath(file)
        if resolved in seen or depth > MAX_MODEL_DEPTH:
            return
        seen.add(resolved)
        out.append(file)
        try:
            text, _ = read_model_file(file)
            if names_no_model(text):
                return
            plain = named_plainly(text)
            if plain is not None:
                subs = [file.parent / value for value in plain if value and "\0" not in value]
            else:
                from .source import load_yaml  # (only here: a command served from what it kept reads no YAML)

                subs = component_models(load_yaml(file, text, only={"components": {"*": {"model": None}}}), file)
        except (ModelError, OSError, RecursionError):
            return
        for sub in subs:
            visit(sub, depth + 1)

    visit(Path(path), 1)
    return out


__all__ = ["MAX_MODEL_DEPTH", "component_models", "model_files", "named_plainly", "names_no_model"]
