"""Load a YAML model file into `Node` trees that remember where things are.

Only `yaml.compose` with the safe loader is used, so nothing in a model file
is ever turned into a Python object other than plain data. Every value keeps
its 1-based line and column, and every scalar keeps the text it was written
with (so ``9.81`` can later become the exact rational 981/100).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import yaml
from yaml.constructor import SafeConstructor
from yaml.nodes import MappingNode, ScalarNode, SequenceNode

from kronsub.errors import Location, ModelError, Problem, ProblemCollector

from .file_reading import read_model_text

_TAG = "tag:yaml.org,2002:"
_MAP, _SEQ, _MERGE = _TAG + "map", _TAG + "seq", _TAG + "merge"
_CONSTRUCTOR = SafeConstructor()
_SCALAR_TAGS: dict[str, Callable[[ScalarNode], Any]] = {
    _TAG + "str": lambda node: node.value,
    _TAG + "int": _CONSTRUCTOR.construct_yaml_int,
    _TAG + "float": _CONSTRUCTOR.construct_yaml_float,
    _TAG + "bool": _CONSTRUCTOR.construct_yaml_bool,
    _TAG + "null": _CONSTRUCTOR.construct_yaml_null,
    # Dates, a lone ``=`` and a lone ``<<`` as values are kept as plain text.
    _TAG + "timestamp": lambda node: node.value,
    _TAG + "value": lambda node: node.value,
    _MERGE: lambda node: node.value,
}
_DEFAULT_HINT = "check the indentation and that every `key: value` has a space after the colon"
_PLAIN_DATA_HINT = "a model file is plain data: remove the tag"
_LEFT_OUT = object()  # a value an outline does not convert


@dataclass(frozen=True)
class Node:
    """A YAML value with its position in the file.

    ``value`` is a ``dict[str, Node]`` (file order) for a mapping, a
    ``tuple[Node, ...]`` for a sequence, and for a scalar the str, int, float,
    bool or None the safe loader resolves (dates stay str). ``text`` is the
    scalar's text as written (quotes and escapes removed; None for
    containers). ``location`` is where the value starts; ``text_location`` is
    where ``text`` itself starts (after an opening quote, or on the first
    line of a ``|``/``>`` block). ``key_locations`` maps each key of a
    mapping to where the key starts. Nodes hold dicts, so they are not
    hashable.
    """

    value: Any
    text: str | None
    location: Location
    key_locations: dict[str, Location] = field(default_factory=dict)
    text_location: Location | None = None

    @property
    def is_mapping(self) -> bool:
        return isinstance(self.value, dict)

    @property
    def is_sequence(self) -> bool:
        return isinstance(self.value, tuple)

    @property
    def is_scalar(self) -> bool:
        return not (self.is_mapping or self.is_sequence)

    def get(self, key: str, default: Node | None = None) -> Node | None:
        """The value under ``key`` of a mapping (``default`` if absent or not a mapping)."""
        if not self.is_mapping:
            return default
        return self.value.get(key, default)

    def to_python(self) -> Any:
        """The plain Python data (dicts, lists, scalars); aliases are copied."""
        if self.is_mapping:
            return {key: node.to_python() for key, node in self.value.items()}
        if self.is_sequence:
            return [node.to_python() for node in self.value]
        return self.value


def load_yaml(path: str | Path, text: str | None = None, only: Mapping | None = None) -> Node:
    """Parse a YAML model file (or ``text``, named ``path`` in messages).

    Raises `ModelError` listing every problem found: unreadable or empty
    file, YAML syntax, duplicate or non-string keys, unsupported tags.
    ``only``: an outline of the values it names (:meth:`_Converter.outline`); every
    other value is ``None``, unchecked, with where it starts.
    """
    name = str(path)
    if text is None:
        text = read_model_text(Path(path))
    root = _compose(text, name)
    if root is None:
        raise ModelError([Problem(
            Location(name, 1, 1), "the file is empty",
            "write the model as YAML `key: value` lines")])
    converter = _Converter(name, text)
    try:
        node = converter.outline(root, only) if only is not None else converter.convert(root)
    except RecursionError:
        raise ModelError([Problem(Location(name), "the YAML is nested too deeply", "flatten the structure")])
    converter.problems.raise_if_any()
    return node


MAX_ALIAS_VALUES = 10_000
"""Most values a file's aliases (``*name``) may repeat in all, each counted with the values
inside it: a few lines of aliases of aliases would otherwise stand for billions of values."""

def excerpt(text: str, limit: int = 40) -> str:
    """At most the first ``limit`` characters of the first line of ``text``, for
    messages: a file that is not a model is never echoed further than that."""
    lines = text.splitlines() or [""]
    first = lines[0]
    if len(first) > limit or len(lines) > 1:
        return first[:limit].rstrip() + "..."
    return first


# libyaml's composer when present (same nodes and marks, several times faster)
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _compose(text: str, name: str) -> yaml.Node | None:
    """The YAML node tree of ``text``; syntax errors become `ModelError`."""
    if _LOADER is not yaml.SafeLoader:
        try:
            return yaml.compose(text, Loader=_LOADER)
        except Exception:
            pass  # the pure-Python parser below words the problem for users
    try:
        return yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as exc:
        raise ModelError([_syntax_problem(exc, name)])
    except yaml.reader.ReaderError as exc:
        location = _location_of_index(name, text, exc.position)
        raise ModelError([Problem(
            location, f"the file contains a character YAML does not allow (U+{exc.character:04X})",
            "remove the character; model files must be plain printable text")])
    except RecursionError:
        raise ModelError([Problem(
            Location(name), "the YAML is nested too deeply", "flatten the structure")])
    except yaml.YAMLError as exc:
        raise ModelError([Problem(Location(name), f"invalid YAML: {exc}", _DEFAULT_HINT)])


def _syntax_problem(exc: yaml.MarkedYAMLError, name: str) -> Problem:
    """A `Problem` at the mark of a scanner/parser/composer error."""
    mark = exc.problem_mark or exc.context_mark
    location = _location_of_mark(name, mark) if mark else Location(name)
    problem, context = exc.problem or "", exc.context or ""
    if problem.startswith("but ") or not problem:
        message = f"{context}, {problem}".strip(", ")
    else:
        message = problem
        if context:
            if context.startswith("while") and exc.context_mark and mark \
                    and exc.context_mark.line != mark.line:
                context += f" that starts at line {exc.context_mark.line + 1}"
            message += f" ({context})"
    return Problem(location, f"invalid YAML: {message}", _syntax_hint(problem, context))


def _syntax_hint(problem: str, context: str) -> str:
    """A hint matching the kind of syntax error."""
    if "'\\t'" in problem:
        return "YAML indentation must use spaces, not tabs"
    if "flow" in context or "expected ',' or" in problem:
        return "close every '[' with ']' and every '{' with '}', and quote values containing ',' '[' ']' '{' '}'"
    if "escape" in problem:
        return "use single quotes, or write a backslash as \\\\ inside double quotes"
    if "quoted scalar" in context:
        return "close the quote, or escape quotes inside the value"
    if "alias" in problem:
        return "define an anchor (&name) before using it as *name"
    if "single document" in context:
        return "a model file holds a single YAML document: remove the extra '---'"
    if "mapping values are not allowed" in problem:
        return _DEFAULT_HINT + "; quote values that contain ': '"
    return _DEFAULT_HINT


def _location_of_mark(name: str, mark: yaml.Mark) -> Location:
    return Location(name, mark.line + 1, mark.column + 1)


def _line_col(text: str, index: int) -> tuple[int, int]:
    index = max(0, min(index, len(text)))
    return text.count("\n", 0, index) + 1, index - (text.rfind("\n", 0, index) + 1) + 1


_ESCAPE_LENGTH = {"x": 4, "u": 6, "U": 10}


def _text_indices(value: str, raw: str, escapes: bool) -> list[int] | None:
    """For each character of a scalar's value, its index in the raw text (or None when the
    two cannot be matched): folded line breaks, indentation and escapes are skipped."""
    indices, j = [], 0
    for ch in value:
        while j < len(raw):
            if raw[j] == ch and not (escapes and ch == "\\"):
                break
            if escapes and raw[j] == "\\":
                if j + 1 < len(raw) and raw[j + 1] == "\n":  # escaped line break
                    j += 2
                    continue
                break
            if raw[j] in " \t\r\n" or (raw[j] == "'" and raw[j:j + 2] == "''"):
                if ch in " \n" and raw[j] in "\r\n":
                    break
                j += 1
                continue
            return None
        if j >= len(raw):
            return None
        indices.append(j)
        if escapes and raw[j] == "\\":
            j += _ESCAPE_LENGTH.get(raw[j + 1] if j + 1 < len(raw) else "", 2)
        elif raw[j] in "\r\n":
            while j < len(raw) and raw[j] in " \t\r\n":
                j += 1
        else:
            j += 1 + (raw[j] == "'" and raw[j:j + 2] == "''")
    return indices


@dataclass(frozen=True)
class TextLocation(Location):
    """Where a scalar's text starts, with the file position of each of its characters."""

    source: str = field(default="", repr=False, compare=False)
    indices: tuple[int, ...] = field(default=(), repr=False, compare=False)

    def shifted(self, columns: int) -> Location:
        if 0 <= columns < len(self.indices):
            return Location(self.file, *_line_col(self.source, self.indices[columns]))
        return Location(self.file, self.line, self.column + columns)


def _location_of_index(name: str, text: str, index: int) -> Location:
    """The location of character ``index`` of ``text``."""
    index = max(0, min(index, len(text)))
    line = text.count("\n", 0, index) + 1
    return Location(name, line, index - (text.rfind("\n", 0, index) + 1) + 1)


class _Converter:
    """Turns composed YAML nodes into `Node` objects, collecting problems."""

    def __init__(self, name: str, text: str):
        self.name = name
        self.text = text
        self.problems = ProblemCollector()
        self.done: dict[int, Node] = {}  # aliases share nodes: convert each once
        self.active: set[int] = set()
        self.sizes: dict[int, int] = {}  # values a node stands for, its aliases' expanded
        self.repeated = 0  # values repeated through aliases, so far

    def convert(self, node: yaml.Node) -> Node:
        key = id(node)
        if key in self.done:
            self._repeat(node)
            return self.done[key]
        location = _location_of_mark(self.name, node.start_mark)
        if key in self.active:
            self.problems.add(location, "an alias refers to a value that contains it",
                              "aliases must not be recursive")
            return Node(None, None, location)
        self.active.add(key)
        try:
            result = self._convert(node, location)
        finally:
            self.active.discard(key)
        self.done[key] = result
        children = node.value if isinstance(node, SequenceNode) else \
            [value for _, value in node.value] if isinstance(node, MappingNode) else ()
        self.sizes[key] = 1 + sum(self.sizes.get(id(child), 1) for child in children)
        return result

    def _repeat(self, node: yaml.Node) -> None:
        """Count the values an alias repeats; refuse (once) beyond `MAX_ALIAS_VALUES`, so that
        nothing that walks the values (a message quoting them, a copy) grows exponentially."""
        before = self.repeated
        self.repeated += self.sizes.get(id(node), 1)
        if self.repeated > MAX_ALIAS_VALUES >= before:
            self.problems.add(_location_of_mark(self.name, node.start_mark),
                              f"aliases repeat more than {MAX_ALIAS_VALUES:,} values (the value anchored "
                              "here is repeated through aliases of aliases)",
                              "write the values out, or use fewer aliases")

    def outline(self, root: yaml.Node, only: Mapping) -> Node:
        """``root`` with only the values ``only`` names converted: ``{key: deeper}``, where
        ``deeper`` is None for the whole value, or names what to take of it in turn
        (``"*"``: every key). A mapping with a ``<<`` merge is converted whole."""
        if not isinstance(root, MappingNode) or root.tag != _MAP:
            return self.convert(root)
        return self._mapping(root, _location_of_mark(self.name, root.start_mark), only)

    def _convert(self, node: yaml.Node, location: Location) -> Node:
        if isinstance(node, ScalarNode):
            return self._scalar(node, location)
        expected = _MAP if isinstance(node, MappingNode) else _SEQ
        if node.tag != expected:
            self._bad_tag(node.tag, location)
        if isinstance(node, SequenceNode):
            return Node(tuple(self.convert(item) for item in node.value), None, location)
        return self._mapping(node, location)

    def _bad_tag(self, tag: str, location: Location) -> None:
        shown = "!!" + tag[len(_TAG):] if tag.startswith(_TAG) else tag
        self.problems.add(location, f"unsupported YAML tag '{shown}'", _PLAIN_DATA_HINT)

    def _scalar(self, node: ScalarNode, location: Location) -> Node:
        text_location = self._text_location(node, location)
        construct = _SCALAR_TAGS.get(node.tag)
        if construct is None:
            self._bad_tag(node.tag, location)
            return Node(node.value, node.value, location, text_location=text_location)
        try:
            value = construct(node)
        except (ValueError, KeyError, TypeError, yaml.YAMLError):
            tag = node.tag[len(_TAG):]
            self.problems.add(location, f"'{excerpt(node.value)}' is not a valid {tag}",
                              "remove the explicit tag or fix the value")
            value = node.value
        return Node(value, node.value, location, text_location=text_location)

    def _text_location(self, node: ScalarNode, location: Location) -> Location:
        """Where the scalar's text starts (after a quote or a block header).

        For a plain scalar folded over lines, or a quoted one with escapes or line
        breaks, the text does not run on with the file: its characters are mapped
        one by one (`TextLocation`), so an error inside it is placed exactly."""
        if node.style in (None, "", "'", '"'):  # plain is None in PyYAML, "" in libyaml
            start = node.start_mark.index + (1 if node.style else 0)
            end = node.end_mark.index - (1 if node.style else 0)
            raw = self.text[start:end]
            if raw != node.value:
                indices = _text_indices(node.value, raw, node.style == '"')
                if indices is not None:
                    return TextLocation(location.file, *_line_col(self.text, start),
                                        source=self.text, indices=tuple(start + i for i in indices))
        if node.style in ("'", '"'):
            return location.shifted(1)
        if node.style not in ("|", ">"):
            return location
        index = self.text.find("\n", node.start_mark.index)
        end = node.end_mark.index
        while 0 <= index < end:
            line_start = index + 1
            index = self.text.find("\n", line_start)
            line = self.text[line_start:index if index >= 0 else len(self.text)]
            if line.strip():
                start = line_start + len(line) - len(line.lstrip(" "))
                return _location_of_index(self.name, self.text, start)
        return location

    def _mapping(self, node: MappingNode, location: Location, only: Mapping | None = None) -> Node:
        explicit = {key.value for key, _ in node.value
                    if isinstance(key, ScalarNode) and key.tag != _MERGE}
        if only is not None and len(explicit) < len(node.value):
            only = None  # a merge (or a key that is no string): the whole mapping
        values: dict[str, Node] = {}
        key_locations: dict[str, Location] = {}
        written: dict[str, Location] = {}
        for key_node, value_node in node.value:
            if isinstance(key_node, ScalarNode) and key_node.tag == _MERGE:
                self._merge(value_node, explicit, values, key_locations)
                continue
            key = self._key(key_node)
            if key is None:
                continue
            key_location = _location_of_mark(self.name, key_node.start_mark)
            if key in written:
                self._duplicate(key, key_location, written[key])
                continue
            written[key] = key_locations[key] = key_location
            if only is None:
                values[key] = self.convert(value_node)
                continue
            deeper = only.get(key, only.get("*", _LEFT_OUT))
            if deeper is _LEFT_OUT:
                values[key] = Node(None, None, _location_of_mark(self.name, value_node.start_mark))
            elif deeper is None or not isinstance(value_node, MappingNode) or value_node.tag != _MAP:
                values[key] = self.convert(value_node)
            else:
                values[key] = self._mapping(value_node, _location_of_mark(self.name, value_node.start_mark), deeper)
        return Node(values, None, location, key_locations)

    def _duplicate(self, key: str, where: Location, first: Location) -> None:
        self.problems.add(
            where, f"duplicate key '{key}' (first defined at line {first.line})",
            "each key may appear only once in a mapping: remove or rename one of them")

    def _key(self, key_node: yaml.Node) -> str | None:
        """The key as a string, or None after reporting why it is unusable."""
        location = _location_of_mark(self.name, key_node.start_mark)
        if not isinstance(key_node, ScalarNode):
            kind = "mapping" if isinstance(key_node, MappingNode) else "list"
            self.problems.add(location, f"a {kind} cannot be used as a key",
                              "keys must be plain names like `mass:`")
            return None
        key = self._scalar(key_node, location).value
        if not isinstance(key, str):
            shown = excerpt(key_node.value)
            self.problems.add(location, f"key '{shown}' is not a string (YAML reads it as {excerpt(repr(key))})",
                              f"quote the key: '\"{shown}\": ...'")
            return None
        return key

    def _merge(self, value_node: yaml.Node, explicit: set[str],
               values: dict[str, Node], key_locations: dict[str, Location]) -> None:
        """Add the entries of a ``<<`` merge that the mapping does not set itself."""
        sources = value_node.value if isinstance(value_node, SequenceNode) else [value_node]
        for source in sources:
            if not isinstance(source, MappingNode):
                self.problems.add(
                    _location_of_mark(self.name, source.start_mark),
                    "'<<' must be followed by a mapping or a list of mappings",
                    "write `<<: *name` where `&name` marks a mapping")
                continue
            merged = self.convert(source)
            if not merged.is_mapping:
                continue
            for key, item in merged.value.items():
                if key not in explicit and key not in values:
                    values[key] = item
                    key_locations[key] = merged.key_locations[key]


__all__ = ["MAX_ALIAS_VALUES", "Node", "TextLocation", "excerpt", "load_yaml"]
