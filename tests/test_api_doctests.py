"""The examples in the notebook API's docstrings run, and say what they give (doctest)."""
from __future__ import annotations

import doctest

import kronsub.api
from conftest import ROOT


def test_the_api_docstrings_examples(monkeypatch):
    monkeypatch.chdir(ROOT)  # the examples name the bundled models by their paths in the repository
    examples = [t for t in doctest.DocTestFinder().find(kronsub.api) if t.examples]
    assert len(examples) >= 5  # load and derive, symbol, simulate, codegen, accuracy
    result = doctest.testmod(kronsub.api, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0 and result.attempted >= 15
