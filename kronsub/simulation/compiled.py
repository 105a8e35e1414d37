"""The compiled model of a known system, found by its equations' fingerprint.

Emitting C (common subexpressions over every entry) costs far more than compiling it, and
far more than deriving from the cache; so a compiled library is indexed by a fingerprint of
the equations themselves (their cache-format text, :mod:`kronsub.model.cache_format`), the
outputs asked for, the integrators' sources and the compiler, and a run whose fingerprint
is indexed loads the library without emitting a line. The index holds names and digests
only: the library it names is loaded only when its bytes match both the digest recorded
in the index and its sidecar (:func:`.native.verified`); otherwise it is emitted and built
anew.
"""
from __future__ import annotations

import dataclasses
import json
import re
import shutil
from pathlib import Path

from ..atomic import write_atomically
from ..core.known_system import KnownSystem
from . import native

_FOLDER = re.compile(r"[A-Za-z0-9_]+-[0-9a-f]{24}")
_LIBRARY = re.compile(r"lib[A-Za-z0-9_]+\.so")


def fingerprint(system: KnownSystem, outputs=None) -> str | None:
    """sha256 of what the generated C computes: the equations (without the names, texts,
    parameter values and initial values that only its comments and defaults show), the
    outputs, the integrators and the compiler; None when the system cannot be fingerprinted."""
    from ..model import cache_format
    from ..model.derive import content_key

    bare = dataclasses.replace(
        system, name="", description="", initial={}, transition=None,
        parameters=tuple(dataclasses.replace(p, value=None, description="", unit="") for p in system.parameters))
    try:
        text = cache_format.dumps(bare)
    except cache_format.CacheFormatError:
        return None
    command = native.compiler_command()
    parts = [text, repr(outputs), *native.build_identity(), shutil.which(command[0]) or command[0], *command[1:]]
    parts += [(native.CSRC / name).read_text() for name in native.INTEGRATOR_FILES]
    return content_key("compiled-model", *parts)


def _index_file(key: str) -> Path:
    return native._build_root() / "index" / f"{key}.json"


def lookup(key: str) -> Path | None:
    """The verified library indexed under ``key``, or None."""
    try:
        entry = json.loads(_index_file(key).read_text(encoding="utf-8"))
        folder, name, digest = entry["folder"], entry["library"], entry["sha256"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not (isinstance(folder, str) and _FOLDER.fullmatch(folder) and isinstance(name, str)
            and _LIBRARY.fullmatch(name) and isinstance(digest, str)):
        return None
    library = native._build_root() / folder / name
    try:
        recorded = native.sidecar(library).read_text(encoding="ascii").strip()
    except (OSError, UnicodeError):
        return None
    return library if recorded == digest and native.verified(library) else None


def record(key: str, library: Path) -> None:
    """Index ``library`` under ``key`` (an optimisation only: failures are ignored)."""
    try:
        digest = native.sidecar(library).read_text(encoding="ascii").strip()
        index = _index_file(key)
        index.parent.mkdir(exist_ok=True)
        entry = {"folder": library.parent.name, "library": library.name, "sha256": digest}
        write_atomically(index, json.dumps(entry, sort_keys=True))
    except (OSError, UnicodeError):
        pass


def compiled_library(system: KnownSystem, outputs=None) -> Path:
    """The shared library of ``system``'s generated C with the integrators: from the index
    when its fingerprint is there, else emitted, built (:func:`.native.compile_library`) and
    indexed. Raises what ``compile_library`` raises."""
    from ..emitters.code import emit_c

    key = fingerprint(system, outputs)
    if key is not None:
        library = lookup(key)
        if library is not None:
            return library
    generated = [(g.name, g.text) for g in emit_c(system, "model", outputs=outputs)]
    library = native.compile_library(generated, "model")
    if key is not None:
        record(key, library)
    return library
