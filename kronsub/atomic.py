"""Writing files atomically: a temporary file of kronsub's own naming beside the target, then a rename.

The temporary file of ``dir/name`` is ``dir/.name.XXXXXXXX.tmp`` (eight characters of
:func:`tempfile.mkstemp`). A write that fails removes it and names the target in its error; a
process killed mid-write leaves it behind, and the next write of the same target removes such
files when they are older than :data:`STALE_AFTER` seconds (they belong to no running write).
The finished file gets the mode an ordinary ``open`` would give it (the user's umask), or keeps
the mode of the file it replaces.
"""
from __future__ import annotations

import contextlib
import os
import re
import stat
import tempfile
import time
from pathlib import Path

STALE_AFTER = 600.0  # seconds: an older temporary file of ours belongs to no running write
_RANDOM = "[a-z0-9_]{8}"  # what mkstemp puts between prefix and suffix


def temporary_pattern(name: str) -> re.Pattern:
    """The names of kronsub's temporary files for the target ``name``."""
    return re.compile(rf"\.{re.escape(name)}\.{_RANDOM}\.tmp")


def clean_stale(path: Path, age: float = STALE_AFTER) -> list[Path]:
    """Remove stale temporary files of ``path`` (ours by name and owner, older than ``age`` s)."""
    path = Path(path)
    pattern = temporary_pattern(path.name)
    removed = []
    now = time.time()
    try:
        entries = list(os.scandir(path.parent if str(path.parent) else "."))
    except OSError:
        return removed
    for entry in entries:
        if not pattern.fullmatch(entry.name):
            continue
        try:
            st = entry.stat(follow_symlinks=False)
            if stat.S_ISREG(st.st_mode) and st.st_uid == os.geteuid() and now - st.st_mtime > age:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


def _umask() -> int:
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _final_mode(path: Path) -> int:
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~_umask()


def _named(exc: OSError, path: Path) -> OSError:
    """The error with the target's path (a failed write names no file)."""
    if exc.filename:
        return exc
    return type(exc)(exc.errno, exc.strerror or str(exc), str(path))


def cannot_create(exc: OSError, path: Path) -> OSError:
    """A failure to create a file beside ``path``, named after ``path`` (not the temporary file)."""
    folder = path.parent if str(path.parent) else Path(".")
    return type(exc)(exc.errno, f"cannot create a file in {folder} ({exc.strerror or exc})", str(path))


@contextlib.contextmanager
def atomic_file(path: Path, binary: bool = False):
    """A file handle whose content replaces ``path`` when the block ends without an exception.

    On an exception the temporary file is removed and the exception raised again (an
    ``OSError`` then names ``path``). A caller that wants a partial file kept catches the
    exception inside the block, finishes the file and raises after it.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    clean_stale(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise cannot_create(exc, path) from None
    try:
        mode = "wb" if binary else "w"
        kwargs = {} if binary else {"encoding": "utf-8", "newline": "\n"}
        with os.fdopen(fd, mode, **kwargs) as fh:
            yield fh
        os.chmod(tmp, _final_mode(path))
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise _named(exc, path) from None
        raise


def write_atomically(path: Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename."""
    with atomic_file(path, binary=isinstance(data, bytes)) as fh:
        fh.write(data)
