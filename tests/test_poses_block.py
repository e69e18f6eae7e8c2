"""The optional pose block of feature files (issue 26 part 3, ``mtanno features --poses``):
round trips on synthetic and real motions, files without it unchanged to the byte, every
malformed block refused with one message naming the file, training examples cut with their
poses, and the batch's resume logic."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from conftest import DATA, HDM05, NO_DATA_REASON
from world import assert_one_line, cli

from mtanno import synthetic as synth
from mtanno.errors import MtannoError
from mtanno.features import FEATURE_NAMES
from mtanno.features.batch import plan_batch, run_batch, up_to_date
from mtanno.features.extract import extract_file, to_y_up
from mtanno.features.poses import POSE_UNIT, normalize_poses, pose_metadata
from mtanno.features.store import POSE_PREFIX, pose_columns, read_features, write_features
from mtanno.io import canonical_positions, read_motion
from mtanno.io.rigs import CANONICAL_JOINTS
from mtanno.templates.training import ExampleSource, load_examples

COLUMNS = pose_columns(CANONICAL_JOINTS)
META = {"analysis_fps": 30.0, "feature_set": "mr06-ak40"}


def expected_poses(path: Path, native: np.ndarray, *, up: str = "y") -> np.ndarray:
    """What the pose block must hold, computed here from the motion file: the canonical
    joint positions (Y up) at the kept native frames, normalised, as float32."""
    P = to_y_up(canonical_positions(read_motion(path)), up)
    return normalize_poses(P[np.asarray(native) - 1]).astype(np.float32)


def check_round_trip(src: Path, dst: Path, *, up: str = "y") -> np.ndarray:
    X, meta = extract_file(src, dst, poses=True, up=up)
    ff = read_features(dst, poses=True)
    assert ff.has_poses and meta["poses"] == pose_metadata() == ff.meta["poses"]
    assert ff.poses.dtype == np.float32 and ff.poses.shape == (X.shape[1], 22, 3)
    np.testing.assert_allclose(ff.poses, expected_poses(src, ff.native_frames, up=up),
                               rtol=1e-6, atol=1e-6)
    assert np.array_equal(ff.X, X)
    # the features and rows are those of a file without poses
    extract_file(src, dst.with_name("plain.parquet"), up=up)
    plain = read_features(dst.with_name("plain.parquet"))
    assert np.array_equal(plain.X, ff.X) and np.array_equal(plain.native_frames,
                                                            ff.native_frames)
    assert {k: v for k, v in ff.meta.items() if k != "poses"} == plain.meta
    return ff.poses


# ------------------------------------------------------------------------------ round trip

def test_round_trip_synthetic(tmp_path):
    amc = synth.write_pair(tmp_path / "in", "walk", n_frames=40, seed=3)
    poses = check_round_trip(amc, tmp_path / "walk.parquet")
    assert poses.shape[0] == 10
    assert np.all(poses[:, 0, [0, 2]] == 0)  # root at x = z = 0
    right = poses[:, CANONICAL_JOINTS.index("rhip"), 0] - poses[:, CANONICAL_JOINTS.index(
        "lhip"), 0]
    assert np.all(right > 0)  # turned so that left → right is +x
    # without poses=True the block is not read
    ff = read_features(tmp_path / "walk.parquet")
    assert ff.poses is None and ff.has_poses and ff.names == list(FEATURE_NAMES)


def test_round_trip_z_up(tmp_path):
    amc = synth.write_pair(tmp_path / "in", "walk", n_frames=24, seed=5)
    check_round_trip(amc, tmp_path / "walk.parquet", up="z")


def test_align_reexports_the_normalisation():
    import mtanno.align.poses as ap
    import mtanno.features.poses as fp

    assert ap.normalize_poses is fp.normalize_poses and ap.body_scale is fp.body_scale


def _real_files() -> list[Path]:
    if not DATA.is_dir():
        pytest.skip(NO_DATA_REASON)
    files = [HDM05 / "squat1Reps" / "HDM_bd_squat1Reps_001_120.amc",
             DATA / "cmu_02" / "02_05.amc"]
    missing = [f for f in files if not f.is_file()]
    if missing:
        pytest.skip(f"real motion file not present: {missing[0]}")
    return files


def test_round_trip_real(tmp_path):
    from mtanno.align.poses import load_performance

    for src in _real_files():
        poses = check_round_trip(src, tmp_path / f"{src.stem}.parquet")
        # the poses the pose distance of `mtanno align` compares for this motion
        perf = load_performance(src)
        np.testing.assert_allclose(poses, normalize_poses(perf.joints), rtol=1e-6, atol=1e-6)
        legs = np.linalg.norm(poses[:, CANONICAL_JOINTS.index("lhip")]
                              - poses[:, CANONICAL_JOINTS.index("lknee")], axis=1)
        assert 0.3 < float(np.median(legs)) < 0.7, src  # a thigh is about half a leg


@pytest.mark.parametrize("n", [1, 2, 7, 76, 500, 1023, 1024, 1100])
def test_written_as_pyarrow_writes_it(tmp_path, n):
    """Short pose files are assembled by the direct encoder (features/_parquet), long ones by
    pyarrow with zstd: either way the bytes are pyarrow's, and they read back exactly."""
    rng = np.random.default_rng(n)
    X = (rng.random((40, n)) < 0.4).astype(np.uint8)
    P = rng.normal(0.0, 1.0, (n, 22, 3)).astype(np.float32)
    meta = {**META, "poses": pose_metadata()}
    p = tmp_path / "x.parquet"
    write_features(p, X, FEATURE_NAMES, np.arange(n) * 4 + 1, meta, poses=P)
    flat = P.reshape(n, 66)
    table = pa.table({"native_frame": pa.array(np.arange(n, dtype=np.int32) * 4 + 1),
                      **{nm: pa.array(X[i].astype(bool)) for i, nm in enumerate(FEATURE_NAMES)},
                      **{c: pa.array(flat[:, k]) for k, c in enumerate(COLUMNS)}})
    table = table.replace_schema_metadata(
        {b"mtanno": json.dumps({"schema": "mtanno.features/1", **meta}, sort_keys=True)})
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, write_statistics=False, use_dictionary=False,
                   compression="zstd" if n >= 1024 else "none")
    assert p.read_bytes() == sink.getvalue().to_pybytes()
    ff = read_features(p, poses=True)
    assert np.array_equal(ff.poses, P) and np.array_equal(ff.X, X)
    assert pq.read_schema(p).names[41:] == COLUMNS


def test_the_float_encoder_agrees_with_this_pyarrow():
    from mtanno.features import _parquet

    assert _parquet.available_floats() is not None


# ------------------------------------------------------------- files without poses unchanged

#: SHA-256 of files written on main before the pose block existed (pyarrow 26.0.1): the
#: extract_file output of synthetic motions of 24 and 600 frames (6 rows, direct encoder;
#: 150 rows) and a 1100-frame write_features file (zstd, pyarrow).
GOLDEN = {"26.0.1": {
    24: "b7833786ba95a35c34a8ecaf944804c31e6470807a992f0c1b7d203d13b0321e",
    600: "e3c7ab830a1f9470ac010a22f22fe8f44c6eff063f53f372a53d75e6f752a107",
    "long": "62b25f9e20d8c2657c41251a9c3d42c53a6e33867ddd3fbff05cdfb8d3769394"}}


def _digests(root: Path, monkeypatch) -> dict:
    import dataclasses

    import mtanno.features.extract as ex

    monkeypatch.chdir(root)  # relative source paths: the metadata does not name tmp_path
    monkeypatch.setattr(ex, "__version__", "golden")
    read = ex.read_motion

    def read_motion(*args, **kwargs):  # the built-in map's path names the checkout
        m = read(*args, **kwargs)
        m.smap = dataclasses.replace(m.smap, path="mtanno/skeletons/cmu-asf.toml")
        return m

    monkeypatch.setattr(ex, "read_motion", read_motion)
    out = {}
    for n in (24, 600):
        d = Path(f"in{n}")
        d.mkdir()
        (d / "synth.asf").write_text(synth.asf_text())
        (d / "walk.amc").write_text(synth.amc_text(n, 3))
        extract_file(d / "walk.amc", Path(f"out{n}.parquet"))
        out[n] = hashlib.sha256(Path(f"out{n}.parquet").read_bytes()).hexdigest()
    X = (np.random.default_rng(1).random((40, 1100)) < 0.4).astype(np.uint8)
    write_features("long.parquet", X, FEATURE_NAMES, np.arange(1100) * 4 + 1, META)
    out["long"] = hashlib.sha256(Path("long.parquet").read_bytes()).hexdigest()
    return out


def test_without_poses_the_bytes_are_those_of_main(tmp_path, monkeypatch):
    want = GOLDEN.get(pa.__version__)
    if want is None:
        pytest.skip(f"golden digests recorded with pyarrow {', '.join(GOLDEN)}, not "
                    f"{pa.__version__} (its files differ in created_by)")
    assert _digests(tmp_path, monkeypatch) == want


def test_without_poses_the_file_has_no_block(tmp_path):
    amc = synth.write_pair(tmp_path / "in", "walk", n_frames=40, seed=3)
    _, meta = extract_file(amc, tmp_path / "walk.parquet")
    assert "poses" not in meta
    schema = pq.read_schema(tmp_path / "walk.parquet")
    assert schema.names == ["native_frame", *FEATURE_NAMES]
    assert b'"poses"' not in schema.metadata[b"mtanno"]
    assert not read_features(tmp_path / "walk.parquet").has_poses
    assert read_features(tmp_path / "walk.parquet", poses=True).poses is None


# ----------------------------------------------------------------------- malformed blocks

@pytest.fixture(scope="module")
def good(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("good")
    amc = synth.write_pair(root / "in", "walk", n_frames=40, seed=3)
    dst = root / "walk.parquet"
    extract_file(amc, dst, poses=True)
    return dst


def _rewrite(good: Path, dst: Path, change) -> Path:
    """``good`` read with pyarrow, changed by ``change(table, meta) -> (table, meta)``,
    written to ``dst``."""
    table = pq.read_table(good)
    meta = json.loads(table.schema.metadata[b"mtanno"])
    table, meta = change(table, meta)
    pq.write_table(table.replace_schema_metadata({b"mtanno": json.dumps(meta)}), dst)
    return dst


def _drop(*names):
    return lambda t, m: (t.drop_columns(list(names)), m)


def _set(name, values):
    def change(t, m):
        i = t.column_names.index(name)
        return t.set_column(i, t.schema.field(i), pa.array(values, pa.float32())), m
    return change


def _meta(**changes):
    def change(t, m):
        block = dict(m["poses"])
        block.update(changes)
        return t, {**m, "poses": block}
    return change


N = 10  # rows of the good file
MALFORMED = {
    "a column missing": (_drop("pose.lhip.y"), "lacks 1 of its 66 columns: pose.lhip.y"),
    "all columns missing": (_drop(*COLUMNS), "describes poses but the file has none"),
    "no metadata": (lambda t, m: (t, {k: v for k, v in m.items() if k != "poses"}),
                    "pose column(s) pose.root.x, pose.root.y, pose.root.z … without a poses"),
    "stray column": (lambda t, m: (t.append_column("pose.tail.x", pa.array(
        np.zeros(N, np.float32))), m), "column 'pose.tail.x' is not a pose column"),
    "double column": (lambda t, m: (t.set_column(t.column_names.index("pose.root.y"),
                                                 "pose.root.y", t.column("pose.root.y").cast(
                                                     pa.float64())), m),
                      "pose column 'pose.root.y' is double, not float32"),
    "text column": (lambda t, m: (t.set_column(t.column_names.index("pose.neck.z"),
                                               "pose.neck.z", pa.array(["1"] * N)), m),
                    "pose column 'pose.neck.z' is string, not float32"),
    "other joints": (_meta(joints=list(CANONICAL_JOINTS[::-1])), "canonical joints in order"),
    "other unit": (_meta(unit="cm"), "must be in 'leg lengths', got unit 'cm'"),
    "no normalisation": (_meta(normalisation=""), "must say their normalisation"),
    "not an object": (lambda t, m: (t, {**m, "poses": [1, 2]}),
                      "poses in the mtanno metadata must be a JSON object, got list"),
}
#: Refused only when the values are read (poses=True); the schema is fine.
BAD_VALUES = {
    "NaN": (_set("pose.head.x", [0.0] * 3 + [np.nan] + [0.0] * (N - 4)),
            "pose column 'pose.head.x' has NaN or infinite values (rows 4)"),
    "infinity": (_set("pose.rwrist.y", [np.inf] * 2 + [0.0] * (N - 2)),
                 "pose column 'pose.rwrist.y' has NaN or infinite values (rows 1, 2)"),
    "null": (_set("pose.root.z", [None] + [0.0] * (N - 1)),
             "pose column 'pose.root.z' has 1 null value(s) (rows 1)"),
}


@pytest.mark.parametrize("kind", sorted(MALFORMED))
def test_malformed_block_is_refused(good, tmp_path, kind):
    change, message = MALFORMED[kind]
    bad = _rewrite(good, tmp_path / "bad.parquet", change)
    for poses in (False, True):
        with pytest.raises(MtannoError) as e:
            read_features(bad, poses=poses)
        assert str(e.value).startswith(f"{bad}: ") and message in str(e.value), str(e.value)
        assert "\n" not in str(e.value)
    assert_one_line(cli("info", bad), bad, codes=(2,))


@pytest.mark.parametrize("kind", sorted(BAD_VALUES))
def test_bad_pose_values_are_refused_when_read(good, tmp_path, kind):
    change, message = BAD_VALUES[kind]
    bad = _rewrite(good, tmp_path / "bad.parquet", change)
    with pytest.raises(MtannoError) as e:
        read_features(bad, poses=True)
    assert str(e.value) == f"{bad}: {message}"
    ff = read_features(bad)  # consumers that do not read poses are not affected
    assert ff.has_poses and ff.poses is None and ff.X.shape == (40, N)


def test_the_good_file_reads(good, tmp_path):
    same = _rewrite(good, tmp_path / "same.parquet", lambda t, m: (t, m))
    assert read_features(same, poses=True).poses.shape == (N, 22, 3)


def test_writing_a_bad_block_is_refused(tmp_path):
    X = np.zeros((40, 5), np.uint8)
    native = np.arange(5) + 1
    P = np.zeros((5, 22, 3))
    p = tmp_path / "x.parquet"
    with pytest.raises(MtannoError, match=r"poses must be \(frames × 22 × 3\) = \(5 × 22"):
        write_features(p, X, FEATURE_NAMES, native, META, poses=P[:4])
    P[2, 3, 1] = np.nan
    with pytest.raises(MtannoError, match="NaN or infinite"):
        write_features(p, X, FEATURE_NAMES, native, META, poses=P)
    with pytest.raises(MtannoError, match="NaN or infinite"):  # beyond float32
        write_features(p, X, FEATURE_NAMES, native, META, poses=np.full((5, 22, 3), 1e300))
    with pytest.raises(MtannoError, match="describes poses but none were given"):
        write_features(p, X, FEATURE_NAMES, native, {**META, "poses": pose_metadata()})
    with pytest.raises(MtannoError, match="unit"):
        write_features(p, X, FEATURE_NAMES, native,
                       {**META, "poses": {**pose_metadata(), "unit": "m"}},
                       poses=np.zeros((5, 22, 3)))
    names = [*FEATURE_NAMES[:39], POSE_PREFIX + "x"]
    with pytest.raises(MtannoError, match="must not begin with 'pose.'"):
        write_features(p, X, names, native, META)
    assert not list(tmp_path.iterdir())
    # the entry is filled in when absent
    write_features(p, X, FEATURE_NAMES, native, META, poses=np.zeros((5, 22, 3)))
    assert read_features(p).meta["poses"] == pose_metadata()
    assert pose_metadata()["unit"] == POSE_UNIT == "leg lengths"


# ------------------------------------------------------------------------ training examples

def test_load_examples_cuts_the_poses_of_the_segment(tmp_path):
    n = 30
    X = (np.random.default_rng(2).random((40, n)) < 0.3).astype(np.uint8)
    P = np.arange(n * 66, dtype=np.float32).reshape(n, 22, 3)  # every value tells its frame
    with_poses = tmp_path / "doc.parquet"
    write_features(with_poses, X, FEATURE_NAMES, np.arange(n) * 4 + 1, META, poses=P)
    plain = tmp_path / "plain.parquet"
    write_features(plain, X, FEATURE_NAMES, np.arange(n) * 4 + 1, META)
    sources = [ExampleSource("a", str(with_poses), 5, 12), ExampleSource("a", str(with_poses)),
               ExampleSource("b", str(plain), 3, 9)]
    ex = load_examples(sources, poses=True)
    by = {(e.file, e.start): e for e in ex}
    e = by[str(with_poses), 5]
    assert e.poses.dtype == np.float32 and np.array_equal(e.poses, P[4:12])
    assert np.array_equal(e.X, X[:, 4:12]) and e.poses.shape[0] == e.X.shape[1]
    assert np.array_equal(by[str(with_poses), 1].poses, P)
    assert by[str(plain), 3].poses is None  # a file without a block
    # without poses=True nothing changes: no poses loaded
    again = load_examples(sources)
    assert all(x.poses is None for x in again)
    assert all(np.array_equal(a.X, b.X) for a, b in zip(ex, again))


# ------------------------------------------------------------------------- batch and resume

def test_batch_resumes_by_poses(tmp_path):
    folder = tmp_path / "in"
    for k in range(3):
        synth.write_pair(folder, f"walk{k}", n_frames=24 + 4 * k, seed=k)
    out = tmp_path / "out"
    jobs = plan_batch([folder], out)

    def statuses(**kw):
        by = {o.job.dst: o.status for o in run_batch(jobs, **kw).outcomes}
        return [by[j.dst] for j in jobs]

    assert statuses(poses=True) == ["written"] * 3
    assert all(read_features(j.dst, poses=True).poses is not None for j in jobs)
    assert statuses(poses=True) == ["skipped"] * 3
    assert all(up_to_date(j, poses=True) and not up_to_date(j) for j in jobs)
    assert statuses() == ["written"] * 3  # a run without --poses rewrites them without
    assert not any(read_features(j.dst).has_poses for j in jobs)
    assert statuses() == ["skipped"] * 3
    assert statuses(poses=True) == ["written"] * 3  # and with it, with
    # a stored entry of another normalisation is not up to date
    _rewrite(jobs[0].dst, jobs[0].dst, _meta(normalisation="another"))
    assert statuses(poses=True) == ["written", "skipped", "skipped"]


def test_cli_poses_in_processes_and_resume(tmp_path):
    folder = tmp_path / "in"
    for k in range(4):
        synth.write_pair(folder, f"walk{k}", n_frames=24 + 4 * k, seed=k)
    one, two = tmp_path / "o1", tmp_path / "o2"
    r = cli("features", folder, "-o", one, "--poses")
    assert r.exit_code == 0 and "4 written" in r.output, r.output
    r = cli("features", folder, "-o", two, "--poses", "-j", "2")
    assert r.exit_code == 0 and "4 written" in r.output, r.output
    for f in sorted(one.glob("*.parquet")):  # the same bytes from worker processes
        assert f.read_bytes() == (two / f.name).read_bytes()
    assert "4 up to date" in cli("features", folder, "-o", one, "--poses").output
    assert "4 written" in cli("features", folder, "-o", one).output
    r = cli("info", one / "walk0.parquet")
    assert r.exit_code == 0 and not any(ln.startswith("poses") for ln in r.output.splitlines())
    cli("features", folder, "-o", one, "--poses")
    r = cli("info", one / "walk0.parquet")
    assert "poses          22 joints, leg lengths" in r.output.splitlines()


def test_consumers_read_pose_files_as_before(world, tmp_path):
    """annotate, index and learn-mt give the same results on feature files with poses."""
    docfeats = tmp_path / "docfeats"
    assert cli("features", world.docs, "-o", docfeats, "--poses", "-q").exit_code == 0
    assert all(read_features(f).has_poses for f in docfeats.glob("*.parquet"))
    table = tmp_path / "annotation.csv"
    r = cli("annotate", "--mt", world.mt, docfeats, "-o", table, "-q")
    assert r.exit_code == 0, r.output
    assert table.read_text() == world.annotation.read_text()
    r = cli("index", docfeats, "-o", tmp_path / "idx", "-q")
    assert r.exit_code == 0, r.output
    feats = tmp_path / "feats"
    assert cli("features", world.clips, "-o", feats, "--poses", "-q").exit_code == 0
    mt = tmp_path / "mt"
    r = cli("learn-mt", "--manifest", world.manifest, "--features-dir", feats, "--split",
            "train", "-o", mt, "-q")
    assert r.exit_code == 0, r.output
    for f in sorted(world.mt.glob("*.json")):
        a, b = json.loads(f.read_text()), json.loads((mt / f.name).read_text())
        for key in ("length", "weights", "values", "final_cost", "history"):
            assert a[key] == b[key], (f.name, key)
