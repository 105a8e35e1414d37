"""The runs of a sweep, numbered 0 .. count-1, and the inputs of any range of them.

The grid axes (and a table of runs, one axis of several names) are crossed (the last varies
fastest); with sample axes each grid point gets
``samples`` runs, run ``i`` at grid point ``i // samples``. Run ``i``'s uniform number on sample
axis ``j`` is a counter-based hash of ``(seed, j, i)`` (:func:`uniforms`, splitmix64), so the same
spec and seed give the same inputs whichever chunks the runs are cut into; a distribution turns
it into its value by its inverse CDF. A Latin hypercube (``latin``) puts the draw ``w`` of a grid point in stratum
``perm_j(w)`` of axis ``j``, a permutation drawn from ``(seed, j)`` and evaluated draw by draw
(:func:`strata`), so that no worker holds all of it."""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass

import numpy as np

from .axes import GridAxis, SampleAxis, TableAxis

__all__ = ["FEISTEL_ROUNDS", "MAX_RUNS", "Plan", "strata", "uniforms"]

FEISTEL_ROUNDS = 4  # Luby and Rackoff: four rounds of a pseudo-random function make a pseudo-random permutation
MAX_RUNS = 10**9  # runs of one sweep: more is a mistake in the spec (and years of computing), not a study

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _mix(x: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser (Steele, Lea & Flood 2014), on uint64 arrays (wrapping)."""
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


def uniforms(seed: int, axis: int, runs: np.ndarray) -> np.ndarray:
    """A uniform number in (0, 1) for each run index of ``runs`` on ``axis``: 53 bits of
    ``mix(mix(seed, axis) + (run + 1) golden)``, offset by half a unit so never 0 or 1."""
    with np.errstate(over="ignore"):
        key = _mix(np.array([seed & 0xFFFFFFFFFFFFFFFF], dtype=np.uint64) ^ _mix(np.array([axis + 1], dtype=np.uint64)))
        x = _mix(key + (np.asarray(runs, dtype=np.uint64) + np.uint64(1)) * _GOLDEN)
    return ((x >> np.uint64(11)).astype(np.float64) + 0.5) * 2.0**-53


def strata(seed: int, axis: int, count: int, within: np.ndarray) -> np.ndarray:
    """The Latin hypercube's stratum of each draw ``within`` (``0 .. count-1``) on ``axis``: a
    permutation of ``0 .. count-1`` drawn from ``(seed, axis)``, evaluated only at ``within`` (memory
    as ``within``, not as ``count``). A balanced Feistel network of :data:`FEISTEL_ROUNDS` rounds on
    ``2 k`` bits, ``4^k >= count``, each round's function :func:`_mix` keyed by ``(seed, axis,
    round)``, is a permutation of ``0 .. 4^k - 1``; a value ``>= count`` is sent through it again
    until it falls below (cycle walking), which leaves a permutation of ``0 .. count-1``."""
    k = max(1, math.ceil(math.log2(max(count, 2)) / 2))
    while 4 ** k < count:
        k += 1
    half, mask = np.uint64(k), np.uint64((1 << k) - 1)
    with np.errstate(over="ignore"):
        keys = [_mix(np.array([(seed ^ 0x5A17) & 0xFFFFFFFFFFFFFFFF], dtype=np.uint64)
                     ^ _mix(np.array([(axis + 1) * FEISTEL_ROUNDS + r], dtype=np.uint64))) for r in range(FEISTEL_ROUNDS)]

        def encrypt(x: np.ndarray) -> np.ndarray:
            left, right = x >> half, x & mask
            for key in keys:
                left, right = right, left ^ (_mix(key + right * _GOLDEN) & mask)
            return (left << half) | right

        y = encrypt(np.asarray(within, dtype=np.uint64))
        outside = np.flatnonzero(y >= np.uint64(count))
        while outside.size:
            y[outside] = encrypt(y[outside])
            outside = outside[y[outside] >= np.uint64(count)]
    return y.astype(np.int64)


@dataclass(frozen=True)
class Plan:
    """The runs of a sweep: ``grids`` crossed, times ``samples`` draws of the ``draws`` axes."""

    grids: tuple[GridAxis | TableAxis, ...]
    draws: tuple[SampleAxis, ...]
    samples: int
    seed: int
    latin: bool = False

    @property
    def count(self) -> int:
        return math.prod(len(g) for g in self.grids) * self.samples

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for a in self.grids for name in a.names) + tuple(a.name for a in self.draws)

    def inputs(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """The swept values of runs ``start .. stop-1``, by name."""
        runs = np.arange(start, stop, dtype=np.int64)
        out: dict[str, np.ndarray] = {}
        point = runs // self.samples
        for axis in reversed(self.grids):  # the last axis varies fastest
            n = len(axis)
            out.update(axis.take(point % n))
            point = point // n
        for j, axis in enumerate(self.draws):
            u = uniforms(self.seed, j, runs)
            if self.latin:
                within = runs % self.samples
                u = (strata(self.seed, j, self.samples, within) + u) / self.samples
            out[axis.name] = axis.transform(u)
        return {name: out[name] for name in self.names}

    def describe(self) -> dict:
        """The plan as JSON data (the sidecar's ``spec``)."""
        return {"grid": {k: v for a in self.grids for k, v in a.describe().items()},
                "sample": {a.name: a.text for a in self.draws},
                "samples": self.samples, "seed": self.seed, "latin": self.latin, "runs": self.count}

    def digest(self) -> str:
        return hashlib.sha256(json.dumps(self.describe(), sort_keys=True).encode()).hexdigest()
