"""Where kronsub keeps its caches, whether that place is safe, and what is in it.

Two caches share one folder (``$KRONSUB_CACHE_DIR``, else ``$XDG_CACHE_HOME/kronsub``, else
``~/.cache/kronsub``; ``KRONSUB_CACHE_DIR=off`` turns both off): derived known systems as
``<sha256>.system.json`` / ``<sha256>.transition.json`` (and, per scene's share,
``.inertia``, ``.inertia-transition``, ``.effect.<name>``) beside it, and compiled models under
``native/<stem>-<key>/``. A folder that another user owns or that group or others may write is
refused with a warning (someone else could plant entries there), and so is one kronsub cannot
create or write files in (probed as the cache writes: a temporary file created and removed; a
path under ``/proc``, a read-only folder): the known-system cache is then off and compiled
models go to a private temporary folder. A folder kronsub creates is private (mode 0700), so a
permissive umask does not make it refused.
"""
from __future__ import annotations

import os
import re
import shutil
import stat
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

from .atomic import clean_stale

CACHE_ENV = "KRONSUB_CACHE_DIR"

#: names of kronsub's own entries
_PART = r"(system|transition|inertia|inertia-transition|effect\.[A-Za-z_][A-Za-z0-9_.]*)"  # derive.py's parts
SYSTEM_FILE = re.compile(r"[0-9a-f]{64}\." + _PART + r"\.(json|pickle)")
NATIVE_DIR = re.compile(r"[A-Za-z0-9_]+-[0-9a-f]{24}")
INDEX_FILE = re.compile(r"[0-9a-f]{64}\.json")
TEMPORARY = re.compile(r"\.[0-9a-f]{64}\." + _PART + r"\.json\.[a-z0-9_]{8}\.tmp")


class CacheWarning(UserWarning):
    """The cache folder cannot be used safely; kronsub works without it."""


def cache_dir() -> Path | None:
    """The configured cache folder (not checked); None when the cache is off."""
    env = os.environ.get(CACHE_ENV)
    if env == "off":
        return None
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "kronsub"


def unsafe_reason(folder: Path) -> str | None:
    """Why ``folder`` (an existing path) must not hold a cache, or None when it may."""
    try:
        st = os.stat(folder)
    except OSError as exc:
        return f"it cannot be read ({exc.strerror})"
    if not stat.S_ISDIR(st.st_mode):
        return "it is not a folder"
    if st.st_uid != os.geteuid():
        return f"it belongs to another user (uid {st.st_uid})"
    if st.st_mode & 0o022:
        return f"group or others may write to it (mode {stat.S_IMODE(st.st_mode):04o})"
    key = (str(folder), st.st_dev, st.st_ino, st.st_mode)
    if key not in _WRITABLE:  # probed once per folder (and mode) in a process
        _WRITABLE[key] = unwritable_reason(folder)
    return _WRITABLE[key]


_WRITABLE: dict[tuple, str | None] = {}
PROBE = "probe"
"""The target name of the probe's temporary file, ``.probe.XXXXXXXX.tmp`` (:mod:`kronsub.atomic`'s
naming, so one left by a killed process is removed by the next probe once it is stale)."""


def unwritable_reason(folder: Path, it: str = "it") -> str | None:
    """Why kronsub cannot create files in the existing folder ``folder``, or None: probed the
    way the cache writes its entries (:func:`kronsub.atomic.atomic_file`), a temporary file
    created, written and removed (permissions alone do not tell: root may not write in ``/proc``)."""
    clean_stale(folder / PROBE)
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=f".{PROBE}.", suffix=".tmp")
    except OSError as exc:
        return f"no file can be created in {it} ({exc.strerror or exc})"
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(b"kronsub")
    except OSError as exc:
        return f"a file in {it} cannot be written ({exc.strerror or exc})"
    finally:
        try:
            os.unlink(name)
        except OSError:
            pass
    return None


def missing_reason(folder: Path) -> str | None:
    """Why the folder ``folder``, which does not exist, cannot be created, or None (probed in its
    nearest existing parent, without creating it)."""
    parent = folder.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        return f"it cannot be created: {parent} is not a folder"
    reason = unwritable_reason(parent, str(parent))
    return f"it cannot be created: {reason}" if reason else None


_WARNED: set[str] = set()


def safe_folder(folder: Path | None) -> Path | None:
    """``folder``, created if need be, when it is safe for a cache; else None with a warning."""
    if folder is None:
        return None
    try:
        if not folder.exists():  # ours: private, whatever the umask
            folder.mkdir(parents=True, exist_ok=True)
            folder.chmod(0o700)
    except OSError as exc:
        reason = f"it cannot be created ({exc.strerror or exc})"
    else:
        reason = unsafe_reason(folder)
    if reason is None:
        return folder
    if str(folder) not in _WARNED:
        _WARNED.add(str(folder))
        warnings.warn(CacheWarning(
            f"not using the cache folder {folder}: {reason}; kronsub works without it "
            f"(hint: {f'`chmod go-w {folder}`, or ' if 'group or others' in reason else ''}"
            f"set {CACHE_ENV} to a folder of your own)"))
    return None


def usable_cache_dir() -> Path | None:
    """The cache folder when it is configured and safe."""
    return safe_folder(cache_dir())


@dataclass(frozen=True)
class CacheInfo:
    folder: Path | None
    systems: int = 0
    systems_bytes: int = 0
    libraries: int = 0
    libraries_bytes: int = 0


def _size(path: Path) -> int:
    if path.is_file() and not path.is_symlink():
        return path.stat().st_size
    if path.is_dir() and not path.is_symlink():
        return sum(p.stat().st_size for p in path.iterdir() if p.is_file() and not p.is_symlink())
    return 0


def _entries(folder: Path):
    """kronsub's own entries: (known-system files, compiled-model folders)."""
    systems = sorted(p for p in folder.iterdir() if SYSTEM_FILE.fullmatch(p.name)) if folder.is_dir() else []
    native = folder / "native"
    libraries = sorted(p for p in native.iterdir() if NATIVE_DIR.fullmatch(p.name) and p.is_dir()
                       and not p.is_symlink()) if native.is_dir() else []
    return systems, libraries


def info() -> CacheInfo:
    """Where the cache is and what it holds."""
    folder = cache_dir()
    if folder is None or not folder.is_dir():
        return CacheInfo(folder)
    systems, libraries = _entries(folder)
    keys = {p.name.split(".")[0] for p in systems}
    return CacheInfo(folder, len(keys), sum(map(_size, systems)), len(libraries), sum(map(_size, libraries)))


def clear() -> int:
    """Remove kronsub's own entries (and stale temporary files) from the cache; the count removed."""
    folder = cache_dir()
    if folder is None or not folder.is_dir():
        return 0
    systems, libraries = _entries(folder)
    removed = 0
    for path in systems + [p for p in folder.iterdir() if TEMPORARY.fullmatch(p.name) and p.is_file()]:
        path.unlink(missing_ok=True)
        removed += 1
    for lib in libraries:
        shutil.rmtree(lib, ignore_errors=True)
        removed += 1
    index = folder / "native" / "index"  # compiled models by fingerprint (simulation/compiled.py)
    if index.is_dir() and not index.is_symlink():
        for path in index.iterdir():
            if INDEX_FILE.fullmatch(path.name) and path.is_file():
                path.unlink(missing_ok=True)
        try:
            index.rmdir()
        except OSError:
            pass
    try:
        (folder / "native").rmdir()
    except OSError:
        pass
    return removed
