"""The component library and its registry: YAML ``type:`` name -> component class."""
from __future__ import annotations

from .base import Body, Component, ParameterSpec
from .electrical import Branch, CoupledInductors, Inductor
from .particles import Particle1D, Particle2D, Particle3D, ParticlePolar, ParticleSpherical
from .planar import Disc, Flywheel, PinnedRod, PlanarBody, Rod
from .spatial import RigidBody3D, TurnedBody

REGISTRY: dict[str, type[Component]] = {
    cls.type_name: cls
    for cls in (Particle1D, Particle2D, Particle3D, ParticlePolar, ParticleSpherical,
                PlanarBody, Rod, Disc, PinnedRod, Flywheel, RigidBody3D, TurnedBody,
                Inductor, CoupledInductors, Branch)
}

__all__ = ["REGISTRY", "Body", "Component", "ParameterSpec"]
