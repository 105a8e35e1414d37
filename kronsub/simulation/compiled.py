"""The compiled model of a known system, found by its equations' fingerprint.

Emitting C (common subexpressions over every entry) costs far more than compiling it, and
far more than deriving from the cache; so a compiled library is indexed by a fingerprint of
the equations themselves (their cache-format text, :mod:`kronsub.model.cache_format`), the
outputs asked for, the integrators' sources and the compiler, and a run whose fingerprint
is indexed loads the library without emitting a line. The index holds names and digests
only: the library it names is loaded only when its bytes match both the digest recorded
in the index and its sidecar (:func:`.native.verified`) and it says, from a C file compiled
into it (:func:`identity_source`), that it computes these equations with these numbers of
coordinates and parameters; otherwise it is emitted and built anew. Index entries are private
and sealed with their digest (:func:`kronsub.cache.store_entry`).
"""
from __future__ import annotations

import ctypes
import dataclasses
import json
import shutil
from pathlib import Path

from ..cache import LIBRARY_FILE, NATIVE_DIR, load_entry, private_folder, store_entry
from ..core.deferred import pending
from ..core.known_system import KnownSystem
from ..model import cache_format
from ..model.derive import content_key
from ..model.scenes import Outputs
from . import native



def fingerprint(system: KnownSystem, outputs=None, jacobian: bool = False, canonical: bool = True) -> str | None:
    """sha256 of what the generated C computes: the equations (without the names, texts,
    parameter values and initial values that only its comments and defaults show), the
    outputs, the functions asked for, the integrators and the compiler; None when the system
    cannot be fingerprinted. Equations not built yet (under velocity constraints, ``Mbar`` and
    ``hbar`` in ``x``, which the generated C may form at run time) are fingerprinted by what they are
    built from, the transition, without building them."""
    unbuilt = pending(system.mass_matrix) or pending(system.velocity_terms)
    bare = dataclasses.replace(
        system, name="", description="", initial={}, transition=system.transition if unbuilt else None,
        parameters=tuple(dataclasses.replace(p, value=None, description="", unit="") for p in system.parameters))
    try:
        text = cache_format.dumps(bare, unbuilt)
    except cache_format.CacheFormatError:
        return None
    command = native.compiler_command()
    parts = [text, repr(outputs), *native.build_identity(), shutil.which(command[0]) or command[0], *command[1:]]
    parts += [(native.CSRC / name).read_text() for name in native.INTEGRATOR_FILES]
    if jacobian:  # the library with ks_jacobian is another library
        parts.append("jacobian")
    if not canonical:  # and so is the one without ks_rhs_canonical
        parts.append("no canonical form")
    return content_key("compiled-model", *parts)


def _index_file(key: str) -> Path:
    return native.build_root() / "index" / f"{key}.json"


INDEX_BYTES = 4096  # an index entry names a folder, a library and a digest


def lookup(key: str) -> Path | None:
    """The verified library indexed under ``key``, or None (one without the integrators' functions,
    :func:`.native.lacking`, read before anything loads it, is removed: it is built again)."""
    try:
        text = load_entry(_index_file(key), INDEX_BYTES)  # private, sealed, read bounded
        entry = json.loads(text.decode("ascii"))
        folder, name, digest = entry["folder"], entry["library"], entry["sha256"]
    except (AttributeError, OSError, ValueError, KeyError, TypeError):
        return None
    if not (isinstance(folder, str) and NATIVE_DIR.fullmatch(folder) and isinstance(name, str)
            and LIBRARY_FILE.fullmatch(name) and isinstance(digest, str)):
        return None
    library = native.build_root() / folder / name
    recorded = native.recorded_digest(library)
    if recorded != digest or not native.verified(library):
        return None
    if native.lacking(library):
        native.discard(library)
        return None
    return library


def record(key: str, library: Path) -> None:
    """Index ``library`` under ``key`` (an optimisation only: failures are ignored)."""
    try:
        digest = native.recorded_digest(library)
        if digest is None:
            return
        index = private_folder(_index_file(key).parent) / f"{key}.json"
        entry = {"folder": library.parent.name, "library": library.name, "sha256": digest}
        store_entry(index, json.dumps(entry, sort_keys=True).encode("ascii"))
    except OSError:
        pass


def identity_source(key: str, nq: int, nparam: int) -> tuple[str, str]:
    """The C file compiled into a model's library that says which model it computes: its
    coordinates, parameters and equations' fingerprint (checked by :func:`belongs`)."""
    return IDENTITY_FILE, (
        "/* kronsub: the model this library computes, checked when it is loaded */\n"
        "int ks_identity_nq(void);\nint ks_identity_nparam(void);\nconst char *ks_identity(void);\n"
        f"int ks_identity_nq(void) {{ return {int(nq)}; }}\n"
        f"int ks_identity_nparam(void) {{ return {int(nparam)}; }}\n"
        f'const char *ks_identity(void) {{ return "{key}"; }}\n')


IDENTITY_FILE = "ks_identity.c"


def belongs(library: Path, key: str, nq: int, nparam: int) -> bool:
    """Whether ``library`` was built for the equations fingerprinted ``key`` with ``nq``
    coordinates and ``nparam`` parameters (what :func:`identity_source` compiled into it)."""
    try:
        lib = ctypes.CDLL(str(library))
        told = lib.ks_identity
        told.restype, told.argtypes = ctypes.c_char_p, []
        counts = int(lib.ks_identity_nq()), int(lib.ks_identity_nparam())
        return told() == key.encode("ascii") and counts == (nq, nparam)
    except (OSError, AttributeError, ValueError):
        return False


def generated_sources(system: KnownSystem, outputs=None, jacobian: bool = False,
                      canonical: bool = True) -> list[tuple[str, str]]:
    """The model's C files a library is built from: the named points left out of ``outputs``
    (a run's table takes them from the numpy module), and ``hbar`` and ``fbar`` apart (no run
    calls them), so neither their emission nor their compilation is paid for, ``Mbar`` alone (the
    energies', once per row) the equations' block's part for it rather than eliminated again, and the circle
    state's right-hand side and a projection's ``Mbar`` kept for run time in files of their own, compiled
    beside the rest; ``jacobian``:
    with the exact ``d ydot/dy`` (``ks_jacobian``); ``canonical``: with the canonical
    right-hand side (:data:`.native.CANONICAL_METHODS` integrate it)."""
    from ..emitters.code import emit_c  # heavy (jinja2, the C printer): only when the index misses

    computed = dataclasses.replace(outputs or Outputs(), points=())
    return [(g.name, g.text) for g in emit_c(system, "model", outputs=computed, jacobian=jacobian, terms_apart=False,
                                             canonical=canonical, circle_apart=True, mass_apart=False,
                                             metric_apart=True)]


def compiled_library(system: KnownSystem, outputs=None, jacobian: bool = False, canonical: bool = True) -> Path:
    """The shared library of ``system``'s generated C with the integrators: from the index
    when its fingerprint is there and the library says it computes these equations
    (:func:`belongs`), else emitted, built (:func:`.native.compile_library`) and indexed.
    ``jacobian``: with the exact ``d ydot/dy`` (``ks_jacobian``); ``canonical``: with
    ``ks_rhs_canonical``; the integrators compile meanwhile (:func:`.native.compile_ahead`).
    Raises what ``compile_library`` raises."""
    key = fingerprint(system, outputs, jacobian, canonical)
    nq, nparam = len(system.coordinates), len(system.parameters)
    if key is not None:
        library = lookup(key)
        if library is not None and belongs(library, key, nq, nparam):
            return library
    native.compile_ahead()  # the integrators compile while the model's C is emitted
    generated = generated_sources(system, outputs, jacobian, canonical)
    if key is not None:
        generated.append(identity_source(key, nq, nparam))
    library = native.compile_library(generated, "model")
    if key is not None:
        if not belongs(library, key, nq, nparam):
            raise native.NativeError(f"{library} does not compute the model it was built for")
        record(key, library)
    return library


def native_model(system: KnownSystem, outputs=None, jacobian: bool = False,
                 canonical: bool = True) -> native.NativeModel:
    """:func:`compiled_library` loaded (``canonical`` False: a library for a method on
    ``y = [q; qdot]``, without ``ks_rhs_canonical``); a library removed between its build and its loading
    (``kronsub cache clear`` meanwhile) is built again, once."""
    nq, nparam = len(system.coordinates), len(system.parameters)
    for attempt in (1, 2):
        library = compiled_library(system, outputs, jacobian, canonical)
        try:
            return native.NativeModel(library, nq, nparam, nq + len(system.state_velocities),
                                      canonical=system.speeds is None)
        except OSError:
            if attempt == 2 or library.exists():
                raise
    raise AssertionError("unreachable")


__all__ = ["IDENTITY_FILE", "INDEX_BYTES", "belongs", "compiled_library", "fingerprint", "generated_sources",
           "identity_source", "lookup", "native_model", "record"]
