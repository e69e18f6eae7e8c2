"""The command line: batch behaviour, outputs, exit codes and messages."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from click.testing import CliRunner

from mtanno import synthetic as synth
from mtanno.cli import main
from mtanno.features.store import read_features


@pytest.fixture
def tree(tmp_path):
    """in/synth.asf, in/a/walk1.amc, in/a/walk2.amc, in/b/bad.amc (truncated)."""
    root = tmp_path / "in"
    root.mkdir()
    (root / "synth.asf").write_text(synth.asf_text())
    for sub, stem, seed in (("a", "walk1", 1), ("a", "walk2", 2), ("b", "jump", 3)):
        (root / sub).mkdir(exist_ok=True)
        (root / sub / f"{stem}.amc").write_text(synth.amc_text(24, seed))
    lines = synth.amc_text(10, 4).splitlines()
    (root / "b" / "bad.amc").write_text("\n".join(lines[:-5]) + "\n")
    return root


def run(args, input=None):
    return CliRunner().invoke(main, args, input=input, catch_exceptions=False)


def test_features_batch_continues_past_bad_file(tree, tmp_path):
    out = tmp_path / "out"
    r = run(["features", str(tree), "-o", str(out)])
    assert r.exit_code == 1
    assert f"{tree / 'b' / 'bad.amc'}:" in r.output
    assert "frame 10 ends without values" in r.output
    assert "3 written" in r.output and "1 failed" in r.output
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert written == ["a/walk1.parquet", "a/walk2.parquet", "b/jump.parquet"]
    ff = read_features(out / "a" / "walk1.parquet")
    assert ff.X.shape == (40, 6) and ff.document == "walk1"
    assert ff.native_frames.tolist() == [1, 5, 9, 13, 17, 21]
    assert ff.meta["native_fps"] == 120.0 and ff.meta["skeleton_map"] == "cmu-asf"
    assert ff.meta["source_sha256"] and ff.meta["feature_set"] == "mr06-ak40"


def test_features_file_args_stdin_and_skip(tree, tmp_path):
    out = tmp_path / "out"
    f1 = tree / "a" / "walk1.amc"
    r = run(["features", str(f1), "-o", str(out), "-q"])
    assert r.exit_code == 0 and r.output == ""
    assert (out / "walk1.parquet").exists()
    # up to date → skipped; --force rewrites
    r = run(["features", str(f1), "-o", str(out)])
    assert "0 written" in r.output and "1 up to date" in r.output
    r = run(["features", str(f1), "-o", str(out), "--force"])
    assert "1 written" in r.output
    # a touched but unchanged input is still up to date (provenance, not time stamps) …
    t = time.time() + 5
    os.utime(f1, (t, t))
    r = run(["features", str(f1), "-o", str(out)])
    assert "1 up to date" in r.output
    # … a changed one is recomputed
    f1.write_text(f1.read_text() + "\n")
    r = run(["features", str(f1), "-o", str(out)])
    assert "1 written" in r.output
    # file names on stdin
    r = run(["features", "-", "-o", str(out)], input=f"{tree / 'a' / 'walk2.amc'}\n")
    assert r.exit_code == 0 and (out / "walk2.parquet").exists()


def test_features_up_to_date_follows_the_recorded_provenance(tree, tmp_path):
    """Issue 8 root cause 3: a changed ASF, skeleton map or feature set makes an output
    stale even when the output is newer than every input."""
    out = tmp_path / "out"
    f1 = tree / "a" / "walk1.amc"
    assert run(["features", str(f1), "-o", str(out), "-q"]).exit_code == 0
    meta = read_features(out / "walk1.parquet").meta
    for key in ("source_sha256", "skeleton_file_sha256", "skeleton_map_sha256",
                "feature_table_sha256", "extractor_version", "rig_nodes"):
        assert meta[key], key
    assert "1 up to date" in run(["features", str(f1), "-o", str(out)]).output
    # the ASF changes (bone lengths), its time stamp goes back: not up to date
    asf = tree / "synth.asf"
    old = asf.stat()
    asf.write_text(asf.read_text().replace("length 0.45", "length 0.5", 1))
    os.utime(asf, ns=(old.st_atime_ns, old.st_mtime_ns - 10**10))
    assert "1 written" in run(["features", str(f1), "-o", str(out)]).output
    assert "1 up to date" in run(["features", str(f1), "-o", str(out)]).output
    # another feature set
    assert "1 written" in run(["features", str(f1), "-o", str(out), "--feature-set",
                                "mrc05"]).output
    # a skeleton map given explicitly that differs from the recorded one
    smap = tmp_path / "my.toml"
    from mtanno.io.rigs import builtin_dir

    text = (builtin_dir() / "cmu-asf.toml").read_text()
    smap.write_text(text.replace('name = "cmu-asf"', 'name = "my-asf"'))
    r = run(["features", str(f1), "-o", str(out), "--feature-set", "mrc05", "--skeleton",
             str(smap)])
    assert "1 written" in r.output, r.output


def test_features_jobs_gives_same_output(tree, tmp_path):
    r1 = run(["features", str(tree / "a"), "-o", str(tmp_path / "o1"), "-j", "1"])
    r2 = run(["features", str(tree / "a"), "-o", str(tmp_path / "o2"), "-j", "2"])
    assert r1.exit_code == r2.exit_code == 0
    for stem in ("walk1", "walk2"):
        a = read_features(tmp_path / "o1" / f"{stem}.parquet").X
        b = read_features(tmp_path / "o2" / f"{stem}.parquet").X
        assert np.array_equal(a, b)


def test_failed_file_leaves_no_output(tree, tmp_path):
    out = tmp_path / "out"
    run(["features", str(tree / "b"), "-o", str(out)])
    assert not (out / "bad.parquet").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_explicit_asf_and_missing_asf(tmp_path):
    d = tmp_path / "lonely"
    d.mkdir()
    amc = d / "x.amc"
    amc.write_text(synth.amc_text(8))
    r = run(["features", str(amc), "-o", str(tmp_path / "o")])
    assert r.exit_code == 1 and "no ASF skeleton found" in r.output and str(amc) in r.output
    asf = tmp_path / "skel.asf"
    asf.write_text(synth.asf_text())
    r = run(["features", str(amc), "--asf", str(asf), "-o", str(tmp_path / "o")])
    assert r.exit_code == 0


def test_usage_errors_exit_2(tmp_path):
    r = run(["features", str(tmp_path / "missing"), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "no such file or directory" in r.output
    r = run(["features", str(tmp_path), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "no .amc, .bvh or .c3d files" in r.output
    r = run(["features", str(tmp_path)])
    assert r.exit_code == 2
    r = run(["features", str(tmp_path), "-o", str(tmp_path / "o"), "--jobs", "0"])
    assert r.exit_code == 2


def test_unknown_skeleton_map_is_reported_per_file(tree, tmp_path):
    r = run(["features", str(tree / "a"), "-o", str(tmp_path / "o"), "--skeleton", "nomap"])
    assert r.exit_code == 1 and "no skeleton map named 'nomap'" in r.output


def test_skeleton_map_missing_joint(tree, tmp_path):
    from mtanno.io.rigs import builtin_dir

    src = (builtin_dir() / "cmu-asf.toml").read_text()
    m = tmp_path / "partial.toml"
    m.write_text(src.replace('name = "cmu-asf"', 'name = "partial"').replace('lknee = "lfemur"\n', ""))
    r = run(["features", str(tree / "a" / "walk1.amc"), "-o", str(tmp_path / "o"),
             "--skeleton", str(m)])
    assert r.exit_code == 1
    assert "has no entry for joint 'lknee'" in r.output


def test_info_motion_and_feature_file(tree, tmp_path):
    r = run(["info", str(tree / "a" / "walk1.amc")])
    assert r.exit_code == 0
    assert "frame rate     120 Hz" in r.output and "frames         24" in r.output
    assert "map coverage   22/22" in r.output and "duration       0.20 s" in r.output
    run(["features", str(tree / "a" / "walk1.amc"), "-o", str(tmp_path / "o")])
    r = run(["info", str(tmp_path / "o" / "walk1.parquet")])
    assert r.exit_code == 0 and "mr06-ak40" in r.output
    # bad input is exit code 2, as the README says (issue 8, root cause 12)
    r = run(["info", str(tree / "b" / "bad.amc")])
    assert r.exit_code == 2 and r.output.startswith("mtanno: ") and "Traceback" not in r.output
    # a missing file is "not found", not "no ASF skeleton found" (root cause 11)
    r = run(["info", str(tmp_path / "nope.amc")])
    assert r.exit_code == 2 and r.output == f"mtanno: {tmp_path / 'nope.amc'}: motion file not found\n"


def test_help_texts():
    r = run(["--help"])
    assert "features" in r.output and "info" in r.output
    r = run(["features", "--help"])
    text = " ".join(r.output.split())
    assert "--jobs" in text and "--asf" in text and "Exit code: 0 all written" in text


def test_user_skeleton_folder_follows_xdg(monkeypatch, tmp_path):
    from mtanno.io.rigs import builtin_dir, search_dirs, user_dir

    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "cfg"))
    monkeypatch.setenv("MTANNO_SKELETON_PATH", str(tmp_path / "extra"))
    assert user_dir() == tmp_path / "cfg" / "mtanno" / "skeletons"
    assert search_dirs() == [tmp_path / "extra", user_dir(), builtin_dir()]
    monkeypatch.setenv("XDG_CONFIG_HOME", "")  # empty or relative: the default
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert user_dir() == tmp_path / "home" / ".config" / "mtanno" / "skeletons"
    assert (builtin_dir() / "cmu-asf.toml").is_file()


def _z_up_copy(world, clip, folder):
    """A copy of a synthetic clip turned so that Z is up: the ASF root orientation turns
    the skeleton by +90° about X, the root translations (x, y, z) become (x, −z, y)."""
    folder.mkdir()
    asf = (world.clips / "SYN_a.asf").read_text()
    assert "orientation 0 0 0" in asf
    (folder / "SYN_a.asf").write_text(asf.replace("orientation 0 0 0", "orientation 90 0 0"))
    lines = []
    for line in clip.read_text().splitlines():
        if line.startswith("root "):
            v = [float(x) for x in line.split()[1:]]
            v[0:3] = [v[0], -v[2], v[1]]
            line = "root " + " ".join(f"{x:.6f}" for x in v)
        lines.append(line)
    (folder / clip.name).write_text("\n".join(lines) + "\n")
    return folder / clip.name


@pytest.mark.parametrize("cls", ["kickLFront", "jumpingJack"])
def test_features_up_z_on_a_rotated_clip(world, tmp_path, cls):
    """--up z on a Z-up copy of a clip gives the features of the Y-up original; read as
    Y up (the default) the copy gives other features; the up axis is provenance."""
    clip = world.clips / cls / f"SYN_a_{cls}_001.amc"
    want = read_features(world.feats / cls / f"SYN_a_{cls}_001.parquet")
    rotated = _z_up_copy(world, clip, tmp_path / "rot")
    r = run(["features", str(rotated), "-o", str(tmp_path / "z"), "--up", "z", "-q"])
    assert r.exit_code == 0, r.output
    got = read_features(tmp_path / "z" / f"{rotated.stem}.parquet")
    assert np.array_equal(got.X, want.X) and got.names == want.names
    assert got.meta["up"] == "z" and want.meta["up"] == "y"
    r = run(["features", str(rotated), "-o", str(tmp_path / "y"), "-q"])
    assert r.exit_code == 0, r.output
    assert not np.array_equal(read_features(tmp_path / "y" / f"{rotated.stem}.parquet").X,
                              want.X)
    # the up axis is part of "up to date": the same output with --up y is recomputed
    r = run(["features", str(rotated), "-o", str(tmp_path / "z"), "--up", "y"])
    assert "1 written" in r.output
    r = run(["features", str(rotated), "-o", str(tmp_path / "z"), "--up", "x"])
    assert r.exit_code == 2 and "'x' is not one of 'y', 'z'" in r.output


def test_describe_api_gives_the_info_lines(tree, tmp_path):
    """`mtanno info` prints exactly the lines of the API functions it calls."""
    from mtanno.info import describe_feature_file, describe_motion
    from mtanno.io import read_motion

    amc = tree / "a" / "walk1.amc"
    lines = describe_motion(read_motion(amc))
    assert lines[0] == f"file           {amc}" and "frames         24" in lines
    assert len(lines) == 8 + 22 and all(" <- " in x for x in lines[8:])
    assert lines[6].startswith("map made by    built-in map chosen because")
    assert run(["info", str(amc)]).output.splitlines() == lines
    run(["features", str(amc), "-o", str(tmp_path / "o")])
    ff = read_features(tmp_path / "o" / "walk1.parquet")
    lines = describe_feature_file(ff)
    assert lines[1] == "document       walk1" and lines[3].endswith("40 features")
    assert lines[4].startswith(f"frames         {ff.X.shape[1]} at 30")
    assert run(["info", str(tmp_path / "o" / "walk1.parquet")]).output.splitlines() == lines
