"""Writing output files: a regular file atomically (a temporary file beside it, then a rename),
anything else in its own way, and never a device, a FIFO or a link replaced by a regular file.

:func:`output_target` decides how a path is written. A new path or a regular file is written
through a temporary file of kronsub's own naming, ``dir/.name.XXXXXXXX.tmp`` (eight characters of
:func:`tempfile.mkstemp`; a long name shortened to fit :data:`NAME_MAX`), renamed over it; a
regular file in a folder no file can be created in, but that may itself be written, is written
in place. A symbolic link is followed: its target is
written by those rules and the link stays. A FIFO or a character device (``/dev/null``,
``/dev/stdout``) is opened and written directly. A folder, a socket or a block device is refused
with an :class:`OSError` naming the path. A write that fails removes its temporary file and
names the path the user gave; a process killed mid-write leaves the temporary file behind, and
the next write of the same target removes such files when they are older than
:data:`STALE_AFTER` seconds. The finished file gets the mode an ordinary ``open`` would give it
(the user's umask), or keeps the mode of the file it replaces.
"""
from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import stat
import tempfile
import time
from pathlib import Path

STALE_AFTER = 600.0  # seconds: an older temporary file of ours belongs to no running write
_RANDOM = "[a-z0-9_]{8}"  # what mkstemp puts between prefix and suffix

FILE, STREAM = "file", "stream"
"""How :func:`output_target` says a path is written: through a temporary file, or directly."""


NAME_MAX = 255
"""Longest name of a file, in bytes (the usual file systems'): a temporary file's name is kept
within it however long the target's (:func:`temporary_stem`)."""


def temporary_stem(name: str, tail: str = ".tmp") -> str:
    """``name``, shortened (by its last characters) so that a temporary file's name,
    ``.STEM.XXXXXXXX`` and ``tail``, fits :data:`NAME_MAX` bytes."""
    room = NAME_MAX - len(os.fsencode(tail)) - 10
    stem = name
    while stem and len(os.fsencode(stem)) > room:
        stem = stem[:-1]
    return stem


def temporary_pattern(name: str) -> re.Pattern:
    """The names of kronsub's temporary files for the target ``name`` (``.tmp``, or ``.tmp``
    and the target's own suffix for a writer that needs it, :func:`atomic_path`)."""
    suffix = Path(name).suffix
    plain = rf"\.{re.escape(temporary_stem(name))}\.{_RANDOM}\.tmp"
    if not suffix:
        return re.compile(plain)
    return re.compile(rf"{plain}|\.{re.escape(temporary_stem(name, '.tmp' + suffix))}\.{_RANDOM}\.tmp"
                      rf"{re.escape(suffix)}")


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


def umask() -> int:
    """The process's umask (read without changing it where ``/proc`` tells)."""
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


def final_mode(path: Path) -> int:
    """The mode a write of ``path`` leaves: the replaced file's, else what ``open`` would give."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~umask()


_KINDS = ((stat.S_ISDIR, errno.EISDIR, "is a folder, not a file"),
          (stat.S_ISSOCK, errno.EOPNOTSUPP, "is a socket; kronsub writes files, FIFOs and character devices"),
          (stat.S_ISBLK, errno.EOPNOTSUPP, "is a block device; kronsub writes files, FIFOs and character devices"))


def _followed(path: Path) -> Path | None:
    """Where the symbolic link ``path`` leads, link by link (the last component is no link);
    None through ``/proc`` (``/dev/stdout``, ``/dev/fd/N``: the kernel's own links, written in
    place) or a loop."""
    for _ in range(40):
        if _in_proc(path) or _in_proc(Path(os.path.realpath(path.parent))):
            return None
        try:
            target = os.readlink(path)
        except OSError:  # not a link (any more): there
            return path
        path = Path(os.path.normpath(path.parent / target))  # (absolute targets stay absolute)
    return None


def _in_proc(path: Path) -> bool:
    return str(path) == "/proc" or str(path).startswith("/proc/")


def output_target(path: Path) -> tuple[str, Path]:
    """``(how, where)``: :data:`FILE` for a new path or a regular file (``where`` a symbolic
    link's target), :data:`STREAM` for a FIFO, a character device or a file reached through
    ``/proc`` (``/dev/stdout`` redirected to a file: written in place, as the shell opened it).
    Raises :class:`OSError` naming ``path`` for anything else (a folder, a socket, a block
    device, a link loop)."""
    path = Path(path)
    where = path
    try:
        st = os.lstat(path)
        if stat.S_ISLNK(st.st_mode):
            followed = _followed(path)
            st = os.stat(path)  # the kernel's own resolution
            if followed is None or not _same(followed, st):  # (only a rename needs the link's target)
                return (STREAM, path) if stat.S_ISREG(st.st_mode) or _streamed(st) else _refused(path, st)
            where = followed
    except FileNotFoundError:  # a new file (a dangling link: its target)
        followed = _followed(path) if path.is_symlink() else path
        if followed is None:
            raise OSError(errno.ENOENT, "No such file or directory", str(path)) from None
        return FILE, followed
    except OSError as exc:
        raise type(exc)(exc.errno, exc.strerror or str(exc), str(path)) from None
    if stat.S_ISREG(st.st_mode):
        return FILE, where
    if _streamed(st):
        return STREAM, path
    return _refused(path, st)


def _same(path: Path, st: os.stat_result) -> bool:
    try:
        return os.path.samestat(os.stat(path), st)
    except OSError:
        return False


def _streamed(st: os.stat_result) -> bool:
    return stat.S_ISFIFO(st.st_mode) or stat.S_ISCHR(st.st_mode)


def _refused(path: Path, st: os.stat_result):
    for test, code, why in _KINDS:
        if test(st.st_mode):
            raise OSError(code, why, str(path))
    raise OSError(errno.EOPNOTSUPP, "is not a file kronsub can write", str(path))


def _named(exc: OSError, path: Path, *temporary) -> OSError:
    """The error naming the user's ``path`` (a failed write names no file, a rename the
    temporary one)."""
    if exc.filename and str(exc.filename) not in map(str, temporary):
        return exc
    return type(exc)(exc.errno, exc.strerror or str(exc), str(path))


def cannot_create(exc: OSError, path: Path) -> OSError:
    """A failure to create a file beside ``path``, named after ``path`` (not the temporary file)."""
    folder = path.parent if str(path.parent) else Path(".")
    return type(exc)(exc.errno, f"cannot create a file in {folder} ({exc.strerror or exc})", str(path))


def _open_mode(binary: bool) -> tuple[str, dict]:
    return ("wb", {}) if binary else ("w", {"encoding": "utf-8", "newline": "\n"})


@contextlib.contextmanager
def _direct(path: Path, shown: Path, binary: bool):
    """``path`` opened and written in place (a FIFO, a device, a file no temporary can go beside)."""
    mode, kwargs = _open_mode(binary)
    try:
        with open(path, mode, **kwargs) as fh:
            yield fh
    except OSError as exc:
        raise _named(exc, shown, path) from None


def _temporary(where: Path, shown: Path, suffix: str = "") -> tuple[int, str] | None:
    """A new temporary file beside ``where``; None when none can be created but ``where`` is a
    regular file that may be written in place."""
    folder = where.parent if str(where.parent) else Path(".")
    clean_stale(where)
    try:
        return tempfile.mkstemp(dir=folder, prefix=f".{temporary_stem(where.name, '.tmp' + suffix)}.",
                                suffix=f".tmp{suffix}")
    except OSError as exc:
        if where.is_file() and os.access(where, os.W_OK):
            return None
        raise cannot_create(exc, shown) from None


@contextlib.contextmanager
def atomic_file(path: Path, binary: bool = False):
    """A file handle whose content becomes ``path``'s when the block ends without an exception
    (see :func:`output_target` for how each kind of path is written).

    On an exception the temporary file is removed and the exception raised again (an
    ``OSError`` then names ``path``). A caller that wants a partial file kept catches the
    exception inside the block, finishes the file and raises after it.
    """
    path = Path(path)
    how, where = output_target(path)
    made = _temporary(where, path) if how == FILE else None
    if made is None:
        with _direct(where, path, binary) as fh:
            yield fh
        return
    fd, tmp = made
    try:
        mode, kwargs = _open_mode(binary)
        with os.fdopen(fd, mode, **kwargs) as fh:
            yield fh
        os.chmod(tmp, final_mode(where))
        os.replace(tmp, where)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise _named(exc, path, tmp, where) from None
        raise


@contextlib.contextmanager
def atomic_path(path: Path):
    """A temporary file's name, ending in ``path``'s suffix, for a writer that wants a name
    (matplotlib's animation writers); when the block ends its content becomes ``path``'s as
    with :func:`atomic_file` (renamed over a regular file, copied into a FIFO or a device)."""
    path = Path(path)
    how, where = output_target(path)
    made = _temporary(where, path, path.suffix) if how == FILE else None
    if made is None:  # written elsewhere (a private temporary file), then copied
        fd, tmp = tempfile.mkstemp(prefix="kronsub-", suffix=path.suffix)
    else:
        fd, tmp = made
    os.close(fd)
    try:
        yield Path(tmp)
        if made is None:
            with open(tmp, "rb") as src, _direct(where, path, True) as dst:
                shutil.copyfileobj(src, dst)
        else:
            os.chmod(tmp, final_mode(where))
            os.replace(tmp, where)
    except OSError as exc:
        raise _named(exc, path, tmp, where) from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def write_atomically(path: Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` as :func:`atomic_file` does."""
    with atomic_file(path, binary=isinstance(data, bytes)) as fh:
        fh.write(data)


__all__ = ["NAME_MAX", "STALE_AFTER", "atomic_file", "atomic_path", "cannot_create", "clean_stale", "final_mode",
           "output_target", "temporary_pattern", "temporary_stem", "umask", "write_atomically"]
