"""Model files: the sections a model file may have, the files a model uses, and its content hash.

A model's cache key (:func:`model_key`) is the hash of its derivation text and, recursively, of
the model files its known systems name; reading them builds nothing.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from ..errors import ModelError
from .derive import content_key
from .file_reading import SourceFile, read_model_file
from .source import Node, load_yaml
from .uses import MAX_MODEL_DEPTH, component_models

TOP_LEVEL = ("name", "description", "parameters", "components", "coordinates", "definitions", "connection",
             "constraints", "prescribed", "velocity_constraints", "speeds", "effects", "initial", "scenes")
_SECTION_LINE = re.compile(r"^[ \t]*(?:---[ \t]*)?(?:\{[ \t]*)?[\"']?(?:" + "|".join(TOP_LEVEL) + r")[\"']?[ \t]*:",
                           re.M)


def looks_like_model(text: str) -> bool:
    """Whether a line of ``text`` begins with a model section (``name:``, ``{components:``): a
    file named by ``model:`` without one is no model, and nothing of it is quoted in messages
    (its first line may be a secret)."""
    return _SECTION_LINE.search(text) is not None


def model_key(path: Path, stack: tuple[str, ...] = (), read: list[SourceFile] | None = None) -> str:
    """The content hash of a model file and, recursively, of the model files it uses;
    ``read`` (when given) gets the :class:`SourceFile` of each file read, in that order.

    Cheap next to loading: it reads the YAML but builds nothing, so a cached
    known system is found without deriving or even constructing its model.
    """
    resolved = resolved_path(path)
    if resolved in stack or len(stack) >= MAX_MODEL_DEPTH:
        return ""  # the cycle, or the depth, is reported when the model is loaded
    text, source = read_model_file(path)
    if read is not None:
        read.append(source)
    if alone(text):
        return content_key(text)
    root = load_yaml(path, text, only={"components": {"*": {"model": None}}})
    subs = []
    for sub_path in component_models(root, path):
        try:
            subs.append(model_key(sub_path, stack + (resolved,), read))
        except ModelError:  # reported where `model:` names it, when the model is loaded
            subs.append("unreadable")
    return content_key(derivation_text(root, text), *subs)


def alone(text: str) -> bool:
    """Whether a model file plainly names no other model file and has no ``scenes:``: the
    words are nowhere in it, nor any escape (``"mod\\x65l"``) that could spell them. Its key
    is then its text's, without reading the YAML."""
    return "model" not in text and "scenes" not in text and "\\" not in text


def derivation_text(root: Node, text: str) -> str:
    """The text a derivation depends on: the file without its ``scenes:`` section, so
    editing a scene keeps the cached inertia and effects that every scene shares."""
    if not root.is_mapping or "scenes" not in root.key_locations:
        return text
    lines = text.splitlines(keepends=True)
    start = root.key_locations["scenes"].line
    after = [loc.line for loc in root.key_locations.values() if loc.line > start]
    end = min(after) if after else len(lines) + 1
    return "".join(lines[:start - 1] + lines[end - 1:])


def each_once(files: list[SourceFile]) -> tuple[SourceFile, ...]:
    """``files`` in order, each file once (the first time it was read)."""
    seen: set[str] = set()
    out = []
    for f in files:
        key = resolved_path(Path(f.file))
        if key not in seen:
            seen.add(key)
            out.append(f)
    return tuple(out)


def resolved_path(path: Path) -> str:
    """The absolute path with symbolic links followed; a loop is left for reading to report."""
    return os.path.realpath(path)


__all__ = ["TOP_LEVEL", "alone", "derivation_text", "each_once",
           "looks_like_model", "model_key", "resolved_path"]
