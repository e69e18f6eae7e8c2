"""The matching kernels run as plain Python (NUMBA_DISABLE_JIT=1) and give the oracle's answers.

Run in a subprocess because the JIT switch is read at import time. The popcount's final multiply
wraps around modulo 2**64 by design; numpy warns about that in plain Python, so the warning is
silenced here and nowhere else.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SCRIPT = r"""
import sys, warnings
import numpy as np
sys.path.insert(0, sys.argv[1])
warnings.filterwarnings("ignore", "overflow encountered", RuntimeWarning)
import numba
assert numba.config.DISABLE_JIT
from naive_match import hits_naive, match_naive
from mtanno.retrieve import extract_hits
from mtanno.templates.match import PreparedTemplate, match_documents, match_template
rng = np.random.default_rng(1)
cases = 0
for f, K, L, steps, sw in [(40, 7, 30, ((1, 1), (1, 2), (2, 1)), (1, 1, 2)),
                           (70, 5, 20, ((1, 1), (1, 2), (2, 1)), (1, 1, 2)),
                           (12, 6, 25, ((1, 1), (0, 1), (1, 0)), (1, 1, 1))]:
    V = rng.integers(0, 2, size=(f, K)).astype(float)
    V[rng.random((f, K)) < 0.3] = 0.5
    w = rng.uniform(0.3, 2.7, size=K)
    X = (rng.random((f, L)) < 0.5).astype(np.uint8)
    for variant in ("reference", "paper"):
        fast = PreparedTemplate(V, w, variant=variant, steps=steps, step_weights=sw).fast
        assert fast == (f <= 64 and steps[1] == (1, 2))
        d, s = match_template(V, w, X, variant=variant, steps=steps, step_weights=sw)
        dn, sn = match_naive(V, w, X, variant=variant, steps=steps, step_weights=sw)
        assert np.array_equal(d, dn) and np.array_equal(s, sn), (f, K, L, variant)
        (d2, s2), (d3, s3) = match_documents(V, w, [X[:, :9], X[:, 9:]], variant=variant,
                                             steps=steps, step_weights=sw)
        assert np.array_equal(d2, match_naive(V, w, X[:, :9], variant=variant, steps=steps,
                                              step_weights=sw)[0])
        for mode in ("retrieval", "classification"):
            h = extract_hits(d, s, tau=0.3, mode=mode, max_hits=3)
            hn, tr = hits_naive(d, s, tau=0.3, mode=mode, max_hits=3)
            assert [(x.start, x.end, x.cost) for x in h] == hn and h.truncated == tr
        cases += 1
assert cases == 6
print("ok")
"""


def test_match_kernels_without_jit():
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    tests = Path(__file__).resolve().parent
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(tests)], env=env, capture_output=True,
                       text=True)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-3000:]
