"""The frame classifier as evidence (issue 35, part 3): window packing and k-NN votes
against the slow reference (also with the JIT off), the agreement of hand-made segments,
the frame bank file, and the evidence kind."""

from __future__ import annotations

import numpy as np
import pytest
from naive_frames import neighbours, unpack, vote, window
from nojit import run_without_jit

from mtanno.confidence.frames import (
    BACKGROUND_LABEL,
    FRAME_HALF,
    FRAME_K,
    FRAME_SAMPLES,
    FRAME_STEP,
    build_frame_bank,
    pack_windows,
    read_frame_bank,
    sample_frames,
    write_frame_bank,
)
from mtanno.errors import MtannoError


def check_against_naive(seed: int) -> None:
    from mtanno.confidence._frame_kernels import _neighbours, _vote

    rng = np.random.default_rng(seed)
    X = (rng.random((5, 40)) < 0.4).astype(np.uint8)
    frames = np.array([0, 3, 17, 39], np.int64)
    packed = pack_windows(X, frames)
    bits = 5 * (2 * FRAME_HALF + 1)
    for q, t in enumerate(frames):
        assert np.array_equal(unpack(packed[q], bits), window(X, int(t), FRAME_HALF))
    T = (rng.random((5, 60)) < 0.4).astype(np.uint8)
    train = pack_windows(T)
    labels = rng.integers(0, 3, size=60)
    dense = np.array([window(T, t, FRAME_HALF) for t in range(60)])
    for allowed in (np.array([True, True, True]), np.array([True, False, True]),
                    np.array([False, False, False])):
        out = np.empty(len(frames), np.int64)
        _vote(packed, train, labels.astype(np.int64), allowed, FRAME_K, 3, out)
        want = [vote(window(X, int(t), FRAME_HALF), dense, labels.tolist(), allowed, FRAME_K)
                for t in frames]
        assert out.tolist() == want
        near = np.empty((len(frames), FRAME_K), np.int64)
        _neighbours(packed, train, labels.astype(np.int64), allowed, FRAME_K, near)
        assert near.tolist() == [neighbours(window(X, int(t), FRAME_HALF), dense,
                                            labels.tolist(), allowed, FRAME_K) for t in frames]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kernels_match_naive(seed):
    check_against_naive(seed)


def test_kernels_without_jit():
    run_without_jit("test_frames", "check_against_naive", (3,))


def _motion(kind: str, n: int, rng) -> np.ndarray:
    """Hand-made features: 'walk' toggles features 0-3 every 5 frames, 'wave' holds 4-7 on
    with 8 blinking; noise flips 2 % of the bits."""
    X = np.zeros((12, n), np.uint8)
    t = np.arange(n)
    if kind == "walk":
        X[0:2, (t // 5) % 2 == 0] = 1
        X[2:4, (t // 5) % 2 == 1] = 1
    elif kind == "wave":
        X[4:8] = 1
        X[8, t % 3 == 0] = 1
    else:  # background: features 9-11 drift
        X[9:12, (t // 7) % 3 == 0] = 1
    flip = rng.random(X.shape) < 0.02
    return np.where(flip, 1 - X, X).astype(np.uint8)


def test_agreement_of_hand_made_segments():
    rng = np.random.default_rng(4)
    bank = build_frame_bank([("walk", _motion("walk", 60, rng)),
                             ("wave", _motion("wave", 60, rng))],
                            [_motion("bg", 80, rng)])
    assert bank.names == [BACKGROUND_LABEL, "walk", "wave"]
    assert bank.windows.shape[0] == 30 + 30 + 40  # every FRAME_STEP-th frame
    assert FRAME_STEP == 2
    doc = np.concatenate([_motion("walk", 50, rng), _motion("wave", 50, rng),
                          _motion("bg", 50, rng)], axis=1)
    assert bank.agreement(doc, 5, 40, {"walk"}) == 1.0
    assert bank.agreement(doc, 55, 95, {"wave"}) == 1.0
    assert bank.agreement(doc, 55, 95, {"walk"}) == 0.0  # a wave labelled walk
    assert bank.agreement(doc, 105, 145, {"walk"}) == 0.0  # background labelled walk
    half = bank.agreement(doc, 25, 74, {"walk"})  # half walk, half wave: a soft vote
    assert 0.3 <= half <= 0.7
    assert set(bank.votes(doc, np.arange(105, 145, 8))) == {BACKGROUND_LABEL}
    # a class the classifier must not know votes for the next nearest
    assert "wave" not in bank.votes(doc, np.arange(55, 95, 8), exclude={"wave"})
    assert bank.votes(doc, np.array([60]), exclude={"", "walk", "wave"}) == [None]
    with pytest.raises(MtannoError, match="features per frame"):
        bank.votes(doc[:5], np.array([3]))


def test_sample_frames_spread_and_short_segments():
    assert sample_frames(10, 12).tolist() == [10, 11, 12]
    assert FRAME_SAMPLES > 3
    s = sample_frames(0, 99)
    assert s[0] == 0 and s[-1] == 99 and len(s) == FRAME_SAMPLES and np.all(np.diff(s) > 0)
    with pytest.raises(MtannoError, match="before it starts"):
        sample_frames(5, 4)


def test_frame_bank_file_round_trip(tmp_path):
    rng = np.random.default_rng(5)
    bank = build_frame_bank([("walk", _motion("walk", 30, rng))], [_motion("bg", 20, rng)])
    write_frame_bank(tmp_path / "f.parquet", bank)
    back = read_frame_bank(tmp_path / "f.parquet")
    assert np.array_equal(back.windows, bank.windows)
    assert np.array_equal(back.labels, bank.labels) and back.names == bank.names
    assert back.n_features == bank.n_features
    (tmp_path / "x.parquet").write_bytes(b"PAR1 not really")
    with pytest.raises(MtannoError, match="frame bank"):
        read_frame_bank(tmp_path / "x.parquet")
    with pytest.raises(MtannoError, match="not found"):
        read_frame_bank(tmp_path / "missing.parquet")
    with pytest.raises(MtannoError, match="no training frames"):
        build_frame_bank([])
    with pytest.raises(MtannoError, match="different numbers of features"):
        build_frame_bank([("a", np.zeros((3, 4))), ("b", np.zeros((4, 4)))])


def test_classifier_evidence_is_the_agreement():
    from mtanno.confidence.evidence import (
        DEFAULT_EVIDENCE,
        FRAME_EVIDENCE,
        label_facts,
        segment_evidence,
    )
    from mtanno.labels.segments import Annotation

    assert FRAME_EVIDENCE == ("classifier",) and "classifier" not in DEFAULT_EVIDENCE
    rng = np.random.default_rng(6)
    bank = build_frame_bank([("walk", _motion("walk", 60, rng)),
                             ("wave", _motion("wave", 60, rng))])
    doc = np.concatenate([_motion("walk", 40, rng), _motion("wave", 40, rng)], axis=1)
    facts = label_facts({"walk": 30, "wave": 30}, tau_for=lambda c: 0.1)
    rows = [Annotation("d", 2, 37, "walk", 0.05), Annotation("d", 42, 77, "walk", 0.05),
            Annotation("d", 42, 77, "wave", 0.05)]
    E = segment_evidence(rows, facts, names=("cost", "classifier"), frame_bank=bank, X=doc)
    assert E[:, 1].tolist() == [1.0, 0.0, 1.0]
    with pytest.raises(MtannoError, match="frame classifier"):
        segment_evidence(rows, facts, names=("classifier",))
