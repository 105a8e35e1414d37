"""Independent derivations that kronsub's results are checked against, never made with kronsub.

* :mod:`reference.mechanics`: ``sympy.physics.mechanics`` (``KanesMethod``, ``LagrangesMethod``)
  for chains, pendulums and the bundled models.
* :mod:`reference.closed_loops`: ``KanesMethod`` with configuration constraints for closed
  loops (dependent coordinates by Newton, dependent speeds from the velocity constraints).
* :mod:`reference.rolling`: the rolling disc by ``KanesMethod`` with its rolling constraints,
  and ``KanesMethod.linearize`` (dependent speeds taken along) at any state.
* :mod:`reference.lagrange`: Lagrange's equations of a hand-written ``T`` and ``V``, virtual
  power over the bodies, and Lagrange multipliers on the full coordinates, in plain sympy.
* ``reference.<folder>``: the hand derivations of the models in ``tests/models/<folder>/``
  built with :mod:`reference.lagrange`.
"""
