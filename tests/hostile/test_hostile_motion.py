"""Hostile motion files (issue 22, the IO part): numbers a header declares are bounded,
absurd or incomplete motion is refused in the reader, skeleton maps that give two joints
one node are refused, every motion error names its file, and ``features`` batches go on
past inputs that cannot be read (a name on standard input that does not exist, a FIFO in an
input folder).

Each test runs the command line on small synthetic files (mtanno's synthetic ASF/AMC, a
hand-written BVH laid out like the CMU conversion) and checks the exact behaviour: exit
code, one ``mtanno:`` line naming the file (and its line where there is one), nothing
written for the bad input, the good input of the batch written, inputs unchanged, no numpy
RuntimeWarning.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from test_bvh import CGSPEED_LIKE
from world import assert_one_line, checksums, cli, temporaries

from mtanno import synthetic
from mtanno.errors import MtannoError
from mtanno.features.store import read_features
from mtanno.io.asf import read_asf

#: Channels of the CGSPEED_LIKE hierarchy (root 6, 30 joints × 3).
N_CHANNELS = 6 + 3 * 30


def bvh_text(n_frames: int = 12, *, frames_line: str | None = None,
             frame_time: str = "0.0083333", value: str | None = None) -> str:
    """A BVH of the CMU layout (the cmu-bvh map fits it): a slowly bending pose, the root
    10 units up. ``frames_line`` replaces the 'Frames:' count, ``value`` the first
    rotation of the second frame."""
    hierarchy = CGSPEED_LIKE.split("MOTION")[0]
    rows = []
    for f in range(n_frames):
        row = ["0", "10", "0"] + [f"{(3 * f + k) % 17:.1f}" for k in range(N_CHANNELS - 3)]
        if f == 1 and value is not None:
            row[3] = value
        rows.append(" ".join(row))
    count = frames_line if frames_line is not None else str(n_frames)
    return (f"{hierarchy}MOTION\nFrames: {count}\nFrame Time: {frame_time}\n"
            + "\n".join(rows) + "\n")


def line_of(text: str, start: str) -> int:
    """1-based line of the first line of ``text`` that starts with ``start``."""
    return next(k for k, ln in enumerate(text.split("\n"), 1) if ln.startswith(start))


def no_runtime_warning(*args, input=None):
    """``cli(*args)``, failing if numpy (or anything) raised a RuntimeWarning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = cli(*args, input=input)
    bad = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert not bad, [str(w.message) for w in bad]
    assert "RuntimeWarning" not in r.output, r.output
    return r


def batch(tmp_path: Path, name: str, text: str, *, good: str = "bvh") -> tuple[Path, Path]:
    """An input folder with a good clip and the bad file ``name`` (holding ``text``);
    returns (folder, bad file)."""
    src = tmp_path / "in"
    src.mkdir(exist_ok=True)
    if good == "bvh":
        (src / "good.bvh").write_text(bvh_text())
    else:
        synthetic.write_pair(src, "good", n_frames=24)
    bad = src / name
    bad.write_text(text)
    return src, bad


def check_batch(tmp_path: Path, src: Path, bad: Path, *, line: int | None = None) -> str:
    """``features`` over ``src`` reports ``bad`` in one line (at ``line``) and exit 1,
    writes the good clip, nothing for the bad one, changes no input, leaves no temporary."""
    before = checksums(src)
    out = tmp_path / "out"
    r = no_runtime_warning("features", src, "-o", out)
    msg = assert_one_line(r, bad, codes=(1,))
    if line is not None:
        assert msg.startswith(f"mtanno: {bad}:{line}: "), msg
    assert not (out / f"{bad.stem}.parquet").exists()
    read_features(out / "good.parquet")
    assert checksums(src) == before and temporaries(tmp_path) == []
    return msg


def check_info(bad: Path, *, line: int | None = None) -> str:
    """``info`` on ``bad``: exit 2 and one line naming it (at ``line``)."""
    r = no_runtime_warning("info", bad)
    msg = assert_one_line(r, bad, codes=(2,))
    if line is not None:
        assert msg.startswith(f"mtanno: {bad}:{line}: "), msg
    return msg


# --------------------------------------------------------------------- header numbers

def test_good_bvh_reads(tmp_path):
    """The test's own BVH is a good motion file (so the refusals below are the bad part)."""
    path = tmp_path / "ok.bvh"
    path.write_text(bvh_text())
    r = no_runtime_warning("features", path, "-o", tmp_path / "out")
    assert r.exit_code == 0, r.output
    assert read_features(tmp_path / "out" / "ok.parquet").X.shape[1] == 3


@pytest.mark.parametrize("count", ["999999999999", "100000", "13"])
def test_bvh_frame_count_beyond_the_file(tmp_path, count):
    """'Frames:' is bounded by what the MOTION data can hold, before any room is made for
    it: no 589 TiB allocation (MemoryError), one line at the Frames line."""
    text = bvh_text(frames_line=count)
    src, bad = batch(tmp_path, "huge.bvh", text)
    msg = check_batch(tmp_path, src, bad, line=line_of(text, "Frames:"))
    assert f"'Frames: {count}'" in msg and "internal error" not in msg
    check_info(bad, line=line_of(text, "Frames:"))


@pytest.mark.parametrize("frame_time", ["1e300", "1e-300", "0.00001", "11", "1e-5"])
def test_bvh_frame_time_out_of_range(tmp_path, frame_time):
    """Frame Time must be within 0.1 ms … 10 s (1e300 gave ZeroDivisionError, 1e-300
    OverflowError)."""
    text = bvh_text(frame_time=frame_time)
    src, bad = batch(tmp_path, "rate.bvh", text)
    msg = check_batch(tmp_path, src, bad, line=line_of(text, "Frame Time:"))
    assert "Frame Time" in msg and "internal error" not in msg
    check_info(bad, line=line_of(text, "Frame Time:"))


@pytest.mark.parametrize("rate", ["1e300", "1e-300", "0.01", "20000"])
def test_amc_samples_per_second_out_of_range(tmp_path, rate):
    text = synthetic.amc_text(24).replace(":DEGREES", f":DEGREES\n:SAMPLES-PER-SECOND {rate}")
    src, bad = batch(tmp_path, "rate.amc", text, good="amc")
    check_batch(tmp_path, src, bad, line=line_of(text, ":SAMPLES-PER-SECOND"))
    check_info(bad, line=line_of(text, ":SAMPLES-PER-SECOND"))


def test_amc_frame_number_absurd(tmp_path):
    """A first frame number beyond 2³¹ (one beyond 2⁶³ overflowed the parse kernel's
    argument)."""
    text = synthetic.amc_text(24)
    rows = text.split("\n")
    k = rows.index("1")
    rows[k] = "99999999999999999999999"
    src, bad = batch(tmp_path, "frameno.amc", "\n".join(rows), good="amc")
    msg = check_batch(tmp_path, src, bad, line=k + 1)
    assert "frame number" in msg


# --------------------------------------------------------------------- absurd values

@pytest.mark.parametrize("value", ["1e300", "-1e300", "1e200"])
def test_bvh_absurd_channel_value(tmp_path, value):
    """A channel value whose square overflows was computed from inf with a RuntimeWarning
    (exit 0): refused at its line."""
    text = bvh_text(value=value)
    src, bad = batch(tmp_path, "absurd.bvh", text)
    data_line = line_of(text, "Frame Time:") + 2  # the second frame
    msg = check_batch(tmp_path, src, bad, line=data_line)
    assert "absurd" in msg and "channel 4" in msg
    check_info(bad, line=data_line)


def test_bvh_absurd_position_channel(tmp_path):
    text = bvh_text().replace("\n0 10 0 ", "\n0 1e250 0 ", 1)
    src, bad = batch(tmp_path, "absurd.bvh", text)
    check_batch(tmp_path, src, bad, line=line_of(text, "Frame Time:") + 1)


def test_bvh_absurd_offset(tmp_path):
    text = bvh_text().replace("OFFSET 2.3 -6.2 0", "OFFSET 2.3 -6e250 0")
    src, bad = batch(tmp_path, "offset.bvh", text)
    msg = check_batch(tmp_path, src, bad, line=line_of(text, "{ OFFSET 2.3 -6e250"))
    assert "absurd" in msg


@pytest.mark.parametrize("what", ["bone length", "units length", "direction"])
def test_asf_absurd_lengths(tmp_path, what):
    """An ASF whose lengths overflow once squared (a bone of 1e300, ':units length
    1e-300'): refused in the ASF reader, naming the ASF and its line; the AMC fails."""
    asf = synthetic.asf_text()
    if what == "bone length":
        asf = asf.replace("length 7.3", "length 7.3e300", 1)
        needle = "     length 7.3e300"
    elif what == "units length":
        asf = asf.replace("  length 0.45", "  length 1e-300")
        needle = "  length 1e-300"
    else:
        asf = asf.replace("direction 0.34 -0.94 0", "direction 0.34 -9.4e299 0", 1)
        needle = "     direction 0.34 -9.4e299 0"
    d = tmp_path / "in"
    synthetic.write_pair(d / "bad", "clip", n_frames=24)
    (d / "bad" / "synth.asf").write_text(asf)
    synthetic.write_pair(d, "good", n_frames=24)
    before = checksums(d)
    r = no_runtime_warning("features", d, "-o", tmp_path / "out")
    msg = assert_one_line(r, d / "bad" / "synth.asf", codes=(1,))
    assert msg.startswith(f"mtanno: {d / 'bad' / 'synth.asf'}:{line_of(asf, needle)}: "), msg
    read_features(tmp_path / "out" / "good.parquet")
    assert not (tmp_path / "out" / "bad" / "clip.parquet").exists()
    assert checksums(d) == before


def test_amc_absurd_root_translation(tmp_path):
    text = synthetic.amc_text(24)
    rows = text.split("\n")
    k = next(i for i, ln in enumerate(rows) if ln.startswith("root ") and i > 10)
    vals = rows[k].split()
    vals[1] = "1e250"
    rows[k] = " ".join(vals)
    src, bad = batch(tmp_path, "far.amc", "\n".join(rows), good="amc")
    msg = check_batch(tmp_path, src, bad, line=k + 1)
    assert "absurd" in msg and "'root'" in msg


def test_amc_absurd_rotation(tmp_path):
    text = synthetic.amc_text(24)
    rows = text.split("\n")
    k = next(i for i, ln in enumerate(rows) if ln.startswith("ltibia "))
    rows[k] = "ltibia 1e250"
    src, bad = batch(tmp_path, "spin.amc", "\n".join(rows), good="amc")
    msg = check_batch(tmp_path, src, bad, line=k + 1)
    assert "'ltibia'" in msg


# --------------------------------------------------------------------- incomplete motion

def _without_bone(text: str, bone: str, *, every: bool = True) -> str:
    rows = text.split("\n")
    if every:
        return "\n".join(r for r in rows if not r.startswith(bone + " "))
    k = next(i for i, r in enumerate(rows) if r.startswith(bone + " "))
    return "\n".join(rows[:k] + rows[k + 1:])


@pytest.mark.parametrize("bone", ["rtibia", "lhumerus", "lowerback"])
def test_amc_bone_missing_in_every_frame(tmp_path, bone):
    """A bone with rotation dofs that the skeleton map needs, absent from every frame: its
    rotation would silently be zero (features wrong on up to every frame). Refused, naming
    the AMC and its first frame."""
    text = _without_bone(synthetic.amc_text(24), bone)
    src, bad = batch(tmp_path, "nobone.amc", text, good="amc")
    msg = check_batch(tmp_path, src, bad, line=line_of(text, "1"))
    assert f"bone '{bone}'" in msg and "no values in any frame" in msg
    check_info(bad, line=line_of(text, "1"))


def test_amc_bone_the_map_does_not_need_may_be_absent(tmp_path):
    """A bone below every mapped joint (the toes' bone ends at 'ltoes': ltoes itself is
    needed, but nothing needs a bone hanging from a finger) is no reason to refuse: only
    bones the skeleton map needs are checked. Here: a skeleton with an extra finger bone
    that the AMC never gives."""
    asf = synthetic.asf_text().replace(
        "  end\n:hierarchy",
        "  end\n  begin\n     id 99\n     name lthumb\n     direction 1 0 0\n     length 1\n"
        "     axis 0 0 0  XYZ\n    dof rx rz\n  end\n:hierarchy").replace(
        "    lhand lfingers", "    lhand lfingers lthumb")
    d = tmp_path / "in"
    synthetic.write_pair(d, "clip", n_frames=24)
    (d / "synth.asf").write_text(asf)
    assert "lthumb" in (d / "synth.asf").read_text()
    r = no_runtime_warning("features", d, "-o", tmp_path / "out")
    assert r.exit_code == 0, r.output


def test_real_amc_files_still_read(tmp_path, data_dir):
    """Every real CMU/HDM05 AMC gives all its bones (so the check refuses none): one clip
    of each set through ``features``."""
    d = tmp_path / "in"
    d.mkdir()
    for asf, amc in [(data_dir / "cmu_02" / "02.asf", data_dir / "cmu_02" / "02_01.amc"),
                     (data_dir / "hdm05_cut" / "HDM_bk.asf", data_dir / "hdm05_cut" /
                      "hopBothLegs1hops" / "HDM_bk_hopBothLegs1hops_020_120.amc")]:
        shutil.copyfile(asf, d / asf.name)
        shutil.copyfile(amc, d / amc.name)
    r = no_runtime_warning("features", d, "-o", tmp_path / "out")
    assert r.exit_code == 0, r.output
    assert len(list((tmp_path / "out").glob("*.parquet"))) == 2


# --------------------------------------------------------------------- skeleton maps

def test_skeleton_map_two_joints_one_node(tmp_path):
    """A map giving both knees one bone was accepted (the features between them void):
    refused in the map reader, naming the map file, the joints and the node."""
    from mtanno.io.rigs import builtin_dir

    text = (builtin_dir() / "cmu-asf.toml").read_text()
    smap = tmp_path / "knees.toml"
    smap.write_text(text.replace('name = "cmu-asf"', 'name = "knees"')
                    .replace('rknee = "rfemur"', 'rknee = "lfemur"'))
    amc = synthetic.write_pair(tmp_path / "in", "clip", n_frames=24)
    before = checksums(tmp_path / "in", smap)
    msg = assert_one_line(no_runtime_warning("info", amc, "--skeleton", smap), smap,
                          codes=(2,))
    assert "'lknee'" in msg and "'rknee'" in msg and "'lfemur'" in msg
    r = cli("features", amc, "-o", tmp_path / "out", "--skeleton", smap)
    line = assert_one_line(r, smap, codes=(1,))
    assert "'lfemur'" in line
    assert checksums(tmp_path / "in", smap) == before


@pytest.mark.parametrize("heading", ['"x"', '{ node = "root", axis = [1, 2] }',
                                     '{ node = "root", axis = ["a", 0, 0] }',
                                     '{ node = "root", axis = [0, 0, 0] }',
                                     '{ node = 3, axis = [1, 0, 0] }'])
def test_skeleton_map_bad_heading(tmp_path, heading):
    """A heading that is not a table of a node and three numbers is one line naming the
    map (a string or a word in the axis gave a traceback)."""
    from mtanno.io.rigs import builtin_dir

    text = (builtin_dir() / "cmu-asf.toml").read_text()
    text = re.sub(r"(?m)^heading = .*$", f"heading = {heading}", text)
    smap = tmp_path / "h.toml"
    smap.write_text(text.replace('name = "cmu-asf"', 'name = "h"'))
    amc = synthetic.write_pair(tmp_path / "in", "clip", n_frames=24)
    msg = assert_one_line(no_runtime_warning("info", amc, "--skeleton", smap), smap,
                          codes=(2,))
    assert "heading" in msg


# --------------------------------------------------------------------- rigs that are not humanoid

@pytest.mark.parametrize("kind", ["quadruped", "chain", "hand", "legs-only", "short-spine"])
def test_rig_that_is_not_humanoid(tmp_path, kind):
    """A BVH rig whose names say nothing and whose hierarchy is not a humanoid's (issue 31,
    finding 5): one line naming the file and saying why, in a batch that goes on, in
    ``info`` and in ``skeleton guess`` (which writes nothing)."""
    from test_rig_topology import NOT_HUMANOID, not_humanoid_file

    src, _ = batch(tmp_path, "placeholder.bvh", "")
    (src / "placeholder.bvh").unlink()
    bad = not_humanoid_file(src, kind)
    why = NOT_HUMANOID[kind][1]
    for msg in (check_batch(tmp_path, src, bad), check_info(bad)):
        assert f"mapped automatically: from its hierarchy, {why}; the joint names " in msg
        assert msg.endswith("; pass --skeleton MAP.toml (docs/formats.md)")
    out = tmp_path / "map.toml"
    msg = assert_one_line(no_runtime_warning("skeleton", "guess", bad, "-o", out), bad,
                          codes=(2,))
    assert why in msg and not out.exists() and temporaries(tmp_path) == []


def test_bvh_with_two_roots(tmp_path):
    """Two skeletons in one file (two ROOT blocks): one line at the second ROOT."""
    from test_rig_topology import humanoid, write_bvh

    one = write_bvh(tmp_path / "one.bvh", humanoid()).read_text()
    head, motion = one.split("MOTION\n")
    rows = motion.splitlines()
    text = (head + head.replace("HIERARCHY\n", "") + "MOTION\n" + "\n".join(
        rows[:2] + [f"{r} {r}" for r in rows[2:]]) + "\n")
    src, bad = batch(tmp_path, "two.bvh", text)
    line = head.count("\n") + 1
    for msg in (check_batch(tmp_path, src, bad, line=line), check_info(bad, line=line)):
        assert "a second ROOT: only one skeleton per file is supported" in msg
    msg = assert_one_line(no_runtime_warning("skeleton", "guess", bad), bad, codes=(2,))
    assert "a second ROOT" in msg


# --------------------------------------------------------------------- messages name the file

def test_motion_without_frames_is_named_in_a_batch(tmp_path):
    """'motion has no frames' named no file: in a batch the user could not tell which."""
    text = bvh_text(0)
    src, bad = batch(tmp_path, "empty.bvh", text)
    msg = check_batch(tmp_path, src, bad)
    assert "no frames" in msg


def test_feature_errors_name_the_motion():
    """Errors of the feature computation on a read motion name its file (the API path)."""
    from mtanno.features.extract import features_from_motion
    from mtanno.io.skeleton import Motion

    rig = synthetic_rig()
    for positions, what in [(np.zeros((0, rig.n_nodes, 3)), "no frames"),
                            (np.full((3, rig.n_nodes, 3), np.nan), "NaN or infinite")]:
        m = Motion(rig=rig, positions=positions, heading=np.ones((len(positions), 3)),
                   fps=120.0, source="walk.amc")
        with pytest.raises(MtannoError, match=what) as e:
            features_from_motion(m)
        assert str(e.value).startswith("walk.amc: "), str(e.value)


def synthetic_rig():
    """The rig of mtanno's synthetic ASF."""
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "s.asf"
        p.write_text(synthetic.asf_text())
        return read_asf(p).rig


def test_folder_named_like_a_motion_file(tmp_path):
    """A folder named x.amc is a folder: searched (its clips written), and when it holds no
    motion file the message names it."""
    empty = tmp_path / "x.amc"
    empty.mkdir()
    r = cli("features", empty, "-o", tmp_path / "out")
    line = assert_one_line(r, empty, codes=(2,))
    assert "folder" in line
    full = tmp_path / "y.bvh"
    synthetic.write_pair(full, "clip", n_frames=24)
    r = cli("features", full, "-o", tmp_path / "out2")
    assert r.exit_code == 0, r.output
    read_features(tmp_path / "out2" / "clip.parquet")


@pytest.mark.parametrize("how", ["argument", "stdin"])
def test_an_input_that_yields_nothing_is_a_failed_input(tmp_path, how):
    """Issue 31 (7): beside a good input, an empty folder named like a motion file
    (``empty.amc/``) or any empty folder was skipped without a word (exit 0). Each is a
    failed input: one line naming it, counted in "failed", exit 1, the good one written."""
    good = synthetic.write_pair(tmp_path / "in", "good", n_frames=24)
    for name, what in (("empty.amc", "a folder (named like a motion file) holding no"),
                       ("empty", "no .amc, .bvh or .c3d files in this folder or below")):
        empty = tmp_path / name
        empty.mkdir()
        out = tmp_path / f"out-{name}"
        r = (cli("features", good, empty, "-o", out) if how == "argument" else
             cli("features", "-", "-o", out, input=f"{good}\n{empty}\n"))
        line = assert_one_line(r, empty, codes=(1,))
        assert what in line and "1 written" in r.output and "1 failed" in r.output, r.output
        read_features(out / "good.parquet")
        assert sorted(p.name for p in out.iterdir()) == ["good.parquet"]


def test_an_output_name_too_long_fails_alone(tmp_path):
    """Issue 31: one motion file whose output name is longer than a folder entry may be
    (NAME_MAX, 255 bytes: ``<250 characters>.parquet``) stopped the whole features batch
    (exit 2, nothing written). It is one failed input now, the others written; and a name
    just short enough is written, although its temporary name is longer (cut to fit)."""
    src = tmp_path / "in"
    synthetic.write_pair(src, "good", n_frames=24)
    too_long, near = src / ("a" * 250 + ".amc"), src / ("b" * 240 + ".amc")
    for p in (too_long, near):
        p.write_text(synthetic.amc_text(24, 1))
    out = tmp_path / "out"
    for _ in range(2):  # the rerun: the others up to date, the long one fails again
        r = cli("features", src, "-o", out)
        line = assert_one_line(r, out / ("a" * 250 + ".parquet"), codes=(1,))
        assert "File name too long" in line, line
        assert "1 failed" in r.output
    read_features(out / "good.parquet")
    read_features(out / ("b" * 240 + ".parquet"))
    assert "2 up to date" in r.output and temporaries(out) == []


# --------------------------------------------------------------------- batch inputs

def test_missing_name_on_stdin_is_reported_and_the_batch_goes_on(tmp_path):
    good = synthetic.write_pair(tmp_path / "in", "good", n_frames=24)
    missing = tmp_path / "in" / "gone.amc"
    other = tmp_path / "in" / "notes.txt"
    other.write_text("x\n")
    out = tmp_path / "out"
    r = cli("features", "-", "-o", out, input=f"{missing}\n{good}\n")
    line = assert_one_line(r, missing, codes=(1,))
    assert "not found" in line
    read_features(out / "good.parquet")
    r = cli("features", "-", "-o", out, input=f"{other}\n{good}\n")
    line = assert_one_line(r, other, codes=(1,))
    assert "unknown motion file type" in line


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_fifo_in_an_input_folder_is_a_failed_input(tmp_path):
    """A FIFO named like a motion file in an input folder was skipped (0 failed): it is a
    failed input, reported in one line, never opened (opening it would block)."""
    src = tmp_path / "in"
    synthetic.write_pair(src, "good", n_frames=24)
    fifo = src / "pipe.amc"
    os.mkfifo(fifo)
    r = cli("features", src, "-o", tmp_path / "out")
    line = assert_one_line(r, fifo, codes=(1,))
    assert "FIFO" in line
    read_features(tmp_path / "out" / "good.parquet")
    assert "1 failed" in r.output
    # named on the command line it is a usage error, still never opened
    r = cli("features", fifo, "-o", tmp_path / "out3")
    assert_one_line(r, fifo, codes=(2,))
    assert not (tmp_path / "out3").exists()


def test_empty_output_name_is_refused(tmp_path, monkeypatch):
    """``features -o ''`` wrote into the current folder."""
    amc = synthetic.write_pair(tmp_path / "in", "good", n_frames=24)
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    r = cli("features", amc, "-o", "")
    assert r.exit_code == 2 and "Traceback" not in r.output, r.output
    assert [ln for ln in r.output.splitlines() if ln.startswith("mtanno:")] == [
        r.output.strip()]
    assert list(cwd.iterdir()) == []


def test_unknown_file_type_is_exit_2_in_features_as_in_info(tmp_path):
    c3d = tmp_path / "take.fbx"
    c3d.write_bytes(b"\x02\x50" + bytes(510))
    for args in (["info", c3d], ["features", c3d, "-o", tmp_path / "out"]):
        line = assert_one_line(cli(*args), c3d, codes=(2,))
        assert "unknown motion file type '.fbx'" in line
    assert not (tmp_path / "out").exists()


def test_a_run_that_writes_nothing_leaves_no_new_folder(tmp_path):
    """Every input failed: the output folder (and parents) the run made are removed."""
    src, bad = batch(tmp_path, "huge.bvh", bvh_text(frames_line="999999999999"))
    (src / "good.bvh").unlink()
    out = tmp_path / "new" / "out"
    r = cli("features", src, "-o", out)
    assert_one_line(r, bad, codes=(1,))
    assert not (tmp_path / "new").exists()
    # an existing output folder is kept
    existing = tmp_path / "existing"
    existing.mkdir()
    r = cli("features", src, "-o", existing)
    assert r.exit_code == 1 and existing.is_dir() and list(existing.iterdir()) == []
