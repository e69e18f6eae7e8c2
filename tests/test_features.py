"""Feature kernels against slow reference versions, and the feature table's bookkeeping."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive import hysteresis_naive, reduce_naive, velocity_naive
from naive_features import features_numpy, velocity

from mtanno import synthetic
from mtanno.errors import MtannoError
from mtanno.features import (
    FEATURE_NAMES,
    FEATURES,
    GROUPS,
    MIRROR_PAIRS,
    analysis_frames,
    compute_features_native,
    feature_index,
    mirror_permutation,
)
from mtanno.features.hysteresis import _hysteresis_kernel, hysteresis
from mtanno.features.measures import window_samples
from mtanno.io import canonical_positions, read_motion

bits = st.lists(st.booleans(), min_size=0, max_size=60)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_hysteresis_matches_naive(data):
    on = data.draw(bits)
    off = data.draw(st.lists(st.booleans(), min_size=len(on), max_size=len(on)))
    got = hysteresis(np.array(on, bool), np.array(off, bool))
    assert np.array_equal(got, hysteresis_naive(on, off))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.booleans()), min_size=1, max_size=40))
def test_hysteresis_nested_is_ordinary_hysteresis(pairs):
    # strict test implies lenient test: on while off → switch on; while on → stay while off-test
    on = [a for a, _ in pairs]
    off = [a or b for a, b in pairs]
    s, want = 0, []
    for a, b in zip(on, off):
        s = int(a) if s == 0 else int(b)
        want.append(s)
    assert hysteresis(np.array(on), np.array(off)).tolist() == want


def test_hysteresis_kernel_pure_python():
    # the numba kernel's Python body gives the same answer (JIT disabled)
    rng = np.random.default_rng(1)
    on = rng.random((3, 50)) < 0.3
    off = on | (rng.random((3, 50)) < 0.4)
    out = np.empty_like(on)
    _hysteresis_kernel.py_func(on, off, out)
    assert np.array_equal(out.view(np.uint8), hysteresis(on, off))


def test_hysteresis_edge_cases():
    assert hysteresis(np.array([1, 1, 0]), np.array([1, 1, 0])).tolist() == [1, 1, 0]
    # rise and fall in the same frame leave it off
    assert hysteresis(np.array([0, 1]), np.array([1, 0])).tolist() == [0, 0]
    with pytest.raises(ValueError):
        hysteresis(np.zeros(3, bool), np.zeros(4, bool))


@pytest.mark.parametrize("fps", [120.0, 30.0, 60.0])
@pytest.mark.parametrize("win", [0, 100, 250])
@pytest.mark.parametrize("n", [1, 2, 5, 13, 40, 200])
def test_velocity_matches_naive(fps, win, n):
    x = np.random.default_rng(n).normal(size=(n, 3)).cumsum(axis=0)
    assert np.allclose(velocity(x, fps, win), velocity_naive(x, fps, win), atol=1e-9)


def test_velocity_closed_forms_inside_clip():
    x = np.random.default_rng(0).normal(size=(100, 3))
    v = velocity(x, 120.0, 100)
    t = 50  # 0-based; docs/method/features.md §3: v(t) = 10·(x(t+7) − x(t−5)) with 1-based t
    assert np.allclose(v[t], 10 * (x[t + 7] - x[t - 5]))
    v = velocity(x, 120.0, 250)
    assert np.allclose(v[t], 4 * (x[t + 16] - x[t - 14]))


def test_window_samples_exact():
    assert window_samples(100, 120) == 12  # 0.1*120 in floats is 12.000000000000002
    assert window_samples(250, 120) == 30
    assert window_samples(0, 120) == 1
    assert window_samples(100, 30) == 3
    assert window_samples(250, 30) == 8


@pytest.mark.parametrize("fps", [120.0, 30.0, 60.0, 100.0, 25.0, 119.88])
@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 7, 100, 101])
def test_analysis_frames_match_naive(fps, n):
    assert analysis_frames(n, fps).tolist() == reduce_naive(n, fps).tolist()


def test_analysis_frames_120hz_keeps_every_fourth():
    assert analysis_frames(9, 120.0).tolist() == [0, 4, 8]
    assert len(analysis_frames(301, 120.0)) == 76  # ceil(301/4)


def test_table_groups_and_mirrors():
    assert len(FEATURES) == 40 and len(set(FEATURE_NAMES)) == 40
    assert [f.id for f in FEATURES] == [f"F{i:02d}" for i in range(1, 41)]
    assert GROUPS["upper"] == tuple(range(0, 14))
    assert GROUPS["lower"] == tuple(range(14, 26))
    assert GROUPS["mix"] == tuple(range(26, 40))
    perm = mirror_permutation()
    assert sorted(perm) == list(range(40))
    assert all(perm[perm[i]] == i for i in range(40))
    for a, b in MIRROR_PAIRS:
        assert FEATURES[a].mirror == FEATURES[b].id and FEATURES[b].mirror == FEATURES[a].id
    assert feature_index("rknee_bent") == feature_index("F20") == 19
    with pytest.raises(MtannoError, match="unknown feature 'nope'"):
        feature_index("nope")


def test_compute_features_rejects_bad_shapes():
    with pytest.raises(MtannoError, match="frames"):
        compute_features_native(np.zeros((5, 3, 3)), np.zeros((5, 3)), 120.0)
    with pytest.raises(MtannoError, match="no frames"):
        compute_features_native(np.zeros((0, 22, 3)), np.zeros((0, 3)), 120.0)


def test_feature_tables_the_kernel_cannot_evaluate_are_refused():
    """A custom table row with fewer joints than its measure reads (the kernel would read
    past its joint table), or an unknown measure, joint or unit, and rates that are not
    positive raise; a single-joint ``fast`` row is fine (no second joint)."""
    from mtanno.features import Feature, compute_features

    J = np.random.default_rng(0).normal(size=(20, 22, 3))
    H = np.tile([0.0, 0.0, 1.0], (20, 1))

    def row(measure, joints, unit=None, params=()):
        return Feature("X1", "x", "x", "upper", None, measure, joints, unit, ("<=", 1.0),
                       ("<=", 0.5), 100, params)

    fast = compute_features_native(J, H, 120.0, features=(row("fast", ("rwrist",)),))
    two = compute_features_native(J, H, 120.0, features=(row("fast", ("rwrist", "rwrist")),))
    assert np.array_equal(fast, two)
    for f, msg in [(row("angle_max", ("rwrist", "relbow")), "'angle_max' needs 8 joints, got 2"),
                   (row("plane_diff", ("rwrist",)), "'plane_diff' needs 5 joints, got 1"),
                   (row("touch", ("rwrist", "relbow", "lwrist")), "touch feature needs"),
                   (row("bogus", ()), "unknown measure 'bogus'"),
                   (row("height", ("rwrist", "nose")), "unknown joint 'nose'"),
                   (row("height", ("rwrist", "relbow"), unit="cm"), "unknown unit 'cm'")]:
        with pytest.raises(MtannoError, match=msg):
            compute_features_native(J, H, 120.0, features=(f,))
    with pytest.raises(MtannoError, match="no features"):
        compute_features_native(J, H, 120.0, features=())
    for fps in (0.0, -120.0, float("nan"), float("inf")):
        with pytest.raises(MtannoError, match="frame rate must be a positive number"):
            compute_features(J, H, fps)
    with pytest.raises(MtannoError, match="analysis frame rate must be a positive number"):
        compute_features(J, H, 120.0, target_fps=0.0)


def _synthetic_motion(tmp_path, n=300, seed=0):
    return read_motion(synthetic.write_pair(tmp_path, n_frames=n, seed=seed))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kernel_equals_numpy_measures_bit_for_bit(tmp_path, seed):
    m = _synthetic_motion(tmp_path, 300, seed)
    J = canonical_positions(m)
    got = compute_features_native(J, m.heading, m.fps)
    assert np.array_equal(got, features_numpy(J, m.heading, m.fps))
    assert 0.05 < got.mean() < 0.95  # the synthetic motion switches features on and off


@pytest.mark.parametrize("n", [1, 2, 7, 29])
def test_kernel_short_clips(tmp_path, n):
    # clips shorter than the velocity windows (12 and 30 samples) mirror-pad
    # (docs/method/features.md §8)
    m = _synthetic_motion(tmp_path, n)
    J = canonical_positions(m)
    assert np.array_equal(compute_features_native(J, m.heading, m.fps),
                          features_numpy(J, m.heading, m.fps))


def test_kernel_other_frame_rate(tmp_path):
    m = _synthetic_motion(tmp_path, 200)
    J = canonical_positions(m)[::4]
    H = m.heading[::4]
    assert np.array_equal(compute_features_native(J, H, 30.0), features_numpy(J, H, 30.0))


def test_compute_features_rejects_nan():
    J = np.zeros((4, 22, 3))
    J[2, 3, 1] = np.nan
    with pytest.raises(MtannoError, match="NaN"):
        compute_features_native(J, np.zeros((4, 3)), 120.0)
