"""What a command made from a model file, kept so that the same command again does not read or
derive the model (no SymPy): ``derive``'s text, ``codegen``'s files, ``simulate``'s prepared run
(:mod:`kronsub.simulation.prepared`).

A record is kept under the key of everything the command's output depends on (:func:`key`):
kronsub's source (its templates and C too, :func:`kronsub.cache.code_fingerprint`), the model file's path (as given and as resolved) and bytes, the command and
its options, and what else the caller names (the compiler). It lists every
model file the model read, itself and those it takes as known systems, with the sha256 of the
bytes it read; :func:`load` returns a record only when each still has that sha256, so a model
file changed since (or between the key and the reading) is never served. Records are private
and sealed (:func:`kronsub.cache.store_entry`): one damaged, another user's or others' to read
is not used, and the command runs as usual.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from ..cache import (KEPT, cache_dir, code_fingerprint, load_entry, private_folder, store_entry, unsafe_reason,
                     usable_cache_dir)
from ..errors import KronsubError
from .file_reading import read_model_file

__all__ = ["FORMAT", "RECORD_BYTES", "key", "load", "quiet_cache_dir", "record"]

FORMAT = "kronsub-kept/1"
RECORD_BYTES = 16 << 20  # generated C of a large model fits; larger outputs are not kept


def key(command: str, model: Path, options: dict, **more) -> str | None:
    """The key of ``command`` on ``model`` with ``options`` (JSON values) and ``more``: None when
    the cache is off or the model file cannot be read."""
    if cache_dir() is None:
        return None
    try:
        _, source = read_model_file(model)
    except (KronsubError, OSError):
        return None
    parts = {"format": FORMAT, "kronsub": code_fingerprint(), "command": command, "model": str(model),
             "path": os.path.abspath(model), "sha256": source.sha256, "options": options, **more}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def quiet_cache_dir() -> Path | None:
    """The cache folder when it is configured, there and safe, with no warning (the command that
    runs after a miss gives it)."""
    folder = cache_dir()
    return folder if folder is not None and folder.is_dir() and unsafe_reason(folder) is None else None


def record(key: str, payload: dict, files) -> None:
    """Keep ``payload`` (JSON values) under ``key`` with the model files it was made from
    (:class:`~.file_reading.SourceFile` s: their paths and sha256 as read). Private and sealed;
    an optimisation only: failures are ignored."""
    folder = usable_cache_dir()
    if folder is None:
        return
    entry = {"format": FORMAT, "key": key, "files": [[os.path.abspath(f.file), f.sha256] for f in files],
             "payload": payload}
    try:
        text = json.dumps(entry, allow_nan=False).encode()
        if len(text) <= RECORD_BYTES:
            store_entry(private_folder(folder / KEPT) / f"{key}.json", text)
    except (OSError, ValueError):
        pass


def load(key: str) -> dict | None:
    """The payload kept under ``key`` when its record is sound and every model file it names
    still has its recorded sha256; else None."""
    folder = quiet_cache_dir()
    if folder is None:
        return None
    text = load_entry(folder / KEPT / f"{key}.json", RECORD_BYTES)  # private, this user's, sealed; bounded
    try:
        entry = json.loads(text.decode())
        if entry["format"] != FORMAT or entry["key"] != key or not isinstance(entry["payload"], dict):
            return None
        for name, digest in entry["files"]:
            if read_model_file(Path(name))[1].sha256 != digest:
                return None
    except (AttributeError, KeyError, TypeError, ValueError, KronsubError, OSError):
        return None
    return entry["payload"]
