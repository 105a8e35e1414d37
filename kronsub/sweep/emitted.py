"""The generated C of a sweep's libraries, kept: a sweep of a derived system whose C was emitted
before takes it from the cache, without SymPy's common subexpressions and printing.

An entry is kept under the sha256 of everything the emitted text depends on (:func:`key`):
kronsub's source (its templates too, :func:`kronsub.cache.code_fingerprint`), the derived system whole (its equations, names, values and initial values,
as the known-system cache writes it, :mod:`kronsub.model.cache_format`), what the caller adds
(the outputs, the Taylor integrator's order) and SymPy's version. It lives in
the folder of kept outputs (:data:`kronsub.cache.KEPT`), private and sealed
(:func:`kronsub.cache.store_entry`); one damaged, another user's or others' to read, or holding
anything but C files for this key, is not used, and the C is emitted as usual. What the files
hold is checked again where they are built (:class:`.ensemble.Sources`' sha256)."""
from __future__ import annotations

import json
import re
from collections.abc import Callable

from ..cache import KEPT, load_entry, private_folder, store_entry, usable_cache_dir
from ..core.deferred import pending
from ..model import cache_format
from ..model.derive import content_key
from ..model.kept import RECORD_BYTES, quiet_cache_dir

__all__ = ["FORMAT", "kept_files", "key"]

FORMAT = "kronsub-sweep-c/1"
_NAME = re.compile(r"[A-Za-z0-9_]+\.[ch]")  # a generated file's name: a C file or a header, no folder

Files = list[tuple[str, str]]


def key(kind: str, system, extra: str = "") -> str | None:
    """The key of the C files ``kind`` emits for ``system`` with ``extra``; None when the system
    cannot be written in the cache's format. Equations not built yet (under velocity constraints,
    ``Mbar`` and ``hbar`` in ``x``, which the generated C may form at run time) count by what they
    are built from, the transition the system carries, without building them."""
    import sympy

    unbuilt = pending(system.mass_matrix) or pending(system.velocity_terms)
    try:
        text = cache_format.dumps(system, unbuilt)
    except cache_format.CacheFormatError:
        return None
    return content_key("sweep-emitted-c", FORMAT, kind, text, extra, sympy.__version__)


def _load(folder, name: str) -> Files | None:
    text = load_entry(folder / KEPT / f"{name}.json", RECORD_BYTES)  # private, this user's, sealed; bounded
    if text is None:
        return None
    try:
        entry = json.loads(text.decode())
        files = [(str(n), str(t)) for n, t in entry["files"]]
        if entry["format"] != FORMAT or entry["key"] != name or not files or \
                not all(_NAME.fullmatch(n) and isinstance(t, str) for n, t in entry["files"]):
            return None
    except (AttributeError, KeyError, TypeError, ValueError):
        return None
    return files


def kept_files(kind: str, system, extra: str, emit: Callable[[], Files]) -> Files:
    """The C files of ``emit()``, from the cache when they were kept for the same key, else
    emitted and kept (an optimisation only: a cache that cannot be written is passed by)."""
    name = key(kind, system, extra)
    folder = quiet_cache_dir() if name is not None else None
    if folder is not None:
        files = _load(folder, name)
        if files is not None:
            return files
    files = list(emit())
    folder = usable_cache_dir() if name is not None else None
    if folder is not None:
        try:
            text = json.dumps({"format": FORMAT, "key": name, "files": files}).encode()
            if len(text) <= RECORD_BYTES:
                store_entry(private_folder(folder / KEPT) / f"{name}.json", text)
        except (OSError, ValueError):
            pass
    return files
