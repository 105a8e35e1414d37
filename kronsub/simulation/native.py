"""Compiled models: C sources built with kronsub's C integrators and called through ctypes.

A model's C file provides the ABI of ``templates/model.h.j2`` (``ks_rhs``, ``ks_rhs_canonical``,
``ks_momentum``, ``ks_velocity``, ``ks_kinetic_energy``, ``ks_potential_energy``), with the state
``y = [q; qdot]`` of ``2 nq`` entries, the canonical state ``z = [q; p]``, ``p = Mbar qdot``, and the
parameters as a flat array. :func:`compile_library` builds it together with ``csrc/integrators.c``
into one shared library, cached by content hash; :class:`NativeModel` loads it and runs

- ``dop853``: Dormand-Prince 8(5,3), adaptive, with 7th-order dense output at the requested times:
  the default for accuracy (rtol = atol = 1e-10 keeps energy to about 1e-10 over a few periods);
- ``gauss4``: the 2-stage Gauss-Legendre method with a fixed step on ``z = [q; p]``, symplectic, so
  the energy error stays bounded over long conservative runs (order 4: error ~ h^4);
- ``rk4``: the classical Runge-Kutta method with a fixed step, the cheap baseline.

The whole integration runs in C: no Python per step.
"""
from __future__ import annotations

import atexit
import ctypes
import hashlib
import math
import os
import platform
import re
import shlex
import shutil
import stat
import struct
import subprocess
import tempfile
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from kronsub.atomic import clean_stale
from kronsub.cache import private_folder, read_private, safe_folder, usable_cache_dir, write_private
from kronsub.errors import KronsubError

CSRC = Path(__file__).resolve().parent / "csrc"
INTEGRATOR_FILES = ("integrators.h", "integrators.c")
INTEGRATOR_SYMBOLS = ("ks_status_message", "ks_dop853", "ks_gauss4", "ks_rk4", "ks_map_rows", "ks_energy_rows")
"""What ``integrators.c`` gives every library."""
FLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror")
# for the processor the library runs on (the instruction set heyoka's JIT also targets); no
# contraction into fused multiply-adds, so results stay those of the portable build. On x86:
# * no fused multiply-add instructions at all: gcc 12 makes a pair ``a c + b d``, ``b c - a d``
#   one vfmaddsub even under -ffp-contract=off (seen in the 10-link chain's velocity terms, and in the Taylor
#   integrator's angle addition where it vectorizes 128 bits wide, as for Zen 1);
# * every function on a cache line of its own start, so a hot function's speed does not depend on
#   the sizes of those before it (the 10-link chain's right-hand side: 244 or 296 ns a call as
#   the code before it moved it by 16 bytes)
_X86_FLAGS = ("-mno-fma", "-falign-functions=64")
HOST_FLAGS = ("-march=native", *(_X86_FLAGS if platform.machine().lower() in ("x86_64", "amd64", "i386", "i686")
                                 else ()), "-ffp-contract=off")
LIBS = ("-lm",)
COMPILE_TIMEOUT = 600.0

METHODS = ("dop853", "gauss4", "rk4")
CANONICAL_METHODS = ("gauss4",)
"""The methods that integrate the canonical state ``z = [q; p]`` (``ks_rhs_canonical``)."""


class NativeError(KronsubError):
    """A compiled model could not be built, loaded or evaluated."""


class CompilerNotFound(NativeError):
    """No C compiler: ``$CC`` (default ``gcc``) is not on the PATH."""


class CompileError(NativeError):
    """The C compiler rejected the sources; ``stderr`` holds its messages."""

    def __init__(self, message: str, stderr: str = ""):
        self.stderr = stderr
        super().__init__(message)


class SingularMassMatrix(NativeError):
    """The right-hand side returned 1: ``Mbar(q)`` is not positive definite at this state."""


# ---------------------------------------------------------------------------------------------
# Building
# ---------------------------------------------------------------------------------------------

def compiler_command() -> list[str]:
    """The compiler command, ``$CC`` split as a shell would (default ``gcc``).

    Raises :class:`CompilerNotFound` when its program is not on the PATH.
    """
    text = os.environ.get("CC", "").strip() or "gcc"
    command = shlex.split(text)
    if shutil.which(command[0]) is None:
        raise CompilerNotFound(
            f"C compiler {command[0]!r} not found; set CC to a C compiler (such as gcc or cc)"
        )
    return command


def _host_cpu() -> str:
    """A digest naming this machine's processor and its instruction-set extensions (Linux's
    ``/proc/cpuinfo``); empty where it cannot be read, and then nothing is built for it."""
    global _HOST_CPU
    if _HOST_CPU is None:
        try:
            with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
                head = fh.read(1 << 16).split("\n\n", 1)[0]  # the first processor
        except OSError:
            head = ""
        facts = [line for line in head.splitlines()
                 if line.split(":", 1)[0].strip() in ("vendor_id", "model name", "flags", "Features", "CPU part")]
        _HOST_CPU = hashlib.sha256("\n".join(facts).encode()).hexdigest() if facts else ""
    return _HOST_CPU


_HOST_CPU: str | None = None


def host_flags() -> tuple[str, ...]:
    """:data:`HOST_FLAGS` where the processor can be named (:func:`_host_cpu`, part of every
    library's key, so that a cache folder shared by several machines never hands one a library
    built for another's instructions), unless ``KRONSUB_PORTABLE_C=1``; else none."""
    if os.environ.get("KRONSUB_PORTABLE_C", "").strip() not in ("", "0") or not _host_cpu():
        return ()
    return HOST_FLAGS


def build_flags() -> tuple[str, ...]:
    """The compiler flags of a library: :data:`FLAGS` and :func:`host_flags`. The generated
    C itself builds with :data:`FLAGS` alone."""
    return FLAGS + host_flags()


def build_identity(flags: tuple[str, ...] | None = None) -> list[str]:
    """What a library's key holds of how it is built: the flags (:func:`build_flags` unless
    given), the libraries and, for a build for the host, its processor."""
    flags = build_flags() if flags is None else flags
    return [*flags, *LIBS, *([f"cpu {_host_cpu()}"] if flags != FLAGS else [])]


def _named_sources(sources: Sequence[str | tuple[str, str]], stem: str) -> list[tuple[str, str]]:
    """``(file name, text)`` for every source: plain texts become ``{stem}_{i}.c``."""
    named = []
    for i, item in enumerate(sources):
        if isinstance(item, str):
            named.append((f"{stem}_{i}.c", item))
        else:
            name, text = item
            if Path(name).name != name or name in INTEGRATOR_FILES:
                raise ValueError(f"source file name {name!r} must be a plain name, not one of "
                                 f"{', '.join(INTEGRATOR_FILES)}")
            named.append((name, text))
    names = [name for name, _ in named]
    if len(set(names)) != len(names):
        raise ValueError(f"source file names must be distinct: {names}")
    return named


_SCRATCH: dict[int, Path] = {}  # by process: a forked child makes its own


def _scratch_root() -> Path:
    """One temporary folder per process (a forked child's is not its parent's), removed at exit."""
    pid = os.getpid()
    if pid not in _SCRATCH:
        scratch = Path(tempfile.mkdtemp(prefix="kronsub-native-"))
        atexit.register(lambda: os.getpid() == pid and shutil.rmtree(scratch, True))
        _SCRATCH[pid] = scratch
    return _SCRATCH[pid]


def build_root() -> Path:
    """``<kronsub cache>/native``; a private temporary folder when the cache is off, not
    writable, or not safe (see :mod:`kronsub.cache`)."""
    folder = usable_cache_dir()
    native = safe_folder(folder / "native") if folder is not None else None
    if native is not None:
        try:
            return private_folder(native)  # 0700, whatever mode it was made with
        except OSError:
            pass
    return _scratch_root()


def _digest_file(path: Path) -> str:
    """The sha256 of the regular file ``path`` (no link followed, no FIFO waited on: else an
    :class:`OSError`)."""
    digest = hashlib.sha256()
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(f"{path} is not a regular file")
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def sidecar(library: Path) -> Path:
    """The file beside a library holding the sha256 of its bytes, written when it was built."""
    return library.with_name(library.name + ".sha256")


def _sidecar_lines(library: Path) -> list[str]:
    data = read_private(sidecar(library), 200)
    return data.decode("ascii", "replace").split() if data is not None else []


def recorded_digest(library: Path) -> str | None:
    """The sha256 the sidecar of ``library`` records, when the sidecar is a private regular
    file of this user holding one (read bounded, no link followed); else None."""
    lines = _sidecar_lines(library)
    return lines[0] if lines and re.fullmatch(r"[0-9a-f]{64}", lines[0]) else None


def verified(library: Path, key: str | None = None) -> bool:
    """True when ``library`` is a private regular file of this user (no link) whose sha256 is
    the one its sidecar records (a library planted without one, truncated, changed since its
    build, or that others may write is not), and, given ``key``, whose sidecar says it was
    built from the sources of that key (a folder moved under another key's name is not)."""
    try:
        st = os.lstat(library)
        if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid() or st.st_mode & 0o077:
            return False
        lines = _sidecar_lines(library)
        recorded = recorded_digest(library)
        if recorded is None or key is not None and lines[1:2] != [key]:
            return False
        return _digest_file(library) == recorded
    except OSError:
        return False


def _run_compiler(command: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """Run the compiler (its own function, so tests can count the calls)."""
    return subprocess.run(command, cwd=cwd, capture_output=True, text=True,
                          timeout=COMPILE_TIMEOUT, check=False)


def compile_library(sources: Sequence[str | tuple[str, str]], name_hint: str = "model") -> Path:
    """Build ``sources`` with the integrators into a shared library and return its path.

    ``sources`` are C texts, or ``(file name, text)`` pairs for files that must keep their
    names (a header the C file includes); every ``.c`` file is compiled, with the build folder
    on the include path. The folder ``<cache>/native/<name_hint>-<key>`` is keyed by the sha256
    of every file's name and text, the resolved compiler command and the flags, so an existing
    library is reused and a changed input never meets a stale one; the library is compiled
    under a temporary name and renamed into place, and the sha256 of its bytes and the key
    are written beside it (:func:`sidecar`). A library is reused only when it matches that
    digest and key (:func:`verified`); one planted without a sidecar, truncated, changed or
    moved under another key's name is rebuilt. The folder and its files are private (0700,
    0600); a folder removed meanwhile (``kronsub cache clear``) is made again and the build
    run again (removed twice: in the process's private temporary folder), not reported as a
    missing compiler.
    """
    command = compiler_command()
    stem = re.sub(r"[^A-Za-z0-9_]+", "_", name_hint).strip("_") or "model"
    files = _named_sources(sources, stem)
    files += [(name, (CSRC / name).read_text()) for name in INTEGRATOR_FILES]

    digest = hashlib.sha256()
    for name, text in files:
        digest.update(name.encode() + b"\0" + text.encode() + b"\0")
    resolved = [shutil.which(command[0]) or command[0], *command[1:]]
    flags = build_flags()
    digest.update("\0".join([*resolved, *build_identity(flags)]).encode())
    key = digest.hexdigest()

    # a folder removed meanwhile (`kronsub cache clear`) is made again; removed twice, the build
    # goes to this process's private temporary folder, which nothing else clears
    for root in (build_root, build_root, _scratch_root, _scratch_root):
        folder = root() / f"{stem}-{key[:24]}"
        try:
            try:
                private_folder(folder)
            except FileNotFoundError:
                raise _Vanished from None
            except OSError:  # planted there (a link, a file, another user's): not used
                folder = private_folder(_scratch_root() / folder.name)
            return _build(folder, stem, files, command, flags, key)
        except _Vanished:
            continue
    raise NativeError(f"the build folder {folder} was removed while {stem} was compiled, four times")


class _Vanished(Exception):
    """The build folder was removed during a build."""


def _compile_flags(flags) -> list[str]:
    """The flags of compiling one file to an object: a library's, without ``-shared``."""
    return [f for f in flags if f != "-shared"]


def _ahead_key(command: list[str], compile_flags: list[str], files: list[tuple[str, str]]) -> str:
    digest = hashlib.sha256("\0".join([*command, *compile_flags]).encode())
    for name, text in files:
        digest.update(b"\0" + name.encode() + b"\0" + text.encode())
    return digest.hexdigest()


_AHEAD: dict[str, tuple[int, Future, Path]] = {}  # (the process that started it, its build, the object)


def compile_ahead() -> None:
    """Start compiling the integrators (``csrc``, the same for every model) to an object in the
    background, for the next library :func:`compile_library` builds with the same compiler and
    flags: a caller about to emit a model's C lets the compiler work meanwhile, and the model's
    own files then have the processors to themselves. The object goes to the process's private
    temporary folder; nothing is started without a compiler, or when this process compiled
    them, or is compiling them, already (a forked child starts its own). A failed start is no
    error: the build compiles them."""
    try:
        command = compiler_command()
    except CompilerNotFound:
        return
    flags = _compile_flags(build_flags())
    files = [(name, (CSRC / name).read_text()) for name in INTEGRATOR_FILES]
    key = _ahead_key(command, flags, files)
    if key in _AHEAD and _AHEAD[key][0] == os.getpid():  # a forked child does not wait on its parent's thread
        return
    try:
        folder = private_folder(_scratch_root() / f"integrators-{key[:24]}")
        for name, text in files:
            write_private(folder / name, text.encode())
        fd, name = tempfile.mkstemp(prefix="integrators.", suffix=".o", dir=folder)  # its own: no start
        os.close(fd)                                                               # overwrites another's
    except OSError:
        return
    obj = Path(name)
    step = [*command, *flags, "-c", "-I", str(folder), "-o", str(obj), "integrators.c"]
    pool = ThreadPoolExecutor(max_workers=1)
    _AHEAD[key] = (os.getpid(), pool.submit(_run_compiler, step, folder), obj)
    pool.shutdown(wait=False)


def _compiled_ahead(command: list[str], compile_flags: list[str], files: list[tuple[str, str]]) -> Path | None:
    """The object :func:`compile_ahead` made of the integrators among ``files`` for this
    command and these flags (waiting for it), or None: not started, failed, or gone."""
    ahead = _AHEAD.get(_ahead_key(command, compile_flags, [f for f in files if f[0] in INTEGRATOR_FILES]))
    if ahead is None or ahead[0] != os.getpid():
        return None
    _, future, obj = ahead
    try:
        proc = future.result(timeout=COMPILE_TIMEOUT)
    except Exception:  # a start that failed in any way: compiled with the model
        return None
    return obj if proc.returncode == 0 and obj.is_file() else None


def _compile_and_link(command: list[str], flags, folder: Path, files: list[tuple[str, str]],
                      output: Path, use_ahead: bool = True) -> tuple[subprocess.CompletedProcess, list[str]]:
    """Compile each C file of ``files`` to an object, side by side, the largest first (the
    integrators' object is taken from :func:`compile_ahead` when it made one), then link them
    into ``output`` in the order of ``files`` (``use_ahead`` false: every file compiled here).
    Returns the first failed step, or the link, and its command; the objects made here are removed."""
    compile_flags = _compile_flags(flags)
    c_files = [name for name, _ in files if name.endswith(".c")]
    objects, ready = [], []
    try:
        for name in c_files:
            fd, object_name = tempfile.mkstemp(prefix=f".{name}.", suffix=".o.tmp", dir=folder)
            os.close(fd)
            objects.append(object_name)
        steps = [[*command, *compile_flags, "-c", "-I", str(folder), "-o", obj, name]
                 for name, obj in zip(c_files, objects)]
        ahead = [step for step in steps if step[-1] == "integrators.c"]
        later = [step for step in steps if not ahead or step[-1] != "integrators.c"]
        size = {name: len(text) for name, text in files}
        later.sort(key=lambda step: -size[step[-1]])  # the largest first: a small file waits on no large one
        with ThreadPoolExecutor(max_workers=max(1, min(len(later), os.cpu_count() or 1))) as pool:
            running = [pool.submit(_run_compiler, step, folder) for step in later]
            made = _compiled_ahead(command, compile_flags, files) if ahead and use_ahead else None
            if ahead and made is None:  # none made ahead: compiled now
                later, running = later + ahead, running + [pool.submit(_run_compiler, ahead[0], folder)]
            done = [job.result() for job in running]
        for proc, step in zip(done, later):
            if proc.returncode != 0:
                return proc, step
        if made is not None:
            ready = [str(made)]
        linked = [obj for obj, step in zip(objects, steps) if step in later] + ready
        link = [*command, *flags, "-o", str(output), *linked, *LIBS]
        return _run_compiler(link, folder), link
    except FileNotFoundError:
        if not folder.is_dir():
            raise _Vanished from None
        raise
    finally:
        for obj in objects:
            Path(obj).unlink(missing_ok=True)


def _build(folder: Path, stem: str, files: list[tuple[str, str]], command: list[str], flags, key: str) -> Path:
    """Compile ``files`` in ``folder`` (private) into ``lib{stem}.so`` with its sidecar; raises
    :class:`_Vanished` when the folder disappears meanwhile."""
    library = folder / f"lib{stem}.so"
    if verified(library, key) and not lacking(library):  # one without the integrators is built again
        return library
    try:
        for name, text in files:
            write_private(folder / name, text.encode())
        clean_stale(library)  # left by a build that was killed
        fd, tmp_name = tempfile.mkstemp(prefix=f".lib{stem}.so.", suffix=".tmp", dir=folder)
        os.close(fd)
    except FileNotFoundError:
        raise _Vanished from None
    tmp = Path(tmp_name)
    c_files = [name for name, _ in files if name.endswith(".c")]
    try:
        try:
            proc, full = _compile_and_link(command, flags, folder, files, tmp)
            if proc.returncode != 0 and flags != FLAGS and folder.is_dir():  # a compiler that cannot target the host
                proc, full = _compile_and_link(command, FLAGS, folder, files, tmp)
        except OSError as exc:
            if not folder.is_dir():
                raise _Vanished from None
            raise CompilerNotFound(f"C compiler {command[0]!r} could not be run: {exc}") from exc
        except subprocess.TimeoutExpired as exc:
            raise CompileError(f"compiling {stem} took longer than {COMPILE_TIMEOUT:.0f} s") from exc
        if proc.returncode == 0 and lacking(tmp):  # an object made ahead but not whole: all compiled here
            proc, full = _compile_and_link(command, flags, folder, files, tmp, use_ahead=False)
            missing = lacking(tmp) if proc.returncode == 0 else []
            if missing:
                raise CompileError(f"the library of {stem} lacks {', '.join(missing)} after its build")
        if proc.returncode != 0:
            if not folder.is_dir() or not all((folder / name).is_file() for name in c_files):
                raise _Vanished
            stderr = (proc.stderr or proc.stdout or "").strip()
            raise CompileError(
                f"compiling {stem} failed ({shlex.join(full)}):\n{stderr}", stderr
            )
        try:
            os.chmod(tmp, 0o600)  # private whatever the umask (the linker made it executable)
            digest = _digest_file(tmp)
            os.replace(tmp, library)
            write_private(sidecar(library), f"{digest}\n{key}\n".encode())
        except FileNotFoundError:
            raise _Vanished from None
    finally:
        tmp.unlink(missing_ok=True)
    return library


def lacking(library: Path) -> list[str]:
    """The integrators' functions (:data:`INTEGRATOR_SYMBOLS`) that ``library`` does not define
    (read off its ELF dynamic symbol table, without loading it: a process that loaded a library
    keeps it under its path); all of them for a damaged object, none for a file in another format
    than 64-bit little-endian ELF (left to the loader)."""
    try:
        defined = _defined_symbols(library.read_bytes())
    except (OSError, ValueError, IndexError, struct.error):  # a damaged object
        return list(INTEGRATOR_SYMBOLS)
    return [] if defined is None else [name for name in INTEGRATOR_SYMBOLS if name not in defined]


def _defined_symbols(data: bytes) -> set[str] | None:
    """The names an ELF64 little-endian shared object defines in ``.dynsym``; None for another format."""
    if data[:4] != b"\x7fELF" or data[4] != 2 or data[5] != 1:
        return None
    shoff, = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize) for i in range(shnum)]
    names = set()
    for _, kind, _, _, offset, size, link, _, _, entsize in sections:
        if kind != 11 or not entsize:  # SHT_DYNSYM
            continue
        strings = sections[link][4]
        for at in range(offset, offset + size, entsize):
            name, _, _, shndx = struct.unpack_from("<IBBH", data, at)
            if shndx:  # SHN_UNDEF: referenced, not defined
                end = data.index(b"\0", strings + name)
                names.add(data[strings + name:end].decode("ascii", "replace"))
    return names


def discard(library: Path) -> None:
    """Remove ``library`` and its sidecar from the cache (one found not whole: built again)."""
    for path in (library, sidecar(library)):
        path.unlink(missing_ok=True)


# ---------------------------------------------------------------------------------------------
# Calling
# ---------------------------------------------------------------------------------------------

class _CResult(ctypes.Structure):
    """The C ``ks_result`` of ``integrators.h``."""

    _fields_ = [
        ("status", ctypes.c_int),
        ("t_fail", ctypes.c_double),
        ("n_steps", ctypes.c_long),
        ("n_rejected", ctypes.c_long),
        ("n_evals", ctypes.c_long),
        ("n_rows", ctypes.c_long),
        ("n_stiff", ctypes.c_long),
        ("t_stiff", ctypes.c_double),
    ]


@dataclass(frozen=True)
class IntegrationResult:
    """What one integration did. ``status`` as in ``integrators.h``: 0 reached ``t_end``,
    1 right-hand side failed (singular mass matrix), 2 non-finite state, 3 step size underflow
    (gauss4: stage iteration did not converge), 4 too many steps, 5 output buffer full,
    6 invalid argument, 7 interrupted (``ks_interrupt``, :meth:`NativeModel._waited`). On
    statuses 1 and 2, ``y_fail`` is the state ``[q; qdot]`` at which the right-hand side failed
    (``qdot`` NaN when it cannot be recovered) and ``t_fail`` its time."""

    method: str
    status: int
    message: str
    t_fail: float
    n_steps: int
    n_rejected: int
    n_evals: int
    n_rows: int
    y_fail: np.ndarray | None = None
    t_stiff: float | None = None  # dop853: when Hairer's test first found the problem stiff

    @property
    def ok(self) -> bool:
        return self.status == 0


_D = ctypes.c_double
_P = ctypes.c_void_p
_I = ctypes.c_int
_L = ctypes.c_long

_SIGNATURES = {
    "ks_rhs": (_I, [_D, _P, _P, _P]),
    "ks_rhs_pre": (_I, [_D, _P, _P, _P]),
    "ks_rhs_canonical_pre": (_I, [_D, _P, _P, _P]),
    "ks_prepare": (None, [_P, _P]),
    "ks_npre": (_I, []),
    "ks_rhs_canonical": (_I, [_D, _P, _P, _P]),
    "ks_kinetic_energy": (_D, [_P, _P]),
    "ks_potential_energy": (_D, [_D, _P, _P]),
    "ks_momentum": (None, [_P, _P, _P]),
    "ks_velocity": (_I, [_P, _P, _P]),
    "ks_status_message": (ctypes.c_char_p, [_I]),
    "ks_dop853": (_I, [_P, _I, _P, _D, _P, _D, _D, _D, _D, _D, _L, _P, _L, _P, _P]),
    "ks_gauss4": (_I, [_P, _I, _P, _D, _P, _D, _D, _L, _P, _L, _P, _P]),
    "ks_rk4": (_I, [_P, _I, _P, _D, _P, _D, _D, _L, _P, _L, _P, _P]),
    "ks_map_rows": (_L, [_P, _I, _P, _P, _L, _P]),
    "ks_energy_rows": (None, [_P, _P, _I, _P, _P, _L, _P, _P]),
    "ks_nstate": (_I, []),
    "ks_ncircle": (_I, []),
    "ks_nfirst": (_I, []),
    "ks_jacobian": (_I, [_D, _P, _P, _P]),
    "ks_rhs_circle": (_I, [_D, _P, _P, _P]),
    "ks_rhs_circle_pre": (_I, [_D, _P, _P, _P]),
    "ks_circle_state": (None, [_P, _P]),
    "ks_newton_init": (None, [_P]),
    "ks_identity_nq": (_I, []),
    "ks_identity_nparam": (_I, []),
}
_REQUIRED = ("ks_rhs", *INTEGRATOR_SYMBOLS)

# scratch sizes in doubles, KS_*_WORK(dim) of integrators.h
_WORK = {"dop853": 27, "gauss4": 7, "rk4": 6}


def data_address(array: np.ndarray) -> int:
    """The address of ``array``'s data (``array.ctypes.data``); for a writable array through a
    ctypes view of its buffer, a third of the time (numpy builds a ctypes helper per call,
    and scipy's integrators ask once per right-hand side)."""
    if array.flags.writeable:
        try:
            return ctypes.addressof(ctypes.c_char.from_buffer(array))
        except (TypeError, ValueError, BufferError):  # empty or not contiguous
            pass
    return array.ctypes.data


def _address(fn) -> int:
    """The C address of a ctypes function, to pass as a function pointer."""
    return ctypes.cast(fn, ctypes.c_void_p).value


class NativeModel:
    """A compiled model with ``nq`` coordinates and ``nparam`` parameters, loaded with ctypes."""

    def __init__(self, library: str | Path, nq: int, nparam: int, ny: int | None = None, canonical: bool = True):
        if nq < 1 or nparam < 0:
            raise ValueError(f"nq must be >= 1 and nparam >= 0 (got nq={nq}, nparam={nparam})")
        self.path = Path(library)
        self.nq = nq
        self.ny = 2 * nq if ny is None else ny  # [q; u] under velocity constraints: nq + the speeds
        self.canonical = canonical  # the model has a canonical form z = [q; p] (not in speeds: gauss4 in [q; u])
        self.nparam = nparam
        self._lib = ctypes.CDLL(str(self.path))
        self._fn = {}
        for name, (restype, argtypes) in _SIGNATURES.items():
            try:
                fn = getattr(self._lib, name)
            except AttributeError:
                continue
            fn.restype = restype
            fn.argtypes = argtypes
            self._fn[name] = fn
        missing = [name for name in _REQUIRED if name not in self._fn]
        if missing:
            raise NativeError(f"{self.path} lacks {', '.join(missing)}; build it with compile_library")
        if "ks_identity_nq" in self._fn and "ks_identity_nparam" in self._fn:  # (kronsub.simulation.compiled)
            built = int(self._fn["ks_identity_nq"]()), int(self._fn["ks_identity_nparam"]())
            if built != (nq, nparam):
                raise NativeError(f"{self.path} was built for {built[0]} coordinates and {built[1]} parameters, "
                                  f"not {nq} and {nparam}")
        # implicit constraints: the Newton state [y_d; tolerance] after the parameters, owned here
        self.nstate = int(self._fn["ks_nstate"]()) if "ks_nstate" in self._fn else 0
        self._buffer = np.zeros(max(self.nparam + self.nstate, 1))
        # the circle state z = [y; cos q_c; sin q_c] (emitters/circle.py): 0 without one
        self.nc = int(self._fn["ks_ncircle"]()) if "ks_ncircle" in self._fn and "ks_rhs_circle" in self._fn else 0
        # first-order coordinates (core/first_order.py): their velocities solved, not integrated
        self.nfirst = int(self._fn["ks_nfirst"]()) if "ks_nfirst" in self._fn else 0
        if self.nstate:
            self._fn["ks_newton_init"](data_address(self._buffer[self.nparam:]))

    def set_newton(self, dependent, tol: float | None = None) -> None:
        """Warm start (the dependent coordinates) and tolerance of the compiled Newton's method."""
        if not self.nstate:
            raise NativeError(f"{self.path} has no implicit constraints")
        state = self._buffer[self.nparam:]
        state[: self.nstate - 1] = np.asarray(dependent, dtype=float).ravel()
        if tol is not None:
            state[-1] = tol

    @property
    def dependent(self) -> np.ndarray:
        """The last solution of the compiled Newton's method (a copy)."""
        return self._buffer[self.nparam:self.nparam + max(self.nstate - 1, 0)].copy()

    def _keep(self, pre: np.ndarray) -> None:
        """Keep the Newton state a ``pre`` block ends with (after a run on it)."""
        if self.nstate and pre is not self._buffer:
            self._buffer[self.nparam:] = pre[int(self._fn["ks_npre"]()) - self.nstate:int(self._fn["ks_npre"]())]

    @classmethod
    def build(cls, sources: Sequence[str | tuple[str, str]], name_hint: str, nq: int,
              nparam: int) -> "NativeModel":
        """:func:`compile_library` then load."""
        return cls(compile_library(sources, name_hint), nq, nparam)

    # -- helpers -----------------------------------------------------------------------------

    def _function(self, name: str):
        try:
            return self._fn[name]
        except KeyError:
            raise NativeError(f"{self.path} does not define {name}") from None

    def _param(self, param) -> np.ndarray:
        """``param``, followed by the Newton state with implicit constraints (one buffer, whose
        state the C functions update: the warm start carries over from call to call)."""
        values = np.ascontiguousarray(param if param is not None else [], dtype=float).ravel()
        if values.size != self.nparam:
            raise ValueError(f"param must have {self.nparam} entries (got {values.size})")
        if not self.nstate:
            return values if values.size else np.zeros(1)
        self._buffer[:self.nparam] = values
        return self._buffer

    def _state(self, y, name: str = "y") -> np.ndarray:
        values = np.ascontiguousarray(y, dtype=float)
        if values.shape != (self.ny,):
            raise ValueError(f"{name} must be 1-dimensional with {self.ny} entries "
                             f"(got shape {values.shape})")
        return values

    def _singular(self, t: float | None, y: np.ndarray) -> SingularMassMatrix:
        when = f" at t = {t:.17g}" if t is not None else ""
        q = ", ".join(f"{v:.17g}" for v in y[: self.nq])
        return SingularMassMatrix(f"the mass matrix Mbar is singular or not positive definite{when}, q = [{q}]")

    # -- the model's functions ---------------------------------------------------------------

    def rhs(self, t: float, y, param) -> np.ndarray:
        """``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` (with implicit constraints from the warm start,
        which it updates: through ``pre``, as the C never writes ``param``)."""
        y = self._state(y)
        p, fn = self._prepared(param, "ks_rhs") if self.nstate else (self._param(param), self._function("ks_rhs"))
        ydot = np.empty(self.ny)
        status = fn(t, data_address(y), data_address(p), data_address(ydot))
        self._keep(p)
        if status:
            raise self._singular(t, y)
        return ydot

    def rhs_canonical(self, t: float, z, param) -> np.ndarray:
        """``zdot = [Mbar^-1 p; dT/dq + fbar]`` for ``z = [q; p]``."""
        z, p = self._state(z, "z"), self._param(param)
        zdot = np.empty(self.ny)
        if self._function("ks_rhs_canonical")(t, data_address(z), data_address(p), data_address(zdot)):
            raise self._singular(t, z)
        return zdot

    def circle_state(self, y) -> np.ndarray:
        """``z = [y; cos q_c; sin q_c]`` of the circle coordinates ``q_c`` (see :attr:`nc`)."""
        y = self._state(y)
        z = np.empty(self.ny + 2 * self.nc)
        self._function("ks_circle_state")(data_address(y), data_address(z))
        return z

    def rhs_circle(self, t: float, z, param) -> np.ndarray:
        """``zdot`` of the circle state ``z = [q; qdot; cos q_c; sin q_c]``: ``[ydot; -sin q_c
        qdot_c; cos q_c qdot_c]``."""
        z = np.ascontiguousarray(z, dtype=float)
        if z.shape != (self.ny + 2 * self.nc,):
            raise ValueError(f"z must be 1-dimensional with {self.ny + 2 * self.nc} entries (got shape {z.shape})")
        p, fn = self._prepared(param, "ks_rhs_circle") if self.nstate else \
            (self._param(param), self._function("ks_rhs_circle"))
        zdot = np.empty_like(z)
        status = fn(t, data_address(z), data_address(p), data_address(zdot))
        self._keep(p)
        if status:
            raise self._singular(t, z)
        return zdot

    def kinetic_energy(self, y, param) -> float:
        """``T = 1/2 qdot^T Mbar qdot``."""
        y, p = self._state(y), self._param(param)
        return float(self._function("ks_kinetic_energy")(data_address(y), data_address(p)))

    def potential_energy(self, t: float, y, param) -> float:
        """``V`` of the model's conservative effects."""
        y, p = self._state(y), self._param(param)
        return float(self._function("ks_potential_energy")(t, data_address(y), data_address(p)))

    def energies(self, t, Y, param) -> tuple[np.ndarray, np.ndarray]:
        """Kinetic and potential energy at every row ``(t_r, Y_r)`` of a trajectory (in C)."""
        t = np.asarray(t, dtype=float).ravel()
        Y = np.asarray(Y, dtype=float).reshape(-1, self.ny)
        if len(t) != len(Y):
            raise ValueError(f"t and Y must have as many rows (got {len(t)} and {len(Y)})")
        rows = np.ascontiguousarray(np.column_stack([t, Y]))
        T, V, p = np.empty(len(t)), np.empty(len(t)), self._param(param)
        self._fn["ks_energy_rows"](
            _address(self._function("ks_kinetic_energy")),
            _address(self._function("ks_potential_energy")),
            self.ny, data_address(p), data_address(rows), len(t), data_address(T), data_address(V))
        return T, V

    def momentum(self, y, param) -> np.ndarray:
        """``z = [q; Mbar qdot]``."""
        y, p = self._state(y), self._param(param)
        z = np.empty(self.ny)
        self._function("ks_momentum")(data_address(y), data_address(p), data_address(z))
        return z

    def velocity(self, z, param) -> np.ndarray:
        """``y = [q; Mbar^-1 p]``."""
        z, p = self._state(z, "z"), self._param(param)
        y = np.empty(self.ny)
        if self._function("ks_velocity")(data_address(z), data_address(p), data_address(y)):
            raise self._singular(None, z)
        return y

    def _prepared(self, param, name: str) -> tuple[np.ndarray, object]:
        """The parameter block and right-hand side to call repeatedly: ``pre = [param; derived
        constants]`` with ``<name>_pre`` when the model has ``ks_prepare``, else ``param``."""
        p = self._param(param)
        if "ks_prepare" in self._fn and "ks_npre" in self._fn and f"{name}_pre" in self._fn:
            pre = np.empty(max(int(self._fn["ks_npre"]()), self.nparam + self.nstate) + 1)
            self._fn["ks_prepare"](data_address(p), data_address(pre))
            return pre, self._fn[f"{name}_pre"]
        return p, self._function(name)

    def scipy_rhs(self, param) -> Callable[[float, np.ndarray], np.ndarray]:
        """``f(t, y)`` for ``scipy.integrate.solve_ivp``, calling ``ks_rhs`` with preallocated
        buffers (the returned array is a fresh copy, as solvers keep references to it)."""
        p, fn = self._prepared(param, "ks_rhs")
        ydot = np.empty(self.ny)
        p_ptr, out_ptr, ny = data_address(p), data_address(ydot), self.ny

        keep = self._keep if self.nstate else None

        def f(t, y):
            y = np.ascontiguousarray(y, dtype=float)
            if y.shape != (ny,):
                raise ValueError(f"y must be 1-dimensional with {ny} entries (got shape {y.shape})")
            status = fn(t, data_address(y), p_ptr, out_ptr)
            if keep is not None:
                keep(p)
            if status:
                raise self._singular(t, y)
            return ydot.copy()

        f.param = p  # keeps the parameter buffer alive with the callable
        if "ks_jacobian" in self._fn and not self.nstate:
            f.jacobian = self.scipy_jacobian(param)  # the exact d ydot/dy, for the implicit methods
        return f

    def scipy_jacobian(self, param) -> Callable[[float, np.ndarray], np.ndarray]:
        """``J(t, y) = d ydot/dy`` from ``ks_jacobian`` (the model built with ``jacobian``)."""
        p, fn, ny = self._param(param).copy(), self._function("ks_jacobian"), self.ny

        def jacobian(t, y):
            y = np.ascontiguousarray(y, dtype=float)
            out = np.empty(ny * ny)
            if fn(t, data_address(y), data_address(p), data_address(out)):
                raise self._singular(t, y)
            return out.reshape(ny, ny)

        jacobian.param = p
        return jacobian

    # -- integration -------------------------------------------------------------------------

    def _waited(self, call: Callable[[], object]) -> None:
        """``call()``, a C integration, in a thread of its own while this one waits on it: an
        interrupt (Ctrl-C; SIGTERM and SIGHUP under :func:`kronsub.interrupts.signals_as_interrupts`)
        sets the library's ``ks_interrupt``, the call stops before its next step, and the
        interrupt is raised once it has."""
        try:
            flag = ctypes.c_int.in_dll(self._lib, "ks_interrupt")
        except ValueError:  # (a library without it: called here, as ever)
            call()
            return
        failed: list[BaseException] = []

        def target():
            try:
                call()
            except BaseException as exc:  # (raised here, in the waiting thread)
                failed.append(exc)

        worker = threading.Thread(target=target, name="kronsub-integrate", daemon=True)
        worker.start()
        try:
            worker.join()
        except BaseException:
            flag.value = 1
            while worker.is_alive():  # within a step; a second interrupt meanwhile changes nothing
                try:
                    worker.join()
                except BaseException:
                    pass
            flag.value = 0
            raise
        if failed:
            raise failed[0]

    def integrate(self, method: str, t0: float, y0, t_end: float, dt_out: float, param, *,
                  rtol: float = 1e-10, atol: float = 1e-10, h: float | None = None,
                  max_steps: int = 10_000_000, circle: bool | None = None, interruptible: bool = False,
                  ) -> tuple[np.ndarray, np.ndarray, IntegrationResult]:
        """Integrate from ``y0 = [q; qdot]`` at ``t0`` to ``t_end`` wholly in C.

        Returns the row times ``t``, the states ``Y`` (rows ``[q; qdot]``) and the result. Rows
        are at ``t0, t0 + dt_out, ...`` and exactly at ``t_end``; ``dt_out <= 0`` gives a row at
        every step. ``dop853`` is adaptive (``rtol``, ``atol``; ``h`` the first step, automatic
        when None; ``max_steps`` bounds the step attempts, <= 0 for no bound). ``gauss4`` and ``rk4`` use the fixed
        step ``h`` (default ``dt_out``), shortened so that ``dt_out`` is a whole number of steps;
        ``gauss4`` integrates ``z = [q; p]`` and its rows are converted back to ``[q; qdot]``.
        ``dop853`` and ``rk4`` integrate the circle state ``[q; qdot; cos q_c; sin q_c]`` when the
        model has circle coordinates (``circle`` None or True; False: ``[q; qdot]``); the rows
        are its first ``2 nq`` entries; a run that fails there is run again in ``[q; qdot]``.
        A failure does not raise: the rows computed so far are returned with ``result.status``.
        ``interruptible`` (in the main thread): ``dop853``'s call, whose steps between two rows
        nothing bounds but ``max_steps``, runs while this thread waits, so that Ctrl-C or
        SIGTERM stops it before its next step and is raised (:meth:`_waited`).
        """
        if method not in METHODS:
            raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(METHODS)}")
        if not (math.isfinite(t0) and math.isfinite(t_end) and t_end >= t0):
            raise ValueError(f"need finite t0 <= t_end (got t0={t0}, t_end={t_end})")
        y0 = self._state(y0, "y0")
        span = t_end - t0
        # gauss4 in (q, p = Mbar qdot); with implicit constraints, which have no canonical form,
        # in (q, qdot): fourth order still, the dependent coordinates by Newton in every stage; so
        # with first-order coordinates, whose singular metric has no momentum to solve for; and in
        # the speeds (velocity constraints, a change of velocity frame), [q; u]
        canonical = method in CANONICAL_METHODS and self.canonical and not self.nstate and not self.nfirst
        on_circle = method != "gauss4" and self.nc > 0 and circle is not False
        dim = self.ny + 2 * self.nc if on_circle else self.ny
        start = self.momentum(y0, param) if canonical else self.circle_state(y0) if on_circle else y0
        p, rhs = self._prepared(param, "ks_rhs_canonical" if canonical else "ks_rhs_circle" if on_circle else "ks_rhs")
        rhs_address = _address(rhs)
        work = np.empty(_WORK[method] * dim)
        cres = _CResult()

        if method == "dop853":
            if dt_out > 0:
                capacity = [math.floor(span / dt_out) + 3]
            else:  # rows unknown in advance: grow, rerunning on a full buffer
                limit = max_steps + 2 if max_steps > 0 else 4096 * 16**5
                capacity = [4096 * 16**k for k in range(5) if 4096 * 16**k < limit] + [limit]

            def call(out, rows):
                return self._fn["ks_dop853"](
                    rhs_address, dim, data_address(p), t0, data_address(start), t_end, dt_out, rtol, atol,
                    h if h is not None else 0.0, max_steps, data_address(out), rows, data_address(work),
                    ctypes.byref(cres))

            waited = interruptible and threading.current_thread() is threading.main_thread()
            run = (lambda out, rows: self._waited(lambda: call(out, rows))) if waited else call
        else:
            if h is None:
                h = dt_out if dt_out > 0 else span / 1000.0
            if not (h > 0 and math.isfinite(h)):
                raise ValueError(f"the step h must be positive (got {h})")
            out_every = 1
            if dt_out > 0:
                out_every = max(1, math.ceil(dt_out / h - 1e-9))
                h = dt_out / out_every
            # a span up to 2e-7 h over whole steps takes no extra step: a t_end within 1e-7 dt_out of a
            # row is that row (grid.MERGE, output_time in integrators.c), reached by a longer last step
            n_steps = max(1, math.ceil(span / h * (1 - 2e-7))) if span > 0 else 0
            capacity = [n_steps // out_every + 3]
            fixed = self._fn[f"ks_{method}"]
            step = h

            def run(out, rows):
                return fixed(rhs_address, dim, data_address(p), t0, data_address(start), t_end, step,
                             out_every, data_address(out), rows, data_address(work), ctypes.byref(cres))

        for rows in capacity:
            out = np.empty((rows, dim + 1))
            run(out, rows)
            if cres.status != 5:
                break
        self._keep(p)
        if on_circle and cres.status not in (0, 5):
            # found and told in the model's own coordinates (a square root's domain, a singular
            # Mbar): the circle point of an angle is not that angle's sine and cosine to the bit
            return self.integrate(method, t0, y0, t_end, dt_out, param, rtol=rtol, atol=atol, h=h,
                                  max_steps=max_steps, circle=False, interruptible=interruptible)
        out = out[: cres.n_rows, : self.ny + 1]  # the circle state's rows begin with [t, q, qdot]
        y_fail = work[: self.ny].copy() if cres.status in (1, 2) else None
        if canonical:  # rows [t, q, p] -> [t, q, qdot]
            bad = self._fn["ks_map_rows"](_address(self._function("ks_velocity")), self.ny,
                                          data_address(p), data_address(out), cres.n_rows, data_address(work))
            if bad >= 0:
                raise self._singular(float(out[bad, 0]), out[bad, 1:])
            if y_fail is not None:
                try:
                    y_fail = self.velocity(y_fail, param)
                except SingularMassMatrix:
                    y_fail = np.concatenate([y_fail[: self.nq], np.full(self.ny - self.nq, np.nan)])
        t, Y = out[:, 0].copy(), np.ascontiguousarray(out[:, 1:])
        message = self._fn["ks_status_message"](cres.status).decode()
        result = IntegrationResult(
            method=method, status=cres.status, message=message,
            t_fail=cres.t_fail if cres.status else math.nan,
            n_steps=cres.n_steps, n_rejected=cres.n_rejected, n_evals=cres.n_evals,
            n_rows=cres.n_rows, y_fail=y_fail,
            t_stiff=cres.t_stiff if cres.n_stiff > 0 else None,
        )
        return t, Y, result


__all__ = ["CANONICAL_METHODS", "COMPILE_TIMEOUT", "CSRC", "CompileError", "CompilerNotFound", "FLAGS", "HOST_FLAGS", "INTEGRATOR_FILES",
           "IntegrationResult", "LIBS", "METHODS", "NativeError", "NativeModel", "SingularMassMatrix", "build_flags",
           "build_identity", "build_root", "compile_ahead", "compile_library", "compiler_command", "data_address", "discard",
           "host_flags", "INTEGRATOR_SYMBOLS", "lacking", "recorded_digest", "sidecar", "verified"]
