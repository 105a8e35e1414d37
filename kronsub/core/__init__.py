"""The mathematics of Kron's method, pure data and functions: the primitive, the subspace and
the projection ``Mbar = Cᵀ M C`` (9'), (D), the known system, implicit constraints (25)-(29),
linearisation. It imports only the components below it, never the model reader, the
emitters, the simulation or the notebook face above it."""
