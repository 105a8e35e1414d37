"""The known-system cache's file format: data that cannot execute.

A derived known system is stored as JSON: its dataclass fields by name (generic over the
fields, so a new field needs no change here), matrices as rows, columns and entries, and
every expression as a node of one shared table (a subexpression used twice is stored once).
A node is ``[head, ...]`` whose head must be on a whitelist: numbers, real symbols, ``Add``,
``Mul``, ``Pow`` and the elementary functions the expression parser admits. Loading rebuilds
the expressions from the table without ``eval`` or ``sympify`` of text, as they were stored
(they are canonical already, so nothing is re-evaluated), in time linear in the table (shared
nodes stay shared), refusing expressions that would grow past :data:`TREE_NODES` nodes as
trees (a term doubled again and again). Anything off the whitelist,
malformed, or written by another format version raises :class:`CacheFormatError`: the caller
treats it as a miss and derives again.
"""
from __future__ import annotations

import dataclasses
import functools
import json
from types import MappingProxyType

import sympy
from sympy.matrices.dense import MutableDenseMatrix
from sympy.matrices.immutable import ImmutableDenseMatrix

from ..components.base import Body
from ..collector import collector_paused
from ..components.base import Requirement
from ..core import canonical
from ..core.deferred import DeferredMatrix, pending
from ..core.known_system import (Constraint, ImplicitSubspace, KnownSystem, ParameterInfo, ProjectedEffect,
                                 SpeedEquations, Transition)
from ..core.nonholonomic import SpeedProjection, VelocityTransformation
from ..core.placed import PlacedBodies, PlacedPoints
from ..core.sympy_internals import (assume_defined, assumptions_given, basic_new, float_new, float_parts,
                                     valid_nargs)
from ..errors import Location

FORMAT = "kronsub-known-system/1"

#: the dataclasses a cache file may hold, by name
CLASSES = {cls.__name__: cls for cls in (KnownSystem, Transition, ParameterInfo, Body, ProjectedEffect,
                                          ImplicitSubspace, Constraint, Requirement, Location,
                                          SpeedEquations, SpeedProjection, VelocityTransformation)}

#: the functions an expression may apply (those of the parser, kronsub/model/expressions.py)
FUNCTIONS = {cls.__name__: cls for cls in (
    sympy.sin, sympy.cos, sympy.tan, sympy.asin, sympy.acos, sympy.atan, sympy.atan2,
    sympy.sinh, sympy.cosh, sympy.tanh, sympy.exp, sympy.log, sympy.Abs, sympy.sign)}

#: numeric constants that are not Integer or Rational, by name
CONSTANTS = {"pi": sympy.pi, "E": sympy.E, "I": sympy.I, "oo": sympy.oo, "-oo": -sympy.oo,
             "nan": sympy.nan, "zoo": sympy.zoo}
_CONSTANT_NAMES = {value: name for name, value in CONSTANTS.items()}

MATRICES = {"Matrix": MutableDenseMatrix, "ImmutableMatrix": ImmutableDenseMatrix}
_MATRIX_NAMES = {cls: name for name, cls in MATRICES.items()}


class CacheFormatError(ValueError):
    """A cache file (or a value to store) that is not in the format: a cache miss."""


# ---------------------------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------------------------

class _Encoder:
    def __init__(self, unbuilt: bool = False):
        self.unbuilt = unbuilt  # a matrix not built yet written as its shape (a fingerprint's text)
        self.nodes: list = []
        self.index: dict = {}  # id(expr) -> node number
        self.keep: list = []  # keeps the encoded expressions alive, so their ids stay theirs
        self.shared: dict = {}  # structural key -> node number

    def expr(self, e) -> int:
        found = self.index.get(id(e))
        if found is not None:
            return found
        node = self._node(e)
        key = tuple(node)
        number = self.shared.get(key)
        if number is None:
            number = self.shared[key] = len(self.nodes)
            self.nodes.append(node)
        self.index[id(e)] = number
        self.keep.append(e)
        return number

    def _node(self, e) -> list:
        cls = type(e)
        if isinstance(e, sympy.Symbol):
            if cls is not sympy.Symbol:  # Dummy, Wild: not data of a model
                raise CacheFormatError(f"cannot store a {cls.__name__}")
            given = assumptions_given(e)
            return ["S", e.name, *sorted(k for k, v in given.items() if v),
                    *sorted("!" + k for k, v in given.items() if not v)]
        if isinstance(e, sympy.Integer):
            return ["N", int(e)]
        if isinstance(e, sympy.Rational):
            return ["Q", int(e.p), int(e.q)]
        if isinstance(e, sympy.Float):
            (sign, man, exp, bc), prec = float_parts(e)
            return ["F", int(sign), hex(int(man)), int(exp), int(bc), int(prec)]
        if e in _CONSTANT_NAMES and not e.args:
            return ["C", _CONSTANT_NAMES[e]]
        if cls is sympy.Add or cls is sympy.Mul or cls is sympy.Pow or FUNCTIONS.get(cls.__name__) is cls:
            return [cls.__name__, *(self.expr(a) for a in e.args)]
        raise CacheFormatError(f"cannot store a {cls.__name__}")

    def value(self, v):
        if v is None or isinstance(v, (bool, str)):
            return v
        if isinstance(v, int):
            return int(v)
        if isinstance(v, float):
            return {"r": repr(v)}
        if isinstance(v, sympy.MatrixBase):
            if self.unbuilt and pending(v):
                return {"u": [v.rows, v.cols]}
            name = _MATRIX_NAMES.get(MutableDenseMatrix if isinstance(v, DeferredMatrix) else type(v))  # built
            if name is None:
                raise CacheFormatError(f"cannot store a {type(v).__name__}")
            return {"m": [name, v.rows, v.cols, [self.expr(e) for e in v]]}
        if isinstance(v, sympy.Basic):
            return {"x": self.expr(v)}
        if isinstance(v, (tuple, PlacedBodies)):
            return {"t": [self.value(x) for x in v]}
        if isinstance(v, (dict, MappingProxyType, PlacedPoints)):
            return {"d": [[self.value(k), self.value(x)] for k, x in v.items()]}
        stored = stored_class(v)
        if stored is not None:
            return {"c": stored.__name__,
                    "f": {f.name: self.value(getattr(v, f.name)) for f in dataclasses.fields(v)}}
        raise CacheFormatError(f"cannot store a {type(v).__name__}")


def stored_class(v) -> type | None:
    """The class of :data:`CLASSES` that ``v`` is stored as: its own, or the one it subclasses
    without adding data (the notebook's ``api.System`` is a ``KnownSystem``); else None."""
    if not dataclasses.is_dataclass(v) or isinstance(v, type):
        return None
    for cls in type(v).__mro__:
        if CLASSES.get(cls.__name__) is cls:
            same = [f.name for f in dataclasses.fields(cls)] == [f.name for f in dataclasses.fields(v)]
            return cls if same else None
    return None


def dumps(value, unbuilt: bool = False) -> str:
    """The JSON text of ``value`` (a known system, a transition, ...); raises
    :class:`CacheFormatError` when it holds anything the format does not admit. ``unbuilt``: a
    matrix whose entries are not built yet (:func:`~kronsub.core.deferred.pending`) is written as
    its shape, not built (a text to fingerprint, which :func:`loads` does not read back)."""
    enc = _Encoder(unbuilt)
    try:
        body = enc.value(value)
        return json.dumps({"format": FORMAT, "nodes": enc.nodes, "value": body},
                          separators=(",", ":"), ensure_ascii=True)
    except (ValueError, RecursionError) as exc:  # an integer too long for JSON, a tree too deep
        if isinstance(exc, CacheFormatError):
            raise
        raise CacheFormatError(f"cannot store: {exc}") from None


# ---------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------

def _fail(why: str):
    raise CacheFormatError(why)


_SYMBOLS: dict[tuple, sympy.Symbol] = {}
"""Symbols already read, by their node's name and flags (a symbol is immutable and sympy
makes one object per name and assumptions anyway): a file names the same few again."""


def _symbol(node: list) -> sympy.Symbol:
    seen = tuple(node[1:])
    try:
        return _SYMBOLS[seen]
    except (KeyError, TypeError):  # (a TypeError: a flag that is not a string, refused below)
        pass
    name, flags = node[1], node[2:]
    if not isinstance(name, str) or not all(isinstance(f, str) for f in flags):
        _fail("malformed symbol")
    assumptions = {}
    for flag in flags:
        key, value = (flag[1:], False) if flag.startswith("!") else (flag, True)
        if key not in assume_defined:
            _fail(f"unknown assumption {key!r}")
        assumptions[key] = value
    symbol = sympy.Symbol(name, **assumptions)
    if len(_SYMBOLS) < 1 << 16:
        _SYMBOLS[seen] = symbol
    return symbol


def _float(node: list) -> sympy.Float:
    if len(node) != 6 or not all(type(x) is int for x in node[1:2] + node[3:]) or not isinstance(node[2], str):
        _fail("malformed float")
    sign, man, exp, bc, prec = node[1], int(node[2], 16), node[3], node[4], node[5]
    if sign not in (0, 1) or man < 0 or bc != man.bit_length() or not 1 <= prec <= 100_000:
        _fail("malformed float")
    return float_new((sign, man, exp, bc), prec)


def _int(x) -> int:
    if type(x) is not int:
        _fail("malformed number")
    return x


_FUNCTION_HEADS = frozenset(("Pow", *FUNCTIONS))
_INT = {int}


def _nodes(table) -> list:
    """Rebuild the expression table; a node may refer only to nodes before it.

    A reference is looked up as it is read (one past the nodes built so far fails there) and
    checked once for the whole table at the end: a whole number, not negative (a bool is no
    index; a negative one would count from the end). A table that fails is thrown away whole,
    so nothing built from a bad reference is ever returned."""
    if not isinstance(table, list):
        _fail("malformed node table")
    built: list = []
    keep = built.append
    sizes: list = []  # each node's size as a tree (what a walk that does not share would visit)
    size_of = sizes.__getitem__
    references: list = []
    note = references.extend
    noncommutative: set[int] = set()  # the nodes that are not commutative (none, in kronsub's systems)
    new, get = basic_new, built.__getitem__
    for number, node in enumerate(table):
        if type(node) is not list or not node:
            _fail("malformed node")
        head = node[0]
        if head == "Mul" or head == "Add":
            refs = node[1:]
            if len(refs) < 2:
                _fail(f"malformed {head}")
            try:  # what ``Add._from_args`` does with two or more terms in canonical order
                e = new(sympy.Mul if head == "Mul" else sympy.Add, *map(get, refs))
            except (IndexError, TypeError):
                _fail("a node refers to a later one, or by something other than its number")
            note(refs)
            sizes.append(_tree_size(map(size_of, refs)))
            # a sum's or product's commutativity, from its terms'
            commutative = not noncommutative or noncommutative.isdisjoint(refs)
            e.is_commutative = commutative
            keep(e)
            if not commutative:
                noncommutative.add(number)
            continue
        if type(head) is not str:
            _fail("malformed node")
        if head in _FUNCTION_HEADS:
            refs = node[1:]
            try:
                args = [built[i] for i in refs] if refs else _fail("malformed node arguments")
            except (IndexError, TypeError):
                _fail("a node refers to a later one, or by something other than its number")
            note(refs)
            sizes.append(_tree_size(map(size_of, refs)))
            if head == "Pow":
                e = sympy.Pow(*args, evaluate=False) if len(args) == 2 else _fail("malformed Pow")
            else:
                if not valid_nargs(FUNCTIONS[head], len(args)):
                    _fail(f"malformed {head}: {len(args)} arguments")
                e = canonical.function(FUNCTIONS[head], *args)
                if noncommutative and not noncommutative.isdisjoint(refs):  # sympy's rule for a Function
                    noncommutative.add(number)
                keep(e)
                continue
        elif head == "S" and len(node) >= 2:
            e = _symbol(node)
        elif head == "N" and len(node) == 2:
            e = sympy.Integer(_int(node[1]))
        elif head == "Q" and len(node) == 3:
            p, q = _int(node[1]), _int(node[2])
            e = sympy.Rational(p, q) if q > 1 else _fail("malformed rational")
        elif head == "F":
            e = _float(node)
        elif head == "C" and len(node) == 2 and node[1] in CONSTANTS:
            e = CONSTANTS[node[1]]
        else:
            _fail(f"node head {head!r} is not admitted")
        if len(sizes) == number:  # a leaf
            sizes.append(1)
        keep(e)
        if not e.is_commutative:
            noncommutative.add(number)
    if references and (set(map(type, references)) != _INT or min(references) < 0):
        _fail("malformed node arguments: a reference that is not a node's number")
    return built


TREE_NODES = 10_000_000
"""The most nodes an expression of a cache file may have as a tree. The table shares repeated
subexpressions, and loading it is linear in its length, but what uses an expression may walk
it as a tree; a table whose expressions double a term again and again (2**80 nodes in 80
lines) is refused, so it is rebuilt, not walked. Derived systems stay far below (tens of
thousands)."""


def _tree_size(sizes) -> int:
    size = 1 + sum(sizes)
    if size > TREE_NODES:
        _fail(f"an expression of more than {TREE_NODES} nodes as a tree")
    return size


@functools.lru_cache(maxsize=None)
def _field_names(cls: type) -> frozenset:
    return frozenset(f.name for f in dataclasses.fields(cls))


class _Decoder:
    def __init__(self, built: list):
        self.built = built

    def expr(self, i):
        if type(i) is not int or not 0 <= i < len(self.built):
            _fail("malformed expression reference")
        return self.built[i]

    def value(self, v):
        if v is None or isinstance(v, (bool, str, int)):
            return v
        if not isinstance(v, dict) or len(v) != 1 and "c" not in v:
            _fail("malformed value")
        if "x" in v:
            return self.expr(v["x"])
        if "r" in v and isinstance(v["r"], str):
            try:
                return float(v["r"])
            except ValueError:
                _fail("malformed number")
        if "t" in v and isinstance(v["t"], list):
            return tuple(self.value(x) for x in v["t"])
        if "d" in v and isinstance(v["d"], list):
            pairs = v["d"]
            if not all(isinstance(p, list) and len(p) == 2 for p in pairs):
                _fail("malformed mapping")
            return {self._key(k): self.value(x) for k, x in pairs}
        if "m" in v and isinstance(v["m"], list) and len(v["m"]) == 4:
            name, rows, cols, entries = v["m"]
            cls = MATRICES.get(name) if isinstance(name, str) else None
            if cls is None or type(rows) is not int or type(cols) is not int or rows < 0 or cols < 0 \
                    or not isinstance(entries, list) or len(entries) != rows * cols:
                _fail("malformed matrix")
            return canonical.matrix(rows, cols, [self.expr(i) for i in entries], cls)
        if set(v) == {"c", "f"} and isinstance(v["f"], dict):
            cls = CLASSES.get(v["c"]) if isinstance(v["c"], str) else None
            if cls is None:
                _fail(f"class {v['c']!r} is not admitted")
            if v["f"].keys() != _field_names(cls):
                _fail(f"the fields of {cls.__name__} differ")
            return cls(**{k: self.value(x) for k, x in v["f"].items()})
        _fail("malformed value")

    def _key(self, k):
        key = self.value(k)
        if not isinstance(key, (str, int, sympy.Basic)):
            _fail("malformed mapping key")
        return key


def loads(text: str | bytes, expected: type | None = None):
    """The value stored by :func:`dumps`; raises :class:`CacheFormatError` on anything else
    (another format version, a head off the whitelist, a malformed table)."""
    with collector_paused():  # thousands of new objects, no cycles (see kronsub.collector)
        try:
            data = json.loads(text)
        except (ValueError, RecursionError) as exc:
            raise CacheFormatError(f"not JSON: {exc}") from None
        if not isinstance(data, dict) or data.get("format") != FORMAT or set(data) != {"format", "nodes", "value"}:
            _fail("not a kronsub known-system file of this version")
        try:
            value = _Decoder(_nodes(data["nodes"])).value(data["value"])
        except CacheFormatError:
            raise
        except (TypeError, ValueError, AttributeError, RecursionError) as exc:
            raise CacheFormatError(f"malformed: {exc}") from None
    if expected is not None and not isinstance(value, expected):
        _fail(f"expected a {expected.__name__}")
    return value


__all__ = ["CLASSES", "CONSTANTS", "CacheFormatError", "FORMAT", "FUNCTIONS", "MATRICES", "TREE_NODES", "dumps",
           "loads", "stored_class"]
