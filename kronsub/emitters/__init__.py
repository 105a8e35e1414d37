"""Emitters: a derived system as text (Markdown, LaTeX, JSON); one registry of formats.

The formats (:mod:`.text`, with SymPy) are imported when first named, so that
:mod:`.escape` alone (a message for the terminal, a JSON document) costs no SymPy."""
from __future__ import annotations

__all__ = ["EMITTERS", "emit_json", "emit_latex", "emit_markdown"]


def __getattr__(name: str):
    if name in __all__:
        from . import text  # SymPy and the templates: when a format is first named

        return getattr(text, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
