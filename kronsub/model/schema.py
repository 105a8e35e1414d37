"""The packaged JSON Schema of the model format (``schema.json`` beside this module), and
the lists of names the reader takes from it."""
from __future__ import annotations

import functools
import json
from importlib import resources


@functools.cache
def model_schema() -> dict:
    """The JSON Schema of a model file (draft 2020-12)."""
    return json.loads(resources.files(__package__).joinpath("schema.json").read_text("utf-8"))


def scene_methods() -> tuple[str, ...]:
    """The integration methods a scene may name: the schema's enum, which the tests keep equal to
    the simulation's method table."""
    return tuple(model_schema()["$defs"]["scene"]["properties"]["method"]["enum"])


__all__ = ["model_schema", "scene_methods"]
