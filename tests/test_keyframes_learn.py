"""Keyframe learning (docs/method.md §6): fitness on training sequences, the genetic
algorithm's properties on tiny problems (a brute-force optimum, reproducibility, elitism),
jittered copies, the hard and heuristic methods, and learn-keyframes through the CLI."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
from world import cli

from mtanno.errors import MtannoError
from mtanno.keyframes import load_keyframes
from mtanno.keyframes.fitness import TrainingSet, f_beta, jitter_edges, keyframe_tolerance
from mtanno.keyframes.ga import GAParams, Problem, run_ga
from mtanno.keyframes.learn import (
    keyframe_training_set,
    learn_keyframes,
    run_seeds,
    validation_folds,
)
from mtanno.templates.model import MotionTemplate
from mtanno.templates.store import load_template_folder

NAMES = ["a", "b", "c", "d"]
GROUPS = {"g": ("a", "b"), "h": ("c", "d")}


def tiny_training(seed: int = 0):
    """Class P: feature a on for a while, then b on; class N: a and b never together in
    that order; a few clips each, random noise on c, d."""
    rng = np.random.default_rng(seed)
    mats, labels = [], []
    for k in range(8):
        L = int(rng.integers(12, 20))
        X = np.zeros((4, L), np.uint8)
        X[2:] = rng.random((2, L)) < 0.3
        if k < 4:  # positives: a on at 2..5, b on at 7..9
            X[0, 2:6] = 1
            X[1, 7:10] = 1
            labels.append("P")
        else:  # negatives: b before a, or a alone
            X[1, 1:4] = 1
            if k % 2:
                X[0, 8:11] = 1
            labels.append("N")
        mats.append(X)
    return mats, labels


def tiny_problem(mats, labels, **kw):
    ts = TrainingSet(mats, labels, NAMES, GROUPS, **kw)
    K = 12
    soft = np.zeros((4, K))
    soft[0, 2:6] = 1
    soft[1, 7:10] = 1
    soft[2:] = 0.3
    strict = np.where(soft == 1, 1.0, np.where(soft == 0, 0.0, 0.5))
    rows = [np.array([0, 1]), np.array([2, 3])]
    return ts, Problem(strict, soft, rows, ts, ts.positives("P"))


def test_f_beta_and_tolerance():
    assert f_beta(1.0, 1.0, 2) == 1.0
    assert f_beta(0.0, 0.0, 2) == 0.0
    assert f_beta(0.5, 1.0, 2) == pytest.approx(5 * 0.5 / (4 * 0.5 + 1))
    assert keyframe_tolerance(0b1111, 1) == 1 and keyframe_tolerance(0b111, 1) == 0
    assert keyframe_tolerance(0b111111, 2) == 2 and keyframe_tolerance(0b11111, 2) == 0


def test_training_sequences_map_frames_to_clips():
    mats, labels = tiny_training()
    ts = TrainingSet(mats, labels, NAMES, GROUPS, seed=3)
    assert ts.n_clips == 8 and ts.doc_offset[-1] == sum(X.shape[1] for X in mats)
    for c in range(ts.n_clips):  # every clip's frames are where clip_of_frame says
        a = ts.clip_start[c]
        assert (ts.clip_of_frame[a:a + ts.lengths[c]] == c).all()
    # a query "a on, then b on 3..6 frames later" finds exactly the positives
    score = ts.score([(3, 0, 0b01, 0b01), (8, 0, 0b10, 0b10)], [(3, 6)], ts.positives("P"), 2)
    assert (score.P, score.R, score.found, score.positives) == (1.0, 1.0, 4, 4)
    # "b on" alone also fires on the negatives
    score = ts.score([(8, 0, 0b10, 0b10)], [], ts.positives("P"), 2)
    assert score.R == 1.0 and score.P == 0.5


def test_jitter_moves_edges_by_at_most_one_frame():
    rng = np.random.default_rng(1)
    X = (np.cumsum(rng.random((6, 80)) < 0.15, axis=1) % 2).astype(np.uint8)
    Y = jitter_edges(X, rng=np.random.default_rng(2))
    assert Y.shape == X.shape and (Y != X).any()
    for i in range(6):  # each changed frame is next to an edge of X
        edges = set(np.flatnonzero(X[i, 1:] != X[i, :-1]) + 1)
        for t in np.flatnonzero(Y[i] != X[i]):
            assert t in edges or t + 1 in edges
    assert np.array_equal(Y, jitter_edges(X, rng=np.random.default_rng(2)))
    mats, labels = tiny_training()
    ts = TrainingSet(mats, labels, NAMES, GROUPS, jitter=2)
    assert ts.n_clips == 24 and ts.n_original == 8
    assert list(ts.labels[8:16]) == list(ts.labels[:8])


def _brute_force_best(ts, problem, beta=2.0):
    """Best F over every query of one or two keyframes whose vectors are sub-patterns of
    the strict template's columns and whose gaps are any (dmin, dmax) in 0..12."""
    best = 0.0
    singles = []
    for q in range(1, problem.K + 1):
        for g, rows in enumerate(problem.group_rows):
            fixed = [k for k in range(len(rows)) if problem.strict[rows[k], q - 1] != 0.5]
            for n in range(1, len(fixed) + 1):
                for sub in combinations(fixed, n):
                    mask = sum(1 << k for k in sub)
                    value = sum(int(problem.strict[rows[k], q - 1] == 1) << k for k in sub)
                    singles.append((q, g, mask, value))
    for gene in singles:
        best = max(best, ts.score([gene], [], problem.positives, beta).F)
    for a in singles:
        for b in singles:
            if (b[0], b[1]) <= (a[0], a[1]):
                continue
            for lo in range(0, 7):
                for hi in (lo, lo + 3, lo + 6):
                    best = max(best, ts.score([a, b], [(lo, hi)], problem.positives, beta).F)
    return best


def test_ga_reaches_the_brute_force_optimum():
    mats, labels = tiny_training()
    ts, problem = tiny_problem(mats, labels)
    want = _brute_force_best(ts, problem)
    assert want == 1.0  # "a, then b" separates the classes
    params = GAParams(population=12, generations=30, max_keyframes=3)
    best = max(run_ga(problem, rng=s, params=params).score.F for s in range(3))
    assert best == pytest.approx(want)


def test_ga_is_reproducible_and_elitist():
    mats, labels = tiny_training(1)
    ts, problem = tiny_problem(mats, labels)
    params = GAParams(population=10, generations=25)
    a = run_ga(problem, rng=7, params=params)
    b = run_ga(problem, rng=np.random.default_rng(7), params=params)
    assert (a.genes, a.gaps, a.score) == (b.genes, b.gaps, b.score)
    best = a.history["best"]
    assert len(best) == 26 and all(y >= x for x, y in zip(best, best[1:]))
    assert all(0 <= m <= 1 for m in a.history["mean"])


def test_run_seeds_depend_on_class_and_run():
    s = run_seeds("kick", 3, 4)
    assert len({tuple(x.generate_state(2)) for x in s}) == 4
    assert [x.entropy for x in run_seeds("kick", 3, 2)] == [x.entropy for x in s[:2]]
    assert s[0].generate_state(2).tolist() != run_seeds("squat", 3, 1)[0].generate_state(2).tolist()


def test_ga_parameters_are_checked():
    for bad in (dict(population=0), dict(parents=1), dict(stiffness=(0.9, 0.5)),
                dict(beta=0.0), dict(mismatches=3), dict(specialize_delta=0.5)):
        with pytest.raises(MtannoError):
            GAParams(**bad)


def test_validation_folds_by_performer_and_by_clip():
    mats, labels = tiny_training()
    ts = TrainingSet(mats, labels, NAMES, GROUPS, performers=["x", "y"] * 4)
    fold, usable, how = validation_folds(ts, ts.positives("P"))
    assert "performers (2)" in how and usable == [0, 1]
    assert list(fold) == [0, 1] * 4
    ts = TrainingSet(mats, labels, NAMES, GROUPS, jitter=1)
    fold, usable, how = validation_folds(ts, ts.positives("P"))
    assert "clips" in how and (fold[8:] == fold[:8]).all()  # copies go with originals


def _world_training(world):
    from mtanno.templates import group_by_class, load_examples, sources_from_manifest

    srcs = sources_from_manifest(world.manifest, features_dir=world.feats, split="train")
    groups = group_by_class(srcs)
    examples = [e for c in groups for e in load_examples(groups[c])]
    return examples, keyframe_training_set(examples)


@pytest.mark.parametrize("method", ["ga", "hard", "heuristic"])
def test_methods_on_synthetic_classes(world, method):
    examples, ts = _world_training(world)
    mts = load_template_folder(world.mt)
    for cls in ("squat", "kickLFront"):
        q = learn_keyframes(ts, cls, mts[cls], method=method, runs=4, seed=1,
                            params=GAParams(generations=20),
                            examples=[e for e in examples if e.class_name == cls])
        fit = q.provenance["fitness"]
        assert q.class_name == cls and q.feature_set == mts[cls].feature_set
        assert 1 <= q.n and all(1 <= k.position <= q.template_length for k in q.keyframes)
        if method == "hard":  # hard-template columns occur in every training clip
            assert fit["R"] == 1.0
        if method == "ga":
            assert fit["F"] >= 0.8
            assert q.provenance["validation"]["usable_folds"] >= 1


def test_learn_keyframes_refuses_bad_requests(world):
    examples, ts = _world_training(world)
    mt = load_template_folder(world.mt)["squat"]
    with pytest.raises(MtannoError, match="unknown keyframe method"):
        learn_keyframes(ts, "squat", mt, method="nope")
    with pytest.raises(MtannoError, match="runs must be"):
        learn_keyframes(ts, "squat", mt, runs=0)
    with pytest.raises(MtannoError, match="no training clips"):
        learn_keyframes(ts, "nope", mt)
    only = keyframe_training_set([e for e in examples if e.class_name == "squat"])
    with pytest.raises(MtannoError, match="at least two classes"):
        learn_keyframes(only, "squat", mt, runs=2)
    fake = MotionTemplate("squat", [f"x{i}" for i in range(mt.n_features)], mt.values,
                          mt.weights)
    with pytest.raises(MtannoError, match="other features"):
        learn_keyframes(ts, "squat", fake, runs=2)


# --------------------------------------------------------------------------- CLI

def _learn(world, out, *extra):
    return cli("learn-keyframes", "--mt", world.mt, "--manifest", world.manifest,
               "--features-dir", world.feats, "--split", "train", "-o", out, "--runs", "4",
               "--generations", "15", "-q", *extra)


def test_cli_same_seed_same_bytes_whatever_jobs(world, tmp_path):
    r1 = _learn(world, tmp_path / "j1", "--jobs", "1", "--seed", "5")
    r2 = _learn(world, tmp_path / "j2", "--jobs", "2", "--seed", "5")
    assert r1.exit_code == 0, r1.output
    assert r2.exit_code == 0, r2.output
    files = sorted(p.name for p in (tmp_path / "j1").glob("*.json"))
    assert files and files == sorted(p.name for p in (tmp_path / "j2").glob("*.json"))
    for f in files:
        assert (tmp_path / "j1" / f).read_bytes() == (tmp_path / "j2" / f).read_bytes()
    r3 = _learn(world, tmp_path / "j3", "--seed", "6", "--class", "squat")
    assert r3.exit_code == 0 and [p.name for p in (tmp_path / "j3").glob("*.json")] == \
        ["squat.json"]
    q = load_keyframes(tmp_path / "j1" / "squat.json")
    assert q.provenance["seed"] == 5 and q.provenance["runs"] == 4
    assert all("sha256" in t for t in q.provenance["training"])
    r = cli("keyframes", "show", tmp_path / "j1")
    assert r.exit_code == 0 and "class          squat" in r.output


@pytest.mark.parametrize("method", ["hard", "heuristic"])
def test_cli_column_methods(world, tmp_path, method):
    r = _learn(world, tmp_path / "kf", "--method", method, "--columns", "2")
    assert r.exit_code == 0, r.output
    q = load_keyframes(tmp_path / "kf" / "walk2Steps.json")
    assert q.provenance["method"].startswith(method)


def test_cli_bad_requests(world, tmp_path):
    r = _learn(world, tmp_path / "x", "--class", "nosuchclass")
    assert r.exit_code == 2 and "no training examples for class(es) nosuchclass" in r.output
    assert not (tmp_path / "x").exists()
    one = tmp_path / "one.csv"
    lines = world.manifest.read_text().splitlines()
    one.write_text("\n".join([lines[0]] + [ln for ln in lines[1:] if ",squat," in ln]) + "\n")
    r = cli("learn-keyframes", "--mt", world.mt, "--manifest", one, "--features-dir",
            world.feats, "-o", tmp_path / "y", "--runs", "2", "-q")
    assert r.exit_code == 2 and "at least two classes" in r.output
    assert not (tmp_path / "y").exists()
