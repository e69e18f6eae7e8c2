"""Calibrated confidence of annotation segments (issue 26, part 1): the probability that a
segment's label is right, from a few numbers of evidence per segment (its Δ̄ over τ, the
margin to the next class, its length against the class's training lengths, …), learned
from segments whose rightness is known (``tune``'s cross-validation) and saved in the class
configuration as a small fitted object, never recomputed at annotation time.

* :func:`fit_logistic` → :class:`LogisticModel` — L2-regularised logistic regression
  (Platt scaling when the evidence is one score; Platt 1999, "Probabilistic outputs for
  support vector machines"), fitted by Newton's method (IRLS) on standardised columns;
* :func:`fit_isotonic` → :class:`IsotonicModel` — isotonic regression of rightness on one
  score by pool-adjacent-violators (Zadrozny & Elkan 2002, "Transforming classifier scores
  into accurate multiclass probability estimates");
* :func:`fit_calibrated` → :class:`CalibrationResult` — one of :data:`CALIBRATION_METHODS`
  fitted on all segments (the :class:`Calibrator` to save) with the out-of-fold
  probabilities of every segment (to measure AUROC and ECE on segments not used to fit:
  :mod:`mtanno.evaluation.calibration`);
* :func:`uncalibrated_confidence` — the fallback score without a tuned configuration
  (:data:`UNCALIBRATED`).

Why :data:`DEFAULT_CALIBRATION` is ``"platt"``: a ``tune`` run is expected to yield hundreds
of held-out segments rather than thousands, and isotonic regression beats Platt scaling
only from about a thousand calibration examples on (Niculescu-Mizil & Caruana 2005,
"Predicting good probabilities with supervised learning"); below that its steps follow the
noise of the sample and its end blocks say exactly 0 or 1. The logistic model is smooth
and strictly monotone in every piece of evidence (no flat blocks that tie segments and
lower their AUROC), and it is what combines several pieces of evidence (isotonic regression
alone takes one score). ``"platt+isotonic"`` maps the logistic model's output
through an isotonic regression, for many segments whose reliability plot bends away from
the diagonal. Logistic regression needs evidence whose log-odds is monotone: give a length
as ``|log(length / typical length)|``, not the ratio itself.

Every model has ``to_dict`` / ``from_dict`` with plain floats, lists and strings (a TOML
table); ``from_dict`` checks what it reads and names the file in its :class:`MtannoError`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mtanno.errors import MtannoError

__all__ = ["CALIBRATION_FOLDS", "CALIBRATION_L2", "CALIBRATION_METHODS", "DEFAULT_CALIBRATION",
           "NEWTON_MAX_ITER", "UNCALIBRATED", "CalibrationResult", "Calibrator", "IsotonicModel",
           "LogisticModel", "check_labels", "fit_calibrated", "fit_isotonic", "fit_logistic",
           "uncalibrated_confidence"]

#: The methods of :func:`fit_calibrated` (module docstring).
CALIBRATION_METHODS = ("platt", "isotonic", "platt+isotonic")
#: The default method: logistic regression alone (module docstring: why).
DEFAULT_CALIBRATION = "platt"
#: Strength λ of the L2 penalty λ/2·|β|² on the standardised coefficients (a Gaussian prior
#: of variance 1/λ on the change of log-odds per standard deviation of a column).
CALIBRATION_L2 = 1.0
#: Folds of the out-of-fold estimate in :func:`fit_calibrated`.
CALIBRATION_FOLDS = 5
#: Newton iterations at most (it converges in about ten).
NEWTON_MAX_ITER = 100
#: The confidence method written in provenance for :func:`uncalibrated_confidence`.
UNCALIBRATED = "uncalibrated"

# standardised evidence is clipped to ±this: ±∞ (no next class, so no margin) becomes the
# limit, far beyond where the sigmoid saturates for any coefficient above 1e-4
_Z_LIMIT = 1e6


# --------------------------------------------------------------------------- checks

def _array(values, what: str) -> np.ndarray:
    a = np.asarray(values)
    if a.dtype.kind not in "biuf":
        raise MtannoError(f"{what} must be numbers, got {a.dtype} values")
    return a


def check_labels(y, n: int, what: str = "labels") -> np.ndarray:
    """0/1 labels (1 = right) as float64, one per row."""
    a = _array(y, what)
    if a.ndim != 1 or len(a) != n:
        raise MtannoError(f"{what} must be one value per row ({n}), got shape {a.shape}")
    f = a.astype(np.float64)
    bad = np.flatnonzero((f != 0) & (f != 1))
    if len(bad):
        raise MtannoError(f"{what} must be 0 or 1 (wrong or right), got {a[bad[0]].item()!r} at "
                          f"index {bad[0]}")
    return f


def _weights(weights, n: int) -> np.ndarray:
    if weights is None:
        return np.ones(n)
    w = _array(weights, "weights").astype(np.float64)
    if w.ndim != 1 or len(w) != n:
        raise MtannoError(f"weights must be one value per row ({n}), got shape {w.shape}")
    bad = np.flatnonzero(~(np.isfinite(w) & (w >= 0)))
    if len(bad):
        raise MtannoError(f"weights must be finite and >= 0, got {w[bad[0]].item()!r} at index {bad[0]}")
    return w


def _matrix(X, what: str = "evidence") -> np.ndarray:
    """(n × k) float64; a 1-D array is one column."""
    a = _array(X, what).astype(np.float64)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise MtannoError(f"{what} must be a matrix (rows × columns), got shape {a.shape}")
    return a


def _names(names, k: int) -> tuple[str, ...]:
    if names is None:
        return tuple(f"x{j}" for j in range(k))
    out = tuple(names) if not isinstance(names, str) else (names,)
    if len(out) != k:
        raise MtannoError(f"{len(out)} evidence names for {k} evidence columns")
    if not all(isinstance(s, str) and s for s in out) or len(set(out)) != len(out):
        raise MtannoError(f"evidence names must be distinct non-empty strings, got {list(out)}")
    return out


def _listed_names(d, what: str, path) -> tuple[str, ...]:
    """The ``names`` list of a model's table, checked (else an error naming ``path``)."""
    names = d["names"]
    if not isinstance(names, (list, tuple)):
        raise MtannoError(f"{what}: names must be a list of strings", path=path)
    try:
        return _names(names, len(names))
    except MtannoError as exc:
        raise MtannoError(f"{what}: {exc.message}", path=path) from None


def _fallback(y: np.ndarray, w: np.ndarray) -> tuple[str | None, float]:
    """Why no model can be fitted (None: it can) and the smoothed rate of right labels,
    (Σw·y + 1) / (Σw + 2) (Laplace's rule: 0.5 without examples, never exactly 0 or 1)."""
    live = w > 0
    rate = (float(w @ y) + 1.0) / (float(w.sum()) + 2.0)
    if not live.any():
        return "no examples", rate
    if np.all(y[live] == 1):
        return "one class only (all right)", rate
    if np.all(y[live] == 0):
        return "one class only (all wrong)", rate
    return None, rate


def _sigmoid(eta: np.ndarray) -> np.ndarray:
    """1 / (1 + e^−η) without overflow: e^η / (1 + e^η) where η < 0."""
    e = np.exp(-np.abs(eta))
    return np.where(eta >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


def _logit(p: float) -> float:
    return math.log(p / (1.0 - p))


# --------------------------------------------------------------------------- dict reading

def _table(d, keys: tuple[str, ...], optional: tuple[str, ...], what: str, path):
    if not isinstance(d, Mapping):
        raise MtannoError(f"{what} must be a table, got {type(d).__name__}", path=path)
    missing = [k for k in keys if k not in d]
    unknown = sorted(str(k) for k in d if k not in keys + optional)
    if missing or unknown:
        said = [f"missing {', '.join(missing)}"] * bool(missing) + \
            [f"unknown {', '.join(unknown)}"] * bool(unknown)
        raise MtannoError(f"{what}: {'; '.join(said)} (keys: {', '.join(keys + optional)})",
                          path=path)
    return d


def _floats(d, key: str, what: str, path, *, n: int | None = None, positive=False) -> tuple:
    v = d[key]
    if not isinstance(v, (list, tuple)):
        raise MtannoError(f"{what}: {key} must be a list of numbers", path=path)
    out = tuple(_float(x, f"{key}[{i}]", what, path, positive=positive) for i, x in enumerate(v))
    if n is not None and len(out) != n:
        raise MtannoError(f"{what}: {key} has {len(out)} values, names has {n}", path=path)
    return out


def _float(x, key: str, what: str, path, *, positive=False) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) \
            or (positive and not x > 0):
        need = "a finite number > 0" if positive else "a finite number"
        raise MtannoError(f"{what}: {key} must be {need}, got {x!r}", path=path)
    return float(x)


def _fallback_of(d, what: str, path) -> str | None:
    v = d.get("fallback")
    if v is not None and not (isinstance(v, str) and v):
        raise MtannoError(f"{what}: fallback must be a non-empty string, got {v!r}", path=path)
    return v


# --------------------------------------------------------------------------- logistic

@dataclass(frozen=True)
class LogisticModel:
    """P(right | x) = σ(b + Σⱼ βⱼ·(xⱼ − meanⱼ)/scaleⱼ), σ the logistic sigmoid.

    ``names`` names the evidence columns in order; ``mean`` and ``scale`` (> 0) standardise
    them; ``coef`` (β) and ``intercept`` (b) are fitted. ``fallback`` says why the model is
    a constant when no model could be fitted ("no examples", "one class only (all right)"),
    else None.
    """

    names: tuple[str, ...]
    mean: tuple[float, ...]
    scale: tuple[float, ...]
    coef: tuple[float, ...]
    intercept: float
    fallback: str | None = None

    def standardise(self, X) -> np.ndarray:
        """(X − mean) / scale, NaN as 0 (the column's mean), clipped to ±1e6 (so ±∞ is
        the limit of large values)."""
        Z = _matrix(X)
        if Z.shape[1] != len(self.names):
            raise MtannoError(f"evidence has {Z.shape[1]} columns, the model "
                              f"{len(self.names)} ({', '.join(self.names)})")
        Z = (Z - np.asarray(self.mean)) / np.asarray(self.scale)
        return np.clip(np.nan_to_num(Z, nan=0.0), -_Z_LIMIT, _Z_LIMIT)

    def linear(self, X) -> np.ndarray:
        """The log-odds b + Z·β of every row of ``X`` (n × k, columns as ``names``)."""
        return self.intercept + self.standardise(X) @ np.asarray(self.coef, dtype=np.float64)

    def predict(self, X) -> np.ndarray:
        """P(right) of every row of ``X`` (n × k, columns in the order of ``names``; a 1-D
        array is one column), in [0, 1]. A NaN entry (evidence missing) counts as its
        column's mean, i.e. contributes nothing; ±∞ as the limit."""
        return _sigmoid(self.linear(X))

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats (a TOML table); ``fallback`` only when set."""
        out: dict[str, Any] = {"names": list(self.names), "mean": list(self.mean),
                               "scale": list(self.scale), "coef": list(self.coef),
                               "intercept": self.intercept}
        if self.fallback is not None:
            out["fallback"] = self.fallback
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, path: str | None = None) -> LogisticModel:
        """The model of :meth:`to_dict`'s table, checked: the lists as long as ``names``,
        finite numbers, every scale > 0 (else :class:`MtannoError` naming ``path``)."""
        what = "logistic model"
        _table(d, ("names", "mean", "scale", "coef", "intercept"), ("fallback",), what, path)
        names = _listed_names(d, what, path)
        n = len(names)
        return cls(names=names, mean=_floats(d, "mean", what, path, n=n),
                   scale=_floats(d, "scale", what, path, n=n, positive=True),
                   coef=_floats(d, "coef", what, path, n=n),
                   intercept=_float(d["intercept"], "intercept", what, path),
                   fallback=_fallback_of(d, what, path))


def _moments(X: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted column means and standard deviations over the non-NaN entries; the scale
    of a constant (or empty) column is 1, so that it standardises to 0."""
    seen = ~np.isnan(X)
    W = np.where(seen, w[:, None], 0.0)
    total = W.sum(axis=0)
    safe = np.where(total > 0, total, 1.0)
    mean = np.where(total > 0, (W * np.where(seen, X, 0.0)).sum(axis=0) / safe, 0.0)
    var = (W * np.where(seen, X - mean, 0.0) ** 2).sum(axis=0) / safe
    scale = np.sqrt(var)
    constant = ~(scale > 1e-12 * np.maximum(1.0, np.abs(mean)))
    return mean, np.where(constant, 1.0, scale)


def _newton(Z: np.ndarray, y: np.ndarray, w: np.ndarray, l2: float, b0: float,
            max_iter: int) -> np.ndarray:
    """argmin over θ = (b, β) of Σ wᵢ·(log(1 + e^ηᵢ) − yᵢ·ηᵢ) + λ/2·|β|², ηᵢ = b + Zᵢ·β:
    Newton steps with a backtracking (Armijo) line search. The objective is strictly
    convex and, with both labels present and λ > 0, has its minimum at a finite θ, also
    for separable data."""
    n, k = Z.shape
    A = np.column_stack([np.ones(n), Z])
    pen = np.full(k + 1, l2)
    pen[0] = 0.0  # the intercept is not penalised

    def objective(theta):
        eta = A @ theta
        return float(w @ (np.logaddexp(0.0, eta) - y * eta) + 0.5 * pen @ theta ** 2)

    theta = np.zeros(k + 1)
    theta[0] = b0
    f = objective(theta)
    ridge = 1e-12 * max(1.0, float(w.sum()))  # keeps H invertible when all p are 0 or 1
    for _ in range(max_iter):
        p = _sigmoid(A @ theta)
        g = A.T @ (w * (p - y)) + pen * theta
        H = (A * (w * p * (1 - p))[:, None]).T @ A + np.diag(pen)
        H[0, 0] += ridge
        step = np.linalg.solve(H, g)
        decrement = float(g @ step)  # the squared Newton decrement, ≥ 0
        if decrement <= 1e-20 * max(1.0, abs(f)):
            break
        t = 1.0
        while True:
            new = theta - t * step
            f_new = objective(new)
            if f_new <= f - 1e-4 * t * decrement or t < 1e-12:
                break
            t *= 0.5
        if f_new > f:  # no decrease left at machine precision
            break
        theta, f = new, f_new
        if t * np.max(np.abs(step)) < 1e-12 * max(1.0, float(np.max(np.abs(theta)))):
            break
    return theta


def fit_logistic(X, y, *, names: Sequence[str] | None = None, l2: float = CALIBRATION_L2,
                 weights=None, max_iter: int = NEWTON_MAX_ITER) -> LogisticModel:
    """L2-regularised logistic regression of ``y`` (0/1, 1 = right) on ``X`` (n × k; a 1-D
    array is one column), fitted by Newton's method (IRLS) on standardised columns.

    The columns are standardised by their (``weights``-weighted) mean and standard
    deviation, stored in the model; the penalty ``l2``/2·|β|² (λ > 0) acts on the
    standardised coefficients, not on the intercept, so it is the same for every unit of
    the evidence and keeps separable data finite. NaN entries count as the column's mean
    (as in :meth:`LogisticModel.predict`); a constant column gets coefficient 0. Without
    examples or with one label only, the model is the constant (Σw·y + 1)/(Σw + 2) (0.5
    without examples) and its ``fallback`` says why. ``names`` name the columns (default
    ``x0``, ``x1``, …)."""
    X = _matrix(X)
    n, k = X.shape
    names = _names(names, k)
    y = check_labels(y, n)
    w = _weights(weights, n)
    if not (isinstance(l2, (int, float)) and not isinstance(l2, bool) and math.isfinite(l2)
            and l2 > 0):
        raise MtannoError(f"{{l2}} must be a finite number > 0, got {l2!r}", options=("l2",))
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
        raise MtannoError(f"{{max_iter}} must be an integer >= 1, got {max_iter!r}",
                          options=("max_iter",))
    inf = np.argwhere(np.isinf(X))
    if len(inf):
        i, j = inf[0]
        raise MtannoError(f"evidence {names[j]} is infinite at index {i}: cap it (e.g. at the "
                          "largest finite value) before fitting")
    mean, scale = _moments(X, w)
    fallback, rate = _fallback(y, w)
    if fallback is not None:
        return LogisticModel(names, tuple(mean.tolist()), tuple(scale.tolist()), (0.0,) * k,
                             _logit(rate), fallback)
    Z = np.nan_to_num((X - mean) / scale, nan=0.0)
    theta = _newton(Z, y, w, float(l2), _logit(float(w @ y) / float(w.sum())), max_iter)
    return LogisticModel(names, tuple(mean.tolist()), tuple(scale.tolist()),
                         tuple(theta[1:].tolist()), float(theta[0]))


# --------------------------------------------------------------------------- isotonic

@dataclass(frozen=True)
class IsotonicModel:
    """A non-decreasing map from a score to P(right): the blocks of an isotonic regression,
    each with its centre ``x`` (the weighted mean score of its examples; strictly
    increasing), its rate of right labels ``y`` (non-decreasing, in [0, 1]) and its total
    ``weight``. :meth:`predict` interpolates linearly between the centres and is constant
    beyond the first and the last. ``fallback`` as in :class:`LogisticModel` (then one
    block, or none without examples)."""

    x: tuple[float, ...]
    y: tuple[float, ...]
    weight: tuple[float, ...]
    fallback: str | None = None

    def predict(self, score) -> np.ndarray:
        """P(right) for every score (any shape); a NaN score (evidence missing) gets the
        model's overall rate (its blocks' weighted mean), 0.5 without blocks."""
        s = _array(score, "scores").astype(np.float64)
        if not self.x:
            return np.full(s.shape, 0.5)
        y = np.asarray(self.y)
        prior = float(np.asarray(self.weight) @ y / sum(self.weight))
        out = np.interp(np.nan_to_num(s, nan=0.0, posinf=np.inf, neginf=-np.inf),
                        np.asarray(self.x), y)
        return np.where(np.isnan(s), prior, out)

    def to_dict(self) -> dict[str, Any]:
        """Plain lists (a TOML table); ``fallback`` only when set."""
        out: dict[str, Any] = {"x": list(self.x), "y": list(self.y), "weight": list(self.weight)}
        if self.fallback is not None:
            out["fallback"] = self.fallback
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, path: str | None = None) -> IsotonicModel:
        """The model of :meth:`to_dict`'s table, checked: lists of one length, finite
        numbers, ``x`` strictly increasing, ``y`` non-decreasing in [0, 1], weights > 0."""
        what = "isotonic model"
        _table(d, ("x", "y", "weight"), ("fallback",), what, path)
        x = _floats(d, "x", what, path)
        y = _floats(d, "y", what, path, n=len(x))
        weight = _floats(d, "weight", what, path, n=len(x), positive=True)
        if any(b <= a for a, b in zip(x, x[1:])):
            raise MtannoError(f"{what}: x must be strictly increasing", path=path)
        if any(b < a for a, b in zip(y, y[1:])) or any(not 0 <= v <= 1 for v in y):
            raise MtannoError(f"{what}: y must be non-decreasing within [0, 1]", path=path)
        return cls(x, y, weight, _fallback_of(d, what, path))


def _pool(s: np.ndarray, y: np.ndarray, w: np.ndarray):
    """Pool-adjacent-violators on examples sorted by distinct score ``s`` (ties already
    pooled): (Σw·s, Σw·y, Σw) of the blocks. Adjacent blocks with equal rates are pooled
    too, so the blocks are the level sets of the fit and their centres spread out."""
    ws, wy, ww = [], [], []
    for a, b, c in zip((w * s).tolist(), (w * y).tolist(), w.tolist()):
        ws.append(a)
        wy.append(b)
        ww.append(c)
        while len(ww) > 1 and wy[-2] * ww[-1] >= wy[-1] * ww[-2]:  # rate[-2] ≥ rate[-1]
            c = ww.pop()
            b = wy.pop()
            a = ws.pop()
            ws[-1] += a
            wy[-1] += b
            ww[-1] += c
    return np.array(ws), np.array(wy), np.array(ww)


def fit_isotonic(score, y, *, weights=None) -> IsotonicModel:
    """Isotonic (non-decreasing) regression of ``y`` (0/1, 1 = right) on a finite 1-D
    ``score`` by pool-adjacent-violators (Zadrozny & Elkan 2002), examples weighted by
    ``weights``: orient the score so that larger means more likely right (e.g. −Δ̄/τ). Tied
    scores are one example. Without examples or with one label only, one block with the
    rate (Σw·y + 1)/(Σw + 2) (none without examples) and ``fallback`` saying why."""
    s = _array(score, "scores").astype(np.float64)
    if s.ndim != 1:
        raise MtannoError(f"scores must be one value per row (1-D), got shape {s.shape}")
    y = check_labels(y, len(s))
    w = _weights(weights, len(s))
    bad = np.flatnonzero(~np.isfinite(s))
    if len(bad):
        raise MtannoError(f"scores must be finite, got {s[bad[0]].item()!r} at index {bad[0]}")
    fallback, rate = _fallback(y, w)
    live = w > 0
    if fallback == "no examples":
        return IsotonicModel((), (), (), fallback)
    if fallback is not None:
        centre = float(w[live] @ s[live] / w[live].sum())
        return IsotonicModel((centre,), (rate,), (float(w.sum()),), fallback)
    s, y, w = s[live], y[live], w[live]
    u, inv = np.unique(s, return_inverse=True)
    ww = np.bincount(inv, weights=w, minlength=len(u))
    wy = np.bincount(inv, weights=w * y, minlength=len(u))
    bs, by, bw = _pool(u, wy / ww, ww)
    x = bs / bw
    # a centre may repeat only by rounding of the weighted mean; keep x strictly increasing
    x = np.maximum.accumulate(x)
    keep = np.concatenate([[True], np.diff(x) > 0])
    rates = np.clip(by / bw, 0.0, 1.0)
    return IsotonicModel(tuple(x[keep].tolist()), tuple(rates[keep].tolist()),
                         tuple(bw[keep].tolist()))


# --------------------------------------------------------------------------- calibrator

@dataclass(frozen=True)
class Calibrator:
    """A fitted confidence: ``method`` (one of :data:`CALIBRATION_METHODS`), the evidence
    ``names`` in column order, the logistic part (``"platt"``, ``"platt+isotonic"``) and the
    isotonic part (``"isotonic"``: on the one evidence column; ``"platt+isotonic"``: on the
    logistic part's probability)."""

    method: str
    names: tuple[str, ...]
    logistic: LogisticModel | None = None
    isotonic: IsotonicModel | None = None

    def predict(self, X) -> np.ndarray:
        """P(right) in [0, 1] of every row of ``X`` (n × k, columns as ``names``)."""
        if self.logistic is None:
            Z = _matrix(X)
            if Z.shape[1] != 1:
                raise MtannoError(f"evidence has {Z.shape[1]} columns, the model 1 "
                                  f"({self.names[0]})")
            return self.isotonic.predict(Z[:, 0])
        p = self.logistic.predict(X)
        return p if self.isotonic is None else self.isotonic.predict(p)

    def to_dict(self) -> dict[str, Any]:
        """``method``, ``names`` and the parts as sub-tables ``logistic`` / ``isotonic``."""
        out: dict[str, Any] = {"method": self.method, "names": list(self.names)}
        if self.logistic is not None:
            out["logistic"] = self.logistic.to_dict()
        if self.isotonic is not None:
            out["isotonic"] = self.isotonic.to_dict()
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, path: str | None = None) -> Calibrator:
        """The calibrator of :meth:`to_dict`'s table, checked: a known method with exactly
        its parts, the logistic part on the same names, one name for ``"isotonic"``."""
        what = "calibration"
        _table(d, ("method", "names"), ("logistic", "isotonic"), what, path)
        method = d["method"]
        if method not in CALIBRATION_METHODS:
            raise MtannoError(f"{what}: unknown method {method!r} (methods: "
                              f"{', '.join(CALIBRATION_METHODS)})", path=path)
        names = _listed_names(d, what, path)
        wants = {"logistic": "platt" in method, "isotonic": "isotonic" in method}
        for part, wanted in wants.items():
            if wanted != (part in d):
                raise MtannoError(f"{what}: method {method!r} "
                                  f"{'needs' if wanted else 'has no'} a {part} table", path=path)
        logistic = LogisticModel.from_dict(d["logistic"], path=path) if wants["logistic"] \
            else None
        if logistic is not None and logistic.names != names:
            raise MtannoError(f"{what}: the logistic model's names {list(logistic.names)} are "
                              f"not the calibration's {list(names)}", path=path)
        if logistic is None and len(names) != 1:
            raise MtannoError(f"{what}: method 'isotonic' takes one evidence name, got "
                              f"{len(names)}", path=path)
        isotonic = IsotonicModel.from_dict(d["isotonic"], path=path) if wants["isotonic"] \
            else None
        return cls(method, names, logistic, isotonic)


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """What :func:`fit_calibrated` returns: the ``calibrator`` fitted on all examples (the
    one to save), ``oof`` the out-of-fold P(right) of every example (from a calibrator
    fitted without the example's fold, all of its parts inside that fold's training
    examples), ``fold`` the 0-based fold of every example, and ``seed`` the seed the folds
    were drawn with (None when a Generator was given)."""

    calibrator: Calibrator
    oof: np.ndarray
    fold: np.ndarray
    seed: int | None


def _fold_ids(y: np.ndarray, folds: int, rng: np.random.Generator, groups) -> np.ndarray:
    """A fold per example: without ``groups`` the right and the wrong examples are dealt
    out in a random order each, so every fold holds both; with ``groups`` whole groups are
    (the segments of one document stay together). With fewer examples than folds some
    folds are empty."""
    if groups is None:
        out = np.empty(len(y), np.int64)
        start = 0
        for label in (1.0, 0.0):
            idx = np.flatnonzero(y == label)
            out[idx[rng.permutation(len(idx))]] = (start + np.arange(len(idx))) % folds
            start += len(idx)
        return out
    _, inv = np.unique(groups, return_inverse=True)
    of_group = np.empty(inv.max() + 1 if len(inv) else 0, np.int64)
    of_group[rng.permutation(len(of_group))] = np.arange(len(of_group)) % folds
    return of_group[inv.ravel()]


def _fit(method: str, X: np.ndarray, y: np.ndarray, names: tuple[str, ...], l2: float,
         fold: np.ndarray) -> Calibrator:
    """The calibrator of ``method`` on all of X, y; the isotonic part of
    ``"platt+isotonic"`` maps the out-of-fold logistic probabilities under ``fold``."""
    if method == "isotonic":
        return Calibrator(method, names, None, fit_isotonic(X[:, 0], y))
    logistic = fit_logistic(X, y, names=names, l2=l2)
    if method == "platt":
        return Calibrator(method, names, logistic)
    inner = np.empty(len(y))
    for f in np.unique(fold):
        test = fold == f
        inner[test] = fit_logistic(X[~test], y[~test], names=names, l2=l2).predict(X[test])
    return Calibrator(method, names, logistic, fit_isotonic(inner, y))


def fit_calibrated(X, y, *, names: Sequence[str], method: str = DEFAULT_CALIBRATION,
                   folds: int = CALIBRATION_FOLDS, rng: np.random.Generator | int = 0,
                   groups=None, l2: float = CALIBRATION_L2) -> CalibrationResult:
    """A calibrated P(right) from evidence ``X`` (n × k, columns named ``names``) and
    labels ``y`` (0/1, 1 = right), with the out-of-fold probability of every example.

    ``method`` (:data:`CALIBRATION_METHODS`; the module docstring says why the default is
    ``"platt"``): ``"platt"`` a logistic model (:func:`fit_logistic`, penalty ``l2``);
    ``"isotonic"`` an isotonic regression on the one column of ``X`` (larger = more likely
    right); ``"platt+isotonic"`` a logistic model whose out-of-fold probabilities an
    isotonic regression maps. The examples are split into ``folds`` (≥ 2) random folds
    (``rng``: a Generator or a seed), keeping the examples of one ``groups`` value
    together when given (e.g. a document's segments); each example's ``oof`` comes from a
    calibrator fitted on the other folds (for ``"platt+isotonic"``, its isotonic part on
    inner folds of those), the returned calibrator from all examples."""
    if method not in CALIBRATION_METHODS:
        raise MtannoError(f"unknown calibration {{method}} {method!r} (methods: "
                          f"{', '.join(CALIBRATION_METHODS)})", options=("method",))
    if isinstance(folds, bool) or not isinstance(folds, int) or folds < 2:
        raise MtannoError(f"{{folds}} must be an integer >= 2, got {folds!r}",
                          options=("folds",))
    X = _matrix(X)
    n, k = X.shape
    names = _names(names, k)
    y = check_labels(y, n)
    if method == "isotonic" and k != 1:
        raise MtannoError(f"calibration 'isotonic' takes one evidence column, got {k} "
                          f"({', '.join(names)}): use 'platt+isotonic' to combine them")
    bad = np.argwhere(~np.isfinite(X) if method == "isotonic" else np.isinf(X))
    if len(bad):  # (checked here so that the index is the caller's, not a fold's)
        i, j = bad[0]
        raise MtannoError(f"evidence {names[j]} is {X[i, j]} at index {i}: "
                          + ("isotonic calibration needs finite scores" if method == "isotonic"
                             else "cap it (e.g. at the largest finite value) before fitting"))
    if groups is not None:
        groups = np.asarray(groups)
        if groups.ndim != 1 or len(groups) != n:
            raise MtannoError(f"groups must be one value per row ({n}), got shape "
                              f"{groups.shape}")
    if isinstance(rng, np.random.Generator):
        seed, gen = None, rng
    elif isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) and rng >= 0:
        seed, gen = int(rng), np.random.default_rng(int(rng))
    else:
        raise MtannoError(f"{{rng}} must be a numpy Generator or a seed (an integer >= 0), got "
                          f"{rng!r}", options=("rng",))
    fold = _fold_ids(y, folds, gen, groups)
    oof = np.empty(n)
    for f in np.unique(fold):
        test = fold == f
        train = ~test
        inner = _fold_ids(y[train], folds, gen, None if groups is None else groups[train]) \
            if method == "platt+isotonic" else None
        oof[test] = _fit(method, X[train], y[train], names, l2, inner).predict(X[test])
    return CalibrationResult(_fit(method, X, y, names, l2, fold), oof, fold, seed)


# --------------------------------------------------------------------------- fallback

def uncalibrated_confidence(cost_ratio) -> np.ndarray:
    """The confidence of segments without a tuned configuration (:data:`UNCALIBRATED` in
    the provenance): ``clip(1 − r, 0, 1)`` of each segment's cost ratio r = Δ̄/τ (its
    cost over its class's threshold; any shape).

    Not a probability, only monotone: a segment matching its template exactly scores 1,
    one just at the threshold 0, linearly between. Chosen over exp(−k·r) because a labelled
    segment has r in [0, 1] (Δ̄ ≤ τ), which 1 − r spans fully with no constant k to pick and
    no value ≥ e^−k left unused; r < 0 gives 1, r ≥ 1 gives 0. NaN is refused."""
    r = _array(cost_ratio, "cost ratios").astype(np.float64)
    bad = np.argwhere(np.isnan(r))
    if len(bad):
        raise MtannoError(f"cost ratio is NaN at index {tuple(bad[0].tolist())}")
    return np.clip(1.0 - r, 0.0, 1.0)
