"""The 31 MRC05 features (feature sets mrc05 and mrc05-reference): table, kernel against the
numpy oracle, capsule semantics, golden outputs of the reference implementation, CLI."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import HDM05, REFERENCE, require_data
from naive_features import features_numpy

from mtanno import synthetic
from mtanno.cli import main
from mtanno.errors import MtannoError
from mtanno.features import FEATURE_SETS, compute_features, compute_features_native, get_feature_set
from mtanno.features.store import read_features
from mtanno.features.table31 import FEATURES31, FEATURES31_REFERENCE, Feature31
from mtanno.io import canonical_positions, read_motion
from mtanno.io.rigs import CANONICAL_JOINTS

SETS31 = ("mrc05", "mrc05-reference")


def test_table31_layout():
    for name in SETS31:
        fs = get_feature_set(name)
        assert len(fs.features) == 31 and len(set(fs.names)) == 31
        assert [f.id for f in fs.features] == [f"F{i:02d}" for i in range(1, 32)]
        assert fs.groups == {"lower": tuple(range(0, 11)), "upper": tuple(range(11, 23)),
                             "mix": tuple(range(23, 31))}
        for a, b in fs.mirror_pairs:
            assert fs.features[a].mirror == fs.features[b].id
            assert fs.features[b].mirror == fs.features[a].id
        assert len(fs.mirror_pairs) == 13
    fs = get_feature_set("mrc05")
    assert fs.index("rknee_bent") == fs.index("F07") == fs.index("Fl7") == fs.index("Fℓ7") == 6
    assert fs.index("kneeRightAngle") == 6 and fs.index("Fm8") == 26
    with pytest.raises(MtannoError, match="unknown feature 'nope' in feature set mrc05"):
        fs.index("nope")
    assert get_feature_set("ak40") is FEATURE_SETS["mr06-ak40"]
    with pytest.raises(MtannoError, match="unknown feature set"):
        get_feature_set("ak41")


def test_mrc05_fixes_exactly_the_listed_bugs():
    # docs/method/features31.md §5.1–5.3; everything else is the reference table
    diff = {f.id: (f, g) for f, g in zip(FEATURES31, FEATURES31_REFERENCE) if f != g}
    assert sorted(diff) == ["F04", "F10", "F11", "F27"]
    assert diff["F04"][1].unit == "femR" and diff["F04"][0].unit == "femL"
    for fid in ("F10", "F11"):
        ref, fixed = diff[fid][1], diff[fid][0]
        assert ref.on == ref.off == (">", 1.0)  # no hysteresis in the reference
        assert fixed.on == (">", 1.25) and fixed.off == (">", 1.0)
    ref, fixed = diff["F27"][1], diff["F27"][0]
    assert (ref.unit, ref.window_ms) == (None, 12) and (fixed.unit, fixed.window_ms) == ("hlL", 100)


def _synthetic(tmp_path, n, seed):
    m = read_motion(synthetic.write_pair(tmp_path, n_frames=n, seed=seed))
    return canonical_positions(m), m.heading, m.fps


@pytest.mark.parametrize("name", SETS31)
@pytest.mark.parametrize("seed", [0, 1])
def test_kernel_equals_numpy_oracle_31(tmp_path, name, seed):
    fs = get_feature_set(name)
    J, H, fps = _synthetic(tmp_path, 300, seed)
    assert np.array_equal(compute_features_native(J, H, fps, features=fs.features),
                          features_numpy(J, H, fps, features=fs.features))


@pytest.mark.parametrize("name", SETS31)
def test_kernel_equals_oracle_on_point_clouds(name):
    # random joint clouds make the capsule, angle-max and height features switch often
    fs = get_feature_set(name)
    rng = np.random.default_rng(7)
    J = rng.normal(size=(400, 22, 3)) * 25 + rng.normal(size=(1, 22, 3)) * 10
    H = np.zeros((400, 3))
    got = compute_features_native(J, H, 120.0, features=fs.features)
    assert np.array_equal(got, features_numpy(J, H, 120.0, features=fs.features))
    touch = [i for i, f in enumerate(fs.features) if f.measure in ("touch", "angle_max", "height")]
    rate = got[touch].mean(axis=1)
    assert ((rate > 0.02) & (rate < 0.98)).sum() >= 6, rate


@pytest.mark.parametrize("n", [1, 2, 7, 29])
def test_kernel_short_clips_31(tmp_path, n):
    fs = get_feature_set("mrc05")
    J, H, fps = _synthetic(tmp_path, n, 3)
    assert np.array_equal(compute_features_native(J, H, fps, features=fs.features),
                          features_numpy(J, H, fps, features=fs.features))


def _one_touch(params, k_on=1.0, k_off=1.0):
    """A one-row table: rfingers against the capsule neck→headtop."""
    return (Feature31("T1", "t", "t", "mix", None, "touch", ("neck", "headtop", "rfingers"),
                      None, ("<=", k_on), ("<=", k_off), params=params),)


def _pose(points):
    """One frame per entry: neck at 0, headtop at (0, 10, 0), rfingers at the given point;
    the other joints far away (body units need frame 1 only, unused by touch rows)."""
    J = np.full((len(points), 22, 3), 500.0)
    J[:, :, 0] += np.arange(22) * 7.0
    J[:, CANONICAL_JOINTS.index("neck")] = 0.0
    J[:, CANONICAL_JOINTS.index("headtop")] = (0.0, 10.0, 0.0)
    J[:, CANONICAL_JOINTS.index("rfingers")] = points
    return J


def test_capsule_semantics():
    # docs/method/features31.md §4: distance to the line inside, balls at the ends when
    # enabled, ≤ k·ℓ
    pts = [(10.0, 5.0, 0.0),    # beside the segment, d = 10 = 1.0·ℓ → touching (≤)
           (10.5, 5.0, 0.0),    # d = 10.5 > 10
           (0.0, 19.0, 0.0),    # beyond headtop by 9 → ball → touching
           (0.0, -3.0, 0.0),    # below the neck by 3: ball only if ball_a
           (8.0, 16.0, 0.0)]    # beyond headtop: distance to the ball sqrt(64+36) = 10
    J = _pose(pts)
    H = np.zeros((len(pts), 3))
    no_neck_ball = compute_features_native(J, H, 120.0, features=_one_touch((1.0, 0.0, 1.0)))
    assert no_neck_ball[0].tolist() == [1, 0, 1, 0, 1]
    both = compute_features_native(J, H, 120.0, features=_one_touch((1.0, 1.0, 1.0)))
    assert both[0].tolist() == [1, 0, 1, 1, 1]
    # radius factor c scales the radius: c = 0.5 → radius 5
    half = compute_features_native(J, H, 120.0, features=_one_touch((0.5, 1.0, 1.0)))
    assert half[0].tolist() == [0, 0, 0, 1, 0]


def test_touch_hysteresis_uses_both_radii():
    # handTouch style: switch on at k = 0.75, stay on up to k = 1.0
    d = [9.0, 7.0, 9.0, 9.9, 10.5, 9.0]
    J = _pose([(x, 5.0, 0.0) for x in d])
    got = compute_features_native(J, np.zeros((len(d), 3)), 120.0,
                                  features=_one_touch((1.0, 1.0, 1.0), 0.75, 1.0))
    assert got[0].tolist() == [0, 1, 1, 1, 0, 0]


# --- golden outputs of the reference implementation (docs/method/features31.md §7) ---------

def _ref_clips():
    if not REFERENCE.is_dir():
        return []
    return sorted(p.stem for p in (REFERENCE / "features31").glob("*.csv"))


def _amc(clip):
    return HDM05 / clip.split("_")[2] / f"{clip}.amc"


def test_reference31_present():
    require_data()
    assert len(_ref_clips()) == 9


@pytest.mark.parametrize("clip", _ref_clips() or ["(no data)"])
def test_mrc05_reference_reproduces_golden_outputs(clip):
    require_data()
    fs = get_feature_set("mrc05-reference")
    ref30 = REFERENCE / "features31" / f"{clip}.csv"
    header = ref30.open().readline().strip().split(",")
    assert [h.split("_", 1)[1] for h in header[1:]] == [f.ref_name for f in fs.features]
    m = read_motion(_amc(clip))
    J = canonical_positions(m)
    want30 = np.loadtxt(ref30, delimiter=",", skiprows=1, ndmin=2)
    X, keep = compute_features(J, m.heading, m.fps, features=fs.features)
    assert np.array_equal(keep + 1, want30[:, 0].astype(int))
    bad = np.flatnonzero((X != want30[:, 1:].T).any(axis=1))
    assert bad.size == 0, f"30 Hz differences in {[fs.features[i].id for i in bad]}"
    want120 = np.loadtxt(REFERENCE / "features31_120hz" / f"{clip}.csv", delimiter=",",
                         skiprows=1, ndmin=2)
    N = compute_features_native(J, m.heading, m.fps, features=fs.features)
    bad = np.flatnonzero((N != want120[:, 1:].T).any(axis=1))
    assert bad.size == 0, f"120 Hz differences in {[fs.features[i].id for i in bad]}"
    # and mrc05 differs only where a bug was fixed, in the direction of the fix
    fixed = compute_features_native(J, m.heading, m.fps, features=get_feature_set("mrc05").features)
    changed = {fs.features[i].id for i in np.flatnonzero((fixed != N).any(axis=1))}
    assert changed <= {"F04", "F10", "F11", "F27"}
    assert (fixed[9] <= N[9]).all() and (fixed[10] <= N[10]).all()  # stricter switch-on


def test_mrc05_root_fast_no_longer_always_on():
    require_data()
    rates = {}
    for name in SETS31:
        fs = get_feature_set(name)
        on = frames = 0
        for clip in _ref_clips():
            m = read_motion(_amc(clip))
            X, _ = compute_features(canonical_positions(m), m.heading, m.fps, features=fs.features)
            on += int(X[26].sum())
            frames += X.shape[1]
        rates[name] = on / frames
    assert rates["mrc05-reference"] > 0.9  # docs/method/features31.md §5.3: 93 % on these clips
    assert rates["mrc05"] < 0.8


def test_cli_feature_set_option(tmp_path):
    src = synthetic.write_pair(tmp_path / "in", n_frames=24, seed=1)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["features", str(src), "-o", str(out), "--feature-set",
                                  "mrc05", "-q"], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    ff = read_features(out / f"{src.stem}.parquet")
    assert ff.X.shape == (31, 6) and ff.meta["feature_set"] == "mrc05"
    assert ff.names == list(get_feature_set("mrc05").names)
    assert ff.meta["groups"]["mix"] == list(get_feature_set("mrc05").names[23:])
    # an up-to-date file of another feature set is rewritten, not skipped
    r = CliRunner().invoke(main, ["features", str(src), "-o", str(out)], catch_exceptions=False)
    assert "1 written" in r.output
    assert read_features(out / f"{src.stem}.parquet").meta["feature_set"] == "mr06-ak40"
    r = CliRunner().invoke(main, ["features", str(src), "-o", str(out), "--feature-set", "x"])
    assert r.exit_code == 2 and "x" in r.output


@pytest.mark.parametrize("name", ["mrc05", "mrc05-reference", "ak40"])
def test_degenerate_rig_gives_nan_tests_not_errors(name):
    # rigs without fingertips map fingers to the wrist (e.g. Bandai BVH): the hand segment
    # has length 0, capsule tests on it are NaN and hence false (docs/method/features31.md §4)
    fs = get_feature_set(name)
    rng = np.random.default_rng(3)
    J = rng.normal(size=(50, 22, 3)) * 25
    for hand, wrist in (("rfingers", "rwrist"), ("lfingers", "lwrist")):
        J[:, CANONICAL_JOINTS.index(hand)] = J[:, CANONICAL_JOINTS.index(wrist)]
    J[10, CANONICAL_JOINTS.index("lhip")] = J[10, CANONICAL_JOINTS.index("rhip")]  # zero normal
    H = np.zeros((50, 3))
    got = compute_features_native(J, H, 120.0, features=fs.features)
    assert np.array_equal(got, features_numpy(J, H, 120.0, features=fs.features))
    if name != "ak40":
        assert not got[fs.index("hands_touching")].any()
