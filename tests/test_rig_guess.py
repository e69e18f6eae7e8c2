"""Skeleton maps made from joint names and the tree (mtanno.io.guess, issue 25 part 1).

Real BVH files — Bandai Namco clips and a CMU-style BVH made here from a real CMU AMC —
are rewritten with the joint names of each common convention (Mixamo with and without
its prefixes, MotionBuilder/HumanIK, the Unreal mannequin, SMPL, SMPL-X, Xsens, Rokoko),
with the extra nodes those rigs have (a reference node, twist and roll bones, zero-length
fingers, IK helpers, a prop, face joints, spine joints inserted with zero length and zero
rotation). None of that moves a canonical joint, so the features of every rewritten file
must equal the original rig's (read with its built-in map) exactly.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mtanno.cli import main
from mtanno.errors import MtannoError
from mtanno.features.extract import features_from_motion
from mtanno.io import read_channels, read_motion
from mtanno.io.bvh import read_bvh
from mtanno.io.guess import classify_name, guess_map
from mtanno.io.rigs import CANONICAL_JOINTS, load_map
from mtanno.io.skeleton import euler_matrix

try:
    from data_cache import bandai_clips
except ImportError:  # pragma: no cover - rootdir-relative import mode
    from tests.data_cache import bandai_clips

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


# --------------------------------------------------------------------------------------
# a small BVH tree that can be renamed and given extra nodes, keeping the motion's text
# --------------------------------------------------------------------------------------

@dataclass
class Node:
    name: str
    offset: str
    channels: list[str]
    children: list[Node] = field(default_factory=list)
    end: bool = False
    cols: tuple[int, int] | None = None  # columns of the original MOTION rows


@dataclass
class Bvh:
    root: Node
    header: list[str]          # "Frames:" and "Frame Time:" lines
    rows: list[list[str]]      # MOTION values as text (kept exactly)

    def nodes(self):
        stack = [self.root]
        while stack:
            n = stack.pop()
            yield n
            stack.extend(reversed(n.children))

    def find(self, name: str) -> Node:
        return next(n for n in self.nodes() if n.name == name and not n.end)

    def parent_of(self, node: Node) -> Node:
        return next(n for n in self.nodes() if any(c is node for c in n.children))

    def rename(self, mapping: dict[str, str]) -> Bvh:
        joints = {n.name: n for n in self.nodes() if not n.end}
        assert set(mapping) <= set(joints), set(mapping) - set(joints)
        for old, new in mapping.items():
            joints[old].name = new
        return self

    def insert_above(self, name: str, new: str) -> Bvh:
        """A joint with zero offset and zero rotation between ``name`` and its parent."""
        node = self.find(name)
        parent = self.parent_of(node)
        extra = Node(new, "0 0 0", ["Zrotation", "Xrotation", "Yrotation"], [node])
        parent.children[parent.children.index(node)] = extra
        return self

    def add_leaf(self, parent: str, *names: str, offset: str = "0 0 0") -> Bvh:
        """A chain of joints ``names`` under ``parent`` with zero rotation, ending in an
        End Site; the first has ``offset``, the others zero offsets."""
        node = self.find(parent)
        for k, name in enumerate(names):
            child = Node(name, offset if k == 0 else "0 0 0",
                         ["Zrotation", "Xrotation", "Yrotation"])
            node.children.append(child)
            node = child
        node.children.append(Node("", "0 0 0", [], end=True))
        return self

    def text(self) -> str:
        out = ["HIERARCHY"]
        order: list[Node] = []

        def emit(n: Node, depth: int, kind: str) -> None:
            pad = "  " * depth
            if n.end:
                out.extend([f"{pad}End Site", f"{pad}{{", f"{pad}  OFFSET {n.offset}",
                            f"{pad}}}"])
                return
            out.extend([f"{pad}{kind} {n.name}", f"{pad}{{", f"{pad}  OFFSET {n.offset}"])
            if n.channels:
                out.append(f"{pad}  CHANNELS {len(n.channels)} {' '.join(n.channels)}")
                order.append(n)
            for c in n.children:
                emit(c, depth + 1, "JOINT")
            out.append(f"{pad}}}")

        emit(self.root, 0, "ROOT")
        out.append("MOTION")
        out.extend(self.header)
        for row in self.rows:
            vals = []
            for n in order:
                vals.extend(row[n.cols[0]:n.cols[1]] if n.cols else ["0"] * len(n.channels))
            out.append(" ".join(vals))
        return "\n".join(out) + "\n"

    def write(self, path: Path) -> Path:
        path.write_text(self.text(), encoding="utf-8")
        return path


def parse_bvh(text: str) -> Bvh:
    """The hierarchy (one keyword per line, as the Bandai files and :func:`cmu_style_bvh`
    write it) and the motion values as text."""
    head, motion = re.split(r"(?m)^MOTION\s*$", text, maxsplit=1)
    stack: list[Node] = []
    root = None
    col = 0
    pending: Node | None = None
    for line in head.splitlines():
        w = line.split()
        if not w or w[0] in ("HIERARCHY", "{"):
            continue
        if w[0] in ("ROOT", "JOINT") or w[:2] == ["End", "Site"]:
            pending = Node(" ".join(w[1:]), "", [], end=w[0] == "End")
            if stack:
                stack[-1].children.append(pending)
            root = root or pending
            stack.append(pending)
        elif w[0] == "OFFSET":
            stack[-1].offset = " ".join(w[1:])
        elif w[0] == "CHANNELS":
            stack[-1].channels = w[2:]
            stack[-1].cols = (col, col + len(w[2:]))
            col += len(w[2:])
        elif w[0] == "}":
            stack.pop()
    lines = [ln for ln in motion.strip().splitlines()]
    rows = [ln.split() for ln in lines[2:] if ln.strip()]
    assert all(len(r) == col for r in rows)
    return Bvh(root, lines[:2], rows)


# --------------------------------------------------------------------------------------
# the conventions, as renamings of the two source rigs
# --------------------------------------------------------------------------------------

def _sided(names: dict[str, str]) -> dict[str, str]:
    """``{"UpperArm_{S}": "{Side}Arm"}`` for both sides (S = L/R, Side = Left/Right,
    s = l/r)."""
    out = {}
    for S, Side in (("L", "Left"), ("R", "Right")):
        for a, b in names.items():
            out[a.format(S=S, Side=Side, s=S.lower())] = b.format(S=S, Side=Side, s=S.lower())
    return out


BANDAI_LIMBS = ("Shoulder_{S}", "UpperArm_{S}", "LowerArm_{S}", "Hand_{S}", "UpperLeg_{S}",
                "LowerLeg_{S}", "Foot_{S}", "Toes_{S}")


def _bandai(trunk: dict[str, str], limbs: tuple[str, ...]) -> dict[str, str]:
    """A renaming of the Bandai rig: trunk names, then the eight limb names per side."""
    return {**trunk, **_sided(dict(zip(BANDAI_LIMBS, limbs, strict=True)))}


MIXAMO_LIMBS = ("{Side}Shoulder", "{Side}Arm", "{Side}ForeArm", "{Side}Hand", "{Side}UpLeg",
                "{Side}Leg", "{Side}Foot", "{Side}ToeBase")


def _mixamo(b: Bvh, prefix: str = "") -> Bvh:
    b.rename(_bandai({"joint_Root": "Armature", "Hips": "Hips", "Spine": "Spine",
                      "Chest": "Spine2", "Neck": "Neck", "Head": "Head"}, MIXAMO_LIMBS))
    b.insert_above("Spine2", "Spine1")
    b.add_leaf("Head", "HeadTop_End")
    for side in ("Left", "Right"):
        b.add_leaf(f"{side}ToeBase", f"{side}Toe_End")
        for finger in ("Thumb", "Index", "Middle", "Ring", "Pinky"):
            b.add_leaf(f"{side}Hand", *(f"{side}Hand{finger}{k}" for k in range(1, 5)))
    if prefix:
        for n in b.nodes():
            if not n.end and n.name != "Armature":
                n.name = prefix + n.name
    return b


def _humanik(b: Bvh) -> Bvh:
    b.rename(_bandai({"joint_Root": "Reference", "Chest": "Spine1"}, MIXAMO_LIMBS))
    for side in ("Left", "Right"):
        for limb in ("Arm", "ForeArm", "UpLeg", "Leg"):
            b.add_leaf(f"{side}{limb}", f"{side}{limb}Roll")
    for n in b.nodes():
        if not n.end:
            n.name = "Character1_" + n.name
    return b


def _unreal(b: Bvh) -> Bvh:
    b.rename(_bandai({"joint_Root": "root", "Hips": "pelvis", "Spine": "spine_01",
                      "Chest": "spine_03", "Neck": "neck_01", "Head": "head"},
                     ("clavicle_{s}", "upperarm_{s}", "lowerarm_{s}", "hand_{s}", "thigh_{s}",
                      "calf_{s}", "foot_{s}", "ball_{s}")))
    b.insert_above("spine_03", "spine_02")
    b.add_leaf("root", "ik_foot_root")
    b.add_leaf("ik_foot_root", "ik_foot_l", offset="10 0 0")
    b.add_leaf("ik_foot_root", "ik_foot_r", offset="-10 0 0")
    for s in ("l", "r"):
        for bone in ("upperarm", "lowerarm", "thigh", "calf"):
            b.add_leaf(f"{bone}_{s}", f"{bone}_twist_01_{s}", offset="5 0 0")
        for finger in ("thumb", "index", "middle", "ring", "pinky"):
            b.add_leaf(f"hand_{s}", *(f"{finger}_0{k}_{s}" for k in (1, 2, 3)))
    b.add_leaf("hand_r", "weapon_r", offset="12 3 0")   # a prop: not a finger tip
    return b


def _smpl(b: Bvh) -> Bvh:
    b.rename(_bandai({"joint_Root": "root", "Hips": "Pelvis", "Spine": "Spine1",
                      "Chest": "Spine3"},
                     ("{S}_Collar", "{S}_Shoulder", "{S}_Elbow", "{S}_Wrist", "{S}_Hip",
                      "{S}_Knee", "{S}_Ankle", "{S}_Foot")))
    b.insert_above("Spine3", "Spine2")
    b.add_leaf("L_Wrist", "L_Hand")
    b.add_leaf("R_Wrist", "R_Hand")
    return b


def _smplx(b: Bvh) -> Bvh:
    b.rename(_bandai({"joint_Root": "root", "Hips": "pelvis", "Spine": "spine1",
                      "Chest": "spine3", "Neck": "neck", "Head": "head"},
                     ("{Side}_collar", "{Side}_shoulder", "{Side}_elbow", "{Side}_wrist",
                      "{Side}_hip", "{Side}_knee", "{Side}_ankle", "{Side}_foot")))
    for n in b.nodes():
        n.name = n.name.replace("Left_", "left_").replace("Right_", "right_")
    b.insert_above("spine3", "spine2")
    b.add_leaf("head", "jaw", offset="0 -4 3")       # face joints: not the head top
    b.add_leaf("head", "left_eye_smplhf", offset="9 3 4")
    b.add_leaf("head", "right_eye_smplhf", offset="9 -3 4")
    for side in ("left", "right"):
        for finger in ("thumb", "index", "middle", "ring", "pinky"):
            b.add_leaf(f"{side}_wrist", *(f"{side}_{finger}{k}" for k in (1, 2, 3)))
    return b


def _xsens(b: Bvh) -> Bvh:
    b.rename(_bandai({"joint_Root": "root", "Hips": "Pelvis", "Spine": "L5", "Chest": "T8"},
                     ("{Side}Shoulder", "{Side}UpperArm", "{Side}ForeArm", "{Side}Hand",
                      "{Side}UpperLeg", "{Side}LowerLeg", "{Side}Foot", "{Side}Toe")))
    b.insert_above("T8", "T12")
    b.insert_above("T12", "L3")
    return b


def _rokoko(b: Bvh) -> Bvh:
    b.rename(_bandai({"joint_Root": "Root", "Spine": "Spine1", "Chest": "Spine4"},
                     ("{Side}Shoulder", "{Side}Arm", "{Side}ForeArm", "{Side}Hand",
                      "{Side}Thigh", "{Side}Shin", "{Side}Foot", "{Side}Toe")))
    b.insert_above("Spine4", "Spine2")
    b.insert_above("Spine4", "Spine3")
    return b


BANDAI_CONVENTIONS = {
    "mixamo": lambda b: _mixamo(b),
    "mixamorig": lambda b: _mixamo(b, "mixamorig:"),
    "mixamorig1": lambda b: _mixamo(b, "mixamorig1:"),
    "humanik": _humanik,
    "unreal": _unreal,
    "smpl": _smpl,
    "smplx": _smplx,
    "xsens": _xsens,
    "rokoko": _rokoko,
}

# The CMU-style source rig (cgspeed names) renamed; LHipJoint, LowerBack, Neck1 and the
# finger base have no counterpart and get a name of the convention's style.
CMU_CONVENTIONS = {
    "mixamo": {"LowerBack": "Spine", "Spine": "Spine1", "Spine1": "Spine2", "Neck1": "Neck2",
               **_sided({"{S}HipJoint": "{Side}HipBase", "{Side}FingerBase": "{Side}Palm",
                             "{S}Thumb": "{Side}HandThumb1"})},
    "unreal": {"Hips": "pelvis", "LowerBack": "spine_01", "Spine": "spine_02",
               "Spine1": "spine_03", "Neck": "neck_01", "Neck1": "neck_02", "Head": "head",
               **_sided({"{S}HipJoint": "hip_{s}", "{Side}UpLeg": "thigh_{s}",
                             "{Side}Leg": "calf_{s}", "{Side}Foot": "foot_{s}",
                             "{Side}ToeBase": "ball_{s}", "{Side}Shoulder": "clavicle_{s}",
                             "{Side}Arm": "upperarm_{s}", "{Side}ForeArm": "lowerarm_{s}",
                             "{Side}Hand": "hand_{s}", "{Side}FingerBase": "palm_{s}",
                             "{Side}HandIndex1": "index_01_{s}", "{S}Thumb": "thumb_01_{s}"})},
    "smpl": {"Hips": "Pelvis", "LowerBack": "Spine1", "Spine": "Spine2", "Spine1": "Spine3",
             "Neck1": "Neck2",
             **_sided({"{S}HipJoint": "{S}_HipBase", "{Side}UpLeg": "{S}_Hip",
                           "{Side}Leg": "{S}_Knee", "{Side}Foot": "{S}_Ankle",
                           "{Side}ToeBase": "{S}_Foot", "{Side}Shoulder": "{S}_Collar",
                           "{Side}Arm": "{S}_Shoulder", "{Side}ForeArm": "{S}_Elbow",
                           "{Side}Hand": "{S}_Wrist", "{Side}FingerBase": "{S}_Hand",
                           "{Side}HandIndex1": "{S}_Index1", "{S}Thumb": "{S}_Thumb1"})},
}


# --------------------------------------------------------------------------------------
# sources: a real Bandai clip, and a CMU-style BVH made from a real CMU AMC
# --------------------------------------------------------------------------------------

CGSPEED = {"root": "Hips", "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1",
           "lowerneck": "Neck", "upperneck": "Neck1", "head": "Head",
           **{f"{s}{a}": f"{S}{b}" for s, S in (("l", "Left"), ("r", "Right"))
              for a, b in (("femur", "UpLeg"), ("tibia", "Leg"), ("foot", "Foot"),
                           ("toes", "ToeBase"), ("clavicle", "Shoulder"), ("humerus", "Arm"),
                           ("radius", "ForeArm"), ("wrist", "Hand"), ("hand", "FingerBase"),
                           ("fingers", "HandIndex1"))},
           "lhipjoint": "LHipJoint", "rhipjoint": "RHipJoint", "lthumb": "LThumb",
           "rthumb": "RThumb"}


def _zyx_degrees(m: np.ndarray) -> np.ndarray:
    """(frames × 3 × 3) rotations → (frames × 3) Z, Y, X angles in degrees with
    m = Rz · Ry · Rx (BVH 'Zrotation Yrotation Xrotation')."""
    y = np.arcsin(np.clip(-m[:, 2, 0], -1.0, 1.0))
    z = np.arctan2(m[:, 1, 0], m[:, 0, 0])
    x = np.arctan2(m[:, 2, 1], m[:, 2, 2])
    return np.degrees(np.stack([z, y, x], axis=1))


def cmu_style_bvh(amc: Path, asf: Path, frames: int = 240) -> str:
    """A BVH laid out like the cgspeed CMU conversions (31 joints, cgspeed names, ZYX
    rotations, the thorax folded into Spine1 so that Neck and the clavicles start there)
    carrying the motion of a real CMU AMC file: each BVH joint turns like the ASF bone it
    is named after and starts where the parent bone ends."""
    rig, ch = read_channels(amc, asf=asf)
    n = min(frames, ch.n_frames)
    names = rig.names
    local = np.tile(np.eye(3), (n, rig.n_nodes, 1, 1))
    for j in range(rig.n_nodes):
        for f in range(n):
            m = rig.pre[j].copy()
            for k in range(3):
                if ch.angles[f, j, k] != 0.0:
                    m = m @ euler_matrix(int(rig.axes[j, k]), ch.angles[f, j, k])
            local[f, j] = m @ rig.post[j]
    root = Node("Hips", "0 0 0", ["Xposition", "Yposition", "Zposition", "Zrotation",
                                 "Yrotation", "Xrotation"])
    bvh_nodes = {0: root}
    values = [np.concatenate([ch.trans[:n, 0], _zyx_degrees(local[:, 0])], axis=1)]
    for j in range(1, rig.n_nodes):
        p = int(rig.parents[j])
        off = np.zeros(3) if p == 0 or names[j] in ("lowerneck", "lclavicle", "rclavicle") \
            else rig.offsets[p]
        node = Node(CGSPEED[names[j]], " ".join(repr(float(v)) for v in off),
                    ["Zrotation", "Yrotation", "Xrotation"])
        bvh_nodes[p].children.append(node)
        bvh_nodes[j] = node
        values.append(_zyx_degrees(local[:, j]))
        if not any(int(q) == j for q in rig.parents):
            node.children.append(Node("", " ".join(repr(float(v)) for v in rig.offsets[j]),
                                      [], end=True))
    col = 0
    order = []  # joints in file (depth-first) order: the MOTION columns' order
    stack = [root]
    while stack:
        node = stack.pop()
        if not node.end:
            order.append(node)
        stack.extend(reversed(node.children))
    by_node = {id(bvh_nodes[j]): values[j] for j in range(rig.n_nodes)}
    data = np.concatenate([by_node[id(nd)] for nd in order], axis=1)
    for nd in order:
        nd.cols = (col, col + len(nd.channels))
        col += len(nd.channels)
    rows = [[repr(float(v)) for v in row] for row in data]
    return Bvh(root, [f"Frames: {n}", "Frame Time: 0.0083333"], rows).text()


def _require_bandai() -> None:
    if not (SHARED / "bandai").is_dir():
        pytest.skip(f"../shared/data not present: the Bandai BVH archives are expected in "
                    f"{SHARED / 'bandai'}")


@pytest.fixture(scope="module")
def bandai_text() -> str:
    _require_bandai()
    clip = next(p for p in bandai_clips("set1.tar.xz")
                if p.name == "dataset-1_walk_normal_001.bvh")
    return clip.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def cmu_file(tmp_path_factory) -> Path:
    folder = SHARED / "cmu_02"
    if not folder.is_dir():
        pytest.skip(f"../shared/data not present: the CMU subject 02 files are expected in "
                    f"{folder}")
    path = tmp_path_factory.mktemp("cmu") / "02_01_cgspeed.bvh"
    path.write_text(cmu_style_bvh(folder / "02_01.amc", folder / "02.asf"), encoding="utf-8")
    return path


def _features(path: Path, **kw) -> tuple[np.ndarray, object]:
    m = read_motion(path, **kw)
    return features_from_motion(m)[0], m


# --------------------------------------------------------------------------------------
# names
# --------------------------------------------------------------------------------------

@pytest.mark.parametrize("name, side, core", [
    ("mixamorig:LeftUpLeg", "l", "upleg"), ("mixamorig1:RightForeArm", "r", "forearm"),
    ("thigh_l", "l", "thigh"), ("lowerarm_twist_01_r", "r", "lowerarmtwist"),
    ("L_Hip", "l", "hip"), ("left_collar", "l", "collar"), ("LHipJoint", "l", "hipjoint"),
    ("UpperLeg_R", "r", "upperleg"), ("Hand_L_End", "", "handlend"), ("L5", "", "l"),
    ("T12", "", "t"), ("spine_03", "", "spine"), ("HeadTop_End", "", "headtopend"),
    ("upper_arm.R", "r", "upperarm"), ("HandLeft", "l", "hand"),
])
def test_classify_name(name, side, core):
    info = classify_name(name)
    assert (info.side, info.core) == (side, core)


def test_classify_name_rig_prefix():
    info = classify_name("Bip01 L Thigh", "Bip01 ")
    assert (info.side, info.core) == ("l", "thigh")


# --------------------------------------------------------------------------------------
# real files renamed: the features equal the original rig's
# --------------------------------------------------------------------------------------

@pytest.mark.realdata
@pytest.mark.parametrize("convention", sorted(BANDAI_CONVENTIONS))
def test_bandai_renamed_features_equal(bandai_text, tmp_path, convention):
    X0, m0 = _features(parse_bvh(bandai_text).write(tmp_path / "orig.bvh"))
    assert m0.smap.name == "bandai-bvh"
    path = BANDAI_CONVENTIONS[convention](parse_bvh(bandai_text)).write(tmp_path / "r.bvh")
    X, m = _features(path)
    assert m.smap.name.startswith("guessed-") and m.smap.path == "generated"
    assert "confirmed by the pose" in m.smap.how and "legs and arms" in m.smap.how
    assert m.smap.heading_axis == m0.smap.heading_axis == (0.0, -1.0, 0.0)
    np.testing.assert_array_equal(m.positions[:, [m.rig.index(m.smap.joints[j])
                                                  for j in CANONICAL_JOINTS]],
                                  m0.positions[:, [m0.rig.index(m0.smap.joints[j])
                                                   for j in CANONICAL_JOINTS]])
    assert X.shape == X0.shape and (X == X0).all()


@pytest.mark.realdata
def test_bandai_guess_agrees_with_builtin_map(bandai_text, tmp_path):
    path = parse_bvh(bandai_text).write(tmp_path / "orig.bvh")
    m = read_motion(path)
    g = guess_map(*read_bvh(path))
    assert (g.joints, g.heading_node, g.heading_axis) == \
        (m.smap.joints, m.smap.heading_node, m.smap.heading_axis)
    result = CliRunner().invoke(main, ["skeleton", "guess", str(path)])
    assert result.exit_code == 0 and "the map 'bandai-bvh' fits this rig" in result.output


@pytest.mark.realdata
def test_cmu_style_source_reads_with_builtin_map(cmu_file):
    m = read_motion(cmu_file)
    assert m.smap.name == "cmu-bvh" and m.fps == 120.0 and m.n_frames == 240
    g = guess_map(m.rig, read_bvh(cmu_file)[1])
    assert g.joints == m.smap.joints  # the guess agrees with the hand-written map
    assert g.heading_axis == m.smap.heading_axis == (1.0, 0.0, 0.0)


@pytest.mark.realdata
@pytest.mark.parametrize("convention", sorted(CMU_CONVENTIONS))
def test_cmu_renamed_features_equal(cmu_file, tmp_path, convention):
    X0, m0 = _features(cmu_file)
    text = cmu_file.read_text(encoding="utf-8")
    path = parse_bvh(text).rename(CMU_CONVENTIONS[convention]).write(tmp_path / "r.bvh")
    X, m = _features(path)
    assert m.smap.name.startswith("guessed-")
    assert X.shape == X0.shape and (X == X0).all()


# --------------------------------------------------------------------------------------
# mirrored names, ambiguous rigs
# --------------------------------------------------------------------------------------

def _swap_names(b: Bvh) -> Bvh:
    for n in b.nodes():
        n.name = re.sub(r"Left|Right", lambda m: "Right" if m.group() == "Left" else "Left",
                        n.name)
    return b


@pytest.mark.realdata
def test_mirrored_naming_detected(bandai_text, tmp_path):
    """Names whose sides the pose contradicts: the pose decides (read_motion, the default
    method), or the map made from the names alone refuses them ("mirrored naming")."""
    path = _swap_names(_mixamo(parse_bvh(bandai_text), "mixamorig:")).write(tmp_path / "m.bvh")
    with pytest.raises(MtannoError, match=r"mirrored naming: the legs and arms named left "
                                          r"are on the subject's right") as e:
        guess_map(*read_bvh(path), method="names")
    assert "\n" not in str(e.value) and str(path) in str(e.value)
    X0, _ = _features(parse_bvh(bandai_text).write(tmp_path / "orig.bvh"))
    X, m = _features(path)
    assert m.smap.name == "guessed-mixamo"
    assert m.smap.joints["lhip"] == "mixamorig:RightUpLeg"   # named right, lies left
    assert "sides from the pose on 64 frames: the legs and arms named left lie on the " \
        "subject's right" in m.smap.how
    assert (X == X0).all()
    # --swap-sides makes the map of the correctly named rig: the same features
    X, _ = features_from_motion(read_motion(path, skeleton=_write_map(
        tmp_path, ["--swap-sides"], path)))
    assert (X == X0).all()


@pytest.mark.realdata
def test_mirrored_naming_cmu_rest_pose(cmu_file):
    rig, _ = read_bvh(cmu_file)
    def swap(n: str) -> str:
        return re.sub(r"Left|Right", lambda m: "Right" if m.group() == "Left" else "Left", n)

    rig.names = [swap(n) for n in rig.names]
    rig.meta["end_sites"] = [swap(n) for n in rig.meta["end_sites"]]
    with pytest.raises(MtannoError, match="mirrored naming.*checked on the rest pose"):
        guess_map(rig, method="names")
    smap = guess_map(rig)
    assert smap.joints["lhip"] == "RightUpLeg" and smap.joints["rwrist"] == "LeftHand"


TPOSE = """HIERARCHY
ROOT {hips}
{{
  OFFSET 0 90 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT {lthigh}
  {{ OFFSET 10 -5 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT {lknee}
    {{ OFFSET 0 -40 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT LeftFoot
      {{ OFFSET 0 -40 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        End Site
        {{ OFFSET 0 -5 12 }}
      }}
    }}
  }}
  JOINT RightUpLeg
  {{ OFFSET -10 -5 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT RightLeg
    {{ OFFSET 0 -40 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT RightFoot
      {{ OFFSET 0 -40 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        End Site
        {{ OFFSET 0 -5 12 }}
      }}
    }}
  }}
  JOINT Spine
  {{ OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT Chest
    {{ OFFSET 0 20 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT {neck}
      {{ OFFSET 0 20 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT {head}
        {{ OFFSET 0 8 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          End Site
          {{ OFFSET 0 15 0 }}
        }}
      }}
      JOINT {lcollar}
      {{ OFFSET 5 15 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT {larm}
        {{ OFFSET 10 0 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          JOINT {lelbow}
          {{ OFFSET 25 0 0
            CHANNELS 3 Zrotation Xrotation Yrotation
            JOINT LeftHand
            {{ OFFSET 25 0 0
              CHANNELS 3 Zrotation Xrotation Yrotation
              End Site
              {{ OFFSET 15 0 0 }}
            }}
          }}
        }}
      }}
      JOINT RightShoulder
      {{ OFFSET -5 15 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT RightArm
        {{ OFFSET -10 0 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          JOINT RightForeArm
          {{ OFFSET -25 0 0
            CHANNELS 3 Zrotation Xrotation Yrotation
            JOINT RightHand
            {{ OFFSET -25 0 0
              CHANNELS 3 Zrotation Xrotation Yrotation
              End Site
              {{ OFFSET -15 0 0 }}
            }}
          }}
        }}
      }}
    }}
  }}
}}
MOTION
Frames: 2
Frame Time: 0.0333333
"""
TPOSE_NAMES = {"hips": "Hips", "lthigh": "LeftUpLeg", "lknee": "LeftLeg", "neck": "Neck",
               "head": "Head", "lcollar": "LeftShoulder", "larm": "LeftArm",
               "lelbow": "LeftForeArm"}


TPOSE_JOINTS = {
    "root": "Hips", "lhip": "LeftUpLeg", "rhip": "RightUpLeg", "lknee": "LeftLeg",
    "rknee": "RightLeg", "lankle": "LeftFoot", "rankle": "RightFoot",
    "ltoes": "LeftFoot_End", "rtoes": "RightFoot_End", "belly": "Spine",
    "chest": "Chest", "neck": "Neck", "head": "Head", "headtop": "Head_End",
    "lshoulder": "LeftArm", "rshoulder": "RightArm", "lelbow": "LeftForeArm",
    "relbow": "RightForeArm", "lwrist": "LeftHand", "rwrist": "RightHand",
    "lfingers": "LeftHand_End", "rfingers": "RightHand_End"}


def _tpose(tmp_path: Path, **names: str) -> Path:
    text = TPOSE.format(**{**TPOSE_NAMES, **names})
    row = " ".join(["0"] * (6 + 3 * 18))
    path = tmp_path / "t.bvh"
    path.write_text(text + row + "\n" + row + "\n")
    return path


def test_tpose_rig_mapped(tmp_path):
    m = read_motion(_tpose(tmp_path))
    assert m.smap.name == "guessed-mixamo-style"
    assert m.smap.joints == TPOSE_JOINTS
    assert m.smap.heading_axis == (1.0, 0.0, 0.0)
    assert "legs and arms confirmed by the pose on 2 frames" in m.smap.how


def test_neck_found_without_its_name(tmp_path):
    m = read_motion(_tpose(tmp_path, neck="UpperChest"))
    assert m.smap.joints["neck"] == "UpperChest" and m.smap.joints["chest"] == "Chest"


@pytest.mark.parametrize("names, expected", [
    ({"lknee": "LeftWing", "lelbow": "LeftFin"},
     "could not place lhip, lknee, lankle, ltoes, lshoulder, lelbow, lwrist, lfingers "
     "(lhip, lknee, lankle, ltoes: no joint named like a left knee; lshoulder, lelbow, "
     "lwrist, lfingers: no joint named like a left elbow)"),
    ({"head": "Skull"}, "could not place root, belly, chest, neck, head, headtop (root, "
                        "belly, chest, neck, head, headtop: no joint named Head)"),
    ({"lthigh": "LeftLeg", "lknee": "LeftKnee"},
     "could not place lhip, lknee, lankle, ltoes (lhip, lknee, lankle, ltoes: several knee "
     "candidates (LeftLeg, LeftKnee))"),
])
def test_names_that_do_not_place_every_joint(tmp_path, names, expected):
    """Names that leave joints unplaced: the map made from the names alone lists them in
    one line; read_motion maps the rig from its hierarchy instead."""
    path = _tpose(tmp_path, **names)
    with pytest.raises(MtannoError) as e:
        guess_map(*read_bvh(path), method="names")
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{path}: no skeleton map fits this BVH rig")
    assert expected in msg and msg.endswith("pass skeleton= MAP.toml (docs/formats.md)")
    result = CliRunner().invoke(main, ["skeleton", "guess", "--method", "names", str(path)])
    assert result.exit_code == 2 and result.output.count("\n") == 1
    assert result.output.rstrip().endswith("pass --skeleton MAP.toml (docs/formats.md)")
    assert "Traceback" not in result.output
    m = read_motion(path)
    assert m.smap.name == "guessed-hierarchy"
    renamed = {TPOSE_NAMES[k] + end: v + end for k, v in names.items() for end in ("", "_End")}
    assert m.smap.joints == {k: renamed.get(v, v) for k, v in TPOSE_JOINTS.items()}
    assert m.smap.how.startswith("generated from the hierarchy and rest pose (the joint "
                                 "names place ")


def test_not_placed_at_all(tmp_path):
    """Generic names everywhere: every canonical joint is listed by the names; the
    hierarchy places them all."""
    text = re.sub(r"(ROOT|JOINT) \S+", lambda m: f"{m.group(1)} Bone{m.start()}",
                  _tpose(tmp_path).read_text())
    path = tmp_path / "bones.bvh"
    path.write_text(text)
    with pytest.raises(MtannoError, match="could not place " + ", ".join(CANONICAL_JOINTS)
                       + " \\("):
        guess_map(*read_bvh(path), method="names")
    old = re.findall(r"(?:ROOT|JOINT) (\S+)", _tpose(tmp_path).read_text())
    new = re.findall(r"(?:ROOT|JOINT) (\S+)", text)
    renamed = {**dict(zip(old, new)), **{a + "_End": b + "_End" for a, b in zip(old, new)}}
    m = read_motion(path)
    assert m.smap.joints == {k: renamed[v] for k, v in TPOSE_JOINTS.items()}
    assert "(the joint names place none of the 22 joints)" in m.smap.how


def test_builtin_map_still_wins(tmp_path):
    from test_bvh import CGSPEED_LIKE

    path = tmp_path / "c.bvh"
    path.write_text(CGSPEED_LIKE + " ".join(["0"] * 96) + "\n")
    m = read_motion(path)
    assert m.smap.name == "cmu-bvh" and "built-in map chosen" in m.smap.how


# --------------------------------------------------------------------------------------
# mtanno info and mtanno skeleton guess
# --------------------------------------------------------------------------------------

def _write_map(tmp_path: Path, args: list[str], src: Path) -> Path:
    out = tmp_path / "map.toml"
    result = CliRunner().invoke(main, ["skeleton", "guess", str(src), "-o", str(out), *args])
    assert result.exit_code == 0, result.output
    return out


def test_info_says_how_the_map_was_made(tmp_path):
    result = CliRunner().invoke(main, ["info", str(_tpose(tmp_path))])
    assert result.exit_code == 0, result.output
    assert "skeleton map   guessed-mixamo-style (generated)" in result.output
    assert "map made by    generated from the joint names (Mixamo/HumanIK style)" \
        in result.output
    assert "map coverage   22/22" in result.output


def test_skeleton_guess_round_trip(tmp_path):
    src = _tpose(tmp_path)
    out = _write_map(tmp_path, [], src)
    smap = load_map(out)
    guessed = read_motion(src).smap
    assert (smap.name, smap.joints, smap.detect, smap.heading_node, smap.heading_axis) == \
        (guessed.name, guessed.joints, guessed.detect, guessed.heading_node,
         guessed.heading_axis)
    assert smap.digest == guessed.digest
    X1, _ = features_from_motion(read_motion(src, skeleton=str(out)))
    X0, _ = features_from_motion(read_motion(src))
    assert (X1 == X0).all()
    # to standard output without -o; an error is one line and exit 2
    result = CliRunner().invoke(main, ["skeleton", "guess", str(src)])
    assert result.exit_code == 0 and "[joints]" in result.output
    bad = _tpose(tmp_path, head="Skull")
    result = CliRunner().invoke(main, ["skeleton", "guess", str(bad), "-o", str(out),
                                       "--method", "names"])
    assert result.exit_code == 2 and result.output.count("\n") == 1
    assert "could not place" in result.output


@pytest.mark.realdata
def test_skeleton_guess_round_trip_real(bandai_text, tmp_path):
    path = _unreal(parse_bvh(bandai_text)).write(tmp_path / "u.bvh")
    out = _write_map(tmp_path, [], path)
    X1, m1 = _features(path, skeleton=str(out))
    X0, m0 = _features(path)
    assert m1.smap.digest == m0.smap.digest and (X1 == X0).all()


def test_heading_axis_snapped_and_not(tmp_path):
    rig, _ = read_bvh(_tpose(tmp_path))
    k = rig.index("LeftUpLeg")
    rig.offsets[k] = [10.0, -5.0, 1.0]          # 5.7° off +X: snapped
    assert guess_map(rig).heading_axis == (1.0, 0.0, 0.0)
    rig.offsets[k] = [10.0, -5.0, 8.0]          # 21.8° off: kept as measured
    axis = guess_map(rig).heading_axis
    assert math.isclose(np.linalg.norm(axis), 1.0) and axis[2] > 0.3
