"""Segment verification (issue 26, part 3): the subsequence DTW kernel against a slow
reference (also with the JIT off), sequences, banks and their files."""

from __future__ import annotations

import numpy as np
import pytest
from naive_verify import subsequence_costs as naive_costs
from nojit import run_without_jit

from mtanno.confidence.verify import (
    MAX_QUERY,
    POSE_JOINTS,
    VERIFY_STEP,
    build_bank,
    read_bank,
    sequence,
    subsequence_costs,
    write_bank,
)
from mtanno.errors import MtannoError


def check_against_naive(seed: int, binary: bool) -> None:
    rng = np.random.default_rng(seed)
    dims = 6
    for _ in range(5):
        n = int(rng.integers(1, 7))
        lens = rng.integers(0, 9, size=int(rng.integers(1, 4)))
        B = rng.random((int(lens.sum()), dims)).astype(np.float32)
        if binary:
            B = (B > 0.5).astype(np.float32)
        Q = rng.random((n, dims)).astype(np.float32)
        off = np.concatenate([[0], np.cumsum(lens)])
        got = subsequence_costs(Q, B, off)
        want = naive_costs(Q, B, off)
        assert np.allclose(got, want, rtol=1e-5, atol=1e-6, equal_nan=False), (got, want)


@pytest.mark.parametrize("binary", [True, False])
def test_kernel_matches_naive(binary):
    for seed in range(6):
        check_against_naive(seed, binary)


def test_kernel_without_jit():
    run_without_jit("test_verify", "check_against_naive", (0, False), (1, True))


def test_own_subsequence_costs_zero_and_order():
    rng = np.random.default_rng(3)
    B = rng.random((30, 6)).astype(np.float32)
    off = np.array([0, 12, 30])
    got = subsequence_costs(B[15:22], B, off)
    assert got[1] == pytest.approx(0.0, abs=1e-6)  # the query lies inside item 1
    assert got[0] > 0.01


def test_subsequence_costs_refuse_bad_input():
    Q = np.zeros((3, 6), np.float32)
    B = np.zeros((5, 6), np.float32)
    for kwargs, msg in [({"query": np.zeros((0, 6))}, "no rows"),
                        ({"items": np.zeros((5, 4))}, "same dims"),
                        ({"offsets": np.array([0, 3])}, "offsets"),
                        ({"offsets": np.array([0, 4, 2, 5])}, "offsets"),
                        ({"query": np.zeros((3, 0)), "items": np.zeros((5, 0))}, "no dims"),
                        ({"query": np.full((3, 6), np.nan)}, "finite")]:
        args = {"query": Q, "items": B, "offsets": np.array([0, 5]), **kwargs}
        with pytest.raises(MtannoError, match=msg):
            subsequence_costs(args["query"], args["items"], args["offsets"])


def test_sequence_rates_and_joints():
    X = (np.arange(40 * 10).reshape(40, 10) % 2).astype(np.uint8)
    s = sequence(X=X, representation="features")
    assert s.shape == (len(range(0, 10, VERIFY_STEP)), 40) and s.dtype == np.float32
    P = np.random.default_rng(0).random((10, 22, 3)).astype(np.float32)
    s = sequence(poses=P, representation="poses")
    assert s.shape == (len(range(0, 10, VERIFY_STEP)), 3 * len(POSE_JOINTS))
    assert np.array_equal(s[1, :3], P[VERIFY_STEP, 0])  # root first
    with pytest.raises(MtannoError, match="needs poses"):
        sequence(X=X, representation="poses")
    with pytest.raises(MtannoError, match="unknown representation"):
        sequence(X=X, representation="angles")


def _bank():
    rng = np.random.default_rng(1)
    base = {c: rng.random((12, 6)).astype(np.float32) for c in "ab"}
    ex = [(c, p, base[c] + 0.05 * rng.random((12, 6)).astype(np.float32))
          for c in "ab" for p in ("p1", "p2", "p3")]
    bg = [rng.random((20, 6)).astype(np.float32) + 2.0]
    return build_bank(ex, bg, representation="features"), base


def test_bank_nearest_and_scale():
    bank, base = _bank()
    assert bank.classes == ["a", "b"] and bank.has_background
    near = bank.nearest(base["a"][2:9])
    assert near["a"] < near["b"] < near[""]
    assert all(v > 0 for v in bank.scale.values())
    # a long query is sampled to MAX_QUERY rows
    long = np.repeat(base["a"], 10, axis=0)
    assert long.shape[0] > MAX_QUERY and np.isfinite(bank.nearest(long)["a"])


def test_bank_file_round_trip(tmp_path):
    bank, _ = _bank()
    write_bank(tmp_path / "b.parquet", bank)
    back = read_bank(tmp_path / "b.parquet")
    assert back.labels == bank.labels and back.performers == bank.performers
    assert np.array_equal(back.items, bank.items) and np.array_equal(back.offsets, bank.offsets)
    assert back.scale == pytest.approx(bank.scale)
    (tmp_path / "x.parquet").write_bytes(b"PAR1 not really")
    with pytest.raises(MtannoError, match="verification bank"):
        read_bank(tmp_path / "x.parquet")
    with pytest.raises(MtannoError, match="not found"):
        read_bank(tmp_path / "missing.parquet")
