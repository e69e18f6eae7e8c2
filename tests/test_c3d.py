"""C3D marker files (issue 36): reading, marker sets, gaps and validity, on C3D files made
from synthetic motions in temporary folders (no C3D file is kept in the repository)."""

from __future__ import annotations

import numpy as np
import pytest
from c3d_support import write_c3d
from virtual_markers import place_markers
from world import cli

from mtanno import synthetic
from mtanno.errors import MtannoError
from mtanno.features.extract import analysis_validity, invalid_runs
from mtanno.features.store import read_features, write_features
from mtanno.io import canonical_positions, read_channels, read_motion
from mtanno.io.c3d import read_c3d
from mtanno.io.formats import FORMATS, expected, format_of, looks_like_motion
from mtanno.io.markerjoints import fill_gaps, missing_runs
from mtanno.io.markerset import choose_set, load_set, marker_name
from mtanno.io.rigs import CANONICAL_JOINTS

J = {j: k for k, j in enumerate(CANONICAL_JOINTS)}


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    """A synthetic ASF/AMC motion and its virtual markers (labels, mm, Y up)."""
    root = tmp_path_factory.mktemp("c3dsynth")
    amc = synthetic.write_pair(root, stem="walk", n_frames=240, seed=3)
    rig, ch = read_channels(amc)
    labels, pts = place_markers(rig, ch, prefix="Subject:")
    return amc, labels, pts


def zup(pts):
    return np.stack([pts[..., 0], -pts[..., 2], pts[..., 1]], axis=-1)


def make(tmp_path, synth, name="take.c3d", *, labels=None, pts=None, **kw):
    _, lab, p = synth
    return write_c3d(tmp_path / name, lab if labels is None else labels,
                     zup(p) if pts is None else pts, **kw)


# ------------------------------------------------------------------ format table


def test_format_table_gives_readers_and_messages(tmp_path):
    assert [f.suffix for f in FORMATS] == [".amc", ".bvh", ".c3d"]
    assert expected() == ".amc, .bvh or .c3d"
    assert format_of("X.C3D").name == "C3D"
    with pytest.raises(MtannoError, match=r"unknown motion file type '\.fbx' \(expected "
                                          r"\.amc, \.bvh or \.c3d\)"):
        format_of(tmp_path / "x.fbx")
    assert looks_like_motion("x.dat", b"\x02\x50" + bytes(600))
    assert looks_like_motion("x.dat", b"# c\nHIERARCHY\n")
    assert not looks_like_motion("x.dat", b"PAR1")


# ------------------------------------------------------------------ reading


def test_read_units_axes_prefix_and_unnamed_markers(tmp_path, synth):
    amc, labels, pts = synth
    f = make(tmp_path, synth, labels=labels + ["*0"],
             pts=np.concatenate([zup(pts), zup(pts[:, :1]) + 100], axis=1))
    m = read_c3d(f)
    assert m.labels[-1] == "*0" and m.up == "z" and m.units == "mm" and m.fps == 120.0
    assert np.allclose(m.points[:, :-1], zup(pts), atol=0.01)
    motion = read_motion(f)
    ref = canonical_positions(read_motion(amc))
    assert motion.positions.shape == ref.shape and motion.up == "z" and motion.valid is None
    # Y up and centimetres, as an ASF motion: the joints within a few cm of the skeleton's
    err = np.linalg.norm(canonical_positions(motion) - ref, axis=2)
    assert np.median(err) < 3.0, np.median(err, axis=0)
    assert motion.markers.ignored == ["*0"] and motion.markers.subject == "Subject:"
    # metres and a Y-up file give the same joints
    g = make(tmp_path, synth, "m.c3d", pts=zup(pts) / 1000.0, units="m")
    h = make(tmp_path, synth, "y.c3d", pts=pts, y_screen="+Y")
    for other in (g, h):
        assert np.allclose(read_motion(other).positions, motion.positions, atol=1e-3)
    assert read_motion(h).up == "y"
    # --up overrides the file: a Y-up file read as Z up is lying on its back
    lying = read_motion(h, up="z").positions
    assert not np.allclose(lying, motion.positions, atol=1.0)


def test_features_info_and_markers_guess_on_the_command_line(tmp_path, synth):
    f = make(tmp_path, synth)
    out = tmp_path / "feats"
    r = cli("features", f, "-o", out)
    assert r.exit_code == 0, r.output
    ff = read_features(out / "take.parquet")
    assert ff.fps == 30.0 and ff.X.shape == (40, 60) and ff.valid.all()
    assert ff.meta["markers"]["set"] == "vicon-41" and ff.meta["up"] == "z"
    assert ff.meta["rig"] == "c3d" and ff.meta["invalid"] == []
    r = cli("features", f, "-o", out)
    assert "1 up to date" in r.output
    r = cli("info", f)
    assert r.exit_code == 0 and "marker set     vicon-41" in r.output
    assert "  LKNE (Subject:LKNE) -> lknee, lankle" in r.output
    assert "subject        Subject:" in r.output
    r = cli("info", out / "take.parquet")
    assert "invalid        0 frames (0.0 %)" in r.output and "marker set     vicon-41" in r.output
    guess = tmp_path / "mine.toml"
    r = cli("markers", "guess", f, "-o", guess)
    assert r.exit_code == 0 and "41 of 41 markers found" in r.output, r.output
    out2 = tmp_path / "feats2"
    assert cli("features", f, "-o", out2, "--markers", guess).exit_code == 0
    ff2 = read_features(out2 / "take.parquet")
    assert np.array_equal(ff2.X, ff.X) and ff2.meta["markers"]["set"] == "guessed-take"


def test_other_names_are_refused_with_the_joints_and_how_to_map_them(tmp_path, synth):
    _, labels, pts = synth
    rename = {"LFWT": "LASI", "RFWT": "RASI", "LBWT": "LPSI", "RBWT": "RPSI",
              "LSHN": "LTIB", "RSHN": "RTIB"}
    other = [marker_name(x) for x in labels]
    other = [rename.get(x, x) for x in other]
    f = make(tmp_path, synth, labels=other)
    r = cli("features", f, "-o", tmp_path / "o")
    assert r.exit_code == 1 and "1 failed" in r.output  # a batch: the file fails alone
    line = [ln for ln in r.output.splitlines() if ln.startswith("mtanno:")]
    assert len(line) == 1, r.output
    assert "joints root, lhip, rhip, lknee" in line[0] and "lacks LFWT, RFWT" in line[0]
    assert "mtanno markers guess FILE.c3d -o MAP.toml" in line[0]
    r = cli("info", f)
    assert r.exit_code == 2 and "pass --markers MAP.toml" in r.output
    guess = tmp_path / "plug-in-gait.toml"
    r = cli("markers", "guess", f, "-o", guess)
    assert r.exit_code == 0 and "41 of 41" in r.output
    assert 'LFWT = "LASI"' in guess.read_text() and 'LSHN = "LTIB"' in guess.read_text()
    good = make(tmp_path, synth, "good.c3d")
    assert np.allclose(read_motion(f, markers=guess).positions, read_motion(good).positions)


def test_two_subjects_the_one_with_most_markers_is_read(tmp_path, synth):
    _, labels, pts = synth
    names = [marker_name(x) for x in labels]
    two = ["A:" + n for n in names[:10]] + ["B:" + n for n in names]
    P = np.concatenate([zup(pts[:, :10]) + 5000.0, zup(pts)], axis=1)
    f = make(tmp_path, synth, labels=two, pts=P)
    m = read_motion(f)
    assert m.markers.subject == "B:"
    assert np.allclose(m.positions, read_motion(make(tmp_path, synth, "g.c3d")).positions)


# ------------------------------------------------------------------ marker set files


@pytest.mark.parametrize("text, words", [
    ("name = [", "not a valid TOML marker set"),
    ("[points]\nroot = { mean = [\"A\"] }\n", "[points] lacks the joint(s) lhip"),
    ("[points]\nroot = { spin = [\"A\"] }\n", "exactly one of mean, extend"),
    ("[points]\nroot = { mean = [\"A\"], by = 2 }\n", "mean takes mean, not by"),
    ("[points]\nroot = { extend = [\"A\"], by = 2 }\n", "extend takes two names"),
    ("[points]\nroot = { chord = \"A\", hinge = \"B\", by = 2 }\n", "one of away = NAME"),
    ("[points]\nroot = { hip = \"bell\", side = \"left\" }\n", "unknown hip method 'bell'"),
    ("[points]\nroot = { offset = \"A\", toward = [\"B\", \"C\"], by = \"nope\" }\n",
     "[points] lacks the joint(s)"),
    ("base = \"vicon-41\"\n[markers]\nNOPE = \"X\"\n", "renames NOPE, which the set"),
    ("base = \"vicon-41\"\nmax_gap = 1\n", "only renames markers"),
    ("base = \"no-such-set\"\n", "no marker set named 'no-such-set'"),
])
def test_bad_marker_set_files_are_one_error(tmp_path, text, words):
    p = tmp_path / "set.toml"
    p.write_text(text)
    with pytest.raises(MtannoError, match=None) as e:
        load_set(p)
    assert words in str(e.value) and str(p) in str(e.value)


def test_marker_set_cycles_and_unknown_sizes(tmp_path):
    base = (load_set.__module__ and
            open(choose_set([], "vicon-41").path, encoding="utf-8").read())
    p = tmp_path / "cycle.toml"
    p.write_text(base.replace('chest = { mean = ["T10", "STRN"] }',
                              'chest = { mean = ["belly", "STRN"] }'))
    with pytest.raises(MtannoError, match="depend on each other in a circle"):
        load_set(p)
    p.write_text(base.replace('by = "lknee_offset"', 'by = "no_size"', 1))
    with pytest.raises(MtannoError, match="no size named 'no_size'"):
        load_set(p)


# ------------------------------------------------------------------ gaps


def _rigid_segment(n=200, seed=0):
    """Four markers of a rigid body turning and moving: (frames × 4 × 3)."""
    rng = np.random.default_rng(seed)
    body = rng.normal(size=(4, 3)) * 50
    t = np.linspace(0, 2, n)
    out = np.empty((n, 4, 3))
    for f, a in enumerate(t):
        c, s = np.cos(3 * a), np.sin(3 * a)
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array(
            [[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        out[f] = body @ R.T + [100 * a, 40 * np.sin(2 * a), 3 * a]
    return out


def test_gap_filled_from_its_rigid_segment_is_exact(tmp_path):
    truth = _rigid_segment()
    P = {n: truth[:, k].copy() for k, n in enumerate("ABCD")}
    P["A"][50:70] = np.nan   # inside
    P["A"][:10] = np.nan     # at the start
    P["A"][-8:] = np.nan     # at the end
    filled = fill_gaps(P, {"seg": ("A", "B", "C", "D")}, max_frames=30)
    assert filled == {"A": 38}
    # a rigid segment: the offset to the others is constant, so the fill is exact
    assert np.allclose(P["A"], truth[:, 0], atol=1e-6)
    # interpolating the world position instead would miss the turning body
    world = np.interp(np.arange(50, 70), [49, 70], truth[[49, 70], 0, 0])
    assert np.abs(world - truth[50:70, 0, 0]).max() > 1.0


def test_long_gaps_and_whole_segments_stay_missing():
    truth = _rigid_segment()
    P = {n: truth[:, k].copy() for k, n in enumerate("ABCD")}
    P["A"][50:90] = np.nan                       # 40 frames: too long
    for n in "ABCD":
        P[n][120:125] = np.nan                   # the whole segment: nothing to fill from
    filled = fill_gaps(P, {"seg": ("A", "B", "C", "D")}, max_frames=30)
    assert filled == {}
    assert missing_runs(~np.isfinite(P["A"]).all(axis=1)) == [(50, 89), (120, 124)]


def _gapped(tmp_path, synth, cut, name):
    _, labels, pts = synth
    P = zup(pts).copy()
    names = [marker_name(x) for x in labels]
    for marker, a, b in cut:
        P[a:b, names.index(marker)] = np.nan
    return make(tmp_path, synth, name, pts=P)


def test_each_kind_of_gap(tmp_path, synth):
    clean = read_motion(make(tmp_path, synth, "clean.c3d"))
    # one marker, short (0.2 s), inside and at both ends: filled, the joints hardly move
    short = read_motion(_gapped(tmp_path, synth, [("LKNE", 100, 124), ("LANK", 0, 20),
                                                  ("RWRA", 220, 240)], "short.c3d"))
    assert short.valid is None and short.markers.filled == {"LKNE": 24, "LANK": 20,
                                                             "RWRA": 20}
    # (within 2 cm: the knee marker has two partners, whose offset ignores turning)
    assert np.abs(short.positions - clean.positions).max() < 2.0  # cm
    # one marker, long (0.5 s): its joints invalid there, nowhere else
    long_ = read_motion(_gapped(tmp_path, synth, [("LKNE", 100, 160)], "long.c3d"))
    assert np.flatnonzero(~long_.valid).tolist() == list(range(100, 160))
    assert long_.markers.invalid == {"lknee": 60, "lankle": 60}
    ok = long_.valid  # (to 0.1 mm: the body sizes are medians over fewer frames)
    assert np.allclose(long_.positions[ok], clean.positions[ok], atol=0.01)
    # the whole pelvis, even briefly: nothing to fill from, every joint it feeds invalid
    seg = read_motion(_gapped(tmp_path, synth, [(m, 30, 40) for m in
                                                ("LFWT", "RFWT", "LBWT", "RBWT")], "seg.c3d"))
    assert np.flatnonzero(~seg.valid).tolist() == list(range(30, 40))
    assert {"root", "lhip", "rhip", "lknee", "belly"} <= set(seg.markers.invalid)
    # a long gap at the start: invalid from frame 0, joints held from the first valid one
    start = read_motion(_gapped(tmp_path, synth, [("RSHO", 0, 60)], "start.c3d"))
    assert np.flatnonzero(~start.valid).tolist() == list(range(60))
    assert np.allclose(start.positions[:60, J["rshoulder"]], start.positions[60, J["rshoulder"]])


def test_invalid_frames_in_the_feature_file_and_the_messages(tmp_path, synth):
    f = _gapped(tmp_path, synth, [("LKNE", 100, 160)], "long.c3d")
    out = tmp_path / "feats"
    r = cli("features", f, "-o", out)
    assert r.exit_code == 0, r.output
    assert "are invalid: joints could not be computed" in r.output and "LKNE" in r.output
    assert "% invalid)" in r.output
    ff = read_features(out / "long.parquet")
    native = ff.native_frames - 1
    reach = 30  # the 250 ms velocity window at 120 Hz
    want = (native >= 100 - reach) & (native <= 159 + reach)
    assert np.array_equal(~ff.valid, want)
    assert ff.meta["invalid"] == invalid_runs(ff.valid)
    r = cli("info", out / "long.parquet")
    n = int(want.sum())
    assert f"invalid        {n} frames ({100 * n / ff.X.shape[1]:.1f} %) in 1 stretch" \
        in r.output
    r = cli("info", f)
    assert "invalid        60 frames (25.0 %); joints not computed: lknee 60, lankle 60" \
        in r.output


def test_every_joint_lost_everywhere_is_one_error(tmp_path, synth):
    f = _gapped(tmp_path, synth, [("LKNE", 0, 240)], "nolknee.c3d")
    # (the root too: its height above the hips is measured on the left shank)
    with pytest.raises(MtannoError, match=r"joints root, lknee, lankle, belly cannot be "
                                          r"computed in any frame \(markers absent or never "
                                          r"seen: LKNE\)"):
        read_motion(f)


def test_analysis_validity_reaches_over_the_velocity_window():
    valid = np.ones(100, bool)
    valid[50] = False
    keep = np.arange(0, 100, 4)
    v = analysis_validity(valid, keep, 120.0)
    assert np.array_equal(~v, (keep >= 20) & (keep <= 80))
    assert analysis_validity(None, keep, 120.0).all()


# ------------------------------------------------------------------ feature-file validity


def test_validity_in_feature_files_is_checked_and_old_files_are_all_valid(tmp_path):
    X = np.zeros((2, 10), np.uint8)
    meta = {"analysis_fps": 30.0, "feature_set": "custom"}
    write_features(tmp_path / "old.parquet", X, ["a", "b"], np.arange(1, 11), meta)
    assert read_features(tmp_path / "old.parquet").valid.all()
    write_features(tmp_path / "v.parquet", X, ["a", "b"], np.arange(1, 11),
                   {**meta, "invalid": [[2, 3], [7, 10]]})
    assert np.flatnonzero(~read_features(tmp_path / "v.parquet").valid).tolist() == \
        [1, 2, 6, 7, 8, 9]
    for bad in ([[3, 2]], [[0, 1]], [[5, 11]], [[2, 4], [4, 6]], [[7, 8], [2, 3]], [2, 3],
                "1-2", [[1.5, 2]]):
        p = tmp_path / "bad.parquet"
        write_features(p, X, ["a", "b"], np.arange(1, 11), {**meta, "invalid": bad})
        with pytest.raises(MtannoError, match="invalid in the mtanno metadata"):
            read_features(p)


def test_annotation_never_labels_an_invalid_stretch(world, tmp_path):
    """A document labelled all through, then the same features with a stretch marked
    invalid: no segment touches it (reference labels and the tuned decoder alike)."""
    from mtanno.annotate.batch import annotate_files
    from mtanno.annotate.config import ClassConfig
    from mtanno.annotate.setup import load_class_models

    src = world.doc_files[0]
    ff = read_features(src)
    n = ff.X.shape[1]
    models, layout = load_class_models(world.mt)
    configs = [ClassConfig(), ClassConfig(resolve=True, refine=True, default_tau=0.2)]
    for config in configs:
        rows = annotate_files([src], models, layout=layout, config=config).rows
        labelled = np.zeros(n, bool)
        for r in rows:
            labelled[r.start:r.end + 1] = True
        inside = np.flatnonzero(labelled)
        a = int(inside[len(inside) // 2])
        gap = (max(a - 20, 0), min(a + 20, n - 1))
        doc = tmp_path / f"{config.resolve}" / src.name
        doc.parent.mkdir()
        write_features(doc, ff.X, ff.names, ff.native_frames,
                       {**ff.meta, "invalid": [[gap[0] + 1, gap[1] + 1]]})
        masked = annotate_files([doc], models, layout=layout, config=config).rows
        assert masked, "the rest of the document is still labelled"
        for r in masked:
            assert r.end < gap[0] or r.start > gap[1], (r, gap)


def test_the_report_players_read_c3d_through_the_format_table(tmp_path, synth):
    from mtanno.evaluation.player import load_motion_poses, motion_files

    f = make(tmp_path, synth)
    files = motion_files([tmp_path])
    assert files == {"take": f}
    poses = load_motion_poses(files, ["take"])["take"]
    ff_out = tmp_path / "feats"
    assert cli("features", f, "-o", ff_out, "--poses").exit_code == 0
    block = read_features(ff_out / "take.parquet", poses=True).poses
    assert poses.shape == block.shape == (60, 22, 3)
    assert np.allclose(poses, block, atol=1e-5)


def test_without_the_c3d_package_a_c3d_file_says_how_to_install_it(tmp_path, synth,
                                                                     monkeypatch):
    import sys

    f = make(tmp_path, synth)
    monkeypatch.setitem(sys.modules, "c3d", None)  # import c3d raises ImportError
    with pytest.raises(MtannoError, match="needs the c3d package: pip install c3d"):
        read_c3d(f)
