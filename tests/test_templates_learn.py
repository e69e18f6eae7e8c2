"""Motion-template learning: numba kernels = a naive reading of docs/method/features.md §A, the
golden templates of the reference implementation, thesis Example 3.1 and Claim 3.1."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REFERENCE, require_data
from hypothesis import given, settings
from hypothesis import strategies as st

from mtanno.errors import MtannoError
from mtanno.templates.dtw import _accumulated_cost, _cost_tables, _scratch, dtw, hard_cost, warp
from mtanno.templates.learn import (
    average_step,
    balance,
    contract,
    expand,
    learn,
)

# --------------------------------------------------------------------------- naive oracle
# Plain Python loops written from docs/method/features.md §A (and thesis §3.3.1 for hard MTs);
# every float operation in the order the appendix gives.


def n_round(x):
    r = math.floor(x)
    return r + 1 if x - r >= 0.5 else r


def n_hsum(xs):
    x = xs[0]
    for y in xs[1:]:
        if y != x:
            x = 0.5
    return x


def n_local(V, Vw, W, Ww, i, j, hard):
    p = len(V)
    s = 0.0
    for k in range(p):
        x, y = V[k][i], W[k][j]
        if hard:
            s += 0.0 if (x == 0.5 or y == 0.5) else abs(x - y)
        else:
            s += abs(x - y) / p
    return s * ((Vw[i] + Ww[j]) / 2.0)


def n_dtw_matrix(V, Vw, W, Ww, hard):
    n, m = len(Vw), len(Ww)
    C = [[n_local(V, Vw, W, Ww, i, j, hard) for j in range(m)] for i in range(n)]
    D = [[0.0] * m for _ in range(n)]
    D[0][0] = C[0][0]
    for i in range(1, n):
        D[i][0] = D[i - 1][0] + C[i][0]
    for j in range(1, m):
        D[0][j] = D[0][j - 1] + C[0][j]
    for i in range(1, n):
        for j in range(1, m):
            D[i][j] = min(D[i - 1][j - 1], D[i][j - 1], D[i - 1][j]) + C[i][j]
    return D


def n_warp(V, Vw, W, Ww, hard):
    p, n, m = len(V), len(Vw), len(Ww)
    D = n_dtw_matrix(V, Vw, W, Ww, hard)
    i, j = n - 1, m - 1
    path = [(i, j)]
    while i > 0 and j > 0:
        # diagonal, then horizontal (j−1), then vertical; a later one must be smaller
        opts = [(D[i - 1][j - 1], (i - 1, j - 1)), (D[i][j - 1], (i, j - 1)),
                (D[i - 1][j], (i - 1, j))]
        best = opts[0]
        for o in opts[1:]:
            if o[0] < best[0]:
                best = o
        i, j = best[1]
        path.append((i, j))
    while i > 0:
        i -= 1
        path.append((i, j))
    while j > 0:
        j -= 1
        path.append((i, j))
    path.reverse()
    Wwarp = [[0.0] * n for _ in range(p)]
    Wwt = [0.0] * n
    for b in range(n):
        js = [jj for (ii, jj) in path if ii == b]
        s = 0.0
        for jj in js:
            s += Ww[jj]
        Wwt[b] = s
        for k in range(p):
            if hard:
                Wwarp[k][b] = n_hsum([W[k][jj] for jj in js])
            else:
                acc = 0.0
                for jj in js:
                    acc += Ww[jj] * W[k][jj]
                Wwarp[k][b] = acc / s
    for jj in range(m):
        bs = [ii for (ii, j2) in path if j2 == jj]
        for b in range(bs[0], bs[-1] + 1):
            Wwt[b] = Wwt[b] / len(bs)
    return Wwarp, Wwt, D[n - 1][m - 1], path


def n_expand(V, w):
    V2, w2 = [[] for _ in V], []
    for i in range(len(w)):
        r = max(1, n_round(w[i]))
        for _ in range(r):
            for k in range(len(V)):
                V2[k].append(V[k][i])
            w2.append(w[i] / r)
    return V2, w2


def n_merge(V, w, a, b, hard):
    s = 0.0
    for t in range(a, b):
        s += w[t]
    col = []
    for k in range(len(V)):
        if hard:
            col.append(n_hsum([V[k][t] for t in range(a, b)]))
        else:
            acc = 0.0
            for t in range(a, b):
                acc += w[t] * V[k][t]
            col.append(acc / s)
    return col, s


def n_contract(V, w, hard, whole_previous):
    n = len(w)
    cols, ws, starts = [], [], []
    i = 0
    while i < n:
        if w[i] >= 0.75:
            cols.append([row[i] for row in V])
            ws.append(w[i])
            starts.append(i)
            i += 1
            continue
        s, j = w[i], i + 1
        while s < 0.75 and j < n:
            s += w[j]
            j += 1
        if s >= 0.75 or not cols:
            c, s2 = n_merge(V, w, i, j, hard)
            cols.append(c)
            ws.append(s2)
            starts.append(i)
        else:
            c, s2 = n_merge(V, w, starts[-1] if whole_previous else i - 1, n, hard)
            cols[-1], ws[-1] = c, s2
        i = j
    return [[c[k] for c in cols] for k in range(len(V))], ws


def n_step(U, w, k, hard):
    N = len(U)
    V, Vw = U[k], w[k]
    p, n = len(V), len(Vw)
    num = [list(r) for r in V] if hard else [[Vw[b] * V[q][b] for b in range(n)]
                                             for q in range(p)]
    den = list(Vw)
    cost = [0.0] * N
    for o in [k] + [o for o in range(N) if o != k]:
        if o == k:
            continue
        Wa, Wt, c, _ = n_warp(V, Vw, U[o], w[o], hard)
        for b in range(n):
            for q in range(p):
                if hard:
                    if num[q][b] != Wa[q][b]:
                        num[q][b] = 0.5
                else:
                    num[q][b] += Wt[b] * Wa[q][b]
            den[b] += Wt[b]
        cost[o] = c
    T = [[num[q][b] if hard else num[q][b] / den[b] for b in range(n)] for q in range(p)]
    Tw = [d / N for d in den]
    T, Tw = n_expand(T, Tw)
    T, Tw = n_contract(T, Tw, hard, whole_previous=hard)
    T, Tw = n_expand(T, Tw)
    return T, Tw, cost


def n_learn(examples, weights=None, hard=False, iter_max=10, thresh=0.005):
    U = [[[float(x) for x in row] for row in np.asarray(X)] for X in examples]
    w = ([[1.0] * len(u[0]) for u in U] if weights is None
         else [[float(x) for x in ww] for ww in weights])
    j, emax, eprev, hist = 0, thresh + 1, 0.0, []
    while j < iter_max and emax > thresh and eprev != emax:
        eprev = emax
        j += 1
        newU, neww, allc = [], [], []
        for k in range(len(U)):
            T, Tw, cost = n_step(U, w, k, hard)
            s = 0.0
            for x in Tw:
                s += x
            allc.extend(c / s for c in cost)
            newU.append(T)
            neww.append(Tw)
        emax = max(allc)
        hist.append(emax)
        U, w = newU, neww
    return np.array(U[0]), np.array(w[0]), j, hist


def random_set(rng, *, hard=False, fractional=False, max_len=9, max_p=5, max_n=5):
    N = int(rng.integers(1, max_n + 1))
    p = int(rng.integers(1, max_p + 1))
    out = []
    for _ in range(N):
        X = (rng.random((p, int(rng.integers(1, max_len + 1)))) < rng.random()).astype(float)
        if fractional:
            mask = rng.random(X.shape) < 0.5
            X[mask] = rng.random(int(mask.sum()))
        elif hard:
            X[rng.random(X.shape) < 0.1] = 0.5
        out.append(X)
    return out


# --------------------------------------------------------------------------- kernels = naive


@pytest.mark.parametrize("hard", [False, True])
def test_learn_equals_naive_on_random_sets(hard):
    rng = np.random.default_rng(7 + hard)
    for _ in range(60):
        ex = random_set(rng, hard=hard)
        got = learn(ex, hard=hard)
        v, w, it, hist = n_learn(ex, hard=hard)
        assert got.values.shape == v.shape
        assert np.array_equal(got.values, v) and np.array_equal(got.weights, w)
        assert got.iterations == it and got.cost_max == hist


def test_learn_equals_naive_with_fractional_inputs_and_weights():
    rng = np.random.default_rng(11)
    for _ in range(40):
        ex = random_set(rng, fractional=True)
        ws = [rng.random(X.shape[1]) * 2 + 0.1 for X in ex]
        got = learn(ex, weights=ws, iter_max=3)
        v, w, it, hist = n_learn(ex, weights=ws, iter_max=3)
        assert np.array_equal(got.values, v) and np.array_equal(got.weights, w)
        assert got.iterations == it and got.cost_max == hist


@pytest.mark.parametrize("p", [1, 3, 7, 31, 40, 41])
def test_cost_matrix_terms_are_exact_quotients(p):
    """The kernel's division-free terms (tables, fused multiply-add refinement) give the
    same D matrix, bit for bit, as summing |v − w| / p in feature order."""
    rng = np.random.default_rng(p)
    n, m = 23, 19
    vals = (rng.random((p, n + m)) < 0.3).astype(float)
    mask = rng.random(vals.shape) < 0.6
    vals[mask] = rng.random(int(mask.sum()))
    vals[:, ::5] = 1.0 - vals[:, ::5]
    vals = np.ascontiguousarray(vals)
    wts = rng.random(n + m) + 0.5
    off = np.array([0, n, n + m], dtype=np.int64)
    D = np.empty((n, m))
    _accumulated_cost(vals, wts, _cost_tables(vals, off), 0, n, n, m, 1, False, D,
                      _scratch(p, m))
    V = vals[:, :n].tolist()
    W = vals[:, n:].tolist()
    assert np.array_equal(D, np.array(n_dtw_matrix(V, wts[:n].tolist(), W,
                                                   wts[n:].tolist(), False)))


def test_tiny_entries_fall_back_to_division():
    rng = np.random.default_rng(3)
    ex = [rng.random((4, 6)) * 1e-300, rng.random((4, 5)), (rng.random((4, 7)) < .5) * 1.0]
    vals = np.ascontiguousarray(np.concatenate(ex, axis=1))
    assert _cost_tables(vals, np.array([0, 6, 11, 18]))[4] is False
    got = learn(ex, iter_max=2)
    v, w, _, _ = n_learn(ex, iter_max=2)
    assert np.array_equal(got.values, v) and np.array_equal(got.weights, w)


@pytest.mark.parametrize("hard", [False, True])
def test_public_warp_and_dtw_equal_naive(hard):
    rng = np.random.default_rng(5)
    for _ in range(30):
        V, W = random_set(rng, hard=hard, fractional=not hard, max_n=1)[0], None
        W = random_set(rng, hard=hard, fractional=not hard, max_n=1)[0]
        W = np.resize(W, (V.shape[0], W.shape[1]))
        vw, ww = rng.random(V.shape[1]) + 0.3, rng.random(W.shape[1]) + 0.3
        Wa, Wt, c = warp(V, W, weights_v=vw, weights_w=ww, hard=hard)
        nWa, nWt, nc, npath = n_warp(V.tolist(), vw.tolist(), W.tolist(), ww.tolist(), hard)
        assert np.array_equal(Wa, np.array(nWa)) and np.array_equal(Wt, np.array(nWt))
        assert c == nc
        cost, path = dtw(V, W, weights_v=vw, weights_w=ww, hard=hard)
        assert cost == nc and path.tolist() == [list(x) for x in npath]


def test_average_step_equals_one_reference_of_learning():
    rng = np.random.default_rng(9)
    for _ in range(20):
        ex = random_set(rng, max_n=4)
        for r in range(len(ex)):
            T, Tw, cost = average_step(ex, reference=r)
            U = [X.tolist() for X in ex]
            nT, nTw, ncost = n_step(U, [[1.0] * X.shape[1] for X in ex], r, False)
            assert np.array_equal(T, np.array(nT)) and np.array_equal(Tw, np.array(nTw))
            assert cost.tolist() == ncost


# --------------------------------------------------------------------------- operators


def test_expand_rounds_half_away_from_zero():
    V = np.array([[0.0, 1.0, 0.5, 0.25]])
    w = np.array([2.5, 0.5, 1.5, 0.49999999999999994])
    V2, w2 = expand(V, w)
    assert V2.tolist() == [[0.0, 0.0, 0.0, 1.0, 0.5, 0.5, 0.25]]
    assert w2.tolist() == [2.5 / 3] * 3 + [0.5, 0.75, 0.75, 0.49999999999999994]


def test_contract_reference_rule_and_whole_previous():
    # the reference implementation's own example: weights → [1, 0.75, 1.65]
    w = np.array([1, 0.5, 0.125, 0.125, 1, 0.25, 0.4])
    V = np.array([[0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0]])
    V2, w2 = contract(V, w)
    assert w2.tolist() == [1.0, 0.75, 1.65]
    assert V2[0, 1] == (0.5 * 1.0 + 0.125 * 0.0 + 0.125 * 1.0) / 0.75
    # light end group merged with the single input before it: the 0.6 input is dropped
    w = np.array([1.0, 0.6, 0.6, 0.6])
    V = np.array([[1.0, 0.0, 1.0, 1.0]])
    V2, w2 = contract(V, w)
    assert w2.tolist() == [1.0, 1.2] and V2.tolist() == [[1.0, 1.0]]
    s = 0.6 + 0.6 + 0.6  # left-to-right, as the kernel sums
    V2, w2 = contract(V, w, whole_previous=True)
    assert w2.tolist() == [1.0, s] and V2[0, 1] == (0.6 * 0.0 + 0.6 * 1.0 + 0.6 * 1.0) / s
    V2, w2 = contract(V, w, hard=True)
    assert w2.tolist() == [1.0, s] and V2.tolist() == [[1.0, 0.5]]
    # everything lighter than 0.75 and nothing before it: one column
    V2, w2 = contract(np.array([[0.0, 1.0]]), np.array([0.2, 0.3]))
    assert w2.tolist() == [0.5] and V2.tolist() == [[0.6]]


def test_balance_is_expand_contract_expand():
    rng = np.random.default_rng(2)
    V, w = rng.random((3, 8)), rng.random(8) * 3 + 0.1
    E1 = expand(V, w)
    C = contract(*E1)
    E2 = expand(*C)
    B = balance(V, w)
    assert np.array_equal(B[0], E2[0]) and np.array_equal(B[1], E2[1])


def test_hard_cost():
    # thesis examples after eq. 3.3
    assert hard_cost([1, 0, 1, 1], [1, 1, 0, 0]) == 3
    assert hard_cost([0.5, 0, 1, 0.5], [1, 1, 0.5, 0.5]) == 1
    with pytest.raises(MtannoError):
        hard_cost([1, 0], [1])


# --------------------------------------------------------------------------- thesis


def test_thesis_example_3_1():
    X = np.array([[1, 1, 1, 1, 0, 1]], dtype=float)
    Y = np.array([[0, 1, 0, 0, 0, 0, 1]], dtype=float)
    cost, path = dtw(X, Y, hard=True)
    assert cost == 1.0
    assert [tuple(c + 1) for c in path] == [(1, 1), (2, 2), (3, 2), (4, 2), (5, 3), (5, 4),
                                            (5, 5), (5, 6), (6, 7)]
    T, Tw, costs = average_step([X, Y], reference=0, hard=True)
    assert T.tolist() == [[0.5, 1.0, 0.5, 0.5, 0.0, 0.0, 1.0]]
    assert Tw.tolist() == [1.0, 4 / 3, 0.75, 0.75, 5 / 6, 5 / 6, 1.0]
    # Y has DTW distance 0 to the averaged template (the example's closing remark)
    assert dtw(T, Y, weights_v=Tw, hard=True)[0] == 0.0


@settings(deadline=None, max_examples=150)
@given(st.data())
def test_hard_mt_has_zero_distance_to_every_training_example(data):
    """Thesis Claim 3.1: with the cost c_H and steps (1,0),(0,1),(1,1) every training
    motion has DTW distance 0 to the hard MT."""
    p = data.draw(st.integers(1, 4))
    examples = data.draw(st.lists(
        st.integers(1, 9).flatmap(lambda n: st.lists(
            st.lists(st.sampled_from([0.0, 1.0]), min_size=n, max_size=n),
            min_size=p, max_size=p)),
        min_size=1, max_size=5))
    iters = data.draw(st.integers(1, 10))
    ex = [np.array(X) for X in examples]
    res = learn(ex, hard=True, iter_max=iters)
    assert np.isin(res.values, (0.0, 0.5, 1.0)).all()
    for X in ex:
        assert dtw(res.values, X, weights_v=res.weights, hard=True)[0] == 0.0


# --------------------------------------------------------------------------- input checks


def test_learn_rejects_bad_input():
    ok = np.zeros((3, 4))
    for bad, msg in [
        ([], "no training examples"),
        ([ok, np.zeros((2, 4))], "has 2 features"),
        ([np.zeros((3, 0))], "non-empty"),
        ([np.full((3, 2), 1.5)], "outside"),
        ([np.full((3, 2), np.nan)], "outside"),
    ]:
        with pytest.raises(MtannoError, match=msg):
            learn(bad)
    with pytest.raises(MtannoError, match="hard learning"):
        learn([np.full((3, 2), 0.3)], hard=True)
    with pytest.raises(MtannoError, match="iter_max"):
        learn([ok], iter_max=0)
    with pytest.raises(MtannoError, match="thresh"):
        learn([ok], thresh=float("nan"))
    with pytest.raises(MtannoError, match="weights"):
        learn([ok], weights=[np.zeros(4)])
    with pytest.raises(MtannoError, match="reference"):
        average_step([ok], reference=1)
    with pytest.raises(MtannoError, match="features"):
        dtw(ok, np.zeros((2, 2)))


def test_single_example_is_its_own_template():
    X = (np.random.default_rng(1).random((5, 7)) < 0.5).astype(float)
    res = learn([X])
    assert np.array_equal(res.values, X) and res.weights.tolist() == [1.0] * 7
    assert res.iterations == 1 and res.final_cost == 0.0


# --------------------------------------------------------------------------- golden MTs


def golden_classes():
    mt_dir = REFERENCE / "mt"
    return sorted(p.stem for p in mt_dir.glob("*.csv")) if mt_dir.is_dir() else []


def read_info(cls: str) -> tuple[list[str], int, float]:
    text = (REFERENCE / "mt" / f"{cls}_info.txt").read_text()
    files = re.findall(r"^\d+ (\S+)$", text, re.M)
    iterations = int(re.search(r"^iterations=(\d+)", text, re.M).group(1))
    final = float(re.search(r"^final_cost_max=(\S+)", text, re.M).group(1))
    return files, iterations, final


def load_golden_examples(cls: str, files: list[str]) -> list[np.ndarray]:
    return [np.loadtxt(REFERENCE / "features" / cls / f"{f}.csv", delimiter=",",
                       skiprows=1)[:, 1:].T.copy() for f in files]


def test_golden_templates_reproduced_exactly():
    require_data()
    classes = golden_classes()
    assert len(classes) == 11
    for cls in classes:
        files, iterations, final = read_info(cls)
        res = learn(load_golden_examples(cls, files))
        gold = np.loadtxt(REFERENCE / "mt" / f"{cls}.csv", delimiter=",", skiprows=1)
        assert res.values.shape == (40, gold.shape[0]), cls
        assert np.array_equal(res.values, gold[:, 2:].T), cls
        assert np.array_equal(res.weights, gold[:, 1]), cls
        assert res.iterations == iterations, cls
        assert res.final_cost == pytest.approx(final, rel=1e-9), cls


# --------------------------------------------------------------------------- no JIT

NOJIT = r"""
import sys
import numpy as np
import numba
assert numba.config.DISABLE_JIT
from mtanno.templates.learn import learn
rng = np.random.default_rng(4)
ex = [(rng.random((4, n)) < 0.4).astype(float) for n in (5, 7, 6)]
ex[1][rng.random(ex[1].shape) < 0.3] = 0.37
soft = learn(ex, iter_max=3)
hard = learn([(X > 0.5) * 1.0 for X in ex], hard=True)
np.savez(sys.argv[1], sv=soft.values, sw=soft.weights, hv=hard.values, hw=hard.weights)
"""


def test_kernels_without_jit_give_the_same_templates(tmp_path):
    out = tmp_path / "r.npz"
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    r = subprocess.run([sys.executable, "-c", NOJIT, str(out)], env=env, capture_output=True,
                       text=True, cwd=Path(__file__).resolve().parents[1])
    assert r.returncode == 0, r.stderr[-3000:]
    got = np.load(out)
    rng = np.random.default_rng(4)
    ex = [(rng.random((4, n)) < 0.4).astype(float) for n in (5, 7, 6)]
    ex[1][rng.random(ex[1].shape) < 0.3] = 0.37
    soft = learn(ex, iter_max=3)
    hard = learn([(X > 0.5) * 1.0 for X in ex], hard=True)
    assert np.array_equal(got["sv"], soft.values) and np.array_equal(got["sw"], soft.weights)
    assert np.array_equal(got["hv"], hard.values) and np.array_equal(got["hw"], hard.weights)
