"""From a YAML model file to a validated :class:`~kronsub.model.model.Model`.

The whole file is checked at once: every problem is collected with its
file, line and column, then raised together as one :class:`ModelError`.
Expressions go through the whitelisted parser only. :class:`ModelLoader` orchestrates: the
sections are read by the modules of their job, each a function of the one
:class:`~kronsub.model.reader.ModelReader`: ``parameters.py``, ``components.py`` (library
components in ``parts.py``, known systems in ``known_systems.py``), ``coordinates.py``,
``connection.py``, ``definitions.py``, ``constraints.py``, ``effects.py``, ``initial.py``,
``scenes.py``; ``files.py`` keys the file and those it uses.
"""
from __future__ import annotations

from pathlib import Path

import sympy

from ..budget import allow_for, scope as budget_scope
from ..collector import collector_paused
from ..core.symbols import symbol, velocity_symbol
from ..core.known_system import KnownSystem
from ..core.primitive import Primitive
from .components import read_components
from .currents import name_currents, primitive_charges, subspace_charges
from .connection import (implicit_spec, pivot_connection, read_connection, read_intermediate,
                         read_pivot_angles)
from .circuits import check_circuit
from .constraints import check_multiplier_names, read_constraints
from .coordinates import check_generated_names, name_primitive_coordinates, read_coordinates
from .nonholonomic import check_initial, check_start, read_velocity_constraints, read_velocity_frame
from .prescribed import check_effects, driven_connection, names_time, read_prescribed
from .definitions import read_definitions
from .derive import derive_model, load_cached
from .effects import read_effects
from .files import TOP_LEVEL, derivation_text, each_once, model_key
from .initial import read_initial
from .model import Model
from .parameters import check_values, read_parameters
from .reader import ModelReader, node_kind
from .scenes import build_scenes
from .file_reading import read_model_file
from .source import load_yaml


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

    def derived_model(self, path: Path) -> KnownSystem:
        """The model file ``path``, used here as a known system, derived (from the cache when
        allowed), its key added to this model's."""
        key = model_key(path, self.stack, self.used)
        system = load_cached(key, transition=False) if self.cache else None
        if system is None:
            sub = load_model(path, cache=self.cache, _stack=self.stack)
            system = derive_model(sub, cache=self.cache)
        self.sub_hashes.append(key)
        return system

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
        root = self.check_keys(root, TOP_LEVEL, "the model")
        dnode = root.get("definitions")
        self.definition_keys = set(dnode.value) if dnode is not None and dnode.is_mapping else set()
        name = self.string(root.get("name"), self.path.stem)
        description = self.string(root.get("description"), "")
        read_parameters(self, root.get("parameters"))
        read_components(self, root.get("components"), self.derived_model)
        cnode = root.get("constraints")
        carried = [c for part in self.parts for c in part.constraints]  # of constrained known systems
        constrained = (cnode is not None and cnode.value is not None) or bool(carried)
        coords_node = root.get("coordinates")
        # a closed loop that names no coordinates lets kronsub pick them, as `coordinates: auto`
        auto = (coords_node is None and constrained) or (
            coords_node is not None and coords_node.is_scalar and coords_node.value == "auto")
        # configuration constraints beside velocity constraints: on the listed coordinates, which
        # the connection gives the primitive's; their rates join the velocity constraints
        beside = constrained and root.get("velocity_constraints") is not None
        if beside and auto:
            self.error(coords_node or cnode, "`coordinates: auto` together with `velocity_constraints:` is not "
                       "supported", "list every coordinate under `coordinates:`: the configuration constraints "
                       "then set the last ones they can")
            self.problems.raise_if_any()
        if auto and not constrained:
            self.error(coords_node, "`coordinates: auto` needs `constraints:`",
                       "list the generalized coordinates, e.g. `coordinates: [theta, phi]`")
            self.problems.raise_if_any()  # without coordinates every later check would mislead
        coords = () if auto else read_coordinates(self, coords_node)
        self.generalized_names = {q.name for q in coords}
        if auto:
            self.locations["coordinates"] = (coords_node or cnode or root).location
        primitive = Primitive(tuple(self.parts))
        allow_for(len(primitive.coordinates))  # a default budget grows with the model
        name_primitive_coordinates(self, primitive)
        read_definitions(self, root.get("definitions"), coords, primitive)
        pivot_connection(self, primitive)
        implicit = None
        if constrained:
            constraints = (read_constraints(self, cnode, primitive) if cnode is not None else []) + carried
            check_multiplier_names(self, constraints, carried)
            y = coords if beside else read_intermediate(self, root.get("connection"), primitive, coords)
        else:
            y = coords
        check_generated_names(self, y, primitive)
        read_pivot_angles(self, root.get("connection"), y)
        connection = read_connection(self, root.get("connection"), primitive, y)
        charges = primitive_charges(primitive)
        named = root.get("speeds")  # a change of velocity frame's speeds own their names
        speeds = frozenset(map(str, named.value)) if named is not None and isinstance(named.value, dict) else frozenset()
        name_currents(self, charges + subspace_charges(connection, charges, y), y, speeds)
        motions = read_prescribed(self, root.get("prescribed"), y if not constrained else coords)
        if constrained and (motions or names_time(connection)):
            self.error(root.key_locations.get("prescribed") or root.key_locations["connection"],
                       "a prescribed motion (`t` in the connection) together with `constraints:` is not supported yet",
                       "write the closed loop's coordinates in the connection, or drive it by a load")
        effects = read_effects(self, root.get("effects"), primitive, y)
        if not constrained and not self.problems:
            check_circuit(self, primitive, connection, y, effects)
        if motions:
            check_effects(self, root.get("effects"), effects, motions)
        if motions or names_time(connection):  # where the drive is written (linearize refuses there)
            self.locations["drive"] = root.key_locations.get("prescribed") or root.key_locations["connection"]
        velocity = None
        vnode = root.get("velocity_constraints")
        snode = root.get("speeds")
        frame = snode is not None and snode.value is not None and vnode is None  # a change of velocity frame
        if frame and not snode.is_mapping:
            self.error(root.key_locations["speeds"], "`speeds:` without `velocity_constraints:`",
                       "a list of velocities is a choice under velocity constraints; without them name one speed "
                       "per velocity by its definition (a change of velocity frame): `speeds: {v: cos(theta)*x_dot "
                       "+ sin(theta)*y_dot, w: -sin(theta)*x_dot + cos(theta)*y_dot, r: theta_dot}`")
        elif frame and (constrained or motions or names_time(connection)):
            self.error(root.key_locations["speeds"],
                       "`speeds:` (a change of velocity frame) together with "
                       + ("`constraints:`" if constrained else "a prescribed motion") + " is not supported yet",
                       "write the closed loop's coordinates in the connection, or drive it by a load"
                       if constrained else "drive the system by a load")
        elif frame and not self.problems:
            velocity = read_velocity_frame(self, snode, y, root.key_locations["speeds"])
            if velocity is not None:  # where the velocity-level transformation is written
                self.locations["velocity_constraints"] = root.key_locations["speeds"]
        if vnode is not None and (motions or names_time(connection)):
            self.error(root.key_locations["velocity_constraints"],
                       "`velocity_constraints:` together with a prescribed motion is not supported yet",
                       "drive the system by a load")
        elif vnode is not None and not self.problems:
            holonomic = [(c.name, sympy.sympify(c.expression).xreplace(connection)) for c in constraints] \
                if beside else []
            velocity = read_velocity_constraints(self, vnode, root.get("speeds"), y, primitive, connection,
                                                 holonomic, root.key_locations.get("constraints"))
            if velocity is not None:
                self.locations["velocity_constraints"] = root.key_locations["velocity_constraints"]
        named = ()  # speeds written but not made (their section reported already): no second error at `initial:`
        if velocity is None and snode is not None and snode.is_mapping:
            named = tuple(symbol(k) for k in snode.value if isinstance(k, str) and k.isidentifier())
        initial = read_initial(self, root.get("initial"), y,
                               velocity.transformation.speeds if velocity is not None else named)
        if velocity is not None:
            check_initial(self, root.get("initial"), y, velocity)
        if velocity is not None and not self.problems:
            given = root.get("speeds") is not None and root.get("speeds").value is not None
            check_start(self, root.key_locations["speeds" if given else "velocity_constraints"], velocity, initial,
                        chosen=given)
        declared = root.get("effects")
        scenes = build_scenes(self, root.get("scenes"), list(declared.value) if declared is not None and
                              declared.is_mapping else [], primitive, y,
                              velocity.transformation.speeds if velocity is not None else named)
        snodes = root.get("scenes")
        if velocity is not None and snodes is not None and snodes.is_mapping:  # a scene's values as the model's
            for spec in snodes.value.values():
                if spec.is_mapping:
                    check_initial(self, spec.get("initial"), y, velocity)
        check_values(self)
        if beside and velocity is not None:
            self.locations["constraints"] = root.key_locations["constraints"] if "constraints" in root.value \
                else root.key_locations["velocity_constraints"]
        if constrained and not beside and not self.problems:
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
            joints=tuple(self.joints),
            velocity=velocity,
            currents=dict(self.currents),
        )


__all__ = ["ModelLoader", "load_model"]
