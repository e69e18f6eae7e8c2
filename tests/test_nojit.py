"""The numba kernels run as plain Python (NUMBA_DISABLE_JIT=1) and give the oracles' answers.

Run in a subprocess because the JIT switch is read at import time.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SCRIPT = r"""
import sys, tempfile
from pathlib import Path
import numpy as np
sys.path.insert(0, sys.argv[1])
from naive import fk_naive, hysteresis_naive
from naive_features import features_numpy
from mtanno import synthetic
from mtanno.io import read_channels, read_motion, canonical_positions
from mtanno.io.skeleton import forward_kinematics
from mtanno.features import compute_features_native
from mtanno.features.hysteresis import hysteresis
import numba
assert numba.config.DISABLE_JIT
d = Path(tempfile.mkdtemp())
amc = synthetic.write_pair(d, n_frames=40, seed=5)
rig, ch = read_channels(amc)
P, _ = forward_kinematics(rig, ch.angles, ch.trans, ch.has_trans)
assert np.allclose(P, fk_naive(rig, ch), atol=1e-9)
m = read_motion(amc)
J = canonical_positions(m)
assert np.array_equal(compute_features_native(J, m.heading, m.fps), features_numpy(J, m.heading, m.fps))
rng = np.random.default_rng(0)
on = rng.random(30) < 0.3
off = on | (rng.random(30) < 0.3)
assert np.array_equal(hysteresis(on, off), hysteresis_naive(on, off))
print("ok")
"""


def test_kernels_without_jit():
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    tests = Path(__file__).resolve().parent
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(tests)], env=env, capture_output=True,
                       text=True)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-3000:]
