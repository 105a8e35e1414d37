"""Reading the files a user names (model files, trajectories): safely and bounded.

Only a regular file is read (never a directory, device, FIFO or socket, nor a file under
``/proc`` or ``/sys``), at most a given number of bytes, as UTF-8; every failure is a
:class:`~kronsub.errors.ModelError` located where the file was named. A model file is also
hashed as read (:class:`SourceFile`: what a run's results depend on).
"""
from __future__ import annotations

import errno
import hashlib
import os
import stat
from dataclasses import dataclass
from pathlib import Path

from ..errors import Location, ModelError, Problem


MAX_MODEL_BYTES = 1 << 20
"""Largest model file read, in bytes (1 MiB); checked before the file is parsed."""

_PSEUDO_FILESYSTEMS = ("/proc", "/sys")
_KIND_OF_MODE = ((stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"),
                 (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                 (stat.S_ISSOCK, "a socket"))


@dataclass(frozen=True)
class SourceFile:
    """A model file as read: its path as named and the SHA-256 of its bytes (what a run's
    results depend on, recorded in its metadata)."""

    file: str
    sha256: str


def read_model_file(path: Path, where: Location | None = None) -> tuple[str, SourceFile]:
    """The text of a model file and its :class:`SourceFile`, read only if it is a regular file
    of at most `MAX_MODEL_BYTES`; else a `ModelError` at ``where`` (default: the file itself).

    The file is checked with ``stat`` before it is opened, opened non-blocking
    and checked again on the open descriptor, so a device, FIFO, socket or
    ``/proc`` file is never read and nothing here can block.
    """
    where = where or Location(str(path))
    _check_not_system(path, where)
    data, info = _read_checked(path, where, MAX_MODEL_BYTES, lambda info: _check_regular(path, info, where))
    if len(data) > MAX_MODEL_BYTES:
        raise _too_large(path, len(data), where)
    if data and info.st_size == 0:
        raise _file_error(where, path, "reports a size of 0 but has content: it is not a regular model file",
                          "give the path of a .yaml model file on disk")
    return _decoded(data, path), SourceFile(str(path), hashlib.sha256(data).hexdigest())


def read_model_text(path: Path, where: Location | None = None) -> str:
    """The text of a model file (:func:`read_model_file`)."""
    return read_model_file(path, where)[0]


def _read_checked(path: Path, where: Location, limit: int, check) -> tuple[bytes, os.stat_result]:
    """At most ``limit + 1`` bytes of ``path`` and its ``stat``: ``check(stat)`` (which raises)
    before opening and again on the open descriptor (the file read is the one checked), opened
    non-blocking so that nothing here can wait; an ``OSError`` is a `ModelError` at ``where``."""
    try:
        check(os.stat(path))
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0))
        try:
            info = os.fstat(fd)
            check(info)
            return _read_at_most(fd, limit + 1), info
        finally:
            os.close(fd)
    except OSError as exc:
        raise _os_error(path, exc, where) from None


def _decoded(data: bytes, path: Path, hint: str = "save the file with UTF-8 encoding") -> str:
    """``data`` as UTF-8 text (a byte-order mark dropped); invalid bytes are a `ModelError` at
    their line and column."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise ModelError([Problem(
            Location(str(path), line, column),
            f"the file is not valid UTF-8 text (byte 0x{data[exc.start]:02x})",
            hint)]) from None


def read_user_text(path: Path, kind: str, limit: int = 1 << 30) -> str:
    """The UTF-8 text of a file given on the command line that is not a model (a trajectory CSV,
    a ``--check`` file), with the same guards as :func:`read_model_text`: a regular file of at
    most ``limit`` bytes, opened non-blocking (a FIFO or a device never hangs or floods);
    ``kind`` names it in the hints. Problems are a `ModelError` at the file."""
    where = Location(str(path))
    hint = f"give the path of a {kind} on disk"

    def check(info: os.stat_result) -> None:
        for test, what in _KIND_OF_MODE:
            if test(info.st_mode):
                raise _file_error(where, path, f"is {what}, not a regular file", hint)
        if not stat.S_ISREG(info.st_mode):
            raise _file_error(where, path, "is not a regular file", hint)

    data, _ = _read_checked(path, where, limit, check)
    if len(data) > limit:
        raise _file_error(where, path, f"is too large (more than {limit:,} bytes)", f"check the path: {hint}")
    return _decoded(data, path, f"{hint}, saved as UTF-8")


def system_root(path: Path) -> str | None:
    """``/proc`` or ``/sys`` when ``path`` (links followed) lies under it, by its name alone: one
    missing there (``/proc/kcore`` in a container) is a system path all the same."""
    resolved = os.path.realpath(path)
    return next((root for root in _PSEUDO_FILESYSTEMS if resolved == root or resolved.startswith(root + os.sep)),
                None)


def _check_not_system(path: Path, where: Location) -> None:
    """Refuse a path under /proc or /sys (:func:`system_root`) before it is looked at."""
    root = system_root(path)
    if root is not None:
        raise _file_error(where, path, f"is a system file under {root}, not a model file",
                          "give the path of a .yaml model file")


def _check_regular(path: Path, info: os.stat_result, where: Location) -> None:
    """Refuse anything but a regular file of at most `MAX_MODEL_BYTES` outside /proc and /sys."""
    for test, kind in _KIND_OF_MODE:
        if test(info.st_mode):
            hint = "give the path of a .yaml model file" if kind == "a directory" \
                else "a model must be a regular file: save it to disk first"
            raise _file_error(where, path, f"is {kind}, not a regular file", hint)
    if not stat.S_ISREG(info.st_mode):
        raise _file_error(where, path, "is not a regular file", "give the path of a .yaml model file")
    for root in _PSEUDO_FILESYSTEMS:
        try:
            if os.stat(root).st_dev == info.st_dev:
                raise _file_error(where, path, f"is a system file under {root}, not a model file",
                                  "give the path of a .yaml model file")
        except OSError:
            continue
    if info.st_size > MAX_MODEL_BYTES:
        raise _too_large(path, info.st_size, where)


def _read_at_most(fd: int, limit: int) -> bytes:
    chunks, size = [], 0
    while size < limit:
        try:
            chunk = os.read(fd, min(1 << 16, limit - size))
        except BlockingIOError:  # a file that would block is no model file
            break
        if not chunk:
            break
        chunks.append(chunk)
        size += len(chunk)
    return b"".join(chunks)


def _too_large(path: Path, size: int, where: Location) -> ModelError:
    return _file_error(where, path, f"is too large ({size:,} bytes; a model file may have at most "
                                    f"{MAX_MODEL_BYTES:,} bytes)",
                       "split the model into known systems (`model:` files), or check the path")


_OS_ERRORS = {
    errno.ENOENT: ("file not found", "check the file name and the current directory"),
    errno.EACCES: ("permission denied", "check the file's permissions (it must be readable)"),
    errno.EPERM: ("permission denied", "check the file's permissions (it must be readable)"),
    errno.ELOOP: ("is a loop of symbolic links", "point the link at a real model file"),
    errno.ENOTDIR: ("a part of the path is not a directory", "check the path"),
    errno.ENAMETOOLONG: ("the file name is too long", "check the path"),
    errno.EISDIR: ("is a directory, not a file", "give the path of a .yaml model file"),
}


def _os_error(path: Path, exc: OSError, where: Location) -> ModelError:
    message, hint = _OS_ERRORS.get(exc.errno, (f"cannot read the file: {exc.strerror or exc}",
                                               "check the file's permissions"))
    return _file_error(where, path, message, hint)


def _file_error(where: Location, path: Path, message: str, hint: str) -> ModelError:
    """A problem with the file ``path``, reported at ``where`` (naming the path
    when ``where`` is a place in another file)."""
    if where.file != str(path) or where.line:
        message = f"model file '{path}': {message}"
    return ModelError([Problem(where, message, hint)])


__all__ = ["MAX_MODEL_BYTES", "SourceFile", "read_model_file", "read_model_text", "read_user_text", "system_root"]
