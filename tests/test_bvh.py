"""BVH reader, forward kinematics on BVH rigs and the BVH skeleton maps (docs/method.md §1,
docs/method/features.md §0 and §1.5)."""

from __future__ import annotations

import importlib.util
import re
import sys
import tarfile
from pathlib import Path

import numpy as np
import pytest

from mtanno.errors import MtannoError
from mtanno.io import canonical_positions, read_motion
from mtanno.io.bvh import frame_rate_from_frame_time, read_bvh
from mtanno.io.rigs import CANONICAL_JOINTS, find_map, load_map
from mtanno.io.skeleton import euler_matrix, forward_kinematics

try:
    from data_cache import bandai_clips, unpack_archive
except ImportError:  # pragma: no cover - rootdir-relative import mode
    from tests.data_cache import bandai_clips, unpack_archive

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
SKELETONS = REPO / "mtanno" / "skeletons"


# --------------------------------------------------------------------------------------
# (a) a hand-written BVH with positions worked out by hand
# --------------------------------------------------------------------------------------

# Hips: 6 channels (Z Y X); Chest: 3 channels, order X Y Z; Arm: 3 channels, order Y Z X;
# Leg: 6 channels whose positions replace its offset.
SMALL_HIERARCHY = """\
HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Chest
  {
    OFFSET 0 10 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    JOINT Arm
    {
      OFFSET 5 0 0
      CHANNELS 3 Yrotation Zrotation Xrotation
      End Site
      {
        OFFSET 4 0 0
      }
    }
  }
  JOINT Leg
  {
    OFFSET 0 -2 0
    CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 -8 0
    }
  }
}
"""
SMALL_MOTION = """\
MOTION
Frames: 2
Frame Time: 0.0166667
1 2 3 90 0 0  0 0 0  0 0 0  0 -2 0 0 0 0
0 0 0 0 0 0  90 90 0  0 90 0  1 -3 0 90 0 0
"""
SMALL_BVH = SMALL_HIERARCHY + SMALL_MOTION

# Frame 1: G_Hips = Rz(90) (x→y, y→−x), everything else unrotated.
# Frame 2: Hips at the origin unrotated; L_Chest = Rx(90)·Ry(90) (X Y Z order), so the
# Arm offset (5,0,0) → Ry: (0,0,−5) → Rx: (0,5,0); L_Arm = Rz(90) (Y Z X order, only Z
# nonzero); the arm end (4,0,0) → Rz: (0,4,0) → Ry: (0,4,0) → Rx: (0,0,4). The Leg's
# position channels (1,−3,0) replace its offset; L_Leg = Rz(90) turns (0,−8,0) into (8,0,0).
SMALL_EXPECTED = {
    "Hips": [(1, 2, 3), (0, 0, 0)],
    "Chest": [(-9, 2, 3), (0, 10, 0)],
    "Arm": [(-9, 7, 3), (0, 15, 0)],
    "Arm_End": [(-9, 11, 3), (0, 15, 4)],
    "Leg": [(3, 2, 3), (1, -3, 0)],
    "Leg_End": [(11, 2, 3), (9, -3, 0)],
}


def _write(tmp_path: Path, text: str | bytes, name: str = "clip.bvh") -> Path:
    p = tmp_path / name
    if isinstance(text, str):
        text = text.encode("latin-1")
    p.write_bytes(text)
    return p


def _positions(path: Path, **kw) -> tuple[list[str], np.ndarray]:
    rig, ch = read_bvh(path)
    pos, _ = forward_kinematics(rig, ch.angles, ch.trans, ch.has_trans, **kw)
    return rig.names, pos


def test_small_bvh_rig_layout(tmp_path):
    rig, ch = read_bvh(_write(tmp_path, SMALL_BVH))
    assert rig.kind == "bvh" and rig.end_point is False
    assert rig.names == ["Hips", "Chest", "Arm", "Arm_End", "Leg", "Leg_End"]
    assert rig.parents.tolist() == [-1, 0, 1, 2, 0, 4]
    np.testing.assert_array_equal(rig.offsets[3], [4, 0, 0])
    # axes in the order the CHANNELS line lists the rotations
    assert rig.axes[0].tolist() == [2, 1, 0]   # Z Y X
    assert rig.axes[1].tolist() == [0, 1, 2]   # X Y Z
    assert rig.axes[2].tolist() == [1, 2, 0]   # Y Z X
    assert rig.axes[4].tolist() == [2, 0, 1]   # Z X Y
    np.testing.assert_array_equal(rig.pre, np.tile(np.eye(3), (6, 1, 1)))
    np.testing.assert_array_equal(rig.post, rig.pre)
    assert ch.has_trans.tolist() == [True, False, False, False, True, False]
    assert ch.n_frames == 2 and ch.fps == 60.0
    np.testing.assert_allclose(ch.angles[1, 1], np.deg2rad([90, 90, 0]))
    np.testing.assert_allclose(ch.angles[1, 2], np.deg2rad([0, 90, 0]))  # Y=0, Z=90, X=0
    np.testing.assert_array_equal(ch.trans[1, 4], [1, -3, 0])
    np.testing.assert_array_equal(ch.trans[:, 1], [[0, 10, 0]] * 2)  # no channels: offset


@pytest.mark.parametrize("variant", ["lf", "crlf", "tabs", "latin1", "cr"])
def test_small_bvh_positions_by_hand(tmp_path, variant):
    text = SMALL_BVH
    if variant == "crlf":
        text = text.replace("\n", "\r\n")
    elif variant == "cr":
        text = text.replace("\n", "\r")
    elif variant == "tabs":
        text = re.sub(r"(?m)^ +", lambda m: "\t" * len(m.group()), text).replace(" ", "\t ")
    elif variant == "latin1":
        text = text.replace("Chest", "Brust_für")
    names, pos = _positions(_write(tmp_path, text))
    for name, expected in SMALL_EXPECTED.items():
        name = name.replace("Chest", "Brust_für") if variant == "latin1" else name
        np.testing.assert_allclose(pos[:, names.index(name)], expected, atol=1e-12,
                                   err_msg=name)


def test_small_bvh_through_read_motion(tmp_path):
    smap = tmp_path / "tiny.toml"
    smap.write_text('name = "tiny"\nformat = "bvh"\nheading = { node = "Hips", axis = '
                    '[1.0, 0.0, 0.0] }\n[joints]\nroot = "Hips"\nlwrist = "Arm_End"\n')
    m = read_motion(_write(tmp_path, SMALL_BVH), skeleton=smap)
    assert m.fps == 60.0 and m.smap.name == "tiny"
    np.testing.assert_allclose(m.positions[:, m.rig.index("Arm_End")],
                               SMALL_EXPECTED["Arm_End"], atol=1e-12)
    np.testing.assert_allclose(m.heading, [(0, 1, 0), (1, 0, 0)], atol=1e-12)  # Rz(90)·x


def test_partial_channels(tmp_path):
    """1 rotation channel, 2 position channels: the rest are zero angles / the offset."""
    text = """HIERARCHY
ROOT R
{
  OFFSET 7 8 9
  CHANNELS 2 Zposition Xposition
  JOINT A
  {
    OFFSET 1 0 0
    CHANNELS 1 Yrotation
    End Site
    {
      OFFSET 2 0 0
    }
  }
}
MOTION
Frames: 1
Frame Time: 0.04
-1 5 90
"""
    rig, ch = read_bvh(_write(tmp_path, text))
    assert ch.fps == 25.0
    np.testing.assert_array_equal(ch.trans[0, 0], [5, 8, -1])
    assert rig.axes[1][0] == 1 and sorted(rig.axes[1].tolist()) == [0, 1, 2]
    names, pos = _positions(_write(tmp_path, text))
    np.testing.assert_allclose(pos[0], [[5, 8, -1], [6, 8, -1], [6, 8, -3]], atol=1e-12)


# --------------------------------------------------------------------------------------
# (c) bad input: MtannoError "path:line: ..."
# --------------------------------------------------------------------------------------

def _line_of(text: str, needle: str, nth: int = 0) -> int:
    lines = text.split("\n")
    hits = [k + 1 for k, line in enumerate(lines) if needle in line]
    return hits[nth]


def _bad_cases() -> list[tuple[str, str | bytes, int, str]]:
    """(id, file content, expected 1-based line, words expected in the message)."""
    good = SMALL_BVH
    motion_line = _line_of(good, "MOTION")
    frames_line = motion_line + 1
    row1, row2 = frames_line + 2, frames_line + 3
    rows = good.split("\n")

    def with_row(k: int, new: str) -> str:
        r = list(rows)
        r[k - 1] = new
        return "\n".join(r)

    return [
        ("row-too-few", with_row(row2, "0 0 0 0 0 0 90 90 0 0 90 0 1 -3 0 90 0"), row2,
         "too few"),
        ("row-too-many", with_row(row1, rows[row1 - 1] + " 5"), row1, "too many"),
        ("frames-more-than-rows", good.replace("Frames: 2", "Frames: 3"), frames_line,
         "Frames"),
        ("frames-fewer-than-rows", good.replace("Frames: 2", "Frames: 1"), frames_line,
         "Frames"),
        ("extra-row", good + "1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18\n", frames_line,
         "Frames"),
        ("non-numeric", with_row(row2, rows[row2 - 1].replace("90 90", "90 abc")), row2,
         "abc"),
        ("comma-decimal", with_row(row1, rows[row1 - 1].replace("1 2 3", "1,5 2 3")), row1,
         "1,5"),
        ("underscore", with_row(row2, rows[row2 - 1].replace("90 90", "90 9_0")), row2,
         "9_0"),
        ("nan", with_row(row2, rows[row2 - 1].replace("1 -3 0", "1 nan 0")), row2, "nan"),
        ("inf", with_row(row1, rows[row1 - 1].replace("0 -2 0", "0 -inf 0")), row1, "inf"),
        ("missing-hierarchy", good.replace("HIERARCHY\n", ""), 1, "HIERARCHY"),
        ("missing-motion", SMALL_HIERARCHY, SMALL_HIERARCHY.count("\n"), "MOTION"),
        ("extra-close-brace", good.replace("  }\n  JOINT Leg", "  }\n  }\n  JOINT Leg"),
         _line_of(good, "JOINT Leg") + 1, "brace"),
        ("extra-close-brace-at-end", good.replace("}\nMOTION", "}\n}\nMOTION"),
         motion_line, "brace"),
        ("missing-close-brace", good.replace("      }\n    }\n  }\n", "      }\n    }\n"),
         motion_line - 1, "never closed"),
        ("empty", "", 1, "empty"),
        ("blank", "\n  \n\n", 1, "empty"),
        ("nul-bytes", good.encode().replace(b"OFFSET 5 0 0", b"OFFSET 5\x00\x00 0"),
         _line_of(good, "OFFSET 5 0 0"), "binary"),
        ("gzip", b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03\xad\x92\xcbn\xc3 \x10", 1,
         "binary"),
        ("bad-channel", good.replace("Yrotation Zrotation Xrotation", "Yrotation Zrot Xrotation"),
         _line_of(good, "Yrotation Zrotation Xrotation"), "Zrot"),
        ("channel-count", good.replace("CHANNELS 3 Xrotation", "CHANNELS 4 Xrotation"),
         _line_of(good, "CHANNELS 3 Xrotation"), "declares 4"),
        ("bad-offset", good.replace("OFFSET 0 10 0", "OFFSET 0 ten 0"),
         _line_of(good, "OFFSET 0 10 0"), "ten"),
        ("no-frame-time", good.replace("Frame Time: 0.0166667\n", ""), frames_line + 1,
         "Frame Time"),
        ("zero-frame-time", good.replace("0.0166667", "0"), frames_line + 1, "Frame Time"),
        ("bad-frames", good.replace("Frames: 2", "Frames: two"), frames_line, "two"),
    ]


@pytest.mark.parametrize("case", _bad_cases(), ids=lambda c: c[0])
def test_bad_input_names_path_and_line(tmp_path, case):
    _, content, line, words = case
    path = _write(tmp_path, content)
    with pytest.raises(MtannoError) as info:
        read_bvh(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}:{line}:"), msg
    assert info.value.line == line
    assert words.lower() in msg.lower(), msg


def test_bad_input_crlf_line_numbers(tmp_path):
    rows = SMALL_BVH.split("\n")
    k = _line_of(SMALL_BVH, "MOTION") + 4  # second data row
    rows[k - 1] = rows[k - 1] + " 1"
    path = _write(tmp_path, "\r\n".join(rows))
    with pytest.raises(MtannoError, match=rf"^{re.escape(str(path))}:{k}: too many"):
        read_bvh(path)


def test_zero_frames(tmp_path):
    rig, ch = read_bvh(_write(tmp_path, SMALL_HIERARCHY + "MOTION\nFrames: 0\n"
                                        "Frame Time: 0.0083333\n"))
    assert ch.n_frames == 0 and ch.angles.shape == (0, 6, 3) and ch.fps == 120.0


def test_missing_file(tmp_path):
    with pytest.raises(MtannoError, match="not found"):
        read_bvh(tmp_path / "nope.bvh")


# --------------------------------------------------------------------------------------
# (d) frame rate read from the file
# --------------------------------------------------------------------------------------

@pytest.mark.parametrize("text, fps", [
    ("0.0333333", 30.0), ("0.033333", 30.0), ("0.0166667", 60.0), ("0.016667", 60.0),
    ("0.00833333", 120.0), ("0.008333", 120.0), ("0.0083333333", 120.0), ("0.04", 25.0),
    ("0.01", 100.0), ("0.0333667", 30 / 1.001), ("0.0417083", 24 / 1.001), ("1", 1.0),
    ("8.33333e-3", 120.0),
])
def test_frame_rate_snapped(text, fps):
    assert frame_rate_from_frame_time(text) == fps


def test_frame_rate_not_snapped():
    assert frame_rate_from_frame_time("0.0123") == pytest.approx(1 / 0.0123, rel=1e-12)
    assert frame_rate_from_frame_time("0.0334") == pytest.approx(1 / 0.0334, rel=1e-12)
    assert frame_rate_from_frame_time("0.033") == pytest.approx(1 / 0.033, rel=1e-12)


@pytest.mark.parametrize("frame_time, fps", [("0.0166667", 60.0), ("0.00833333", 120.0),
                                             ("0.008333", 120.0), ("0.0333333", 30.0)])
def test_frame_rate_from_file(tmp_path, frame_time, fps):
    rig, ch = read_bvh(_write(tmp_path, SMALL_BVH.replace("0.0166667", frame_time)))
    assert ch.fps == fps and isinstance(ch.fps, float)
    assert rig.meta["frame_time"] == float(frame_time)


# --------------------------------------------------------------------------------------
# skeleton maps
# --------------------------------------------------------------------------------------

CGSPEED_LIKE = """HIERARCHY
ROOT Hips
{
OFFSET 0 0 0
CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
JOINT LHipJoint
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftUpLeg
{ OFFSET 1.6 -1.7 0.8
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftLeg
{ OFFSET 2.3 -6.2 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftFoot
{ OFFSET 2.7 -7.5 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftToeBase
{ OFFSET 0.2 -0.5 2.2
CHANNELS 3 Zrotation Yrotation Xrotation
End Site
{ OFFSET 0 0 1.2 }
} } } } }
JOINT RHipJoint
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightUpLeg
{ OFFSET -1.6 -1.7 0.8
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightLeg
{ OFFSET -2.3 -6.2 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightFoot
{ OFFSET -2.7 -7.5 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightToeBase
{ OFFSET -0.2 -0.5 2.2
CHANNELS 3 Zrotation Yrotation Xrotation
End Site
{ OFFSET 0 0 1.2 }
} } } } }
JOINT LowerBack
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT Spine
{ OFFSET 0 2.1 -0.1
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT Spine1
{ OFFSET 0 2.1 -0.1
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT Neck
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT Neck1
{ OFFSET 0 1.7 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT Head
{ OFFSET 0 1.5 -0.6
CHANNELS 3 Zrotation Yrotation Xrotation
End Site
{ OFFSET 0 1.7 -0.2 }
} } }
JOINT LeftShoulder
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftArm
{ OFFSET 3.4 0.5 0.2
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftForeArm
{ OFFSET 5.4 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftHand
{ OFFSET 2.4 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftFingerBase
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT LeftHandIndex1
{ OFFSET 0.7 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
End Site
{ OFFSET 0.6 0 0 }
} }
JOINT LThumb
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
End Site
{ OFFSET 0.6 0 0.6 }
} } } } }
JOINT RightShoulder
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightArm
{ OFFSET -3.2 0.6 0.3
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightForeArm
{ OFFSET -5.6 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightHand
{ OFFSET -2.5 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightFingerBase
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
JOINT RightHandIndex1
{ OFFSET -0.8 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
End Site
{ OFFSET -0.7 0 0 }
} }
JOINT RThumb
{ OFFSET 0 0 0
CHANNELS 3 Zrotation Yrotation Xrotation
End Site
{ OFFSET -0.7 0 0.7 }
} } } } } } } } }
MOTION
Frames: 1
Frame Time: 0.0083333
"""


def test_cmu_bvh_map_on_cgspeed_like_rig(tmp_path):
    """A synthetic hierarchy laid out like the cgspeed CMU conversion (rest pose)."""
    n_channels = 6 + 3 * 30
    path = _write(tmp_path, CGSPEED_LIKE + " ".join(["0"] * n_channels) + "\n")
    rig, ch = read_bvh(path)
    assert rig.n_nodes == 31 + 7 and ch.fps == 120.0
    m = read_motion(path)
    assert m.smap.name == "cmu-bvh"
    cov = m.smap.coverage(rig)
    assert all(cov[j] is not None for j in CANONICAL_JOINTS), cov
    p = dict(zip(CANONICAL_JOINTS, canonical_positions(m)[0], strict=True))
    assert np.linalg.norm(p["neck"] - p["chest"]) > 1.0      # F3–F6 need chest ≠ neck
    assert p["headtop"][1] > p["head"][1] > p["neck"][1] > p["chest"][1] > p["root"][1]
    assert p["lfingers"][0] > p["lwrist"][0] > p["lelbow"][0] > p["lshoulder"][0] > 0
    assert p["ltoes"][2] > p["lankle"][2]                    # toe tip in front of the ankle
    # heading: horizontal, pointing to the left hip (+X here)
    np.testing.assert_allclose(m.heading[0], [1, 0, 0])
    assert np.dot(m.heading[0], p["lhip"] - p["rhip"]) > 0


def test_maps_load_and_do_not_overlap():
    bandai = load_map(SKELETONS / "bandai-bvh.toml")
    cmu = load_map(SKELETONS / "cmu-bvh.toml")
    for m in (bandai, cmu):
        assert m.format == "bvh" and set(m.joints) == set(CANONICAL_JOINTS)
        assert m.heading_node == m.joints["root"]
        assert np.linalg.norm(m.heading_axis) == pytest.approx(1.0)
    assert not set(bandai.detect) <= set(cmu.joints.values())
    assert not set(cmu.detect) & {"joint_Root", "UpperLeg_L"}


def test_unpack_archive_once(tmp_path):
    src = tmp_path / "src" / "data"
    src.mkdir(parents=True)
    (src / "a.bvh").write_text(SMALL_BVH)
    archive = tmp_path / "tiny.tar.xz"
    with tarfile.open(archive, "w:xz") as tar:
        tar.add(src, arcname="data")
    cache = tmp_path / "cache"
    out = unpack_archive(archive, cache)
    assert out == cache / "tiny" and (out / "data" / "a.bvh").read_text() == SMALL_BVH
    (out / "data" / "a.bvh").write_text("changed")  # a second call does not unpack again
    assert unpack_archive(archive, cache) == out
    assert (out / "data" / "a.bvh").read_text() == "changed"
    assert [p.name for p in cache.iterdir()] == ["tiny"]  # no temporary folders left


# --------------------------------------------------------------------------------------
# real data: Bandai Namco BVH (set 1 and one set-2 archive)
# --------------------------------------------------------------------------------------

def _require_shared() -> None:
    if not (SHARED / "bandai").is_dir():
        pytest.skip(f"../shared/data not present: the Bandai BVH archives are expected in "
                    f"{SHARED / 'bandai'}")


@pytest.fixture(scope="module")
def set1() -> list[Path]:
    _require_shared()
    clips = bandai_clips("set1.tar.xz")
    assert len(clips) >= 170
    return clips


@pytest.fixture(scope="module")
def walk_clip(set1) -> Path:
    return next(p for p in set1 if p.name == "dataset-1_walk_normal_001.bvh")


def _reference_fk(rig, ch) -> np.ndarray:
    """Slow, independent FK: P_j = P_parent + G_parent · t_j, G_j = G_parent · L_j, with
    L_j the product of the elementary rotations in CHANNELS order (plain numpy)."""
    out = np.empty((ch.n_frames, rig.n_nodes, 3))
    for f in range(ch.n_frames):
        g = [None] * rig.n_nodes
        for j in range(rig.n_nodes):
            loc = np.eye(3)
            for k in range(3):
                loc = loc @ euler_matrix(int(rig.axes[j, k]), ch.angles[f, j, k])
            t = ch.trans[f, j] if ch.has_trans[j] else rig.offsets[j]
            p = rig.parents[j]
            if p < 0:
                g[j], out[f, j] = loc, t
            else:
                g[j] = g[p] @ loc
                out[f, j] = out[f, p] + g[p] @ t
    return out


@pytest.mark.realdata
def test_bandai_reference_fk_and_bone_lengths(walk_clip):
    rig, ch = read_bvh(walk_clip)
    pos, _ = forward_kinematics(rig, ch.angles, ch.trans, ch.has_trans)
    ref = _reference_fk(rig, ch)
    scale = np.abs(ref).max()
    np.testing.assert_allclose(pos, ref, rtol=0, atol=1e-12 * scale)
    # Position channels below Hips repeat the offsets (within the files' 6 digits) ...
    hips, root = rig.index("Hips"), rig.index("joint_Root")
    below = [j for j in range(rig.n_nodes) if ch.has_trans[j] and j not in (hips, root)]
    assert len(below) == 20
    assert np.abs(ch.trans[:, below] - rig.offsets[below]).max() < 1e-4
    # ... so every bone below Hips is rigid and as long as its offset
    for j in range(rig.n_nodes):
        if j in (hips, root):
            continue
        length = np.linalg.norm(pos[:, j] - pos[:, rig.parents[j]], axis=1)
        np.testing.assert_allclose(length, np.linalg.norm(rig.offsets[j]), atol=1e-4,
                                   err_msg=rig.names[j])
    # Hips' position channels replace its offset: the pelvis is ~90 cm above the floor
    # (offset + channel would put it near 180 cm)
    assert 80 < pos[:, hips, 1].mean() < 100


@pytest.mark.realdata
def test_bandai_walk_map_and_heading(walk_clip):
    m = read_motion(walk_clip)
    assert m.smap.name == "bandai-bvh" and m.fps == 30.0
    rig = m.rig
    # the heading axis is the Hips-local right→left hip direction, roughly horizontal
    lr = m.positions[:, rig.index("UpperLeg_L")] - m.positions[:, rig.index("UpperLeg_R")]
    lr /= np.linalg.norm(lr, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("fi,fi->f", lr, m.heading), 1.0, atol=1e-6)
    assert np.abs(m.heading[:, 1]).max() < 0.2
    # it points to the subject's left: left = up × forward (walking direction)
    root = m.positions[:, rig.index("Hips")]
    fwd = root[-1] - root[0]
    fwd[1] = 0
    left = np.cross([0.0, 1.0, 0.0], fwd / np.linalg.norm(fwd))
    assert (m.heading[:, [0, 2]] @ left[[0, 2]]).mean() > 0.8
    # every canonical joint is present and anatomically ordered in height at frame 1
    p = dict(zip(CANONICAL_JOINTS, canonical_positions(m)[0], strict=True))
    assert p["head"][1] > p["neck"][1] > p["chest"][1] > p["belly"][1] > p["root"][1] \
        > p["lknee"][1] > p["lankle"][1]
    assert 155 > p["head"][1] > 120


@pytest.mark.realdata
def test_bandai_set1_all_clips(set1):
    names = None
    for path in set1:
        rig, ch = read_bvh(path)
        frames = int(re.search(rb"Frames:\s*(\d+)", path.read_bytes()[:20000]).group(1))
        assert ch.n_frames == frames > 0
        assert ch.fps == 30.0
        assert np.isfinite(ch.angles).all() and np.isfinite(ch.trans).all()
        names = names or rig.names
        assert rig.names == names and rig.n_nodes == 27 and rig.meta["n_channels"] == 132
        assert find_map(rig).name == "bandai-bvh"


@pytest.mark.realdata
def test_bandai_set2_archive_reads():
    _require_shared()
    clips = bandai_clips("set2-normal.tar.xz")
    assert len(clips) > 400
    total = 0
    for path in clips:
        rig, ch = read_bvh(path)
        assert ch.fps == 30.0 and ch.n_frames > 0 and rig.n_nodes == 27
        assert np.isfinite(ch.angles).all()
        total += ch.n_frames
    assert total > 40_000


# --------------------------------------------------------------------------------------
# peer: pybvh (PyPI) computes the same world positions
# --------------------------------------------------------------------------------------

def _peer():
    pytest.importorskip("pybvh", reason="pybvh (the bench extra) is not installed")
    if "pybvh_peer" in sys.modules:
        return sys.modules["pybvh_peer"]
    spec = importlib.util.spec_from_file_location("pybvh_peer",
                                                  REPO / "scripts" / "pybvh_peer.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["pybvh_peer"] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _compare_with_peer(peer, path: Path, rtol: float) -> float:
    names, theirs, fps, skip = peer.pybvh_read(path)
    mine_names, mine = _positions(path)
    assert sorted(names) == sorted(mine_names)
    keep = [k for k, n in enumerate(names) if n not in skip]
    idx = [mine_names.index(names[k]) for k in keep]
    scale = np.abs(mine).max()
    err = np.abs(mine[:, idx] - theirs[:, keep]).max()
    assert err <= rtol * scale, f"max |mtanno - pybvh| = {err} (scale {scale})"
    assert fps == read_bvh(path)[1].fps
    return err


def test_pybvh_peer_small_file(tmp_path):
    """pybvh reads this one directly (position channels on the root only)."""
    peer = _peer()
    hierarchy = SMALL_HIERARCHY.replace(
        "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
        "CHANNELS 3 Zrotation Xrotation Yrotation")
    motion = ("MOTION\nFrames: 3\nFrame Time: 0.0166667\n"
              "1 2 3 90 0 0  0 0 0  0 0 0  0 0 0\n"
              "0 0 0 0 0 0  90 90 0  0 90 0  90 30 -45\n"
              "-4 5.5 2 10 -120 33  17 -35 80  40 -70 20  -5 12 170\n")
    path = _write(tmp_path, hierarchy + motion)
    assert peer.pybvh_read(path)[3] == []
    _compare_with_peer(peer, path, rtol=1e-12)


@pytest.mark.realdata
def test_pybvh_peer_bandai(walk_clip, tmp_path):
    peer = _peer()
    # the pybvh-compatible rewrite read by both readers: identical up to rounding
    converted = tmp_path / "converted.bvh"
    assert peer.pybvh_compatible(walk_clip, converted) == ["joint_Root"]
    _compare_with_peer(peer, converted, rtol=1e-12)
    # the original file (mtanno) against the rewrite (pybvh): differs only by dropping
    # position channels that repeat the offsets to ~1e-5 cm
    err = _compare_with_peer(peer, walk_clip, rtol=1e-6)
    assert err < 1e-4
