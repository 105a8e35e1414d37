"""The examples in the notebook API's docstrings run, and say what they give (doctest)."""
from __future__ import annotations

import doctest

import pytest

from conftest import ROOT
from kronsub.api import naming, outputs, runs, system

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


@pytest.mark.parametrize("module", [naming, runs, outputs, system], ids=lambda m: m.__name__)
def test_the_api_docstrings_examples(module, monkeypatch):
    monkeypatch.chdir(ROOT)  # the examples name the bundled models by their paths in the repository
    assert any(t.examples for t in doctest.DocTestFinder().find(module))
    result = doctest.testmod(module, optionflags=FLAGS)
    assert result.failed == 0 and result.attempted >= 3
