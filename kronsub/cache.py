"""Where kronsub keeps its caches, whether that place is safe, and what is in it.

The caches share one folder (``$KRONSUB_CACHE_DIR``, else ``$XDG_CACHE_HOME/kronsub``, else
``~/.cache/kronsub``; ``KRONSUB_CACHE_DIR=off`` turns them off): derived known systems as
``<sha256>.system.json`` / ``<sha256>.transition.json`` (and, per scene's share,
``.inertia``, ``.inertia-transition``, ``.effect.<name>``) beside it, and compiled models under
``native/<stem>-<key>/`` (indexed in ``native/index/``), and what commands made from a model
file (:mod:`kronsub.model.kept`) as ``kept/<sha256>.json``. A folder that another user owns
or that group or others may write is refused with a warning (someone else could plant entries
there), and so is one kronsub cannot create or write files in (probed as the cache writes: a
temporary file created and removed; a path under ``/proc``, a read-only folder): the
known-system cache is then off and compiled models go to a private temporary folder. A folder
kronsub creates is private (mode 0700), so a permissive umask does not make it refused.

Entries are private whatever the umask (files 0600, folders 0700: :func:`write_private`,
:func:`private_folder`) and sealed with the sha256 of their payload (:func:`store_entry`);
:func:`load_entry` reads one only when it is a private regular file of this user, opened
without following a link or waiting on a FIFO and at most :data:`ENTRY_BYTES` long, whose
digest matches. :func:`entries` lists kronsub's own entries by ``lstat`` for both
:func:`info` and :func:`clear`, which never follows a link out of the folder.
"""
from __future__ import annotations

import errno
import hashlib
import hmac
import os
import re
import shutil
import stat
import tempfile
import warnings
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from .atomic import clean_stale
from .version import __version__

CACHE_ENV = "KRONSUB_CACHE_DIR"

#: names of kronsub's own entries
_PART = r"(system|transition|inertia|inertia-transition|effect\.[A-Za-z_][A-Za-z0-9_.]*)"  # derive.py's parts
SYSTEM_FILE = re.compile(r"[0-9a-f]{64}\." + _PART + r"\.(json|pickle)")
NATIVE_DIR = re.compile(r"[A-Za-z0-9_]+-[0-9a-f]{24}")
INDEX_FILE = re.compile(r"[0-9a-f]{64}\.json")
TEMPORARY = re.compile(r"\.[0-9a-f]{64}\." + _PART + r"\.json\.[a-z0-9_]{8}\.tmp")
TEMPORARY_INDEX = re.compile(r"\.[0-9a-f]{64}\.json\.[a-z0-9_]{8}\.tmp")
LIBRARY_FILE = re.compile(r"lib[A-Za-z0-9_]+\.so")  # a compiled model in its native/ folder
KEPT = "kept"  # the folder of kept outputs (kronsub.model.kept), named like the index: <sha256>.json


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


def code_fingerprint() -> str:
    """A hash of kronsub's own source (its Python, its C and its templates, which may be
    installed apart from the package) and version, part of every key derived from a model, so a
    changed kronsub never reads a stale entry."""
    global _FINGERPRINT
    if _FINGERPRINT is None:
        digest = hashlib.sha256(__version__.encode())
        package = Path(__file__).resolve().parent
        sources = [path for path in package.rglob("*") if path.suffix in SOURCE_SUFFIXES and path.is_file()]
        for path in sorted(sources):
            digest.update(str(path.relative_to(package)).encode())
            digest.update(path.read_bytes())
        templates = resources.files("kronsub.templates")
        for item in sorted((t for t in templates.iterdir() if t.name.endswith(".j2")), key=lambda t: t.name):
            digest.update(f"templates/{item.name}".encode())
            digest.update(item.read_bytes())
        _FINGERPRINT = digest.hexdigest()
    return _FINGERPRINT


SOURCE_SUFFIXES = (".py", ".c", ".h", ".j2")
"""What counts as kronsub's source in :func:`code_fingerprint`."""


_FINGERPRINT: str | None = None


# ---------------------------------------------------------------------------------------------
# Entries: private, sealed with a digest, read bounded
# ---------------------------------------------------------------------------------------------

SEAL = b"kronsub-cache/1 sha256="
"""The first line of every entry kronsub writes: the sha256 of the rest, recorded at write time."""
ENTRY_BYTES = 64 << 20  # the most an entry may hold (a derived system is far smaller)


def private_folder(folder: Path) -> Path:
    """``folder`` (in an existing one), a real folder of this user, mode 0700 whatever the
    umask; raises :class:`OSError` when it is a link, not a folder, or another user's."""
    try:
        os.mkdir(folder, 0o700)
    except FileExistsError:
        pass
    st = os.lstat(folder)
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid():
        raise OSError(errno.EPERM, "not a folder of this user", str(folder))
    if stat.S_IMODE(st.st_mode) != 0o700:
        os.chmod(folder, 0o700)
    return folder


def write_private(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` (mode 0600 whatever the umask) through a temporary file of
    :mod:`kronsub.atomic`'s naming and a rename."""
    clean_stale(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def store_entry(path: Path, payload: bytes) -> None:
    """Write a cache entry: :data:`SEAL`, the payload's sha256, then the payload (private)."""
    write_private(path, SEAL + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)


def read_private(path: Path, limit: int = ENTRY_BYTES) -> bytes | None:
    """The bytes of ``path`` when it is a regular file of this user that no one else may
    write or read (no link followed, no FIFO waited on, at most ``limit`` bytes); else None."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid() or st.st_mode & 0o077 \
                or st.st_size > limit:
            return None
        chunks, left = [], limit + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        data = b"".join(chunks)
        return data if len(data) <= limit else None
    except OSError:
        return None
    finally:
        os.close(fd)


def load_entry(path: Path, limit: int = ENTRY_BYTES) -> bytes | None:
    """The payload of an entry written by :func:`store_entry`, when it is private and its
    digest matches; else None (the caller rebuilds it)."""
    data = read_private(path, limit + 100)
    if data is None or not data.startswith(SEAL):
        return None
    line, _, payload = data.partition(b"\n")
    recorded = line[len(SEAL):]
    if len(payload) > limit or not hmac.compare_digest(recorded, hashlib.sha256(payload).hexdigest().encode()):
        return None
    return payload


# ---------------------------------------------------------------------------------------------
# What the cache holds (one listing for `cache info` and `cache clear`)
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CacheInfo:
    folder: Path | None
    systems: int = 0
    systems_bytes: int = 0
    libraries: int = 0
    libraries_bytes: int = 0
    kept: int = 0
    kept_bytes: int = 0


@dataclass(frozen=True)
class Entries:
    """kronsub's own entries in a cache folder, none reached through a link."""
    systems: dict  # key -> the files of one derived model (system, transition, parts)
    libraries: list  # compiled-model folders under native/
    index: list  # native/index/*.json
    temporaries: list  # temporary files of interrupted writes
    links: list  # links (FIFOs, sockets) named like entries: removed as themselves, never followed
    kept: list = field(default_factory=list)  # kept outputs, kept/*.json (and their temporary files)


def _lstat(path: Path):
    try:
        return os.lstat(path)
    except OSError:
        return None


def _listing(folder: Path) -> list[tuple[str, os.stat_result]]:
    try:
        names = os.listdir(folder)
    except OSError:
        return []
    return [(name, st) for name in sorted(names) if (st := _lstat(folder / name)) is not None]


def _real_folder(path: Path) -> bool:
    st = _lstat(path)
    return st is not None and stat.S_ISDIR(st.st_mode)


def _odd(st: os.stat_result) -> bool:
    """A link, FIFO, socket or device where an entry should be: removed as itself by ``clear``."""
    return not stat.S_ISREG(st.st_mode) and not stat.S_ISDIR(st.st_mode)


def entries(folder: Path) -> Entries:
    """List kronsub's own entries in ``folder`` by name and kind (``lstat``: a link is never
    followed; a link named like an entry is listed under ``links``)."""
    found = Entries({}, [], [], [], [])
    if not folder.is_dir():  # the folder the user configured (a link to one is the user's choice)
        return found
    for name, st in _listing(folder):
        path = folder / name
        if SYSTEM_FILE.fullmatch(name) or TEMPORARY.fullmatch(name):
            if _odd(st):
                found.links.append(path)
            elif stat.S_ISREG(st.st_mode):
                if SYSTEM_FILE.fullmatch(name):
                    found.systems.setdefault(name.split(".")[0], []).append(path)
                else:
                    found.temporaries.append(path)
    kept = folder / KEPT
    if _real_folder(kept):
        for name, st in _listing(kept):
            if INDEX_FILE.fullmatch(name) or TEMPORARY_INDEX.fullmatch(name):
                (found.links if _odd(st) else found.kept if stat.S_ISREG(st.st_mode) else []).append(kept / name)
    native = folder / "native"
    if not _real_folder(native):
        return found
    for name, st in _listing(native):
        if NATIVE_DIR.fullmatch(name):
            (found.links if _odd(st) else found.libraries if stat.S_ISDIR(st.st_mode)
             else []).append(native / name)
    index = native / "index"
    if _real_folder(index):
        for name, st in _listing(index):
            if INDEX_FILE.fullmatch(name) or TEMPORARY_INDEX.fullmatch(name):
                (found.links if _odd(st) else found.index if stat.S_ISREG(st.st_mode) else []).append(index / name)
    return found


def _size(path: Path) -> int:
    st = _lstat(path)
    if st is None or stat.S_ISLNK(st.st_mode):
        return 0
    if stat.S_ISREG(st.st_mode):
        return st.st_size
    return sum(s.st_size for _, s in _listing(path) if stat.S_ISREG(s.st_mode)) if stat.S_ISDIR(st.st_mode) else 0


def info() -> CacheInfo:
    """Where the cache is and what it holds: derived models (by key) and compiled models."""
    folder = cache_dir()
    if folder is None or not folder.is_dir():
        return CacheInfo(folder)
    found = entries(folder)
    files = [p for group in found.systems.values() for p in group]
    kept = [p for p in found.kept if INDEX_FILE.fullmatch(p.name)]
    return CacheInfo(folder, len(found.systems), sum(map(_size, files)), len(found.libraries),
                     sum(map(_size, found.libraries)), len(kept), sum(map(_size, kept)))


def _inside(path: Path, root: Path) -> bool:
    try:
        return Path(os.path.realpath(path)).is_relative_to(root) and Path(os.path.realpath(path)) != root
    except OSError:
        return False


def clear() -> CacheInfo:
    """Remove kronsub's own entries (and stale temporary files) from the cache: what was
    removed, counted as :func:`info` counts. Nothing outside the cache folder is touched: no
    link is followed (a link named like an entry is removed as a link), and a compiled model's
    folder is removed only when it is a real folder inside the cache."""
    folder = cache_dir()
    if folder is None or not folder.is_dir():
        return CacheInfo(folder)
    root = Path(os.path.realpath(folder))
    found = entries(folder)
    before = info()
    for path in [p for group in found.systems.values() for p in group] + found.temporaries + found.index \
            + found.kept + found.links:
        try:
            os.unlink(path)  # a link itself, never what it points to
        except OSError:
            pass
    for lib in found.libraries:
        if _real_folder(lib) and _inside(lib, root):
            shutil.rmtree(lib, ignore_errors=True)  # (rmtree does not follow links inside)
    for sub in (folder / "native" / "index", folder / "native", folder / KEPT):
        if _real_folder(sub):
            try:
                sub.rmdir()
            except OSError:
                pass
    return before


__all__ = ["CACHE_ENV", "CacheInfo", "CacheWarning", "ENTRY_BYTES", "Entries", "INDEX_FILE", "LIBRARY_FILE",
           "NATIVE_DIR", "PROBE", "KEPT", "SEAL", "SYSTEM_FILE", "TEMPORARY", "TEMPORARY_INDEX", "cache_dir", "clear",
           "code_fingerprint", "entries", "info", "load_entry", "missing_reason", "private_folder", "read_private",
           "safe_folder", "store_entry", "unsafe_reason", "unwritable_reason", "usable_cache_dir", "write_private"]
