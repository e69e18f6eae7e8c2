"""Calibrated segment confidence (mtanno.confidence.calibration) and its measures
(mtanno.evaluation.calibration, mtanno.plot.reliability_figure), issue 26: recovery of known
probabilities on synthetic segments, slow obvious oracles for AUROC, ECE and
pool-adjacent-violators, hand-worked cases, round trips, and every invalid input."""

from __future__ import annotations

import itertools
import json
import math
import sys

import numpy as np
import pytest

from mtanno.confidence.calibration import (
    CALIBRATION_METHODS,
    Calibrator,
    IsotonicModel,
    LogisticModel,
    _pool,
    fit_calibrated,
    fit_isotonic,
    fit_logistic,
    uncalibrated_confidence,
)
from mtanno.errors import MtannoError
from mtanno.evaluation.calibration import auroc, expected_calibration_error, reliability_table

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def sigmoid(z):
    return 1.0 / (1.0 + np.exp(-z))


def draw(rng, n, a=(1.5, -0.8), b=0.3):
    """Synthetic segments: evidence x ~ N(0, I), P(right) = σ(a·x + b), right ~ Bernoulli."""
    x = rng.normal(size=(n, len(a)))
    p = sigmoid(x @ np.asarray(a) + b)
    return x, p, (rng.random(n) < p).astype(int)


# --- slow obvious references -----------------------------------------------------------------

def naive_auroc(score, right):
    pos = [s for s, r in zip(score, right) if r]
    neg = [s for s, r in zip(score, right) if not r]
    if not pos or not neg:
        return math.nan
    wins = sum(1.0 if p > q else 0.5 if p == q else 0.0 for p in pos for q in neg)
    return wins / (len(pos) * len(neg))


def naive_table(prob, right, bins):
    rows = []
    for k in range(bins):
        lo, hi = k / bins, (k + 1) / bins
        members = [(p, r) for p, r in zip(prob, right)
                   if lo <= p < hi or (k == bins - 1 and p == 1.0)]
        if members:
            rows.append((lo, hi, len(members), sum(p for p, _ in members) / len(members),
                         sum(r for _, r in members) / len(members)))
        else:
            rows.append((lo, hi, 0, math.nan, math.nan))
    return rows


def naive_ece(prob, right, bins):
    total = 0.0
    for _, _, count, mp, fr in naive_table(prob, right, bins):
        if count:
            total += count / len(prob) * abs(mp - fr)
    return total


def naive_isotonic(rates, weights):
    """The isotonic fit at every point by the min–max formula:
    f(i) = max_{j ≤ i} min_{k ≥ i} (weighted mean of rates j..k)."""
    n = len(rates)

    def mean(j, k):
        return sum(rates[t] * weights[t] for t in range(j, k + 1)) / \
            sum(weights[t] for t in range(j, k + 1))

    return [max(min(mean(j, k) for k in range(i, n)) for j in range(i + 1)) for i in range(n)]


def gradient(model: LogisticModel, X, y, w, l2):
    """The gradient of the penalised log-loss at a fitted model, in standardised units."""
    Z = np.nan_to_num((X - np.asarray(model.mean)) / np.asarray(model.scale), nan=0.0)
    p = model.predict(X)
    g_b = np.sum(w * (p - y))
    g_beta = Z.T @ (w * (p - y)) + l2 * np.asarray(model.coef)
    return np.concatenate([[g_b], g_beta])


# --- logistic ---------------------------------------------------------------------------------

def test_logistic_recovers_known_probabilities_and_is_calibrated_on_fresh_draws():
    rng = np.random.default_rng(0)
    X, p, y = draw(rng, 5000)
    model = fit_logistic(X, y, names=["dbar", "margin"])
    err = np.abs(model.predict(X) - p)
    assert err.mean() < 0.02 and np.quantile(err, 0.95) < 0.04, (err.mean(), err.max())
    X2, _, y2 = draw(rng, 5000)
    assert expected_calibration_error(model.predict(X2), y2) < 0.03
    assert model.names == ("dbar", "margin") and model.fallback is None


def test_newton_reaches_the_penalised_minimum_with_weights_and_missing_values():
    rng = np.random.default_rng(1)
    X, _, y = draw(rng, 300, a=(2.0, 0.5, -1.0))
    X[rng.random(X.shape) < 0.05] = np.nan
    w = rng.uniform(0.2, 3.0, len(y))
    for l2 in (1e-3, 1.0, 50.0):
        model = fit_logistic(X, y, weights=w, l2=l2)
        assert np.abs(gradient(model, X, y, w, l2)).max() < 1e-8
    assert model.names == ("x0", "x1", "x2")


def test_weights_are_repeated_rows_and_zero_weights_drop_rows():
    rng = np.random.default_rng(2)
    X, _, y = draw(rng, 40)
    twice = fit_logistic(np.vstack([X, X[:10]]), np.concatenate([y, y[:10]]))
    weighted = fit_logistic(X, y, weights=np.r_[np.full(10, 2.0), np.ones(30)])
    assert np.allclose(twice.predict(X), weighted.predict(X), atol=1e-10)
    dropped = fit_logistic(X, y, weights=np.r_[np.zeros(10), np.ones(30)])
    assert np.allclose(dropped.predict(X), fit_logistic(X[10:], y[10:]).predict(X), atol=1e-10)


def test_constant_column_and_intercept_only():
    y = np.array([1, 0, 0, 1, 1])
    model = fit_logistic(np.full((5, 1), 7.0), y)
    assert model.coef == (0.0,) and model.scale == (1.0,)
    assert np.allclose(model.predict([[7.0], [-100.0], [np.nan]]), 0.6, atol=1e-12)


def test_separable_data_stays_finite_and_ordered():
    x = np.array([-2.0, -1.0, 1.0, 2.0])
    for l2 in (1.0, 1e-8):
        model = fit_logistic(x, [0, 0, 1, 1], l2=l2)
        assert all(math.isfinite(v) for v in (*model.coef, model.intercept))
        p = model.predict(x)
        assert np.all(np.diff(p) > 0) and p[0] < 0.5 < p[-1]
    assert fit_logistic(x, [0, 0, 1, 1], l2=1e-8).coef[0] > fit_logistic(x, [0, 0, 1, 1]).coef[0]


@pytest.mark.parametrize("y, weights, reason, p", [
    ([], None, "no examples", 0.5),
    ([1, 1, 1], None, "one class only (all right)", 4 / 5),
    ([0, 0], None, "one class only (all wrong)", 1 / 4),
    ([0, 1, 1], [1, 0, 0], "one class only (all wrong)", 1 / 3),
    ([0, 1], [0, 0], "no examples", 0.5),
])
def test_degenerate_labels_give_a_constant_that_says_why(y, weights, reason, p):
    X = np.arange(2 * len(y), dtype=float).reshape(len(y), 2)
    model = fit_logistic(X, y, weights=weights)
    assert model.fallback == reason and model.coef == (0.0, 0.0)
    assert np.allclose(model.predict([[0.0, 1.0], [5.0, -3.0]]), p)


def test_predict_missing_and_infinite_evidence():
    rng = np.random.default_rng(3)
    X, _, y = draw(rng, 200)
    model = fit_logistic(X, y)
    assert model.predict([[np.nan, 0.5]])[0] == model.predict([[model.mean[0], 0.5]])[0]
    p = model.predict([[np.inf, 0.0], [-np.inf, 0.0], [np.inf, -np.inf]])
    assert p[0] == 1.0 and p[1] == 0.0 and p[2] == 1.0  # coef[0] > 0 > coef[1]
    assert np.all(np.isfinite(model.predict(rng.normal(size=(50, 2)) * 1e300)))


def test_logistic_round_trip_is_exact_through_json_and_toml():
    rng = np.random.default_rng(4)
    X, _, y = draw(rng, 100)
    for model in (fit_logistic(X, y, names=["a", "b"]), fit_logistic(X[:3], [1, 1, 1])):
        d = model.to_dict()
        assert LogisticModel.from_dict(d) == model
        assert LogisticModel.from_dict(json.loads(json.dumps(d))) == model
        toml = "\n".join(f"{k} = {json.dumps(v)}" for k, v in d.items())
        assert LogisticModel.from_dict(tomllib.loads(toml)) == model


GOOD = {"names": ["a", "b"], "mean": [0.0, 1.0], "scale": [1.0, 2.0], "coef": [0.5, -1],
        "intercept": 0}


@pytest.mark.parametrize("change, message", [
    ({"scale": [1.0, 0.0]}, "scale[1] must be a finite number > 0, got 0.0"),
    ({"scale": [1.0, -2.0]}, "scale[1] must be a finite number > 0"),
    ({"mean": [0.0]}, "mean has 1 values, names has 2"),
    ({"coef": [0.5, float("nan")]}, "coef[1] must be a finite number, got nan"),
    ({"coef": [0.5, True]}, "coef[1] must be a finite number, got True"),
    ({"coef": "0.5"}, "coef must be a list of numbers"),
    ({"intercept": float("inf")}, "intercept must be a finite number"),
    ({"intercept": "1"}, "intercept must be a finite number"),
    ({"names": ["a", "a"]}, "distinct non-empty strings"),
    ({"names": ["a", ""]}, "distinct non-empty strings"),
    ({"names": "ab"}, "names must be a list of strings"),
    ({"fallback": 3}, "fallback must be a non-empty string"),
    ({"slope": [1.0]}, "unknown slope"),
    ({"intercept": None}, "missing intercept"),
])
def test_logistic_from_dict_refuses_bad_tables(change, message):
    d = {**GOOD, **change}
    d = {k: v for k, v in d.items() if v is not None}
    with pytest.raises(MtannoError, match=None) as info:
        LogisticModel.from_dict(d, path="conf.toml")
    text = str(info.value)
    assert text.startswith("conf.toml: logistic model: ") and message in text, text
    assert "\n" not in text


def test_logistic_from_dict_needs_a_table():
    with pytest.raises(MtannoError, match="logistic model must be a table, got list"):
        LogisticModel.from_dict([1, 2])
    assert LogisticModel.from_dict(GOOD).predict([[0.0, 1.0]])[0] == 0.5


@pytest.mark.parametrize("call, message", [
    (lambda: fit_logistic(np.zeros((3, 2)), [0, 1]), "one value per row (3)"),
    (lambda: fit_logistic(np.zeros((3, 2)), [0, 1, 2]), "must be 0 or 1 (wrong or right), got 2 "
                                                        "at index 2"),
    (lambda: fit_logistic(np.zeros((2, 1)), [0.5, 1]), "got 0.5 at index 0"),
    (lambda: fit_logistic(np.zeros((2, 1)), [np.nan, 1]), "got nan at index 0"),
    (lambda: fit_logistic(np.zeros((2, 1)), ["0", "1"]), "labels must be numbers"),
    (lambda: fit_logistic(np.zeros((2, 2, 2)), [0, 1]), "must be a matrix"),
    (lambda: fit_logistic([[1.0], [np.inf]], [0, 1]), "evidence x0 is infinite at index 1"),
    (lambda: fit_logistic(np.zeros((2, 1)), [0, 1], l2=0), "l2= must be a finite number > 0"),
    (lambda: fit_logistic(np.zeros((2, 1)), [0, 1], max_iter=0), "max_iter= must be an integer"),
    (lambda: fit_logistic(np.zeros((2, 1)), [0, 1], weights=[1, -1]), "weights must be finite "
                                                                       "and >= 0, got -1.0"),
    (lambda: fit_logistic(np.zeros((2, 1)), [0, 1], weights=[1]), "weights must be one value"),
    (lambda: fit_logistic(np.zeros((2, 2)), [0, 1], names=["a"]), "1 evidence names for 2"),
    (lambda: fit_logistic(np.zeros((2, 2)), [0, 1]).predict(np.zeros((4, 3))),
     "evidence has 3 columns, the model 2 (x0, x1)"),
])
def test_invalid_logistic_input(call, message):
    with pytest.raises(MtannoError) as info:
        call()
    assert message in str(info.value), str(info.value)


# --- isotonic ---------------------------------------------------------------------------------

def test_isotonic_hand_worked():
    model = fit_isotonic([1, 2, 3, 4], [0, 1, 0, 1])
    assert model.x == (1.0, 2.5, 4.0) and model.y == (0.0, 0.5, 1.0)
    assert model.weight == (1.0, 2.0, 1.0)
    assert np.allclose(model.predict([0, 1, 1.75, 2.5, 3.25, 4, 9, np.inf, -np.inf]),
                       [0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 0])
    assert model.predict([np.nan])[0] == 0.5  # the overall rate
    ties = fit_isotonic([2, 1, 1, 3], [1, 1, 0, 0], weights=[1, 1, 1, 2])
    # tie at 1 → rate 1/2, then 1 at 2 and 0 at 3 (weight 2) pool to 1/3 < 1/2: all pool
    assert ties.y == (pytest.approx(2 / 5),) and ties.x == (pytest.approx(2.0),)
    flat = fit_isotonic([1, 2, 3, 4], [1, 0, 1, 0])  # decreasing: one block
    assert flat.y == (0.5,) and flat.x == (2.5,)


def test_pool_adjacent_violators_against_the_min_max_formula():
    rng = np.random.default_rng(5)
    for n in range(1, 25):
        rates = rng.integers(0, 4, n) / 3.0
        weights = rng.integers(1, 4, n).astype(float)
        s = np.arange(n, dtype=float)
        bs, by, bw = _pool(s, rates, weights)
        fit = naive_isotonic(rates.tolist(), weights.tolist())
        # the oracle's level sets (consecutive equal values) are the blocks
        levels = [(v, sum(weights[i] for i, _ in group))
                  for v, group in itertools.groupby(enumerate(fit),
                                                    key=lambda t: round(t[1], 9))]
        assert np.allclose(by / bw, [v for v, _ in levels]), n
        assert np.allclose(bw, [w for _, w in levels]), n
        assert np.all(np.diff(by / bw) > 0)


def test_isotonic_recovers_a_monotone_truth():
    rng = np.random.default_rng(6)
    s = rng.uniform(0, 1, 5000)
    p = 0.05 + 0.9 * s ** 2
    model = fit_isotonic(s, rng.random(5000) < p)
    err = np.abs(model.predict(s) - p)
    assert err.mean() < 0.03, err.mean()
    grid = np.linspace(0.05, 0.95, 19)
    assert np.abs(model.predict(grid) - (0.05 + 0.9 * grid ** 2)).max() < 0.08
    assert np.all(np.diff(model.x) > 0) and np.all(np.diff(model.y) > 0)


def test_isotonic_degenerate_and_round_trip():
    assert fit_isotonic([], []).fallback == "no examples"
    assert np.all(fit_isotonic([], []).predict([0.1, np.nan]) == 0.5)
    one = fit_isotonic([1.0, 3.0], [1, 1])
    assert one.fallback == "one class only (all right)" and one.x == (2.0,)
    assert one.y == (0.75,)
    rng = np.random.default_rng(7)
    for model in (fit_isotonic(rng.normal(size=50), rng.random(50) < 0.5), one,
                  fit_isotonic([], [])):
        d = model.to_dict()
        assert IsotonicModel.from_dict(json.loads(json.dumps(d))) == model
        if model.x:
            toml = "\n".join(f"{k} = {json.dumps(v)}" for k, v in d.items())
            assert IsotonicModel.from_dict(tomllib.loads(toml)) == model


@pytest.mark.parametrize("d, message", [
    ({"x": [1, 1], "y": [0, 1], "weight": [1, 1]}, "x must be strictly increasing"),
    ({"x": [1, 2], "y": [1, 0], "weight": [1, 1]}, "y must be non-decreasing within [0, 1]"),
    ({"x": [1, 2], "y": [0, 1.5], "weight": [1, 1]}, "y must be non-decreasing within [0, 1]"),
    ({"x": [1, 2], "y": [0, 1], "weight": [1, 0]}, "weight[1] must be a finite number > 0"),
    ({"x": [1, 2], "y": [0], "weight": [1, 1]}, "y has 1 values"),
    ({"x": [1, math.inf], "y": [0, 1], "weight": [1, 1]}, "x[1] must be a finite number"),
    ({"x": [1], "y": [0]}, "missing weight"),
    ("x", "isotonic model must be a table, got str"),
])
def test_isotonic_from_dict_refuses_bad_tables(d, message):
    with pytest.raises(MtannoError) as info:
        IsotonicModel.from_dict(d, path="c.toml")
    assert str(info.value).startswith("c.toml: isotonic model") and message in str(info.value)


@pytest.mark.parametrize("call, message", [
    (lambda: fit_isotonic([1.0, np.nan], [0, 1]), "scores must be finite, got nan at index 1"),
    (lambda: fit_isotonic([1.0, np.inf], [0, 1]), "scores must be finite"),
    (lambda: fit_isotonic([[1.0, 2.0]], [0, 1]), "one value per row (1-D)"),
    (lambda: fit_isotonic([1.0, 2.0], [0, 1, 1]), "labels must be one value per row (2)"),
    (lambda: fit_isotonic([1.0, 2.0], [0, -1]), "must be 0 or 1"),
])
def test_invalid_isotonic_input(call, message):
    with pytest.raises(MtannoError) as info:
        call()
    assert message in str(info.value), str(info.value)


# --- fit_calibrated ---------------------------------------------------------------------------

def test_platt_out_of_fold_probabilities_come_from_the_other_folds():
    rng = np.random.default_rng(8)
    X, _, y = draw(rng, 120)
    result = fit_calibrated(X, y, names=["a", "b"], folds=4, rng=3)
    assert result.seed == 3 and sorted(set(result.fold.tolist())) == [0, 1, 2, 3]
    for f in range(4):
        test = result.fold == f
        assert 0 < y[test].sum() < test.sum()  # stratified: both labels in every fold
        m = fit_logistic(X[~test], y[~test], names=["a", "b"])
        assert np.array_equal(result.oof[test], m.predict(X[test]))
    assert result.calibrator.logistic == fit_logistic(X, y, names=["a", "b"])
    assert result.calibrator.isotonic is None
    again = fit_calibrated(X, y, names=["a", "b"], folds=4, rng=3)
    assert np.array_equal(again.oof, result.oof)
    assert fit_calibrated(X, y, names=["a", "b"], rng=np.random.default_rng(0)).seed is None


def test_groups_stay_in_one_fold():
    rng = np.random.default_rng(9)
    X, _, y = draw(rng, 90)
    groups = np.repeat([f"doc{i}" for i in range(9)], 10)
    result = fit_calibrated(X, y, names=["a", "b"], folds=3, groups=groups)
    for g in set(groups):
        assert len(set(result.fold[groups == g].tolist())) == 1
    assert np.bincount(result.fold).tolist() == [30, 30, 30]


def test_platt_isotonic_fixes_a_misspecified_link():
    rng = np.random.default_rng(10)
    u = rng.uniform(-2, 2, 4000)
    p = sigmoid(4 * u ** 3)
    y = rng.random(4000) < p
    platt = fit_calibrated(u, y, names=["u"])
    both = fit_calibrated(u, y, names=["u"], method="platt+isotonic")
    assert np.abs(both.oof - p).mean() < 0.025 < 0.04 < np.abs(platt.oof - p).mean()
    c = both.calibrator
    inner = np.empty(len(y))
    for f in np.unique(both.fold):
        test = both.fold == f
        inner[test] = fit_logistic(u[~test], y[~test], names=["u"]).predict(u[test])
    assert c.isotonic == fit_isotonic(inner, y)
    assert np.array_equal(c.predict(u), c.isotonic.predict(c.logistic.predict(u)))
    iso = fit_calibrated(u, y, names=["u"], method="isotonic")
    assert np.abs(iso.oof - p).mean() < 0.03 and iso.calibrator.logistic is None


@pytest.mark.parametrize("method", CALIBRATION_METHODS)
def test_calibrator_round_trip_and_small_inputs(method):
    rng = np.random.default_rng(11)
    X, _, y = draw(rng, 60, a=(1.0,))
    c = fit_calibrated(X, y, names=["score"], method=method).calibrator
    assert Calibrator.from_dict(json.loads(json.dumps(c.to_dict())), path="c.toml") == c
    assert c.method == method and np.all((c.predict(X) >= 0) & (c.predict(X) <= 1))
    for n in (0, 1, 2, 3):
        r = fit_calibrated(X[:n], np.ones(n), names=["score"], method=method)
        assert r.oof.shape == (n,) and np.all((r.oof > 0) & (r.oof < 1))
        assert np.all(np.isfinite(r.calibrator.predict(X[:5])))


@pytest.mark.parametrize("change, message", [
    ({"method": "beta"}, "unknown method 'beta' (methods: platt, isotonic, platt+isotonic)"),
    ({"isotonic": {"x": [0.5], "y": [0.5], "weight": [1.0]}}, "method 'platt' has no a isotonic"),
    ({"logistic": None}, "method 'platt' needs a logistic table"),
    ({"names": ["b"]}, "the logistic model's names ['a'] are not the calibration's ['b']"),
    ({"names": "a"}, "calibration: names must be a list of strings"),
    ({"extra": 1}, "unknown extra"),
])
def test_calibrator_from_dict_refuses_bad_tables(change, message):
    d = {"method": "platt", "names": ["a"],
         "logistic": {"names": ["a"], "mean": [0.0], "scale": [1.0], "coef": [1.0],
                      "intercept": 0.0}}
    d = {k: v for k, v in {**d, **change}.items() if v is not None}
    with pytest.raises(MtannoError) as info:
        Calibrator.from_dict(d, path="c.toml")
    assert str(info.value).startswith("c.toml: ") and message in str(info.value), str(info.value)


def test_isotonic_calibrator_takes_one_name():
    d = {"method": "isotonic", "names": ["a", "b"],
         "isotonic": {"x": [0.5], "y": [0.5], "weight": [1.0]}}
    with pytest.raises(MtannoError, match="method 'isotonic' takes one evidence name, got 2"):
        Calibrator.from_dict(d)
    c = Calibrator.from_dict({**d, "names": ["a"]})
    with pytest.raises(MtannoError, match="evidence has 2 columns, the model 1"):
        c.predict(np.zeros((3, 2)))


@pytest.mark.parametrize("kwargs, message", [
    ({"method": "beta"}, "unknown calibration method= 'beta'"),
    ({"folds": 1}, "folds= must be an integer >= 2, got 1"),
    ({"folds": 2.0}, "folds= must be an integer >= 2"),
    ({"method": "isotonic"}, "calibration 'isotonic' takes one evidence column, got 2"),
    ({"groups": [1, 2]}, "groups must be one value per row (4)"),
    ({"names": ["a"]}, "1 evidence names for 2 evidence columns"),
    ({"rng": 1.5}, "rng= must be a numpy Generator or a seed (an integer >= 0), got 1.5"),
    ({"rng": -1}, "rng= must be a numpy Generator or a seed"),
    ({"l2": -1.0}, "l2= must be a finite number > 0"),
])
def test_invalid_fit_calibrated_input(kwargs, message):
    X = np.zeros((4, 2))
    with pytest.raises(MtannoError) as info:
        fit_calibrated(X, [0, 1, 0, 1], **{"names": ["a", "b"], **kwargs})
    assert message in str(info.value), str(info.value)


def test_fit_calibrated_names_bad_evidence_by_the_callers_index():
    X = np.zeros((6, 2))
    X[4, 1] = np.inf
    with pytest.raises(MtannoError, match="evidence b is inf at index 4: cap it"):
        fit_calibrated(X, [0, 1] * 3, names=["a", "b"])
    with pytest.raises(MtannoError, match="evidence s is nan at index 2: isotonic calibration "
                                          "needs finite scores"):
        fit_calibrated([0.0, 1, np.nan, 2], [0, 1, 0, 1], names=["s"], method="isotonic")
    X[4, 1] = np.nan  # missing evidence is the column's mean for the logistic model
    assert np.all(np.isfinite(fit_calibrated(X, [0, 1] * 3, names=["a", "b"]).oof))


def test_uncalibrated_confidence():
    r = np.array([-0.5, 0.0, 0.25, 1.0, 3.0, np.inf])
    assert uncalibrated_confidence(r).tolist() == [1.0, 1.0, 0.75, 0.0, 0.0, 0.0]
    grid = np.linspace(0, 1, 11)
    assert np.all(np.diff(uncalibrated_confidence(grid)) < 0)
    with pytest.raises(MtannoError, match=r"cost ratio is NaN at index \(1,\)"):
        uncalibrated_confidence([0.1, np.nan])


# --- measures ---------------------------------------------------------------------------------

def test_auroc_hand_worked():
    assert auroc([0.1, 0.4, 0.35, 0.8], [0, 0, 1, 1]) == 0.75
    assert auroc([1, 2, 3], [0, 1, 1]) == 1.0 and auroc([1, 2, 3], [1, 0, 0]) == 0.0
    assert auroc([5, 5, 5, 5], [0, 1, 0, 1]) == 0.5
    assert auroc([1, 2, 2, 3], [0, 0, 1, 1]) == 0.875  # the tie at 2 counts half
    assert auroc([-np.inf, np.inf], [False, True]) == 1.0
    assert math.isnan(auroc([1, 2], [1, 1])) and math.isnan(auroc([], []))


def test_auroc_and_ece_against_slow_references_with_ties():
    rng = np.random.default_rng(12)
    for trial in range(60):
        n = int(rng.integers(1, 40))
        score = rng.integers(0, 6, n) / 5.0  # ties, and probabilities on bin edges
        if trial % 3 == 0:
            score = rng.random(n)
        right = rng.random(n) < 0.4
        assert auroc(score, right) == pytest.approx(naive_auroc(score, right), nan_ok=True)
        for bins in (1, 3, 10):
            assert expected_calibration_error(score, right, bins=bins) == \
                pytest.approx(naive_ece(score.tolist(), right.tolist(), bins))
            got = reliability_table(score, right, bins=bins).rows()
            want = naive_table(score.tolist(), right.tolist(), bins)
            assert np.allclose(np.array(got, float), np.array(want, float), equal_nan=True)


def test_reliability_table_hand_worked():
    t = reliability_table([0.0, 0.3, 0.35, 0.95, 1.0], [0, 1, 0, 1, 1], bins=10)
    assert t.count.tolist() == [1, 0, 0, 2, 0, 0, 0, 0, 0, 2] and t.n == 5
    assert t.rows()[3] == (0.3, 0.4, 2, pytest.approx(0.325), 0.5)
    assert t.rows()[9][2:] == (2, pytest.approx(0.975), 1.0)  # the last bin holds 1.0
    assert math.isnan(t.rows()[1][3]) and math.isnan(t.rows()[1][4])
    assert t.ece == pytest.approx((0 + 2 * 0.175 + 2 * 0.025) / 5)
    assert expected_calibration_error([0.05, 0.95], [0, 1]) == pytest.approx(0.05)
    assert expected_calibration_error([0.2, 0.6], [1, 1], bins=1) == pytest.approx(0.6)
    assert math.isnan(expected_calibration_error([], []))


@pytest.mark.parametrize("call, message", [
    (lambda: auroc([0.1, 0.2], [1]), "2 scores for 1 right/wrong labels"),
    (lambda: auroc([0.1, np.nan], [1, 0]), "scores must not be NaN (index 1)"),
    (lambda: auroc([0.1, 0.2], [1, 2]), "right must be 0 or 1 (wrong or right), got 2 at index 1"),
    (lambda: auroc([[0.1, 0.2]], [[1, 0]]), "one value per segment (1-D)"),
    (lambda: auroc(["a"], [1]), "scores must be numbers"),
    (lambda: expected_calibration_error([0.1, np.nan], [1, 0]), "probabilities must not be NaN"),
    (lambda: expected_calibration_error([0.1, 1.2], [1, 0]), "must be in [0, 1], got 1.2"),
    (lambda: expected_calibration_error([0.1], [0.5]), "right must be 0 or 1"),
    (lambda: expected_calibration_error([0.1], [1, 0]), "1 probabilities for 2"),
    (lambda: expected_calibration_error([0.1], [1], bins=0), "bins= must be an integer >= 1"),
    (lambda: reliability_table([0.1], [1], bins=2.5), "bins= must be an integer >= 1"),
    (lambda: reliability_table([0.1], [1], bins=True), "bins= must be an integer >= 1"),
])
def test_invalid_measure_input(call, message):
    with pytest.raises(MtannoError) as info:
        call()
    assert message in str(info.value), str(info.value)


def test_measures_are_attached_to_the_evaluation_package():
    import mtanno.evaluation as evaluation

    assert evaluation.auroc is auroc and evaluation.reliability_table is reliability_table
    assert evaluation.expected_calibration_error is expected_calibration_error
    assert "ReliabilityTable" in dir(evaluation)


def test_reliability_figure(tmp_path):
    matplotlib = pytest.importorskip("matplotlib", reason="the 'plot' extra is not installed")
    matplotlib.use("Agg")
    from mtanno.plot import plot_reliability, reliability_figure, save_figure

    t = reliability_table([0.05, 0.1, 0.5, 0.55, 0.9], [0, 0, 1, 0, 1], bins=4)
    figure = reliability_figure(t, title="held-out segments")
    top, bottom = figure.axes
    diagonal, curve = top.lines
    assert diagonal.get_xydata().tolist() == [[0, 0], [1, 1]]
    assert np.allclose(curve.get_xdata(), [0.075, 0.525, 0.9])
    assert np.allclose(curve.get_ydata(), [0.0, 0.5, 1.0])
    assert [b.get_height() for b in bottom.patches] == [2, 0, 2, 1]
    assert [b.get_x() for b in bottom.patches] == [0, 0.25, 0.5, 0.75]
    assert figure._suptitle.get_text() == "held-out segments"
    assert "ECE = " in top.get_legend().get_texts()[1].get_text()
    ax = plot_reliability(t)
    assert len(ax.lines) == 2
    save_figure(figure, tmp_path / "reliability.png")
    assert (tmp_path / "reliability.png").read_bytes()[:4] == b"\x89PNG"
