"""Generated text made in a fresh process under a given ``PYTHONHASHSEED``: deterministic output
is the same text whatever the seed."""
from __future__ import annotations

import os
import subprocess
import sys

EMITTED = ("import kronsub, sys\n"
           "from kronsub.emitters.code import {emitter}\n"
           "s = kronsub.load(sys.argv[1]).derive(cache=False)\n"
           "sys.stdout.write(''.join(g.text for g in {emitter}(s, 'm', route='projected')))\n")


def emitted_under_seed(emitter: str, model, seed: str) -> str:
    """What ``emitter`` (``emit_c``, ``emit_python``) writes for ``model`` on the projected route,
    in a fresh process under ``PYTHONHASHSEED=seed``."""
    env = {**os.environ, "PYTHONHASHSEED": seed}
    return subprocess.run([sys.executable, "-c", EMITTED.format(emitter=emitter), str(model)], env=env, check=True,
                          capture_output=True, text=True).stdout
