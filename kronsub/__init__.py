"""kronsub: equations of motion of interconnected systems by Kron's method of subspaces.

    >>> import kronsub
    >>> system = kronsub.load("models/hoffmann/system1.yaml").derive()
    >>> system.mass_matrix            # Mbar = C^T M C  (9'), (22)

Data flows one way: YAML -> model -> primitive -> subspace -> equations.
"""
__version__ = "0.1.0"


def load(path, *, text=None, cache=True):
    """Load and validate a model file; returns a :class:`kronsub.model.model.Model`.

    ``text`` gives the YAML directly (``path`` then names it in messages);
    ``cache=False`` derives sub-models from scratch.
    """
    from .model.loader import load_model

    return load_model(path, text=text, cache=cache)


__all__ = ["load", "__version__"]
