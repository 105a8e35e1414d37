"""The core: primitive systems, the subspace projection, constraints and the expression algebra
under them (Kron's method, independent of YAML, printing and integration)."""
