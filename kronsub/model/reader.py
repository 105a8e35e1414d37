"""The reading context of a model file: its problems, names, parameters and the shared readers.

Every section reader (``parameters.py``, ``components.py``, ``parts.py``, ``known_systems.py``,
``coordinates.py``, ``connection.py``, ``constraints.py``, ``definitions.py``, ``effects.py``,
``initial.py``, ``scenes.py``; ``loader.py`` calls them in order) takes the one
:class:`ModelReader` of the file being read; every problem is collected with its file, line and
column and raised together as one :class:`ModelError`.
"""
from __future__ import annotations

import dataclasses
import difflib
import re
from pathlib import Path

import sympy

from ..budget import WorkBudgetExceeded
from ..components.base import Requirement
from ..core.known_system import ParameterInfo
from ..core.primitive import Part
from ..core.symbols import TIME, free_symbols_of
from ..errors import Location, ModelError, ProblemCollector, close_matches, near_names
from .expressions import parse_expression
from .files import resolved_path
from .file_reading import SourceFile
from .units import check_units, dimension
from .source import Node, excerpt

IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")  # whole names only: fullmatch
RESERVED = {"t", "pi"}
OUTPUT_COLUMNS = ("kinetic_energy", "potential_energy", "total_energy")
"""Columns of a trajectory beside the state (``kronsub/simulation/table.py``): a coordinate of
one of these names would be written twice and lost from the DataFrame."""
MEANT_RATIO = 0.8
"""How like a valid key a misspelt one must be (difflib's ratio) to be read as that key."""
_UNKNOWN_NAME = re.compile(r"unknown name '([^']+)'")


class ModelReader:
    """The reading of one model file: what the section readers share.

    They may use: :meth:`error` (record a problem at a node or location; all are raised together
    as one :class:`ModelError`), ``problems`` (the collector), ``root`` (the file's top node),
    ``locations`` (item -> where it was written), :meth:`expr` (parse a scalar as an expression),
    :meth:`string`, :meth:`mapping`, :meth:`check_keys`, :meth:`identifier`, ``names`` and
    ``primitive_names``, ``subspace_names`` (the symbols an expression may use), ``parameters``,
    :meth:`parameter_names`, :meth:`parameter_values`, ``definitions``, :meth:`is_broken` and
    ``failed_components`` (parts that failed, so a later reference reports nothing more),
    ``pivots`` and ``auto_connection`` (parts hung from a moving point), ``requirements``, ``parts``,
    and the definitions in place (:meth:`definition_names`, :meth:`substitute_definitions`).
    """

    def __init__(self, path: Path, root: Node, text: str, stack: tuple[str, ...], cache: bool = True,
                 source: SourceFile | None = None):
        self.cache = cache
        self.source = source  # the file as read (None: the text was given)
        self.used: list[SourceFile] = []  # the model files read for the known systems, recursively
        self.parsed: dict = {}  # parts of expressions built so far (parse_expression's shared)
        self.path = path
        self.file = str(path)
        self.root = root
        self.text = text
        self.stack = stack + (resolved_path(path),)
        self.problems = ProblemCollector()
        self.names: dict[str, sympy.Basic] = {"t": TIME}
        self.parameters: dict[str, ParameterInfo] = {}
        self.declared: set[str] = set()  # parameters this model declares itself
        self.inherited: dict[str, tuple[str, sympy.Expr | None]] = {}  # name -> (component, value) first brought
        self.parts: list[Part] = []
        self.sub_hashes: list[str] = []
        self.locations: dict[str, Location] = {}
        self.failed_components = False
        self.requirements: list[Requirement] = []  # what the components need of the parameters' values
        # one typo, one error: names of components that failed, and the coordinate names their
        # `coordinates:` renames declared, so later references to them report nothing more
        self.broken_parts: set[str] = set()
        self.broken_names: set[str] = set()
        self.generalized_names: set[str] = set()
        self.primitive_names: dict[str, sympy.Symbol] = {}
        self.subspace_names: dict[str, sympy.Symbol] = {}  # the connection's coordinates, for effects
        self.pivots: list[tuple] = []  # pinned parts hanging from a moving point (`pivot:`)
        self.auto_connection: dict[sympy.Symbol, tuple] = {}
        self.joints: list = []  # where the joints of `constraints:` act (constraints.Joint), for drawing
        # `definitions:` (definitions.py): name -> (placeholder, expansion; None when it failed)
        self.definitions: dict[str, tuple[sympy.Symbol, sympy.Expr | None]] = {}
        self.definition_keys: set[str] = set()  # their names, known before they are read
        self.currents: dict[str, str] = {}  # charge coordinate -> its current's name (currents.py)
        self._units_of: tuple[int, dict, dict] = (-1, {}, {})  # (parameters seen, their dimensions, the
        # dimensions of the subexpressions met) for check_units

    def error(self, node_or_loc, message: str, hint: str | None = None) -> None:
        loc = node_or_loc.location if isinstance(node_or_loc, Node) else node_or_loc
        self.problems.add(loc, message, hint)

    def expr(self, node: Node, names: dict | None = None, what: str = "expression") -> sympy.Expr | None:
        """Parse a scalar node as an expression; None (problem recorded) on failure."""
        if not node.is_scalar or node.value is None or isinstance(node.value, bool):
            self.error(node, f"expected {what} (a number or a formula), found {node_kind(node)}",
                       "write e.g. `2*a1*sin(theta)`")
            return None
        text = node.text if node.text is not None else str(node.value)
        table = names if names is not None else self.names
        try:
            value = parse_expression(text, {**table, **self.definition_names()},
                                     node.text_location or node.location, what=what, shared=self.parsed)
        except WorkBudgetExceeded:
            raise  # the budget is spent: nothing further is read
        except ModelError as exc:
            for problem in exc.problems:
                unknown = _UNKNOWN_NAME.search(problem.message)
                if unknown and self.is_broken(unknown.group(1)):
                    continue  # a consequence of a component reported already
                generalized = unknown and self.generalized_name(unknown.group(1))
                if unknown and unknown.group(1) in self.definition_keys and unknown.group(1) not in self.definitions:
                    problem = dataclasses.replace(problem, hint=(
                        f"'{unknown.group(1)}' is a definition; definitions are read after the parameters and "
                        "components, so they cannot be used in parameter values, component parameters or "
                        "points: write the expression here, or make it a parameter"))
                elif generalized:
                    problem = self.generalized_problem(problem, unknown.group(1), generalized)
                elif unknown and unknown.group(1) == "t":
                    problem = dataclasses.replace(problem, hint=(
                        "`t` (time) cannot appear here: the effects (and a known system's parameters that "
                        "drive its effects alone), the connection and `prescribed:` motions may depend on time; "
                        "constraints, component parameters and values may not"))
                elif unknown and unknown.group(1) in self.parameters:
                    problem = dataclasses.replace(problem, hint=(
                        f"'{unknown.group(1)}' is a parameter, and a parameter's value is a constant: write a "
                        "number (or an expression of numbers), and the formula where the value is used"))
                self.problems.problems.append(problem)
            return None
        value = self.substitute_definitions(value, table, node, what)
        if value is not None and isinstance(value, sympy.Basic) and value.has(sympy.Add):
            if len(self.parameters) != self._units_of[0]:  # the parameters' dimensions, read once
                self._units_of = (len(self.parameters), {info.symbol: dimension(info.unit)
                                                         for info in self.parameters.values() if info.unit}, {})
            units = self._units_of[1]
            if units:
                check_units(value, units, str(node.text_location or node.location), self._units_of[2])
        return value

    def generalized_name(self, name: str) -> str | None:
        """"coordinate" or "velocity" when ``name`` is a generalized coordinate (or its velocity)
        that is not also a primitive one; else None."""
        if name in self.generalized_names and name not in self.primitive_names:
            return "coordinate"
        base = name[:-4] if name.endswith("_dot") else None
        if base and base in self.generalized_names and base not in self.primitive_names:
            return "velocity"
        return None

    def generalized_problem(self, problem, name: str, kind: str):
        """The unknown-name problem for a generalized coordinate or velocity, said as such."""
        return dataclasses.replace(problem, hint=f"'{name}' is a generalized {kind}, which cannot appear here")

    def mapping(self, node: Node | None, what: str, hint: str) -> dict[str, Node]:
        if node is None or node.value is None:
            return {}
        if not node.is_mapping:
            self.error(node, f"`{what}` must be a mapping, found {node_kind(node)}", hint)
            return {}
        return node.value

    def check_keys(self, node: Node, allowed, what: str) -> Node:
        """Report every key of ``node`` not in ``allowed``; return ``node`` read as meant.

        A misspelt key whose one near name is absent (``coordinate:`` for ``coordinates:``) is
        reported once and its value read under that name, so that what depends on it is checked
        as written instead of failing again for the key's absence."""
        meant = {}
        for key in node.value:
            if key not in allowed:
                near = near_names(key, allowed) if isinstance(key, str) else []
                if (near and near[0] not in node.value and near[0] not in meant.values()
                        and difflib.SequenceMatcher(None, key, near[0]).ratio() >= MEANT_RATIO):
                    meant[key] = near[0]
                split = isinstance(key, str) and not IDENTIFIER.fullmatch(key.strip()) and any(
                    c in key for c in ")]*/+-")
                self.error(node.key_locations.get(key, node.location), f"unknown key '{key}' in {what}",
                           "this looks like the rest of an expression: in a `{...}` mapping a comma ends the "
                           "value, so quote an expression with commas, e.g. `value: \"atan2(y, x)\"`"
                           if split else f"did you mean '{meant[key]}'?" if key in meant
                           else close_matches(key, allowed))
        if not meant:
            return node
        return dataclasses.replace(
            node, value={meant.get(k, k): v for k, v in node.value.items()},
            key_locations={meant.get(k, k): loc for k, loc in node.key_locations.items()})

    def identifier(self, name: str, loc: Location, what: str) -> bool:
        if not IDENTIFIER.fullmatch(name):
            self.error(loc, f"{what} name {name!r} is not a valid name",
                       "use letters, digits and underscores, starting with a letter")
            return False
        if name in RESERVED:
            self.error(loc, f"{what} name '{name}' is reserved", "'t' is time and 'pi' is the constant")
            return False
        if what == "coordinate" and name in OUTPUT_COLUMNS:
            self.error(loc, f"{what} name '{name}' is the name of a column `simulate` writes",
                       f"rename it: beside the state, the trajectory has the columns {', '.join(OUTPUT_COLUMNS)}")
            return False
        return True

    def parameter_values(self) -> dict:
        """The parameters' values (symbol -> number) as declared or inherited."""
        return {info.symbol: info.value for info in self.parameters.values() if info.value is not None}

    def string(self, node: Node | None, default: str) -> str:
        if node is None:
            return default
        if not node.is_scalar or not isinstance(node.value, str):
            self.error(node, f"expected text, found {node_kind(node)}", "quote it")
            return default
        return node.value

    def add_parameter(self, info: ParameterInfo, *, inherited: bool = False, location: Location | None = None) -> None:
        if location is not None and (not inherited or f"parameter:{info.name}" not in self.locations):
            self.locations[f"parameter:{info.name}"] = location
        if info.name in self.parameters:
            if not inherited:
                self.parameters[info.name] = info
            return
        self.parameters[info.name] = info
        self.names[info.name] = info.symbol

    def is_broken(self, name: str) -> bool:
        """Whether ``name`` (plain or dotted) belongs to a component that failed to load."""
        return name in self.broken_names or name.split(".", 1)[0] in self.broken_parts

    def parameter_names(self) -> dict[str, sympy.Symbol]:
        return {k: v.symbol for k, v in self.parameters.items()}

    def definition_names(self) -> dict[str, sympy.Symbol]:
        """The definitions' placeholders by name, for the parser (empty before they are read)."""
        return {name: placeholder for name, (placeholder, _) in self.definitions.items()}

    def substitute_definitions(self, value, table: dict, node: Node, what: str):
        """``value`` (parsed with the definitions' placeholders) with each definition put in its
        place; a definition using a name that ``table`` (what this place may use) lacks is a problem."""
        if value is None or not self.definitions:
            return value
        used = [(name, ph, expansion) for name, (ph, expansion) in self.definitions.items()
                if ph in getattr(value, "free_symbols", ())]
        if not used:
            return value
        if any(expansion is None for _, _, expansion in used):
            return None  # the definition's own problem is reported already
        allowed = {v for v in table.values() if isinstance(v, sympy.Symbol)} | {TIME}
        ok = True
        for name, _, expansion in used:
            foreign = sorted(s.name for s in free_symbols_of([expansion]) - allowed)
            if foreign:
                ok = False
                can = sorted(k for k, v in table.items() if isinstance(v, sympy.Symbol) and "." not in k and k != "t")
                shown = ", ".join(can[:16]) + (", ..." if len(can) > 16 else "") if can else "none: numbers only"
                self.error(node, f"in {what}: definition '{name}' uses {', '.join(repr(f) for f in foreign)}, "
                                   "which cannot appear here",
                           f"names usable here: {shown}")
        if not ok:
            return None
        return value.xreplace({ph: expansion for _, ph, expansion in used})


def node_kind(node: Node) -> str:
    if node.is_mapping:
        return "a mapping"
    if node.is_sequence:
        return "a list"
    if node.value is None:
        return "nothing"
    return f"'{excerpt(node.text if node.text is not None else str(node.value))}'"


__all__ = ["IDENTIFIER", "OUTPUT_COLUMNS", "RESERVED", "ModelReader", "node_kind"]
