"""Skeleton maps made from a BVH rig's hierarchy and pose (mtanno.io.topology, issue 31
finding 5), for rigs whose joint names say nothing.

Synthetic rigs built here (a T-pose humanoid with or without fingers, twist bones, face
joints, a tail, IK helpers, in other rest poses, reflected, with shuffled children) check
the map joint by joint; non-humanoid rigs (four legs, a chain, a hand, legs without a
torso) check the one-line refusal. Real Bandai clips whose joints are renamed by several
schemes (``Bone01``…, ``j00``…, random strings, Japanese and Cyrillic names, shuffled
children, sided names on the wrong sides) and reflected in X, and a CMU-style BVH made
from a real CMU AMC file, must give the named rig's map and therefore its features.
"""

from __future__ import annotations

import math
import random
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from test_rig_guess import Bvh, Node, cmu_style_bvh, parse_bvh

from mtanno.cli import main
from mtanno.errors import MtannoError
from mtanno.features.extract import features_from_motion
from mtanno.features.table import mirror_permutation
from mtanno.io import read_motion
from mtanno.io.bvh import read_bvh
from mtanno.io.guess import guess_map, map_toml
from mtanno.io.rigs import CANONICAL_JOINTS, load_map
from mtanno.io.topology import HierarchyError, hierarchy_map

try:
    from data_cache import SHARED_DATA, bandai_clips
except ImportError:  # pragma: no cover - rootdir-relative import mode
    from tests.data_cache import SHARED_DATA, bandai_clips

# --------------------------------------------------------------------------------------
# synthetic rigs: readable names inside, renamed to meaningless ones before reading
# --------------------------------------------------------------------------------------

ROT = ["Zrotation", "Xrotation", "Yrotation"]


def J(name: str, offset, *children: Node, end=None) -> Node:
    """A joint; a joint without children ends in an End Site (``end``, else zero)."""
    kids = list(children)
    if not kids or end is not None:
        kids.append(Node("", " ".join(map(repr, map(float, end or (0, 0, 0)))), [], end=True))
    return Node(name, " ".join(repr(float(v)) for v in offset), list(ROT), kids)


def joints(root: Node) -> list[Node]:
    out, stack = [], [root]
    while stack:
        n = stack.pop()
        if not n.end:
            out.append(n)
        stack.extend(reversed(n.children))
    return out


def write_bvh(path: Path, root: Node, frames: list[dict[str, tuple]] | int = 2,
              names: dict[str, str] | None = None) -> Path:
    """The rig as a BVH file: 6 channels on the root, 3 on every joint; ``frames`` gives
    per frame the (Z, X, Y) rotation in degrees of some joints (others zero), or a number
    of rest-pose frames; ``names`` renames joints (internal name → written name)."""
    root.channels = ["Xposition", "Yposition", "Zposition", *ROT]
    order = joints(root)
    col = 0
    for n in order:
        n.cols = (col, col + len(n.channels))
        col += len(n.channels)
    if isinstance(frames, int):
        frames = [{}] * frames
    rows = []
    for f in frames:
        row = []
        for n in order:
            vals = list(f.get(n.name, (0.0, 0.0, 0.0)))
            row.extend(["0", "0", "0"] + vals if n is root else vals)
        rows.append([repr(float(v)) for v in row])
    b = Bvh(root, [f"Frames: {len(rows)}", "Frame Time: 0.0333333"], rows)
    if names:
        b.rename({k: v for k, v in names.items() if any(n.name == k for n in order)})
    return b.write(path)


def humanoid(*, hands: str = "none", clavicle: float = 12.0, extras: tuple[str, ...] = (),
             pose: str = "T") -> Node:
    """A humanoid standing at the origin facing +Z, its left on +X (Y up), in a T-pose
    (``pose="A"``: arms 45° down; ``"lying"``: on its back, head along -Z). ``hands``:
    ``none`` (the wrist's End Site), ``fingers`` (five, the middle one longest), ``thumb``
    (a CMU-like hand: palm, fingers and a thumb from the wrist), ``palm`` (fingers and
    thumb branching off a palm joint); ``extras``: ``twist``
    (twist bones along the thigh and upper arm), ``face`` (eyes and jaw), ``tail``,
    ``ik`` (IK helpers under the reference node, as in the Unreal mannequin)."""
    def arm(s: str, x: float) -> Node:
        d = (x * math.cos(math.radians(45)), -math.sin(math.radians(45))) if pose == "A" \
            else (x, 0.0)
        if hands == "fingers":
            fingers = [J(f"{s}{f}1", (x * 3, -0.5 + k * 0.3, 2.0 - k),
                         J(f"{s}{f}2", (x * length, 0, 0), J(f"{s}{f}3", (x * 2.5, 0, 0),
                                                             end=(x * 2, 0, 0))))
                       for k, (f, length) in enumerate((("thumb", 2.5), ("index", 4.0),
                                                        ("middle", 4.5), ("ring", 4.2),
                                                        ("pinky", 3.0)))]
            hand = [J(f"{s}wrist", (d[0] * 24, d[1] * 24, 0), *fingers)]
        elif hands == "palm":  # fingers and thumb branch off a palm joint below the wrist
            hand = [J(f"{s}wrist", (d[0] * 24, d[1] * 24, 0), J(f"{s}palm", (x * 5, 0, 0), *(
                J(f"{s}{f}1", (x * 3, 0, 2.0 - k), J(f"{s}{f}2", (x * length, 0, 0),
                                                   end=(x * 2, 0, 0)))
                for k, (f, length) in enumerate((("thumb", 2.5), ("index", 4.0),
                                                 ("middle", 4.5), ("pinky", 3.0))))))]
        elif hands == "thumb":
            hand = [J(f"{s}wrist", (d[0] * 24, d[1] * 24, 0),
                      J(f"{s}palm", (x * 8, 0, 0), J(f"{s}fingers", (x * 4, 0, 0),
                                                     end=(x * 3, 0, 0))),
                      J(f"{s}thumb", (x * 3, 0, 3), end=(x * 2, 0, 2)))]
        else:
            hand = [J(f"{s}wrist", (d[0] * 24, d[1] * 24, 0), end=(d[0] * 18, d[1] * 18, 0))]
        upper = [J(f"{s}elbow", (d[0] * 27, d[1] * 27, 0), *hand)]
        if "twist" in extras:
            upper.append(J(f"{s}armtwist", (d[0] * 13, d[1] * 13, 0)))
        return J(f"{s}clav", (x * 3, 8, 0), J(f"{s}shoulder", (x * clavicle, 0, -1), *upper))

    def leg(s: str, x: float) -> Node:
        knee = [J(f"{s}knee", (0, -42, 0), J(f"{s}ankle", (0, -42, 0),
                                            J(f"{s}toe", (0, -6, 13), end=(0, 0, 5))))]
        if "twist" in extras:
            knee.append(J(f"{s}legtwist", (0, -20, 0)))
        return J(f"{s}hip", (x * 9, -6, 0), *knee)

    head_kids = []
    if "face" in extras:
        head_kids += [J("leye", (3, 4, 8), end=(0, 0, 1)), J("reye", (-3, 4, 8), end=(0, 0, 1)),
                      J("jaw", (0, -3, 6), end=(0, -2, 4))]
    neck = J("neck", (0, 10, 0), J("head", (0, 9, 0), *head_kids, end=(0, 17, 0)))
    chest = J("chest", (0, 14, 0), neck, arm("l", 1.0), arm("r", -1.0))
    pelvis_kids = [leg("l", 1.0), leg("r", -1.0),
                   J("spine1", (0, 10, 0), J("spine2", (0, 14, 0), chest))]
    if "tail" in extras:
        pelvis_kids.append(J("tail1", (0, 0, -10), J("tail2", (0, -5, -20),
                                                      J("tail3", (0, -10, -20), end=(0, -10, -5)))))
    ref_kids = [J("pelvis", (0, 95, 0), *pelvis_kids)]
    if "ik" in extras:
        ref_kids += [J("ikfootroot", (0, 0, 0), J("iklfoot", (9, 8, 0)), J("ikrfoot", (-9, 8, 0))),
                     J("ikhandroot", (0, 0, 0), J("ikhandgun", (-60, 110, 20),
                                                  J("iklhand", (8, 0, 0)),
                                                  J("ikrhand", (-8, 0, 0))))]
    root = J("ref", (0, 0, 0), *ref_kids)
    if pose == "lying":  # (x, y, z) -> (x, z, -y): on its back, feet along +Z... head -Z
        for n in [*joints(root), *(c for j in joints(root) for c in j.children if c.end)]:
            x, y, z = map(float, n.offset.split())
            n.offset = f"{x!r} {z!r} {-y!r}"
    return root


#: The canonical joints of :func:`humanoid` by its internal names (no hands).
EXPECTED = {
    "root": "pelvis", "lhip": "lhip", "rhip": "rhip", "lknee": "lknee", "rknee": "rknee",
    "lankle": "lankle", "rankle": "rankle", "ltoes": "ltoe_End", "rtoes": "rtoe_End",
    "belly": "spine1", "chest": "chest", "neck": "neck", "head": "head",
    "headtop": "head_End", "lshoulder": "lshoulder", "rshoulder": "rshoulder",
    "lelbow": "lelbow", "relbow": "relbow", "lwrist": "lwrist", "rwrist": "rwrist",
    "lfingers": "lwrist_End", "rfingers": "rwrist_End"}


def bone_names(root: Node, seed: int | None = None) -> dict[str, str]:
    """Internal name → ``Bone01``… in file order (or shuffled with ``seed``)."""
    names = [n.name for n in joints(root)]
    order = list(range(1, len(names) + 1))
    if seed is not None:
        random.Random(seed).shuffle(order)
    return {n: f"Bone{k:02d}" for n, k in zip(names, order)}


def mapped(path: Path, **kw):
    """The map read_motion makes for ``path``, in internal names when ``names`` is given."""
    names = kw.pop("names", None)
    m = read_motion(path, **kw)
    if names is None:
        return m.smap.joints, m
    back = {v + end: k + end for k, v in names.items() for end in ("", "_End")}
    return {k: back[v] for k, v in m.smap.joints.items()}, m


def shuffle_children(root: Node, seed: int) -> Node:
    rng = random.Random(seed)
    for n in joints(root):
        rng.shuffle(n.children)
    return root


def reflect_x(root: Node) -> Node:
    for n in [*joints(root), *(c for j in joints(root) for c in j.children if c.end)]:
        x, y, z = n.offset.split()
        n.offset = f"{-float(x)!r} {y} {z}"
    return root


def swap_lr(d: dict[str, str]) -> dict[str, str]:
    """A map with the left and right canonical joints exchanged."""
    def other(k: str) -> str:
        return ("r" + k[1:] if k[0] == "l" else "l" + k[1:]) if k in SIDED else k
    return {other(k): v for k, v in d.items()}


SIDED = {k for k in CANONICAL_JOINTS if k[0] in "lr" and k != "root"}


# --------------------------------------------------------------------------------------
# synthetic humanoids
# --------------------------------------------------------------------------------------

def test_meaningless_names_mapped_from_the_hierarchy(tmp_path):
    root = humanoid()
    names = bone_names(root)
    got, m = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert got == EXPECTED
    assert m.smap.name == "guessed-hierarchy" and m.smap.path == "generated"
    assert m.smap.heading_axis == (1.0, 0.0, 0.0)
    assert m.smap.how.startswith("generated from the hierarchy and rest pose (the joint "
                                 "names place none of the 22 joints); pelvis Bone02 where "
                                 "two legs and the spine meet, shoulder branch ")
    assert "sides from the pose on 2 frames (toes point forward)" in m.smap.how


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_children_order_does_not_matter(tmp_path, seed):
    root = shuffle_children(humanoid(hands="fingers", extras=("face", "tail")), seed)
    names = bone_names(root, seed)
    got, _ = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert got == {**EXPECTED, "lfingers": "lmiddle3_End", "rfingers": "rmiddle3_End"}


@pytest.mark.parametrize("pose", ["T", "A", "lying"])
def test_rest_poses(tmp_path, pose):
    root = humanoid(pose=pose)
    names = bone_names(root)
    got, m = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert got == EXPECTED
    assert m.smap.heading_axis == (1.0, 0.0, 0.0)


def test_reflected_rig_read_as_its_mirror_image(tmp_path):
    """Every offset's X negated: the joints built as left now lie on the subject's right
    (the rig still faces +Z), so they are the right canonical joints."""
    root = reflect_x(humanoid(hands="fingers"))
    names = bone_names(root)
    got, m = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert got == swap_lr({**EXPECTED, "lfingers": "lmiddle3_End", "rfingers": "rmiddle3_End"})
    assert m.smap.heading_axis == (1.0, 0.0, 0.0)   # from the (new) right hip to the left


def test_extra_bones_left_out(tmp_path):
    root = humanoid(hands="fingers", extras=("twist", "face", "tail", "ik"))
    names = bone_names(root)
    got, _ = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert got == {**EXPECTED, "lfingers": "lmiddle3_End", "rfingers": "rmiddle3_End"}


def test_long_clavicle_wrist_where_the_thumb_branches(tmp_path):
    """A clavicle longer than the forearm (as in the CMU rigs): the two longest bones would
    be clavicle and upper arm; the thumb branching off marks the wrist."""
    root = humanoid(hands="thumb", clavicle=30.0)
    names = bone_names(root)
    got, m = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert got == {**EXPECTED, "lfingers": "lfingers_End", "rfingers": "rfingers_End"}
    assert "the wrist where the fingers branch off" in m.smap.how
    root = humanoid(hands="palm", clavicle=30.0)   # fingers branch off a palm joint
    names = bone_names(root)
    got, m = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert got == {**EXPECTED, "lfingers": "lmiddle2_End", "rfingers": "rmiddle2_End"}
    root = humanoid(clavicle=30.0)          # no hand to go by: the two longest bones
    names = bone_names(root)
    got, m = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert (got["lshoulder"], got["lelbow"], got["lwrist"]) == ("lclav", "lshoulder", "lelbow")


def test_sides_from_the_knees_without_feet(tmp_path):
    """No feet (the ankle's End Site has zero length): the bent knees give forward."""
    root = humanoid()
    for n in joints(root):
        if n.name in ("ltoe", "rtoe"):
            n.offset, n.children[0].offset = "0.0 0.0 0.0", "0.0 0.0 0.0"
    names = bone_names(root)
    bent = [{f"{s}hip": (0, -30.0 - k, 0) for s in "lr"} | {f"{s}knee": (0, 60.0 + k, 0)
                                                          for s in "lr"} for k in range(4)]
    got, m = mapped(write_bvh(tmp_path / "h.bvh", root, bent, names=names), names=names)
    assert got == {**EXPECTED, "ltoes": "ltoe_End", "rtoes": "rtoe_End"}
    assert "(knees bend forward)" in m.smap.how
    with pytest.raises(MtannoError, match="cannot tell the left leg from the right"):
        read_motion(write_bvh(tmp_path / "s.bvh", root, 2, names=names))


def test_named_sides_on_the_wrong_side_follow_the_pose(tmp_path):
    """Meaningless names with side marks on the wrong sides: the hierarchy is used and
    the pose, not the marks, gives the sides."""
    root = humanoid()
    names = {k: f"Bone{i:02d}" + ({"l": "_R", "r": "_L"}.get(k[0], "") if k != "ref" else "")
             for i, k in enumerate(bone_names(root), 1)}
    got, m = mapped(write_bvh(tmp_path / "h.bvh", root, names=names), names=names)
    assert got == EXPECTED and m.smap.name == "guessed-hierarchy"


# --------------------------------------------------------------------------------------
# rigs that are not humanoid: one line saying why
# --------------------------------------------------------------------------------------

def quadruped() -> Node:
    """Four legs under a horizontal spine (along +Z), a tail, a neck and head in front."""
    def leg(s: str, x: float) -> Node:
        return J(f"{s}hip", (x * 8, -4, 0), J(f"{s}knee", (0, -25, 0), J(
            f"{s}ankle", (0, -25, 0), J(f"{s}toe", (0, -5, 5), end=(0, 0, 3)))))

    def front(s: str, x: float) -> Node:
        return J(f"{s}clav", (x * 6, -3, 0), J(f"{s}shoulder", (x * 3, -3, 0), J(
            f"{s}elbow", (0, -24, 0), J(f"{s}wrist", (0, -24, 0), end=(0, -3, 4)))))

    chest = J("chest", (0, 0, 15), front("l", 1), front("r", -1),
              J("neck", (0, 10, 12), J("head", (0, 6, 10), end=(0, 2, 14))))
    return J("pelvis", (0, 60, 0), leg("l", 1), leg("r", -1),
             J("tail", (0, 2, -10), J("tail2", (0, -4, -15), end=(0, -6, -15))),
             J("spine", (0, 0, 15), J("spine2", (0, 0, 15), chest)))


def chain() -> Node:
    node = J("c9", (0, 10, 0))
    for k in range(8, -1, -1):
        node = J(f"c{k}", (0, 10, 0), node)
    return node


def hand() -> Node:
    return J("wrist", (0, 100, 0), *(J(f"f{k}1", (k - 2, 3, 8), J(f"f{k}2", (0, 0, 4), J(
        f"f{k}3", (0, 0, 3), end=(0, 0, 2)))) for k in range(5)))


def legs_only() -> Node:
    root = humanoid()
    spine1 = next(n for n in joints(root) if n.name == "spine1")
    spine1.children = [J("spine2", (0, 14, 0), J("neck", (0, 24, 0), end=(0, 20, 0)))]
    return root


def short_spine() -> Node:
    """Arms and neck branch off the spine's first joint: no room for belly and chest."""
    root = humanoid()
    pelvis = next(n for n in joints(root) if n.name == "pelvis")
    chest = next(n for n in joints(root) if n.name == "chest")
    chest.offset = "0.0 38.0 0.0"
    pelvis.children[2] = chest
    return root


NOT_HUMANOID = {
    "quadruped": (quadruped, "the legs do not point away from the spine (mean cosine of "
                             "their directions -0.17 on 2 frames, -0.17 in the rest pose): "
                             "four legs, not two?"),
    "chain": (chain, "no joint has three branches (two legs and a spine)"),
    "hand": (hand, "no joint above wrist (where two legs and the spine would meet) where two "
                   "arms and the neck branch off"),
    "legs-only": (legs_only, "no joint above pelvis (where two legs and the spine would "
                             "meet) where two arms and the neck branch off"),
    "short-spine": (short_spine, "the spine from the pelvis (pelvis) to the shoulders "
                                 "(chest) has too few joints for a belly and a chest"),
}


def not_humanoid_file(tmp_path: Path, kind: str) -> Path:
    """A BVH of a rig that is not a humanoid's (:data:`NOT_HUMANOID`), its names kept
    (none of them is a name the name-based guess knows)."""
    return write_bvh(tmp_path / f"{kind}.bvh", NOT_HUMANOID[kind][0]())


@pytest.mark.parametrize("kind", sorted(NOT_HUMANOID))
def test_not_humanoid_refused_in_one_line(tmp_path, kind):
    path = not_humanoid_file(tmp_path, kind)
    why = NOT_HUMANOID[kind][1]
    with pytest.raises(HierarchyError) as e:
        hierarchy_map(*read_bvh(path))
    assert e.value.reason == why
    with pytest.raises(MtannoError) as e:
        read_motion(path)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{path}: no skeleton map fits this BVH rig")
    assert f"cannot be mapped automatically: from its hierarchy, {why}; the joint " \
        "names place " in msg and msg.endswith("; pass skeleton= MAP.toml (docs/formats.md)")
    for args in (["info", str(path)], ["skeleton", "guess", str(path)],
                 ["skeleton", "guess", "--method", "hierarchy", str(path)]):
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 2 and result.output.count("\n") == 1, result.output
        assert why in result.output and "--skeleton MAP.toml" in result.output


def test_method_hierarchy_and_options(tmp_path):
    root = humanoid()
    path = write_bvh(tmp_path / "h.bvh", root)    # names no convention knows
    assert guess_map(*read_bvh(path)).joints == EXPECTED
    smap = guess_map(*read_bvh(path), method="hierarchy")
    assert smap.name == "guessed-hierarchy" and smap.joints == EXPECTED
    assert smap.how.startswith("generated from the hierarchy and rest pose; pelvis pelvis")
    with pytest.raises(MtannoError, match="unknown method 'x'"):
        guess_map(*read_bvh(path), method="x")
    with pytest.raises(MtannoError, match="swap_sides= swaps the sides the joint names"):
        guess_map(*read_bvh(path), method="hierarchy", swap_sides=True)


# --------------------------------------------------------------------------------------
# mtanno info and mtanno skeleton guess
# --------------------------------------------------------------------------------------

def test_info_and_skeleton_guess(tmp_path):
    root = humanoid(hands="fingers")
    names = bone_names(root)
    src = write_bvh(tmp_path / "h.bvh", root, names=names)
    result = CliRunner().invoke(main, ["info", str(src)])
    assert result.exit_code == 0, result.output
    assert "skeleton map   guessed-hierarchy (generated)" in result.output
    assert "map made by    generated from the hierarchy and rest pose" in result.output
    out = tmp_path / "map.toml"
    result = CliRunner().invoke(main, ["skeleton", "guess", str(src), "-o", str(out)])
    assert result.exit_code == 0, result.output
    text = out.read_text(encoding="utf-8")
    assert "# generated from the hierarchy and rest pose" in text
    smap, used = load_map(out), read_motion(src).smap
    assert (smap.name, smap.joints, smap.heading_node, smap.heading_axis, smap.digest) == \
        (used.name, used.joints, used.heading_node, used.heading_axis, used.digest)
    X1, _ = features_from_motion(read_motion(src, skeleton=str(out)))
    X0, _ = features_from_motion(read_motion(src))
    assert (X1 == X0).all()


# --------------------------------------------------------------------------------------
# real data: Bandai clips renamed, reflected; a CMU-style BVH renamed
# --------------------------------------------------------------------------------------

CLIPS = ("dataset-1_walk_normal_001.bvh", "dataset-1_bow_musical_001.bvh",
         "dataset-1_punch_normal_002.bvh")

JAPANESE = {"joint_Root": "全ての親", "Hips": "センター", "Spine": "上半身", "Chest": "上半身2",
            "Neck": "首", "Head": "頭",
            **{f"{a}_{S}": f"{side}{b}" for S, side in (("L", "左"), ("R", "右"))
               for a, b in (("Shoulder", "肩"), ("UpperArm", "腕"), ("LowerArm", "ひじ"),
                            ("Hand", "手首"), ("UpperLeg", "足"), ("LowerLeg", "ひざ"),
                            ("Foot", "足首"), ("Toes", "つま先"))}}
CYRILLIC = {"joint_Root": "корень", "Hips": "таз", "Spine": "позвоночник", "Chest": "грудь",
            "Neck": "шея", "Head": "голова",
            **{f"{a}_{S}": f"{b}_{side}" for S, side in (("L", "Л"), ("R", "П"))
               for a, b in (("Shoulder", "ключица"), ("UpperArm", "плечо"),
                            ("LowerArm", "предплечье"), ("Hand", "кисть"),
                            ("UpperLeg", "бедро"), ("LowerLeg", "голень"), ("Foot", "стопа"),
                            ("Toes", "пальцы"))}}


def _scheme(scheme: str, names: list[str]) -> dict[str, str]:
    """Bandai joint name → its name in ``scheme``."""
    rng = random.Random(31)
    if scheme == "bone":
        return {n: f"Bone{k:02d}" for k, n in enumerate(names, 1)}
    if scheme == "j00":
        return {n: f"j{k:02d}" for k, n in enumerate(names)}
    if scheme in ("random", "shuffled"):
        return {n: "".join(rng.choice("abcdefghijklmnopqrstuvwxyz0123456789")
                           for _ in range(8)) for n in names}
    if scheme == "japanese":
        return JAPANESE
    if scheme == "cyrillic":
        return CYRILLIC
    if scheme == "wrong-sides":  # side marks, but on the other side
        return {n: f"Bone{k:02d}" + ("_R" if n.endswith("_L") else "_L"
                                     if n.endswith("_R") else "")
                for k, n in enumerate(names, 1)}
    raise AssertionError(scheme)


def _require(path: Path) -> None:
    if not path.exists():
        pytest.skip(f"../shared/data not present: {path} is expected for this test")


@pytest.fixture(scope="module")
def bandai() -> dict[str, Path]:
    _require(SHARED_DATA / "bandai" / "set1.tar.xz")
    clips = {p.name: p for p in bandai_clips("set1.tar.xz")}
    return {c: clips[c] for c in CLIPS}


def _read(path: Path, **kw):
    m = read_motion(path, **kw)
    return features_from_motion(m)[0], m


def _renamed_map(smap, ren: dict[str, str]) -> dict[str, str]:
    back = {v + end: k + end for k, v in ren.items() for end in ("", "_End")}
    return {k: back[v] for k, v in smap.joints.items()}


@pytest.mark.realdata
@pytest.mark.parametrize("scheme", ["bone", "j00", "random", "japanese", "cyrillic",
                                    "shuffled", "wrong-sides"])
@pytest.mark.parametrize("clip", CLIPS)
def test_bandai_renamed(bandai, tmp_path, clip, scheme):
    """The renamed rig gets the Bandai map, so its features equal the named rig's."""
    text = bandai[clip].read_text(encoding="utf-8")
    X0, m0 = _read(bandai[clip])
    b = parse_bvh(text)
    names = [n.name for n in b.nodes() if not n.end]
    ren = _scheme(scheme, names)
    b.rename(ren)
    if scheme == "shuffled":
        shuffle_children(b.root, 7)
    X, m = _read(b.write(tmp_path / "r.bvh"))
    assert m.smap.name == "guessed-hierarchy"
    assert _renamed_map(m.smap, ren) == m0.smap.joints
    assert m.smap.heading_axis == m0.smap.heading_axis
    assert X.shape == X0.shape and np.mean(X == X0) >= 0.999
    assert (X == X0).all()


def _reflect_bvh(b: Bvh) -> Bvh:
    """The motion reflected in X: offsets and X positions negated, rotations about Y and
    Z reversed (M·R_y(θ)·M = R_y(−θ) for M = diag(−1, 1, 1))."""
    def neg(v: str) -> str:
        return v[1:] if v.startswith("-") else "-" + v

    for n in b.nodes():
        x, y, z = n.offset.split()
        n.offset = f"{neg(x)} {y} {z}"
        for k, ch in enumerate(n.channels if n.cols else ()):
            if ch in ("Xposition", "Yrotation", "Zrotation"):
                for row in b.rows:
                    row[n.cols[0] + k] = neg(row[n.cols[0] + k])
    return b


@pytest.mark.realdata
@pytest.mark.parametrize("clip", CLIPS)
def test_bandai_reflected(bandai, tmp_path, clip):
    """A clip reflected in X and renamed is read as the mirror image it shows: the joints
    named _L lie on the subject's right and become the right canonical joints. Its
    features equal those of the reflected clip with its Bandai names read with the Bandai
    map's sides exchanged, and (up to F1/F2, whose unit is the left humerus for both
    hands) the original's with left and right swapped."""
    text = bandai[clip].read_text(encoding="utf-8")
    X0, m0 = _read(bandai[clip])
    named = _reflect_bvh(parse_bvh(text)).write(tmp_path / "named.bvh")
    swapped = tmp_path / "swapped.toml"
    from dataclasses import replace
    swapped.write_text(map_toml(replace(m0.smap, name="bandai-swapped",
                                        joints=swap_lr(m0.smap.joints),
                                        heading_axis=(0.0, 1.0, 0.0))), encoding="utf-8")
    Xn, _ = _read(named, skeleton=str(swapped))
    b = _reflect_bvh(parse_bvh(text))
    ren = _scheme("bone", [n.name for n in b.nodes() if not n.end])
    X, m = _read(b.rename(ren).write(tmp_path / "r.bvh"))
    assert _renamed_map(m.smap, ren) == swap_lr(m0.smap.joints)
    assert m.smap.heading_axis == (0.0, 1.0, 0.0)
    assert (X == Xn).all()
    perm = mirror_permutation()
    assert np.mean(X == X0[perm]) >= 0.99
    assert (X[2:] == X0[perm][2:]).mean() >= 0.999


@pytest.mark.realdata
def test_bandai_named_mirrored_by_the_names(bandai, tmp_path):
    """A rig no map file fits whose names put left on the subject's right (Mixamo names,
    sides exchanged): the pose decides, so the features equal the correctly named rig's."""
    from test_rig_guess import _mixamo, _swap_names

    text = bandai[CLIPS[0]].read_text(encoding="utf-8")
    X0, _ = _read(bandai[CLIPS[0]])
    X, m = _read(_swap_names(_mixamo(parse_bvh(text))).write(tmp_path / "m.bvh"))
    assert m.smap.joints["lknee"] == "RightLeg" and (X == X0).all()


@pytest.mark.realdata
@pytest.mark.parametrize("amc", ["02_01.amc", "02_05.amc"])
def test_cmu_style_renamed(tmp_path, amc):
    """A CMU-style BVH (cgspeed layout: thumbs, long clavicles, zero-length hip joints)
    made from a real CMU AMC file, renamed j00…: the cmu-bvh map, the same features."""
    folder = SHARED_DATA / "cmu_02"
    _require(folder / amc)
    src = tmp_path / "c.bvh"
    src.write_text(cmu_style_bvh(folder / amc, folder / "02.asf"), encoding="utf-8")
    X0, m0 = _read(src)
    assert m0.smap.name == "cmu-bvh"
    b = parse_bvh(src.read_text(encoding="utf-8"))
    ren = _scheme("j00", [n.name for n in b.nodes() if not n.end])
    X, m = _read(b.rename(ren).write(tmp_path / "j.bvh"))
    assert _renamed_map(m.smap, ren) == m0.smap.joints
    assert m.smap.heading_axis == m0.smap.heading_axis
    assert "the wrist where the fingers branch off" in m.smap.how
    assert (X == X0).all()


def test_names_first(tmp_path, monkeypatch):
    """A rig the names place is never looked at as a hierarchy (speed: names first)."""
    import mtanno.io.guess as guess

    def fail(*a, **k):
        raise AssertionError("hierarchy_map called")

    monkeypatch.setattr(guess, "hierarchy_map", fail)
    root = humanoid()
    path = write_bvh(tmp_path / "h.bvh", root, names={
        "pelvis": "Hips", "lhip": "LeftUpLeg", "rhip": "RightUpLeg", "lknee": "LeftLeg",
        "rknee": "RightLeg", "lankle": "LeftFoot", "rankle": "RightFoot", "head": "Head",
        "neck": "Neck", "lelbow": "LeftForeArm", "relbow": "RightForeArm",
        "lshoulder": "LeftArm", "rshoulder": "RightArm"})
    assert read_motion(path).smap.name == "guessed-mixamo-style"
    assert re.search("hierarchy", read_motion(path).smap.how) is None
