"""Emitters: a derived system as text (Markdown, LaTeX, JSON); one registry of formats."""
from .text import EMITTERS, emit_json, emit_latex, emit_markdown

__all__ = ["EMITTERS", "emit_json", "emit_latex", "emit_markdown"]
