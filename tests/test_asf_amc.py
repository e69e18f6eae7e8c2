"""ASF/AMC reading: layout, kinematics against a naive version, and every bad-input path."""

from __future__ import annotations

import numpy as np
import pytest
from naive import fk_naive

from mtanno import synthetic as synth
from mtanno.errors import MtannoError
from mtanno.io import find_asf, read_channels, read_motion
from mtanno.io.asf import read_asf
from mtanno.io.skeleton import _fk_kernel, forward_kinematics


@pytest.fixture
def pair(tmp_path):
    return synth.write_pair(tmp_path, n_frames=30)


def test_fk_matches_naive(pair):
    rig, ch = read_channels(pair)
    P, _ = forward_kinematics(rig, ch.angles, ch.trans, ch.has_trans)
    assert np.allclose(P, fk_naive(rig, ch), atol=1e-9)


def test_fk_kernel_pure_python(pair):
    rig, ch = read_channels(pair)
    P, H = forward_kinematics(rig, ch.angles, ch.trans, ch.has_trans)
    P2, H2 = np.empty_like(P), np.empty_like(H)
    _fk_kernel.py_func(ch.angles, ch.trans, ch.has_trans, rig.parents, rig.offsets, rig.axes,
                       rig.pre, rig.post, rig.end_point, 0, np.array([1.0, 0, 0]), P2, H2)
    assert np.allclose(P, P2) and np.allclose(H, H2)


def test_units_and_bone_lengths_constant(pair):
    skel = read_asf(pair.parent / "synth.asf")
    m = read_motion(pair)
    rig = m.rig
    for j in range(1, rig.n_nodes):
        d = np.linalg.norm(m.positions[:, j] - m.positions[:, rig.parents[j]], axis=1)
        want = np.linalg.norm(rig.offsets[j])
        assert np.allclose(d, want, atol=1e-9)
    # lengths are file units / 0.45 * 2.54 cm
    k = rig.index("lfemur")
    assert np.isclose(np.linalg.norm(rig.offsets[k]), 7.3 / 0.45 * 2.54)
    assert skel.dofs["lclavicle"] == ["ry", "rz"]


def test_crlf_and_latin1(tmp_path):
    asf = tmp_path / "synth.asf"
    asf.write_bytes(synth.asf_text().replace("\n", "\r\n").encode())
    amc = tmp_path / "synth_crlf.amc"
    text = synth.amc_text(12, header="#!OML:ASF X:\\f\xfcr Bonn\\synth.ASF\n")
    amc.write_bytes(text.replace("\n", "\r\n").encode("latin-1"))
    plain = synth.write_pair(tmp_path / "plain", n_frames=12)
    assert np.array_equal(read_motion(amc).positions, read_motion(plain).positions)


def test_samples_per_second_header(tmp_path):
    synth.write_pair(tmp_path, n_frames=5)
    amc = tmp_path / "synth_60.amc"
    amc.write_text(":SAMPLES-PER-SECOND 60\n" + synth.amc_text(5))
    assert read_motion(amc).fps == 60.0
    assert read_motion(tmp_path / "synth_walk.amc").fps == 120.0


def test_find_asf_rules(tmp_path):
    (tmp_path / "HDM_bd.asf").write_text("x")
    (tmp_path / "HDM_bk.asf").write_text("x")
    sub = tmp_path / "squat"
    sub.mkdir()
    (sub / "HDM_bd_squat_001_120.amc").write_text("x")
    assert find_asf(sub / "HDM_bd_squat_001_120.amc") == tmp_path / "HDM_bd.asf"
    (sub / "HDM_tr_squat_001_120.amc").write_text("x")
    with pytest.raises(MtannoError, match="several ASF files"):
        find_asf(sub / "HDM_tr_squat_001_120.amc")
    only = tmp_path / "only"
    only.mkdir()
    (only / "skeleton.asf").write_text("x")
    (only / "02_05.amc").write_text("x")
    assert find_asf(only / "02_05.amc") == only / "skeleton.asf"
    # the longest matching stem wins: 02.asf vs 02_0.asf for 02_05
    (only / "02.asf").write_text("x")
    (only / "02_0.asf").write_text("x")
    assert find_asf(only / "02_05.amc") == only / "02_0.asf"


def test_missing_asf(tmp_path):
    amc = tmp_path / "deep" / "a.amc"
    amc.parent.mkdir()
    amc.write_text(synth.amc_text(3))
    # tmp_path has no ASF anywhere above (pytest's tmp dirs hold none)
    with pytest.raises(MtannoError, match="no ASF skeleton found") as e:
        read_motion(amc)
    assert str(amc) in str(e.value)


def _amc_lines(n=4):
    return synth.amc_text(n).splitlines()


def _bad(tmp_path, lines, name="bad.amc"):
    (tmp_path / "synth.asf").write_text(synth.asf_text())
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def _line_of(lines, prefix, occurrence=1):
    hits = [i + 1 for i, s in enumerate(lines) if s.startswith(prefix)]
    return hits[occurrence - 1]


def test_amc_too_few_values(tmp_path):
    lines = _amc_lines()
    n = _line_of(lines, "lfemur ", 2)
    lines[n - 1] = " ".join(lines[n - 1].split()[:-1])
    p = _bad(tmp_path, lines)
    with pytest.raises(MtannoError) as e:
        read_motion(p)
    assert str(e.value).startswith(f"{p}:{n}: too few values for bone 'lfemur'")


def test_amc_too_many_values(tmp_path):
    lines = _amc_lines()
    n = _line_of(lines, "rtibia ", 3)
    lines[n - 1] += " 1.0"
    p = _bad(tmp_path, lines)
    with pytest.raises(MtannoError) as e:
        read_motion(p)
    assert str(e.value).startswith(f"{p}:{n}: too many values for bone 'rtibia'")


def test_amc_unknown_bone(tmp_path):
    lines = _amc_lines()
    n = _line_of(lines, "head ", 2)
    lines[n - 1] = lines[n - 1].replace("head", "tail", 1)
    p = _bad(tmp_path, lines)
    with pytest.raises(MtannoError) as e:
        read_motion(p)
    assert str(e.value).startswith(f"{p}:{n}: unknown bone 'tail'")


def test_amc_nan_value(tmp_path):
    lines = _amc_lines()
    n = _line_of(lines, "ltibia ", 4)
    lines[n - 1] = "ltibia nan"
    p = _bad(tmp_path, lines)
    with pytest.raises(MtannoError) as e:
        read_motion(p)
    assert str(e.value).startswith(f"{p}:{n}: NaN or infinite value for bone 'ltibia'")


def test_amc_not_a_number(tmp_path):
    lines = _amc_lines()
    n = _line_of(lines, "ltibia ", 2)
    lines[n - 1] = "ltibia 1.2.3"
    p = _bad(tmp_path, lines)
    with pytest.raises(MtannoError, match=rf":{n}: value for bone 'ltibia' is not a number"):
        read_motion(p)


def test_amc_truncated(tmp_path):
    lines = _amc_lines(5)
    n = _line_of(lines, "rhumerus ", 5)
    p = _bad(tmp_path, lines[: n - 1])  # cut inside frame 5, before rhumerus
    with pytest.raises(MtannoError) as e:
        read_motion(p)
    assert str(e.value).startswith(f"{p}:{n - 1}: frame 5 ends without values for bone")
    assert "truncated" in str(e.value)


def test_amc_truncated_mid_line(tmp_path):
    lines = _amc_lines(5)
    last = len(lines)
    lines[-1] = lines[-1].split()[0]  # bone name with no values
    p = _bad(tmp_path, lines)
    with pytest.raises(MtannoError, match=rf":{last}: too few values"):
        read_motion(p)


def test_amc_frame_number_gap(tmp_path):
    lines = _amc_lines(4)
    n = lines.index("3")
    lines[n] = "7"
    p = _bad(tmp_path, lines)
    with pytest.raises(MtannoError, match=rf":{n + 1}: frame number 7 where 3 was expected"):
        read_motion(p)


@pytest.mark.parametrize("content,msg", [(b"", "file is empty"), (b"  \n\n", "file is empty"),
                                         (b"\x00\x01\x02binary", "binary data")])
def test_amc_empty_or_binary(tmp_path, content, msg):
    p = _bad(tmp_path, [])
    p.write_bytes(content)
    with pytest.raises(MtannoError, match=msg) as e:
        read_motion(p)
    assert str(e.value).startswith(f"{p}:1:")


@pytest.mark.parametrize("content,msg", [(b"", "file is empty"), (b"\x00PK\x03", "binary data"),
                                         (b":units\n  length 0.45\n", "no ':bonedata'")])
def test_asf_empty_binary_or_not_asf(tmp_path, content, msg):
    amc = synth.write_pair(tmp_path, n_frames=3)
    (tmp_path / "synth.asf").write_bytes(content)
    with pytest.raises(MtannoError, match=msg) as e:
        read_motion(amc)
    assert str(e.value).startswith(f"{tmp_path / 'synth.asf'}:")


def test_asf_bad_lines(tmp_path):
    text = synth.asf_text().replace("direction 0.34 -0.94 0\n", "direction 0.34 -0.94\n", 1)
    amc = synth.write_pair(tmp_path, n_frames=3)
    asf = tmp_path / "synth.asf"
    asf.write_text(text)
    n = next(i + 1 for i, s in enumerate(text.splitlines()) if s.strip() == "direction 0.34 -0.94")
    with pytest.raises(MtannoError, match=rf"synth.asf:{n}: 'direction' needs 3 numbers"):
        read_motion(amc)
    asf.write_text(synth.asf_text().replace("lfemur ltibia", "lfemur nobone"))
    with pytest.raises(MtannoError, match="hierarchy names unknown bone 'nobone'"):
        read_motion(amc)


def test_unknown_suffix(tmp_path):
    p = tmp_path / "x.fbx"
    p.write_bytes(b"abc")
    with pytest.raises(MtannoError, match="unknown motion file type '.fbx'"):
        read_motion(p)


def test_amc_room_for_frames_from_earlier_files(tmp_path):
    """The parser sizes its arrays from the frames of earlier files of the same skeleton;
    a file of much shorter frames (more frames for its size) is read again with room for
    all, and reads as it does on its own."""
    from mtanno.io.amc import read_amc
    from mtanno.io.rigmotion import _cached_asf

    long_ = synth.write_pair(tmp_path, stem="long", n_frames=20)
    rounded = [ln if ln.isdigit() or ln.startswith((":", "#")) else
               ln.split()[0] + " " + " ".join(str(round(float(v))) for v in ln.split()[1:])
               for ln in synth.amc_text(400).splitlines()]
    short = tmp_path / "short.amc"
    short.write_text("\n".join(rounded) + "\n")
    skel = _cached_asf(tmp_path / "synth.asf")
    read_amc(long_, skel)  # the skeleton has seen 20 frames of long numbers
    ch = read_amc(short, skel)
    alone = read_amc(short, read_asf(tmp_path / "synth.asf"))
    assert ch.n_frames == alone.n_frames == 400
    assert np.array_equal(ch.angles, alone.angles) and np.array_equal(ch.trans, alone.trans)
