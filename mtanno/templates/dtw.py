"""Classical DTW between weighted templates, and the warping of one template onto another.

This is the alignment step of motion-template learning ([MR06] §4.1; the exact variant of
the reference implementation is ``docs/method/features.md`` §A, ``warp``). A *template*
here is a (features × columns) float64 matrix with one positive weight per column; a
training clip is a 0/1 matrix at 30 Hz with all weights 1, so "columns" are frames at 30 Hz.

* Soft local cost ([MR06] §4.1): ``c(i,j) = (Σ_k |V(k,i) − W(k,j)|) / f · (Vw(i) + Ww(j)) / 2``,
  summed term by term in feature order — the rounding of this sum decides DTW ties, and
  the golden templates depend on it.
* Hard local cost (thesis §3.3.1, eq. 3.2–3.3): ``Σ_k d(V(k,i), W(k,j))`` with ``d = 0`` when
  either entry is the wildcard 0.5, else ``|x − y|``; multiplied by the same weight factor
  (it is the same learning loop, docs/method.md §3.2).
* Steps (1,0), (0,1), (1,1); ``D(1,1) = C(1,1)``; first row and column accumulated one step
  at a time. Backtracking from the last cell prefers the diagonal, then the reference's
  horizontal step (the other template advances), then the vertical one; a later choice
  needs a strictly smaller value. On reaching the first row or column the path runs
  straight to (1,1).

The numba kernels below are private; :func:`dtw` and :func:`warp` validate their input and
are what the rest of mtanno (and the tests) call. The learning loop in
:mod:`mtanno.templates.learn` drives the kernels directly for speed: the local cost is
symmetric bit for bit, so one accumulated-cost matrix serves both orders of a pair (only
the tie order of the backtracking differs).
"""

from __future__ import annotations

from fractions import Fraction

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

from mtanno.errors import MtannoError

__all__ = ["dtw", "warp", "hard_cost"]


# --------------------------------------------------------------------------- kernels


if numba.config.DISABLE_JIT:  # pragma: no cover - exercised by tests/test_nojit-style runs

    def _fma(a, b, c):
        """a·b + c with one rounding (exact rational arithmetic, then one conversion)."""
        return float(Fraction(a) * Fraction(b) + Fraction(c))

else:

    @intrinsic
    def _fma(typingctx, a, b, c):
        """a·b + c with one rounding (``llvm.fma.f64``; IEEE fusedMultiplyAdd)."""
        sig = types.float64(types.float64, types.float64, types.float64)

        def codegen(context, builder, signature, args):
            fnty = ir.FunctionType(ir.DoubleType(), [ir.DoubleType()] * 3)
            fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.fma.f64")
            return builder.call(fn, args)

        return sig, codegen


#: Smallest nonzero entry for which :func:`_accumulated_cost` replaces ``d / f`` by
#: multiplications (no underflow in the correction steps); below it, it divides.
FMA_SAFE_MIN = 2.0 ** -900


@numba.njit(cache=True)
def _accumulated_cost(vals, wts, tabs, a0, n, b0, m, b, hard, D, scratch):
    """Fill ``D[:n, :m]`` with the accumulated DTW cost of template A (columns
    ``a0 .. a0+n−1`` of ``vals``) against template B (number ``b``, columns
    ``b0 .. b0+m−1``); ``scratch`` is :func:`_scratch` for at least m columns.

    The soft local cost of cell (i, j) is ``Σ_k |A(k,i) − B(k,j)| / f``, each term rounded
    and added in feature order (one accumulator per B column, so the loop over j
    vectorizes without reordering any sum). Exact shortcuts, none of which changes a bit:

    * a column equal to the previous column of its template has the same sums, so they
      are computed once per run of equal columns (in A: the row is reused; in B: the
      loop runs over the runs);
    * for A entries exactly 0 or 1 the terms come from the tables of
      :func:`_cost_tables`, and are skipped when they are 0 for every B column;
    * otherwise ``d / f`` is obtained as ``q = d·RN(1/f)`` refined twice by
      ``q += (d − q·f)·RN(1/f)`` with fused multiply-adds (Markstein's theorem: one
      refinement of a quotient within 1 ulp is correctly rounded; the first refinement
      brings q within 1 ulp for any f), unless tiny entries could underflow.
    """
    p = vals.shape[0]
    P0, P1, zero_row, one_row, fma_ok, same_prev = tabs
    fp = float(p)
    y = 1.0 / fp
    acc, run, Bv, B0, B1 = scratch
    # B reduced to one column per run of equal columns
    mu = 0
    for j in range(m):
        if j > 0 and same_prev[b0 + j]:
            run[j] = mu - 1
        else:
            run[j] = mu
            mu += 1
    for j in range(m):
        if j == 0 or not same_prev[b0 + j]:
            u = run[j]
            for k in range(p):
                Bv[k, u] = vals[k, b0 + j]
                B0[k, u] = P0[k, b0 + j]
                B1[k, u] = P1[k, b0 + j]
    wb = wts[b0:b0 + m]
    a = acc[:mu]
    for i in range(n):
        if i == 0 or not same_prev[a0 + i]:
            for u in range(mu):
                a[u] = 0.0
            for k in range(p):
                v = vals[k, a0 + i]
                if hard:
                    row = Bv[k]
                    for u in range(mu):
                        d = abs(v - row[u])
                        # entries are 0, 0.5 or 1: |x − y| = 0.5 exactly when one is a wildcard
                        if d == 0.5:
                            d = 0.0
                        a[u] = a[u] + d
                elif v == 0.0:
                    if not zero_row[b, k]:
                        t = B0[k]
                        for u in range(mu):
                            a[u] = a[u] + t[u]
                elif v == 1.0:
                    if not one_row[b, k]:
                        t = B1[k]
                        for u in range(mu):
                            a[u] = a[u] + t[u]
                elif fma_ok:
                    row = Bv[k]
                    for u in range(mu):
                        d = abs(v - row[u])
                        q = d * y
                        q = _fma(_fma(-q, fp, d), y, q)
                        a[u] = a[u] + _fma(_fma(-q, fp, d), y, q)
                else:
                    row = Bv[k]
                    for u in range(mu):
                        a[u] = a[u] + abs(v - row[u]) / p
        wi = wts[a0 + i]
        Di = D[i]
        if i == 0:
            for j in range(m):
                c = a[run[j]] * ((wi + wb[j]) / 2.0)
                Di[j] = c if j == 0 else Di[j - 1] + c
        else:
            Dp = D[i - 1]
            Di[0] = Dp[0] + a[0] * ((wi + wb[0]) / 2.0)
            prev = Di[0]
            for j in range(1, m):
                c = a[run[j]] * ((wi + wb[j]) / 2.0)
                best = min(min(Dp[j - 1], prev), Dp[j])
                prev = best + c
                Di[j] = prev


@numba.njit(cache=True)
def _scratch(p, maxlen):
    """Work arrays of :func:`_accumulated_cost` for templates of up to ``maxlen`` columns."""
    return (np.empty(maxlen), np.empty(maxlen, dtype=np.int64), np.empty((p, maxlen)),
            np.empty((p, maxlen)), np.empty((p, maxlen)))


@numba.njit(cache=True)
def _cost_tables(vals, off):
    """Per entry the soft cost terms against a reference entry 0 (``|0 − w| / f``) and 1
    (``|1 − w| / f``); per template and feature whether the row is all 0 / all 1; whether
    every nonzero entry is ≥ :data:`FMA_SAFE_MIN`; per column whether it equals the
    previous column of its template."""
    p, total = vals.shape
    N = off.shape[0] - 1
    P0 = np.empty((p, total))
    P1 = np.empty((p, total))
    fma_ok = True
    for k in range(p):
        for c in range(total):
            w = vals[k, c]
            P0[k, c] = abs(0.0 - w) / p
            P1[k, c] = abs(1.0 - w) / p
            if w != 0.0 and abs(w) < FMA_SAFE_MIN:
                fma_ok = False
    zero_row = np.ones((N, p), dtype=np.bool_)
    one_row = np.ones((N, p), dtype=np.bool_)
    same_prev = np.zeros(total, dtype=np.bool_)
    for t in range(N):
        for c in range(off[t], off[t + 1]):
            same = c > off[t]
            for k in range(p):
                x = vals[k, c]
                if x != 0.0:
                    zero_row[t, k] = False
                if x != 1.0:
                    one_row[t, k] = False
                if same and x != vals[k, c - 1]:
                    same = False
            same_prev[c] = same
    return P0, P1, zero_row, one_row, fma_ok, same_prev


@numba.njit(cache=True)
def _backtrack(D, n, m, transposed, pi, pj):
    """Optimal path through ``D[:n, :m]`` from (0,0) to (n−1,m−1) into ``pi``/``pj``;
    returns its length.

    Ties: diagonal, then the step along the *other* template, then the step along the
    reference. The reference is A (rows) unless ``transposed``, when it is B (columns),
    so the row step is preferred to the column step."""
    i = n - 1
    j = m - 1
    L = 0
    while i > 0 and j > 0:
        pi[L] = i
        pj[L] = j
        L += 1
        best = D[i - 1, j - 1]
        step = 0
        if transposed:
            if D[i - 1, j] < best:
                best = D[i - 1, j]
                step = 2
            if D[i, j - 1] < best:
                step = 1
        else:
            if D[i, j - 1] < best:
                best = D[i, j - 1]
                step = 1
            if D[i - 1, j] < best:
                step = 2
        if step == 0:
            i -= 1
            j -= 1
        elif step == 1:
            j -= 1
        else:
            i -= 1
    while i > 0:
        pi[L] = i
        pj[L] = j
        L += 1
        i -= 1
    while j > 0:
        pi[L] = i
        pj[L] = j
        L += 1
        j -= 1
    pi[L] = 0
    pj[L] = 0
    L += 1
    # reverse into path order (0,0) … (n−1,m−1)
    for t in range(L // 2):
        u = L - 1 - t
        pi[t], pi[u] = pi[u], pi[t]
        pj[t], pj[u] = pj[u], pj[t]
    return L


@numba.njit(cache=True)
def _warp(vals, wts, nr, o0, pr, po, L, hard, S, wd):
    """Warp template O (columns ``o0 …`` of ``vals``) onto a reference of ``nr`` columns
    along the path ``(pr[t], po[t])`` (docs/method/features.md §A ``warp``).

    Writes ``Wwarp`` into ``S[:, :nr]`` — per reference column b the weighted mean
    ``Σ Ww(j)·W(:,j) / Σ Ww(j)`` of the O columns j matched to b (sums in path order), or
    their hard sum (thesis Def. 3.4) when ``hard`` — and ``Wwt`` into ``wd[:nr]``: the summed
    weights, then, O column by O column, divided by r where that column is matched to r
    reference columns (this acts on the accumulated sums, as the reference does)."""
    p = vals.shape[0]
    for b in range(nr):
        wd[b] = 0.0
        for k in range(p):
            S[k, b] = 0.0
    prev = -1
    for t in range(L):
        b = pr[t]
        c = o0 + po[t]
        w = wts[c]
        first = b != prev
        prev = b
        wd[b] += w
        if hard:
            for k in range(p):
                x = vals[k, c]
                if first:
                    S[k, b] = x
                elif S[k, b] != x:
                    S[k, b] = 0.5
        else:
            for k in range(p):
                S[k, b] += w * vals[k, c]
    if not hard:
        for b in range(nr):
            for k in range(p):
                S[k, b] = S[k, b] / wd[b]
    t = 0
    while t < L:
        u = t
        while u + 1 < L and po[u + 1] == po[t]:
            u += 1
        r = u - t + 1
        if r > 1:
            for s in range(t, u + 1):
                wd[pr[s]] = wd[pr[s]] / r
        t = u + 1


@numba.njit(cache=True)
def _accumulate(num, den, r0, nr, S, wd, hard):
    """Add a warped template to reference R's sums (columns ``r0 …`` of ``num``/``den``):
    soft ``num += Wwt·Wwarp``, hard ``num = num ⊕ Wwarp``; always ``den += Wwt``."""
    p = num.shape[0]
    for b in range(nr):
        w = wd[b]
        for k in range(p):
            if hard:
                if num[k, r0 + b] != S[k, b]:
                    num[k, r0 + b] = 0.5
            else:
                num[k, r0 + b] += w * S[k, b]
        den[r0 + b] += w


@numba.njit(cache=True)
def _init_sums(vals, wts, hard, num, den):
    """``num = Vw .* V`` (hard: V) and ``den = Vw`` for every reference at once."""
    p, total = vals.shape
    for c in range(total):
        den[c] = wts[c]
        for k in range(p):
            num[k, c] = vals[k, c] if hard else wts[c] * vals[k, c]


@numba.njit(cache=True)
def _all_references(vals, wts, off, hard, num, den, cmax, csum, D, pi, pj, S, wd):
    """One learning iteration's sums for every reference at once, and per reference the
    largest and the summed DTW cost of the examples against it (``cmax``, ``csum``: N
    values each, so memory grows with N, not N², for classes of many short examples).

    Each unordered pair (a, b) is aligned once: the local cost is symmetric bit for bit,
    so the accumulated-cost matrix of (b, a) is the transpose of that of (a, b); only
    the backtracking (tie order) differs. Looping a < b in order adds, for every
    reference, the other examples in ascending order, as the reference does."""
    N = off.shape[0] - 1
    tabs = _cost_tables(vals, off)
    scratch = _scratch(vals.shape[0], D.shape[1])
    _init_sums(vals, wts, hard, num, den)
    for a in range(N):  # the cost of a reference against itself: 0
        cmax[a] = 0.0
        csum[a] = 0.0
    for a in range(N):
        a0 = off[a]
        n = off[a + 1] - a0
        for b in range(a + 1, N):
            b0 = off[b]
            m = off[b + 1] - b0
            _accumulated_cost(vals, wts, tabs, a0, n, b0, m, b, hard, D, scratch)
            c = D[n - 1, m - 1]
            cmax[a] = max(cmax[a], c)
            cmax[b] = max(cmax[b], c)
            csum[a] += c
            csum[b] += c
            L = _backtrack(D, n, m, False, pi, pj)
            _warp(vals, wts, n, b0, pi, pj, L, hard, S, wd)
            _accumulate(num, den, a0, n, S, wd, hard)
            L = _backtrack(D, n, m, True, pi, pj)
            _warp(vals, wts, m, a0, pj, pi, L, hard, S, wd)
            _accumulate(num, den, b0, m, S, wd, hard)


@numba.njit(cache=True)
def _one_reference(vals, wts, off, r, hard, num, den, cost, D, pi, pj, S, wd):
    """The sums of reference ``r`` alone (others aligned in ascending order)."""
    N = off.shape[0] - 1
    tabs = _cost_tables(vals, off)
    scratch = _scratch(vals.shape[0], D.shape[1])
    _init_sums(vals, wts, hard, num, den)
    a0 = off[r]
    n = off[r + 1] - a0
    for o in range(N):
        if o == r:
            cost[o] = 0.0
            continue
        b0 = off[o]
        m = off[o + 1] - b0
        _accumulated_cost(vals, wts, tabs, a0, n, b0, m, o, hard, D, scratch)
        cost[o] = D[n - 1, m - 1]
        L = _backtrack(D, n, m, False, pi, pj)
        _warp(vals, wts, n, b0, pi, pj, L, hard, S, wd)
        _accumulate(num, den, a0, n, S, wd, hard)


# --------------------------------------------------------------------------- public API


def _as_template(X, w, what: str) -> tuple[np.ndarray, np.ndarray]:
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[0] == 0 or X.shape[1] == 0:
        raise MtannoError(f"{what} must be a non-empty (features × columns) matrix, "
                          f"got shape {X.shape}")
    if not np.isfinite(X).all() or X.min() < 0.0 or X.max() > 1.0:
        raise MtannoError(f"{what} has entries outside [0, 1] (or NaN)")
    if w is None:
        w = np.ones(X.shape[1])
    w = np.asarray(w, dtype=np.float64)
    if w.shape != (X.shape[1],):
        raise MtannoError(f"{what} weights must have one entry per column "
                          f"({X.shape[1]}), got shape {w.shape}")
    if not (np.isfinite(w).all() and (w > 0).all()):
        raise MtannoError(f"{what} weights must be positive and finite")
    return X, w


def _pair(V, Vw, W, Ww, hard):
    V, Vw = _as_template(V, Vw, "reference")
    W, Ww = _as_template(W, Ww, "template")
    if V.shape[0] != W.shape[0]:
        raise MtannoError(f"the templates have {V.shape[0]} and {W.shape[0]} features")
    if hard:
        for X in (V, W):
            if not np.isin(X, (0.0, 0.5, 1.0)).all():
                raise MtannoError("the hard cost needs entries 0, 0.5 or 1")
    vals = np.ascontiguousarray(np.concatenate([V, W], axis=1))
    wts = np.concatenate([Vw, Ww])
    return vals, wts, V.shape[1], W.shape[1]


def dtw(V: np.ndarray, W: np.ndarray, *, weights_v: np.ndarray | None = None,
        weights_w: np.ndarray | None = None, hard: bool = False) -> tuple[float, np.ndarray]:
    """Classical DTW of template ``W`` against reference ``V`` (both features × columns).

    Returns ``(cost, path)``: the accumulated cost ``D(n, m)`` and the optimal path as a
    (length × 2) array of 0-based (V column, W column) pairs from (0, 0) to (n−1, m−1),
    with the tie rules of the module docstring. Weights default to 1 per column.
    ``hard=True`` uses the thesis' wildcard cost c_H (entries must be 0, 0.5 or 1);
    thesis Claim 3.1 says every training clip has cost 0 against its hard MT.
    """
    vals, wts, n, m = _pair(V, weights_v, W, weights_w, hard)
    D = np.empty((n, m))
    off = np.array([0, n, n + m], dtype=np.int64)
    _accumulated_cost(vals, wts, _cost_tables(vals, off), 0, n, n, m, 1, bool(hard), D,
                      _scratch(vals.shape[0], m))
    pi = np.empty(n + m, dtype=np.int64)
    pj = np.empty(n + m, dtype=np.int64)
    L = _backtrack(D, n, m, False, pi, pj)
    return float(D[n - 1, m - 1]), np.stack([pi[:L], pj[:L]], axis=1)


def warp(V: np.ndarray, W: np.ndarray, *, weights_v: np.ndarray | None = None,
         weights_w: np.ndarray | None = None,
         hard: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """Warp template ``W`` onto the length of reference ``V`` (docs/method/features.md §A,
    ``warp``).

    Returns ``(Wwarp, Wwt, cost)``: the warped (features × n) matrix (weighted mean of the
    W columns matched to each V column, or their hard sum when ``hard``), the warped
    weights (summed, then spread evenly over the reference columns a W column is
    stretched across), and the DTW cost of :func:`dtw`.
    """
    vals, wts, n, m = _pair(V, weights_v, W, weights_w, hard)
    hard = bool(hard)
    D = np.empty((n, m))
    off = np.array([0, n, n + m], dtype=np.int64)
    _accumulated_cost(vals, wts, _cost_tables(vals, off), 0, n, n, m, 1, hard, D,
                      _scratch(vals.shape[0], m))
    pi = np.empty(n + m, dtype=np.int64)
    pj = np.empty(n + m, dtype=np.int64)
    L = _backtrack(D, n, m, False, pi, pj)
    p = vals.shape[0]
    S = np.empty((p, n))
    wd = np.empty(n)
    _warp(vals, wts, n, n, pi, pj, L, hard, S, wd)
    return S, wd, float(D[n - 1, m - 1])


def hard_cost(x: np.ndarray, y: np.ndarray) -> float:
    """c_H(x, y) = Σ_i d(x_i, y_i), d = 0 if either entry is 0.5, else |x_i − y_i|
    (thesis eq. 3.2–3.3), for two feature vectors."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 1:
        raise MtannoError(f"need two feature vectors of equal length, got {x.shape}, {y.shape}")
    d = np.abs(x - y)
    d[(x == 0.5) | (y == 0.5)] = 0.0
    return float(d.sum())
