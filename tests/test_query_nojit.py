"""The index kernels and the 31-feature measures run as plain Python (NUMBA_DISABLE_JIT=1)
and give the same answers as the compiled kernels. Subprocess: the switch is read at import."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

SCRIPT = r"""
import json, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
import numba
assert numba.config.DISABLE_JIT
from test_query_nojit import results
print(json.dumps(results()))
"""


def results() -> dict:
    """Query, interval and feature results on fixed random data (JSON-able)."""
    import numpy as np
    from naive_features import features_numpy

    from mtanno.features import compute_features_native, get_feature_set
    from mtanno.index import (
        FuzzySet,
        GroupQuery,
        Query,
        example_query,
        index_from_matrices,
        search,
    )

    rng = np.random.default_rng(9)
    names = ["a", "b", "c", "d"]
    docs = {f"x{i}": (np.cumsum(rng.random((4, 60)) < 0.15, axis=1) % 2).astype(np.uint8)
            for i in range(3)}
    idx = index_from_matrices(docs, names, {"g": ["a", "b", "c"], "h": ["d"]})
    out = {}
    g3 = (FuzzySet(((3, 0),)), FuzzySet(((3, 1), (3, 3))), FuzzySet(((3, 2),)))
    for mode, m in (("fuzzy", 0), ("fuzzy", 1), ("adaptive", 0)):
        hits = search(idx, Query((GroupQuery("g", g3),), mode, m))
        out[f"{mode}{m}"] = [hits.doc.tolist(), hits.start.tolist(), hits.end.tolist()]
    two = (GroupQuery("g", g3), GroupQuery("h", (FuzzySet(((1, 0),)), FuzzySet(((1, 1),)))))
    hits = search(idx, Query(two, "adaptive"))
    out["two"] = [hits.doc.tolist(), hits.start.tolist(), hits.end.tolist()]
    out["intervals"] = [a.tolist() for a in idx.groups["g"].intervals([(5, 4)])]
    for feats, frames, n in ((["a", "c"], (5, 40), 3), (["a", "b", "d"], (0, 59), 1)):
        hits = search(idx, example_query(idx, docs["x1"], names, feats, frames=frames,
                                         min_segment=n))  # smoothed (Query.smooth)
        out[f"example{n}"] = [hits.doc.tolist(), hits.start.tolist(), hits.score.tolist()]
    J = rng.normal(size=(40, 22, 3)) * 25
    H = np.zeros((40, 3))
    for name in ("mrc05", "mrc05-reference"):
        fs = get_feature_set(name)
        X = compute_features_native(J, H, 120.0, features=fs.features)
        assert np.array_equal(X, features_numpy(J, H, 120.0, features=fs.features))
        out[name] = X.tolist()
    return out


def test_index_and_31_kernels_without_jit():
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    tests = Path(__file__).resolve().parent
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(tests)], env=env, capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    assert json.loads(r.stdout.strip().splitlines()[-1]) == results()
