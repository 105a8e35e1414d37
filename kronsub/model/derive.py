"""Deriving a model, with derived known systems cached on disk by content hash."""
from __future__ import annotations

import dataclasses
import hashlib
import warnings
from pathlib import Path

import numpy as np
import numpy.random  # noqa: F401  numpy loads it on first use; imported with the rest
import sympy

from ..budget import PER_OPERATION, WorkBudgetExceeded, allow_for, charge, scope
from ..cache import code_fingerprint, load_entry, store_entry, usable_cache_dir
from ..collector import collector_paused
from ..core.constraints import project_implicit
from ..core.deferred import pending
from ..core.doubles import graph_nodes
from ..core.known_system import KnownSystem, ProjectedEffect, Transition
from ..core.nonholonomic import speed_equations
from ..core.numeric_jacobian import jacobian
from ..core.operations import count_ops
from ..core.symbols import free_symbols_of
from ..core.trigpoly import ExpansionTooLarge
from ..core.subspace import (Subspace, assemble, assembled_potentials, effect_labels, project_effects,
                             project_inertia)
from ..errors import Location
from . import cache_format
from .energy_kinds import effect_kinds


def cache_dir() -> Path | None:
    """Where derived known systems are kept, when that folder is safe (see :mod:`kronsub.cache`)."""
    return usable_cache_dir()


def content_key(*parts: str) -> str:
    """The cache key of a model: kronsub's code, the file's text and its sub-models' keys."""
    digest = hashlib.sha256()
    digest.update(code_fingerprint().encode())
    for part in parts:
        digest.update(part.encode())
        digest.update(b"\0")
    return digest.hexdigest()


def _cache_file(key: str, part: str) -> Path | None:
    folder = cache_dir()
    if folder is None or not key:
        return None
    return folder / f"{key}.{part}.json"


def _load(path: Path | None, expected: type):
    """The value stored at ``path``; None when it is missing, damaged (its digest, recorded when
    it was written, differs), stale, not ours or not private (:func:`kronsub.cache.load_entry`)."""
    if path is None:
        return None
    text = load_entry(path)  # a private regular file whose digest matches, read bounded; else None
    if text is None:
        return None
    try:
        return cache_format.loads(text, expected)
    except cache_format.CacheFormatError:
        return None  # rebuilt by the caller


def load_cached(key: str, *, transition: bool = True) -> KnownSystem | None:
    """The derived known system stored under ``key``, if any.

    The transition (primitive, ``C``) is kept apart and read only when asked for:
    a known system used as a component does not need it.
    """
    system = _load(_cache_file(key, "system"), KnownSystem)
    if system is None:
        return None
    if transition:
        steps = _load(_cache_file(key, "transition"), Transition)
        if steps is None:
            return None
        system = dataclasses.replace(system, transition=steps)
    return system


def store_cached(key: str, system: KnownSystem) -> None:
    """Store a derived system (and, apart, its transition) under ``key``."""
    path = _cache_file(key, "system")
    if path is None:
        return
    try:
        transition = cache_format.dumps(system.transition)
        known = cache_format.dumps(dataclasses.replace(system, transition=None))
        store_entry(_cache_file(key, "transition"), transition.encode())
        store_entry(path, known.encode())
    except (OSError, cache_format.CacheFormatError):
        pass  # the cache is an optimisation only


def derive_model(model, *, cache: bool = True, effects=None) -> KnownSystem:
    """Project the model's primitive onto its subspace (cached by content hash).

    ``effects`` (effect names, dotted for a known system's own) keeps only those: the
    others are left out before projection, so nothing of them is derived. ``fbar`` is the
    sum of the effects' projected forces (8'), (F), so ``Mbar``, ``hbar`` (the inertia) and
    each effect are cached apart, and every selection of effects shares them. The cache
    holds data only (:mod:`.cache_format`); name, description, initial values and requirements
    always come from ``model`` (the same text may live under several file names). The cyclic garbage
    collector is paused meanwhile (:func:`.collector_paused`). A default work budget grows
    with the primitive here as when the model was read (`kronsub.budget.allow_for`), so a
    derivation in a budget of its own (the API's ``load(path).derive()``, a scene's) is bounded
    as the command's is: the active work budget, or a default one (`kronsub.budget.scope`); an
    expansion too large is placed at the model's file.
    """
    try:
        with scope():
            allow_for(len(model.primitive.coordinates))
            with collector_paused():
                system = _derive(model, cache, effects)
            _charge_printed(system, model)
    except ExpansionTooLarge as exc:
        raise exc.at(Location(model.path)) from None
    return system


def _charge_printed(system: KnownSystem, model) -> None:
    """Charge the work budget for printing the equations, before any command prints them:
    their operations counted as printed (a definition used twice, twice; ``count_ops`` counts
    each distinct part once), so that equations too long to print stop here, placed at the file.
    Equations not built yet (:func:`.deferred.pending`) are charged as they are built."""
    parts = [*(e for m in (system.mass_matrix, system.velocity_terms) if not pending(m) for e in m),
             *system.forces, system.potential_energy]
    try:
        charge(PER_OPERATION["print"] * sum(count_ops(e) for e in parts), "the printed size of the equations")
    except WorkBudgetExceeded as exc:
        raise exc.at(Location(model.path)) from None


def _derive(model, cache: bool, effects) -> KnownSystem:
    key = model.content_hash if cache else ""
    own = {"name": model.name, "description": model.description, "initial": dict(model.initial),
           "requirements": model.requirements, "currents": dict(model.currents),
           "effect_kinds": effect_kinds(model.primitive, model.effects)}
    if key and effects is None:
        hit = load_cached(key)
        if hit is not None:
            return dataclasses.replace(hit, **own)
    implicit = model.implicit
    # with implicit constraints, the explicit step goes to the intermediate coordinates y first
    coordinates = implicit.intermediate if implicit is not None else model.coordinates
    labels = effect_labels(model.primitive, model.effects)
    chosen = labels if effects is None else tuple(label for label in labels if label in set(effects))
    inertia = _load_inertia(key)
    pieces = {label: _load(_cache_file(key, f"effect.{label}"), ProjectedEffect) for label in chosen}
    missing = {label for label, piece in pieces.items() if piece is None}
    if inertia is None or missing:
        sub = Subspace(model.primitive, coordinates, model.connection)
        if inertia is None:
            try:  # under velocity constraints, Mbar and hbar in x are built when first read
                inertia = project_inertia(sub, model.primitive, name=model.name, parameters=model.parameters,
                                          description=model.description, deferred=model.velocity is not None)
            except WorkBudgetExceeded as exc:  # placed at the connection, whose algebra grew
                raise exc.at(model.locations.get("connection") or Location(model.path)) from None
            if implicit is None and not sub.only_renames(model.primitive):
                check_subspace_rank(model, sub)
            if not _pending(inertia):
                _store_parts(key, {"inertia": dataclasses.replace(inertia, transition=None),
                                   "inertia-transition": inertia.transition})
        try:
            projected = project_effects(sub, model.primitive, model.effects, only=missing)
        except WorkBudgetExceeded as exc:
            raise exc.at(Location(model.path)) from None
        for piece in projected:
            pieces[piece.label] = piece
            _store_parts(key, {f"effect.{piece.label}": piece})
    system = dataclasses.replace(assemble(inertia, [pieces[label] for label in chosen],
                                          assembled_potentials(model.primitive)), **own)
    if implicit is not None:
        system = dataclasses.replace(derive_implicit(model, system), **own)
    velocity = model.velocity
    if velocity is not None:  # xdot = C u + d: the equations in the speeds beside those in x
        system = dataclasses.replace(system, speeds=speed_equations(
            system, velocity.transformation, velocity.constraint_names, dict(velocity.definitions),
            tidy="frame" if velocity.frame else "entry"))
    if key and effects is None and not _pending(system):
        store_cached(key, system)
    return system


def _pending(system: KnownSystem) -> bool:
    """Whether ``Mbar`` or ``hbar`` of ``system`` (or its velocity constraints' ``A``) are not built
    yet: then nothing is stored (the cache holds what was derived, and storing would build them)."""
    return pending(system.mass_matrix) or pending(system.velocity_terms) or \
        (system.speeds is not None and pending(system.speeds.constraint_matrix))


def derive_implicit(model, intermediate: KnownSystem) -> KnownSystem:
    """The second of two steps, the paper's resting place between (13) and its group property:
    the primitive onto ``y`` (the explicit connection, ``intermediate``), then ``y`` onto
    ``g(y) = 0`` (25)-(29)."""
    spec = model.implicit
    taken = {q.name for q in model.primitive.coordinates}
    return project_implicit(intermediate, spec.independent, spec.dependent, spec.constraints,
                            closed_form=spec.closed_form, branch=spec.branch, choice=spec.choice, taken=taken)


def _load_inertia(key: str) -> KnownSystem | None:
    """The cached ``Mbar``, ``hbar`` and transition of a model, without effects."""
    inertia = _load(_cache_file(key, "inertia"), KnownSystem)
    steps = _load(_cache_file(key, "inertia-transition"), Transition)
    if inertia is None or steps is None:
        return None
    return dataclasses.replace(inertia, transition=steps)


def _store_parts(key: str, parts: dict) -> None:
    for part, value in parts.items():
        path = _cache_file(key, part)
        if path is None:
            return
        try:
            store_entry(path, cache_format.dumps(value).encode())
        except (OSError, cache_format.CacheFormatError):
            pass  # the cache is an optimisation only


class RankWarning(UserWarning):
    """``C`` lost rank at a sample configuration: the coordinates are not independent there."""


def check_subspace_rank(model, sub: Subspace, samples: int = 3) -> None:
    """`check_rank` of the subspace's ``C``, evaluated straight from the algebra's form."""
    algebra = sub.algebra
    atoms = [a for row in sub.C for entry in row for a in algebra.atoms_of(entry)]
    symbols = sorted(free_symbols_of(atoms) - set(sub.coords), key=lambda s: s.name)

    def f(q, p):
        at = algebra.numeric({**dict(zip(sub.coords, q)), **dict(zip(symbols, p))})
        return [[at(entry) for entry in row] for row in sub.C]

    _sample_rank(model, f, symbols, samples,
                 constant=not symbols and not any(algebra.depends_on(entry) for row in sub.C for entry in row),
                 analytic=not any(a.has(*_PIECEWISE) for a in atoms))


def check_rank(model, positions, samples: int = 3) -> None:
    """Warn when ``C = dx/dxbar`` (21) of the connection's ``positions`` (each ``x`` in the
    generalized coordinates) is rank-deficient at sample configurations; ``C`` is evaluated
    there in floating point (:func:`.numeric_jacobian.jacobian`, each shared subexpression
    once), never formed symbolically."""
    coords = list(model.coordinates)
    positions = [sympy.sympify(x) for x in positions]
    nodes = graph_nodes(positions)
    symbols = sorted({n for n in nodes if n.is_Symbol} - set(coords), key=lambda s: s.name)
    analytic = not any(isinstance(n, _PIECEWISE) for n in nodes)

    def f(q, p):
        return jacobian(positions, coords, {**dict(zip(coords, q)), **dict(zip(symbols, p))})

    _sample_rank(model, f, symbols, samples, constant=not symbols and analytic, analytic=analytic)


_PIECEWISE = (sympy.Abs, sympy.sign, sympy.Heaviside, sympy.DiracDelta, sympy.Piecewise)
"""What makes ``C`` piecewise (``abs`` and ``sign`` in a connection): full rank in one piece
says nothing of another."""


def _sample_rank(model, f, symbols, samples: int, constant: bool, analytic: bool = False) -> None:
    """Warn at the first of ``samples`` random configurations where ``f(q, p)`` (``C``) has
    rank below the number of coordinates.

    An ``analytic`` ``C`` is decided by the first configuration inside the connection's
    domain: with full rank there, a minor of ``C`` is a nonzero analytic function of the
    configuration, zero only on a set of measure zero that further random samples would not
    find either. The other samples are then drawn only past configurations outside the domain."""
    coords = model.coordinates
    values = model.parameter_values()
    rng = np.random.default_rng(20261121)
    for _ in range(1 if constant else samples):
        q = [float(v) for v in rng.uniform(-1.0, 1.0, len(coords))]
        p = [float(values[s]) if s in values and sympy.sympify(values[s]).is_number else float(rng.uniform(0.5, 1.5))
             for s in symbols]
        try:
            m = np.array(f(q, p), dtype=float)
        except (ValueError, ZeroDivisionError, OverflowError, TypeError):
            continue  # outside the subspace's domain at this sample
        if not np.all(np.isfinite(m)):
            continue
        rank = np.linalg.matrix_rank(m) if m.size else 0
        if rank < len(coords):
            where = ", ".join(f"{c}={v:.3g}" for c, v in zip(coords, q))
            loc = model.locations.get("connection")
            prefix = f"{loc}: " if loc else ""
            warnings.warn(RankWarning(
                f"{prefix}C = dx/dxbar has rank {rank} < {len(coords)} at {where}: the generalized "
                "coordinates are not independent there"))
            return
        if analytic:
            return


__all__ = ["RankWarning", "cache_dir", "check_rank", "check_subspace_rank", "content_key", "derive_implicit",
           "derive_model", "load_cached", "store_cached"]
