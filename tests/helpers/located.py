"""A model that ``derive`` refuses, and the line and column its error must name."""
from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from kronsub.cli import main


def refused(folder: Path, text: str) -> tuple[Path, str]:
    """``kronsub derive`` of ``text`` written to a model file in ``folder``: the file and the
    output, after checking that it failed with exit 1 and no traceback."""
    path = folder / "model.yaml"
    path.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["derive", str(path), "--no-cache"])
    out = result.output
    assert result.exit_code == 1, out
    assert "Traceback" not in out
    return path, out


def line_column(text: str, index: int) -> tuple[int, int]:
    """The 1-based line and column of character ``index`` of ``text``."""
    return text.count("\n", 0, index) + 1, index - (text.rfind("\n", 0, index) + 1) + 1


__all__ = ["line_column", "refused"]
