"""The alignment kernels run as plain Python (NUMBA_DISABLE_JIT=1) and give the oracles'
answers (tests/naive_align.py through test_align.check_against_oracle)."""

from __future__ import annotations

from nojit import run_without_jit


def test_align_kernels_without_jit():
    run_without_jit("test_align", "check_against_oracle", *[(seed,) for seed in range(6)])
