"""Run a test function as plain Python (NUMBA_DISABLE_JIT=1) in a subprocess.

Numba reads the switch at import time, so kernels can only be run uncompiled in a fresh
interpreter. ``run_without_jit("test_keyframes_search", "check_against_oracle", 3)`` imports
that test module there and calls the function with the (JSON-able) arguments; the test
fails with the subprocess's traceback if it raises. One helper for every kernel module's
JIT-off test (STUMPY runs its whole suite this way; here the oracle checks suffice).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

_SCRIPT = r"""
import importlib, json, sys
sys.path.insert(0, sys.argv[1])
import numba
assert numba.config.DISABLE_JIT, "NUMBA_DISABLE_JIT was not honoured"
mod = importlib.import_module(sys.argv[2])
for args in json.loads(sys.argv[4]):
    getattr(mod, sys.argv[3])(*args)
print("ok")
"""


def run_without_jit(module: str, function: str, *calls: tuple) -> None:
    """Call ``module.function(*args)`` for each ``args`` in ``calls`` with the JIT off."""
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    tests = Path(__file__).resolve().parent
    r = subprocess.run([sys.executable, "-c", _SCRIPT, str(tests), module, function,
                        json.dumps([list(c) for c in calls])], env=env, capture_output=True,
                       text=True)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr[-4000:]
