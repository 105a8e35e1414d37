"""kronsub: equations of motion of interconnected systems by Kron's method of subspaces.

    >>> import kronsub
    >>> system = kronsub.load("models/hoffmann/system1.yaml").derive()
    >>> system.mass_matrix            # Mbar = C^T M C  (9'), (22)

Data flows one way: YAML -> model -> primitive -> subspace -> equations.
"""
__version__ = "0.1.0"


def load(path, *, text=None):
    """Load and validate a model file; returns a :class:`kronsub.model.Model`."""
    from .model.loader import load_model

    return load_model(path, text=text)


__all__ = ["load", "__version__"]
