"""Writes tests/data/yardsticks.json: what ``sympy.trigsimp`` and ``sympy.fu`` make of each
printed entry of every bundled model that tests/test_readable.py measures (minutes of sympy;
the measuring is tests/helpers/readable.py's).

The test reads it to save that time, for an entry printed exactly as stored and the same
sympy version; anything else it measures afresh. Run after a change of the printed forms:

    python tests/data/yardsticks.py
"""
from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent), str(HERE.parent.parent)]
os.environ.setdefault("KRONSUB_CACHE_DIR", tempfile.mkdtemp())

import sympy  # noqa: E402

from helpers import readable  # noqa: E402


def main() -> None:
    readable.STORED.clear()  # measure everything afresh
    entries: dict = {}
    for name in readable.YARDSTICK_MODELS:
        entries.update(readable.measured_yardsticks(name))
        print(f"{name}: {len(entries)} entries so far", file=sys.stderr)
    lines = [f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in sorted(entries.items())]
    text = f'{{"sympy": {json.dumps(sympy.__version__)}, "entries": {{\n' + ",\n".join(lines) + "\n}}\n"
    json.loads(text)
    readable.YARDSTICKS.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
