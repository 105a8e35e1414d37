"""From a YAML model file to a validated :class:`~kronsub.model.model.Model`.

The whole file is checked at once: every problem is collected with its
file, line and column, then raised together as one :class:`ModelError`.
Expressions go through the whitelisted parser only. The sections are read by the modules of
their job, each a function of the one :class:`~kronsub.model.reader.ModelReader`: ``parts.py``
(components and known systems), ``connection.py``, ``definitions.py``, ``constraints.py``,
``effects.py``, ``initial.py``, ``scenes.py``; ``files.py`` keys the file and those it uses.
"""
from __future__ import annotations

import functools
import os
from pathlib import Path

import sympy

from ..budget import WorkBudgetExceeded, allow_for, scope as budget_scope
from ..collector import collector_paused
from ..components import REGISTRY
from ..core.constraints import Constraint, multiplier_name
from ..core.known_system import ParameterInfo
from ..core.primitive import Part, Primitive
from ..core.symbols import TIME, symbol, velocity_symbol
from ..errors import Location, ModelError
from .connection import (implicit_spec, pivot_connection, read_connection, read_intermediate,
                         read_pivot_angles)
from .constraints import read_constraints
from .prescribed import check_effects, driven_connection, names_time, read_prescribed
from .definitions import read_definitions
from .derive import derive_model, load_cached
from .effects import build_effect
from .files import (MAX_MODEL_DEPTH, TOP_LEVEL, derivation_text, each_once, looks_like_model, model_key,
                    resolved_path)
from .initial import read_initial
from .model import Model
from .names import Declared, generated_name_clashes
from .parts import (component_origin, component_parameters, coordinate_names, inertial_parameters,
                    inherit_parameter, known_system_part, library_component, mark_broken, placed)
from .reader import ModelReader, node_kind
from .requirements import body_requirements, unmet
from .scenes import build_scenes
from .source import Node, load_yaml, read_model_file, read_model_text, system_root


def load_model(path, *, text: str | None = None, cache: bool = True, _stack: tuple[str, ...] = ()) -> Model:
    """Load a model file; sub-model files are loaded (and derived) recursively.

    ``cache=False`` derives sub-models from scratch instead of reading the cache. The work
    is charged to the active work budget, or to a default one (`kronsub.budget.scope`).
    """
    path = Path(path)
    source = None
    if text is None:
        text, source = read_model_file(path)
    root = load_yaml(path, text)
    with collector_paused(), budget_scope():  # see kronsub.collector
        return ModelLoader(path, root, text, _stack, cache, source).build()


class ModelLoader(ModelReader):
    """The reading of one model file, section by section, into a :class:`Model` (:meth:`build`)."""

    # ----------------------------------------------------------- utilities
    def _multiplier_clashes(self, constraints, carried) -> None:
        """Two constraints whose multipliers get one name (a joint `B`'s `B.x` and a constraint
        `B_x` are both `mu_B_x`) would be one entry of the reactions: refused, naming both."""
        seen: dict[str, Constraint] = {}
        own = {id(c) for c in carried}
        owner = {id(c): part.name for part in self.parts for c in part.constraints}  # the component of each
        for c in constraints:
            name = multiplier_name(c.name)
            first = seen.setdefault(name, c)
            if first is c:
                continue
            here = next((x for x in (c, first) if id(x) not in own), None)
            if here is None:  # both from known systems: at the component entries that bring them in
                parts = [owner.get(id(x), x.name.split(".", 1)[0]) for x in (first, c)]
                at = [self.locations.get(f"component:{p}") for p in parts]
                came = (f"both come from the component '{parts[0]}'" if parts[0] == parts[1] else
                        f"they come from the component '{parts[0]}'" + (f" (at {at[0]})" if at[0] else "")
                        + f" and this one, '{parts[1]}'")
                self.error(at[1] or at[0] or self.root, f"constraints '{first.name}' and '{c.name}' have the "
                           f"same multiplier name '{name}' in the reactions: {came}",
                           "rename one of the components: a known system's constraints are named after its "
                           "component (`left.cx`, multiplier `mu_left_cx`)")
                continue
            key = here.name if f"constraint:{here.name}" in self.locations else here.name.rsplit(".", 1)[0]
            self.error(self.locations.get(f"constraint:{key}", self.root), f"constraints '{first.name}' and "
                       f"'{c.name}' have the same multiplier name '{name}' in the reactions",
                       "rename one of them (a joint `B` names its equations `B.x`, `B.y`, whose multipliers "
                       "are `mu_B_x`, `mu_B_y`)")

    # --------------------------------------------------------------- build
    def build(self) -> Model:
        root = self.root
        if not root.is_mapping:
            found = "a single value" if root.is_scalar and root.value is not None else node_kind(root)
            self.error(root, f"a model file must be a mapping of sections, found {found}",
                       "start with `name:`, `components:`, `coordinates:` and `connection:`")
            self.problems.raise_if_any()
        if root.value and not any(key in TOP_LEVEL for key in root.value):
            first = next(iter(root.value))  # not a model: echo nothing of it, not even a key
            self.error(root.key_locations[first], "this is not a kronsub model: no key is a model section",
                       "a model has `name:`, `components:`, `coordinates:` and `connection:`; check the path")
            self.problems.raise_if_any()
        self.check_keys(root, TOP_LEVEL, "the model")
        dnode = root.get("definitions")
        self.definition_keys = set(dnode.value) if dnode is not None and dnode.is_mapping else set()
        name = self.string(root.get("name"), self.path.stem)
        description = self.string(root.get("description"), "")
        self._parameters(root.get("parameters"))
        self._components(root.get("components"))
        cnode = root.get("constraints")
        carried = [c for part in self.parts for c in part.constraints]  # of constrained known systems
        constrained = (cnode is not None and cnode.value is not None) or bool(carried)
        coords_node = root.get("coordinates")
        auto = coords_node is not None and coords_node.is_scalar and coords_node.value == "auto"
        if auto and not constrained:
            self.error(coords_node, "`coordinates: auto` needs `constraints:`",
                       "list the generalized coordinates, e.g. `coordinates: [theta, phi]`")
            self.problems.raise_if_any()  # without coordinates every later check would mislead
        coords = () if auto else self._coordinates(coords_node)
        self.generalized_names = {q.name for q in coords}
        if auto:
            self.locations["coordinates"] = coords_node.location
        primitive = Primitive(tuple(self.parts))
        allow_for(len(primitive.coordinates))  # a default budget grows with the model
        self._primitive_names(primitive)
        read_definitions(self, root.get("definitions"), coords, primitive)
        pivot_connection(self, primitive)
        implicit = None
        if constrained:
            constraints = (read_constraints(self, cnode, primitive) if cnode is not None else []) + carried
            self._multiplier_clashes(constraints, carried)
            y = read_intermediate(self, root.get("connection"), primitive, coords)
        else:
            y = coords
        self._generated_names(y, primitive)
        read_pivot_angles(self, root.get("connection"), y)
        connection = read_connection(self, root.get("connection"), primitive, y)
        motions = read_prescribed(self, root.get("prescribed"), y if not constrained else coords)
        if constrained and (motions or names_time(connection)):
            self.error(root.key_locations.get("prescribed") or root.key_locations["connection"],
                       "a prescribed motion (`t` in the connection) together with `constraints:` is not supported yet",
                       "write the closed loop's coordinates in the connection, or drive it by a load")
        effects = self._effects(root.get("effects"), primitive, y)
        if motions:
            check_effects(self, root.get("effects"), effects, motions)
        initial = read_initial(self, root.get("initial"), y)
        declared = root.get("effects")
        scenes = build_scenes(self, root.get("scenes"), list(declared.value) if declared is not None and
                              declared.is_mapping else [], primitive, y)
        self._check_values()
        if constrained and not self.problems:
            implicit = implicit_spec(self, cnode, constraints, connection, y, coords, auto, initial)
            if implicit is not None:
                coords = implicit.independent
        self.problems.raise_if_any()
        if motions:
            connection, coords = driven_connection(connection, coords, motions)
            initial = {k: v for k, v in initial.items() if k not in motions and k not in
                       {velocity_symbol(q) for q in motions}}
        return Model(
            name=name,
            description=description,
            path=self.file,
            parameters=tuple(self.parameters.values()),
            primitive=primitive,
            coordinates=coords,
            connection=connection,
            effects=tuple(effects),
            initial=initial,
            scenes=scenes,
            key_texts=(derivation_text(self.root, self.text), *self.sub_hashes) if self.text is not None else (),
            locations=self.locations,
            implicit=implicit,
            requirements=tuple(self.requirements),
            source=self.source,
            uses=each_once(self.used),
        )

    def _check_values(self) -> None:
        """The components' requirements on the parameters' values (:mod:`.requirements`): a
        problem at the parameter's declaration when the value is one parameter, else where
        the value is given."""
        def declared(req):
            value = req.value
            return self.locations.get(f"parameter:{value.name}") if isinstance(value, sympy.Symbol) else None

        for problem in unmet(self.requirements, self.parameter_values(), declared):
            self.problems.add(problem.location, problem.message, problem.hint)

    # ---------------------------------------------------------- parameters
    def _parameters(self, node: Node | None) -> None:
        for pname, spec in self.mapping(node, "parameters", "write `m1: 1.0` or `m1: {value: 1.0, unit: kg}`").items():
            loc = node.key_locations[pname]
            if not self.identifier(pname, loc, "parameter"):
                continue
            value_node, unit, description = spec, "", ""
            if spec.is_mapping:
                self.check_keys(spec, ("value", "unit", "description"), f"parameter '{pname}'")
                value_node = spec.get("value")
                unit = self.string(spec.get("unit"), "")
                description = self.string(spec.get("description"), "")
            value = None
            if value_node is not None and value_node.value is not None:
                value = self.expr(value_node, {}, what=f"value of parameter '{pname}'")
            self.declared.add(pname)
            self.add_parameter(ParameterInfo(pname, symbol(pname), value, unit, description), location=loc)

    # ---------------------------------------------------------- components
    def _components(self, node: Node | None) -> None:
        comps = self.mapping(node, "components", "write `upper: {type: pinned_rod, parameters: {...}}`")
        if node is not None and not comps and (node.is_mapping or node.value is None):
            self.error(node, "`components:` is empty", "list at least one component")
        if node is None:
            self.error(Location(self.file, 1, 1), "the model has no `components:`",
                       "list the parts of the primitive system under `components:`")
        for cname, spec in comps.items():
            loc = node.key_locations[cname]
            if not self.identifier(cname, loc, "component"):
                continue
            if not spec.is_mapping:
                self.error(spec, f"component '{cname}' must be a mapping", "give at least `type:`")
                continue
            if spec.get("model") is not None:
                part = self._known_system(cname, spec)
            else:
                part = library_component(self, cname, spec)
            if part is not None:
                self.parts.append(part)
                self.locations[f"component:{cname}"] = loc
            else:
                self.failed_components = True
                mark_broken(self, cname, spec)

    def _known_system(self, cname: str, spec: Node) -> Part | None:
        """A derived model used as a component (examples II and III)."""
        self.check_keys(spec, ("model", "parameters", "coordinates", "origin", "description"), f"component '{cname}'")
        mnode = spec.get("model")
        if not isinstance(mnode.value, str) or not mnode.value:
            self.error(mnode, f"`model:` of component '{cname}' must be a file name, found {node_kind(mnode)}",
                       "write e.g. `model: system1.yaml` (relative to this model file)")
            return None
        if "\0" in mnode.value:  # no file name holds one (the system calls refuse it)
            self.error(mnode, f"`model:` of component '{cname}' has a NUL character, which no file name can hold",
                       "write the file name without `\\0` or `\\x00` escapes")
            return None
        sub_path = (self.path.parent / mnode.value)
        resolved = resolved_path(sub_path)
        if resolved in self.stack:
            chain = " -> ".join(Path(p).name for p in self.stack + (resolved,))
            self.error(mnode, f"model files form a cycle: {chain}", "a model cannot contain itself")
            return None
        if len(self.stack) >= MAX_MODEL_DEPTH:
            self.error(mnode, f"too many levels of `model:` files: '{mnode.value}' would be level "
                              f"{len(self.stack) + 1}, and the limit is {MAX_MODEL_DEPTH}",
                       "a known system may use known systems, but not this many levels down: write the parts "
                       "of some levels into one model file")
            return None
        if not os.path.lexists(sub_path) and system_root(sub_path) is None:  # read_model_text says what it is
            self.error(mnode, f"model file '{mnode.value}' not found (looked at {sub_path})",
                       "paths are relative to this model file")
            return None
        try:
            if not looks_like_model(read_model_text(sub_path, mnode.text_location or mnode.location)):
                self.error(mnode, f"model file '{mnode.value}' is not a kronsub model: no line of it begins "
                                  "with a model section", "a model file starts its lines with `name:`, "
                                  "`components:`, `coordinates:`...; check the path (nothing of another file "
                                  "is shown)")
                return None
            key = model_key(sub_path, self.stack, self.used)
            system = load_cached(key, transition=False) if self.cache else None
            if system is None:
                sub = load_model(sub_path, cache=self.cache, _stack=self.stack)
                system = derive_model(sub, cache=self.cache)
        except WorkBudgetExceeded:
            raise
        except ModelError as exc:
            self.problems.extend(exc)
            return None
        self.sub_hashes.append(key)
        # parameters: overrides, the rest inherited
        allowed = [p.name for p in system.parameters]
        inertial = functools.cache(lambda: inertial_parameters(system))  # asked only of an override in t
        overrides = component_parameters(self, cname, spec.get("parameters"), allowed,
                                         inertial=lambda key: key in inertial())
        for info in system.parameters:
            if info.name not in overrides:
                inherit_parameter(self, cname, mnode, info)
                self.add_parameter(info, inherited=True, location=spec.location)
        # a constrained system is placed on y: its dependent coordinates can be renamed too
        local = tuple(q.name for q in (system.implicit.intermediate if system.implicit is not None
                                       else system.coordinates))
        names = coordinate_names(self, cname, spec.get("coordinates"), local, "{}")
        origin = component_origin(self, cname, spec.get("origin"), system.dimension, bool(system.points))
        if names is None or any(v is None for v in overrides.values()) or origin is False:
            return None
        part = known_system_part(cname, system, {symbol(k): v for k, v in overrides.items()},
                                 dict(zip(local, names)))
        for body in part.bodies:
            self.requirements += body_requirements(f"{cname}.{body.name}" if body.name else cname, body,
                                                   (spec.get("parameters") or spec).location)
        return placed(part, origin) if origin else part

    # --------------------------------------------------------- coordinates
    def _coordinates(self, node: Node | None) -> tuple[sympy.Symbol, ...]:
        if node is None:
            self.error(Location(self.file, 1, 1), "the model has no `coordinates:`",
                       "list the generalized coordinates of the new system, e.g. `coordinates: [theta, phi]`")
            return ()
        if not node.is_sequence or not node.value:
            self.error(node, "`coordinates:` must be a non-empty list of names", "e.g. `coordinates: [theta, phi]`")
            return ()
        coords, listed = [], set()
        for item in node.value:
            name = item.value
            if not isinstance(name, str):
                self.error(item, f"a coordinate must be a name, found {node_kind(item)}",
                           "e.g. `coordinates: [theta, phi]`")
                continue
            if not self.identifier(name, item.location, "coordinate"):
                self.broken_names.update((name, f"{name}_dot"))  # reported once, not again where it is used
                continue
            if name in self.parameters:
                self.error(item, f"'{name}' is both a parameter and a coordinate", "rename one of them")
                continue
            if name in listed:
                self.error(item, f"coordinate '{name}' is listed twice", "list each coordinate once")
                continue
            listed.add(name)
            coords.append(symbol(name))
            self.locations[f"coordinate:{name}"] = item.location
        for q in coords:
            self.names[q.name] = q
            self.names[velocity_symbol(q).name] = velocity_symbol(q)
        self.locations["coordinates"] = node.location
        return tuple(coords)

    def _primitive_names(self, primitive: Primitive) -> None:
        """Primitive coordinates are known by their names and as ``component.local``."""
        seen: dict[sympy.Symbol, str] = {}
        for part in primitive.parts:
            for q in part.coordinates:
                if q in seen and seen[q] != part.name:
                    self.error(self.root.key_locations.get("components", self.root.location),
                               f"coordinate name '{q}' is used by components '{seen[q]}' and '{part.name}'",
                               f"rename one under its `coordinates:`, e.g. `coordinates: {{...: {q}_{part.name}}}`")
                seen[q] = part.name
                if q.name in self.parameters:
                    self.error(self.root.key_locations.get("components", self.root.location),
                               f"coordinate name '{q}' of '{part.name}' is also a parameter", "rename one")
        self.primitive_names: dict[str, sympy.Symbol] = {}
        for part in primitive.parts:
            local = self._local_names(part)
            for q, lname in zip(part.coordinates, local):
                self.primitive_names.setdefault(q.name, q)
                self.primitive_names[f"{part.name}.{q.name}"] = q
                self.primitive_names.setdefault(f"{part.name}.{lname}", q)
        # effects act on the primitive: their expressions name primitive coordinates only
        self.names = {"t": TIME, **self.parameter_names()}
        for key, q in self.primitive_names.items():
            self.names[key] = q
            self.names[f"{key}_dot"] = velocity_symbol(q)

    def _generated_names(self, coords, primitive: Primitive) -> None:
        """No model name may be the velocity or acceleration name of a coordinate (names.py)."""
        coordinates = [Declared(q.name, "coordinate", self.locations.get(f"coordinate:{q.name}")) for q in coords]
        coords = set(coords)
        for part in primitive.parts:
            where = self.locations.get(f"component:{part.name}")
            coordinates += [Declared(q.name, "coordinate", where, f"component '{part.name}'")
                            for q in part.coordinates if q not in coords]
        parameters = [Declared(name, "parameter", self.locations.get(f"parameter:{name}")) for name in self.parameters]
        for problem in generated_name_clashes(parameters + coordinates, coordinates):
            self.problems.add(problem.location, problem.message, problem.hint)

    def _local_names(self, part: Part) -> tuple[str, ...]:
        cls = REGISTRY.get(part.type_name)
        return cls.coordinates if cls is not None else tuple(q.name for q in part.coordinates)

    # ------------------------------------------------------------- effects
    def _effects(self, node: Node | None, primitive: Primitive, coords):
        """The effects, written in the primitive coordinates or in the subspace's ``coords``
        (those are applied directly in the subspace: core/subspace.py)."""
        for q in coords:
            self.subspace_names[q.name] = q
            self.names.setdefault(q.name, q)
            self.names.setdefault(velocity_symbol(q).name, velocity_symbol(q))
        effects = []
        for ename, spec in self.mapping(node, "effects", "write `gravity: {type: gravity, g: g}`").items():
            loc = node.key_locations[ename]
            if not self.identifier(ename, loc, "effect"):
                continue
            effect = build_effect(self, ename, spec, primitive)
            if effect is not None:
                self.locations[f"effect:{ename}"] = loc
                effects.append(effect)
        return effects


__all__ = ["ModelLoader", "load_model"]
