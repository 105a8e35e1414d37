"""kronsub: equations of motion of interconnected systems by Kron's method of subspaces.

    >>> import kronsub
    >>> system = kronsub.load("models/hoffmann/system1.yaml").derive()
    >>> system.mass_matrix            # Mbar = C^T M C  (9'), (22)

Data flows one way: YAML -> model -> primitive -> subspace -> equations.
"""
from .version import __version__


def load(path, *, text=None, cache=True):
    """Load and validate a model file; returns a :class:`kronsub.api.LoadedModel`, whose
    ``derive(scene=...)`` gives a :class:`kronsub.api.System` (a model with exactly one scene
    uses it unless told otherwise, as every command does).

    ``text`` gives the YAML directly (``path`` then names it in messages);
    ``cache=False`` derives sub-models from scratch.
    """
    from .api import load  # sympy and the model reader: imported when first asked for

    return load(path, text=text, cache=cache)


__all__ = ["load", "__version__"]
