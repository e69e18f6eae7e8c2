"""Skeleton maps made automatically for BVH rigs that no map file fits.

Most BVH archives use one of a few naming conventions (Mixamo with or without the
``mixamorig:`` prefix, MotionBuilder/HumanIK, the Unreal mannequin, SMPL/SMPL-X, the CMU
conversions, Xsens, Rokoko). Their joint names differ, but the anatomy they describe does
not, so the 22 canonical joints (:data:`~mtanno.io.rigs.CANONICAL_JOINTS`) are placed from a
few names and the tree:

* names give the side (``Left…``, ``…_l``, ``L_…``, ``….R``) and anchor each limb on its
  middle joint: a knee (``Leg``, ``LowerLeg``, ``calf``, ``Knee``, ``Shin``) and an elbow
  (``ForeArm``, ``lowerarm``, ``Elbow``), plus ``Head`` and ``Neck``;
* the tree does the rest: hip = parent of the knee, ankle = next joint below it, toes = the
  tip of the chain below the ankle; shoulder = parent of the elbow, wrist = next joint
  below it, fingers = the tip of the middle (else index, else any non-thumb) finger, or the
  wrist's End Site when the rig has no fingers (as the Bandai map does); the pelvis (root)
  is where both legs and the spine meet, so a reference or ground node above it is left
  out; the spine is the path from the pelvis to the neck: its lowest joint is the belly,
  its last one below the neck the chest (skipping joints that sit on the neck, as the CMU
  conversions' ``Spine1``); head top = the tip of the chain above the head (face joints
  such as eyes and jaw left out);
* twist and roll bones, IK helpers and props are never on a chain; fingers are used only
  for the finger tips;
* the heading axis (F40) is the vector from the right to the left hip in the rest pose,
  in the pelvis frame, snapped to a coordinate axis when within 10° of one (rigs align the
  pelvis frame with the body; the hips' small asymmetry of a real subject should not tilt
  it), as the Bandai map's comment derives it;
* the sides are checked against the pose: ``cross(up, forward)`` points to the subject's
  left (``up`` = pelvis → neck, ``forward`` = ankles → toes, right-handed coordinates),
  so where joints named left lie on the right (mirrored naming), for the legs or for the
  arms, the pose decides: those limbs' sides are swapped (``method="names"`` refuses
  them instead).

Where the names do not place every joint (``Bone01``…, names in another script, two
joints named like a knee), the map is made from the hierarchy and pose alone
(:func:`mtanno.io.topology.hierarchy_map`); names come first because they are cheaper and
say more (a face joint, a prop). The result is an ordinary
:class:`~mtanno.io.rigs.SkeletonMap`, so the pipeline does not change; :func:`map_toml`
writes it as a map file (``mtanno skeleton guess``) that ``--skeleton MAP.toml`` reads
back to the same map. A map file that fits the rig always wins (:func:`choose_map`).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.rigs import CANONICAL_JOINTS, SkeletonMap, available_maps, builtin_dir, select_map
from mtanno.io.skeleton import Channels, Rig
from mtanno.io.topology import (
    HierarchyError,
    heading_axis,
    hierarchy_map,
    sample_positions,
    side_score,
)

__all__ = ["choose_map", "guess_map", "map_toml", "classify_name", "METHODS"]

# Name parts -----------------------------------------------------------------------------
_NAMESPACE = re.compile(r"^.*[:|]")           # mixamorig:, mixamorig1:, Character1:, DAG paths
_WORDS = re.compile(r"[A-Z]+(?=[A-Z][a-z]|\d|\b)|[A-Z]?[a-z]+|[A-Z]+|\d+")
_LEFT, _RIGHT = {"l", "left", "lf", "lft"}, {"r", "right", "rt", "rgt"}
#: Words of a joint that is never on a limb or spine chain.
_EXCLUDED = {"twist", "roll", "ik", "pole", "ctrl", "control", "helper", "prop", "weapon",
             "attach", "socket", "target", "corrective", "fk"}
_FACE = {"eye", "jaw", "tongue", "teeth", "tooth", "ear", "nose", "brow", "lip", "cheek",
         "mouth", "chin", "lid", "eyelid", "hair", "smplhf"}
_FINGER_ORDER = ("middle", "index", "ring", "pinky", "little", "finger", "hand")
_THUMB = {"thumb"}
#: Middle joints of the limbs, by their side-free core name (words joined, no digits).
_KNEE = {"leg", "lowerleg", "leglower", "loleg", "calf", "knee", "shin", "tibia", "crus"}
_ELBOW = {"forearm", "lowerarm", "armlower", "loarm", "elbow", "radius"}
#: Canonical joint → its mirror image (``lhip`` ↔ ``rhip``, ...).
_SWAP = {k: ("r" if k[0] == "l" else "l") + k[1:] for k in CANONICAL_JOINTS
         if k[0] in "lr" and k != "root"}
_SIDE_OK = 0.3  # mean cosine needed to confirm (or, negative, to refute) the named sides


@dataclass(frozen=True)
class NameInfo:
    """What a joint name says: its side (``"l"``, ``"r"`` or ``""``), the side-free
    core (lower-case words joined, digits dropped) and its words."""

    side: str
    core: str
    words: tuple[str, ...]


def classify_name(name: str, prefix: str = "") -> NameInfo:
    """Side and core of one joint name (``mixamorig:LeftUpLeg`` → ``l``, ``upleg``;
    ``thigh_l`` → ``l``, ``thigh``; ``L_Hip`` → ``l``, ``hip``; ``L5`` → no side, since
    nothing but a number would remain). ``prefix`` is a rig-wide prefix to drop first."""
    base = _NAMESPACE.sub("", name)
    if prefix and base.startswith(prefix) and len(base) > len(prefix):
        base = base[len(prefix):]
    words = [w.lower() for part in re.split(r"[^A-Za-z0-9]+", base) if part
             for w in _WORDS.findall(part)]
    side = ""
    for k in (0, len(words) - 1):
        if words and words[k] in _LEFT | _RIGHT:
            rest = words[:k] + words[k + 1:]
            if any(not w.isdigit() for w in rest):
                side = "l" if words[k] in _LEFT else "r"
                words = rest
                break
    if not side:  # "HandLeft", "Left_Hand_Index": a side word anywhere
        for k, w in enumerate(words):
            if w in ("left", "right"):
                side, words = w[0], words[:k] + words[k + 1:]
                break
    core = "".join(w for w in words if not w.isdigit())
    return NameInfo(side, core, tuple(words))


def _common_prefix(names: Sequence[str]) -> str:
    """A prefix ending in a separator that most joints share (``Character1_``, ``Bip01 ``),
    dropped before the names are read; empty when there is none."""
    counts: dict[str, int] = {}
    for n in names:
        m = re.match(r"^([A-Za-z0-9]+[_ .])", _NAMESPACE.sub("", n))
        if m:
            counts[m.group(1)] = counts.get(m.group(1), 0) + 1
    best = max(counts.items(), key=lambda kv: kv[1], default=("", 0))
    if best[1] > len(names) / 2 and classify_name(best[0]).side == "":
        return best[0]
    return ""


class _Tree:
    """The rig as a tree with what each joint's name says, and its rest-pose positions."""

    def __init__(self, rig: Rig):
        self.rig = rig
        self.names = list(rig.names)
        self.parents = [int(p) for p in rig.parents]
        self.children: list[list[int]] = [[] for _ in self.names]
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(j)
        self.end_sites = set(rig.meta.get("end_sites", ()))
        real = [n for n in self.names if n not in self.end_sites]
        self.prefix = _common_prefix(real)
        self.info = [classify_name(n, self.prefix) for n in self.names]
        self.rest = np.zeros((len(self.names), 3))
        for j, p in enumerate(self.parents):  # parents come first
            self.rest[j] = (self.rest[p] if p >= 0 else 0.0) + rig.offsets[j]
        self.depth = [0] * len(self.names)
        for j, p in enumerate(self.parents):
            self.depth[j] = self.depth[p] + 1 if p >= 0 else 0

    def excluded(self, j: int) -> bool:
        return bool(_EXCLUDED & set(self.info[j].words))

    def is_end(self, j: int) -> bool:
        return self.names[j] in self.end_sites

    def ancestors(self, j: int) -> list[int]:
        """``j``'s ancestors, nearest first."""
        out = []
        while self.parents[j] >= 0:
            j = self.parents[j]
            out.append(j)
        return out

    def path(self, a: int, b: int) -> list[int]:
        """Nodes from ancestor ``a`` down to ``b``, both included."""
        up = [b] + self.ancestors(b)
        return list(reversed(up[:up.index(a) + 1]))

    def lca(self, nodes: Sequence[int]) -> int:
        common = None
        for j in nodes:
            chain = [j] + self.ancestors(j)
            common = chain if common is None else [a for a in chain if a in set(common)]
        return common[0]

    def height(self, j: int) -> int:
        """Longest chain of joints below ``j``."""
        return max((1 + self.height(c) for c in self.children[j]), default=0)

    def next_joints(self, j: int) -> list[int]:
        """The chain joints directly below ``j``: its children, with excluded ones (twist,
        roll, props) replaced by what hangs below them."""
        out = []
        for c in self.children[j]:
            out.extend(self.next_joints(c) if self.excluded(c) else [c])
        return out

    def parent_joint(self, j: int) -> int:
        """``j``'s parent, skipping excluded joints (a twist bone between two chain joints)."""
        p = self.parents[j]
        while p >= 0 and self.excluded(p):
            p = self.parents[p]
        return p

    def tip(self, j: int, avoid=frozenset()) -> int:
        """The end of the chain below ``j``: at each step the child whose words do not meet
        ``avoid``, and of those the one with the longest chain below it (first in file
        order on a tie); ``j`` itself if it has none."""
        while True:
            nxt = [c for c in self.next_joints(j) if not avoid & set(self.info[c].words)]
            if not nxt:
                return j
            j = max(nxt, key=lambda c: (self.height(c), -c))


@dataclass
class _Placement:
    joints: dict[str, int]
    problems: dict[str, str]


def _place_limbs(t: _Tree, out: _Placement) -> None:
    """Hips, knees, ankles, toes; shoulders, elbows, wrists, fingers (both sides)."""
    for side in ("l", "r"):
        for anchor, vocab, names in (
                ("knee", _KNEE, ("hip", "knee", "ankle", "toes")),
                ("elbow", _ELBOW, ("shoulder", "elbow", "wrist", "fingers"))):
            keys = [side + n for n in names]
            cands = [j for j, i in enumerate(t.info)
                     if i.side == side and i.core in vocab and not t.excluded(j)
                     and not t.is_end(j)]
            if len(cands) != 1:
                why = (f"no joint named like a {'left' if side == 'l' else 'right'} {anchor}"
                       if not cands else
                       f"several {anchor} candidates ({', '.join(t.names[j] for j in cands)})")
                for k in keys:
                    out.problems.setdefault(k, why)
                continue
            mid = cands[0]
            top = t.parent_joint(mid)
            below = t.next_joints(mid)
            if top < 0 or not below:
                for k in keys:
                    out.problems.setdefault(k, f"{t.names[mid]} is not in the middle of a chain")
                continue
            below = [j for j in below if not t.is_end(j)] or below
            low = max(below, key=lambda c: (t.height(c), -c))
            out.joints.update({keys[0]: top, keys[1]: mid, keys[2]: low})
            out.joints[keys[3]] = (t.tip(low) if anchor == "knee" else _finger_tip(t, low))


def _finger_tip(t: _Tree, wrist: int) -> int:
    """The finger tip below the wrist: the middle finger's chain, else the index finger's,
    …, never the thumb's; without named fingers the tip of the wrist's chain (its End Site)."""
    below = [j for j in range(len(t.names)) if wrist in t.ancestors(j) and not t.excluded(j)]
    for word in _FINGER_ORDER:
        named = [j for j in below if word in t.info[j].words and not _THUMB & set(t.info[j].words)]
        if named:
            top = min(named, key=lambda j: (t.depth[j], j))
            return t.tip(top, avoid=frozenset(_THUMB))
    return t.tip(wrist, avoid=frozenset(_THUMB | {"prop", "weapon"}))


def _place_trunk(t: _Tree, out: _Placement) -> None:
    """Root (pelvis), belly, chest, neck, head and head top."""
    heads = [j for j, i in enumerate(t.info) if i.core == "head" and not i.side
             and not t.is_end(j)]
    if len(heads) != 1:
        why = "no joint named Head" if not heads else \
            f"several head candidates ({', '.join(t.names[j] for j in heads)})"
        for k in ("head", "headtop", "neck", "chest", "belly", "root"):
            out.problems.setdefault(k, why)
        return
    head = heads[0]
    out.joints["head"] = head
    out.joints["headtop"] = t.tip(head, avoid=frozenset(_FACE))
    hips = [out.joints[k] for k in ("lhip", "rhip") if k in out.joints]
    if not hips:
        for k in ("root", "belly", "chest", "neck"):
            out.problems.setdefault(k, "no hip to find the pelvis by")
        return
    pelvis = t.lca([*hips, head])
    out.joints["root"] = pelvis
    chain = t.path(pelvis, head)[1:-1]  # between the pelvis and the head
    necks = [j for j in chain if t.info[j].core.startswith("neck")]
    if necks:
        neck = necks[0]
    else:  # no joint named neck: the one above where the arms branch off
        arms = [out.joints[k] for k in ("lshoulder", "rshoulder") if k in out.joints]
        branch = t.lca(arms) if len(arms) == 2 else -1
        after = [j for j in chain if branch in t.ancestors(j)]
        if not after:
            for k in ("neck", "chest", "belly"):
                out.problems.setdefault(k, "no joint named Neck and none between the "
                                           "shoulders' branch and the head")
            return
        neck = after[0]
    out.joints["neck"] = neck
    spine = chain[:chain.index(neck)]
    if not spine:
        for k in ("belly", "chest"):
            out.problems.setdefault(k, f"no joint between the pelvis "
                                       f"({t.names[pelvis]}) and the neck ({t.names[neck]})")
        return
    out.joints["belly"] = spine[0]
    scale = float(np.linalg.norm(t.rest[head] - t.rest[pelvis])) or 1.0
    apart = [j for j in spine if np.linalg.norm(t.rest[neck] - t.rest[j]) > 1e-6 * scale]
    out.joints["chest"] = apart[-1] if apart else spine[-1]


def _side_scores(t: _Tree, j: dict[str, int], channels: Channels | None,
                 ) -> tuple[float | None, float | None, str]:
    """Mean cosine between the named-left minus named-right vector and the subject's left
    (``cross(up, forward)``), for the legs and the arms, over up to 64 frames (the rest
    pose without channels); None where no frame gives a usable direction. Also says which
    pose was used (``64 frames``, ``the rest pose``)."""
    pos, where = sample_positions(t.rig, channels)
    up = pos[:, j["neck"]] - pos[:, j["root"]]
    fwd = (pos[:, j["ltoes"]] - pos[:, j["lankle"]]) + (pos[:, j["rtoes"]] - pos[:, j["rankle"]])
    return (side_score(pos, up, fwd, j["lhip"], j["rhip"]),
            side_score(pos, up, fwd, j["lshoulder"], j["rshoulder"]), where)


_CONVENTIONS = (  # (label, slug, side-free cores or raw names that mark it)
    ("Mixamo, mixamorig: prefix", "mixamo", ("mixamorig",)),
    ("CMU BVH conversion", "cmu", ("LHipJoint", "RHipJoint")),
    ("Unreal mannequin", "unreal", ("thigh_l", "calf_l", "upperarm_l", "lowerarm_l")),
    ("SMPL/SMPL-X", "smpl", ("L_Hip", "L_Collar", "left_collar", "left_hip")),
    ("Xsens MVN", "xsens", ("L5", "T8", "T12")),
    ("Rokoko", "rokoko", ("LeftThigh", "LeftShin")),
    ("MotionBuilder/HumanIK", "humanik", ("Reference", "LeftUpLegRoll", "LeftArmRoll")),
    ("Bandai Namco style", "bandai", ("UpperLeg_L", "LowerLeg_L")),
    ("Mixamo/HumanIK style", "mixamo-style", ("LeftUpLeg", "LeftForeArm")),
)


def _convention(t: _Tree) -> tuple[str, str]:
    """Which naming convention the names look like (for messages and the map's name)."""
    bare = {_NAMESPACE.sub("", n)[len(t.prefix):] if _NAMESPACE.sub("", n).startswith(t.prefix)
            else _NAMESPACE.sub("", n) for n in t.names}
    for label, slug, marks in _CONVENTIONS:
        if slug == "mixamo":
            if any(n.lower().startswith("mixamorig") for n in t.names):
                return label, slug
        elif any(m in bare for m in marks):
            return label, slug
    return "generic names", "generic"


#: How :func:`guess_map` places the joints.
METHODS = ("auto", "names", "hierarchy")
_LEG_KEYS = ("hip", "knee", "ankle", "toes")
_ARM_KEYS = ("shoulder", "elbow", "wrist", "fingers")


class _NamesFailed(Exception):
    """The names do not place every canonical joint: ``detail`` lists what and why (the
    error of the names alone), ``note`` says it in a few words (the ``how`` of a map made
    from the hierarchy instead, and the error where the hierarchy fails too and the names
    placed few joints)."""

    def __init__(self, detail: str, note: str, missing: int):
        super().__init__(detail)
        self.detail, self.note, self.missing = detail, note, missing


def _names_map(rig: Rig, channels: Channels | None, *, swap_sides: bool,
               strict: bool) -> SkeletonMap:
    """The map made from the joint names and the tree (module docstring). Sides the pose
    contradicts are an error with ``strict`` ("mirrored naming"), else swapped (the pose
    decides)."""
    t = _Tree(rig)
    out = _Placement({}, {})
    _place_limbs(t, out)
    _place_trunk(t, out)
    missing = [k for k in CANONICAL_JOINTS if k not in out.joints]
    if missing:
        reasons: dict[str, list[str]] = {}
        for k in missing:
            reasons.setdefault(out.problems.get(k, "not found"), []).append(k)
        detail = "; ".join(f"{', '.join(ks)}: {why}" for why, ks in reasons.items())
        placed = len(CANONICAL_JOINTS) - len(missing)
        raise _NamesFailed(f"could not place {', '.join(missing)} ({detail})",
                           f"the joint names place none of the {len(CANONICAL_JOINTS)} joints"
                           if not placed else f"the joint names place {placed} of the "
                           f"{len(CANONICAL_JOINTS)} joints: {next(iter(reasons))}",
                           len(missing))
    j = out.joints
    if swap_sides:
        j = {_SWAP.get(k, k): v for k, v in j.items()}
    legs, arms, where = _side_scores(t, j, channels)
    bad = [(what, a, b) for what, s, a, b in (("legs", legs, "lhip", "rhip"),
                                               ("arms", arms, "lshoulder", "rshoulder"))
           if s is not None and s < -_SIDE_OK]
    if bad and strict:
        detail = "; ".join(f"{t.names[j[a]]} lies on the subject's right of {t.names[j[b]]}"
                           for _, a, b in bad)
        raise MtannoError(f"mirrored naming: the {' and '.join(w for w, _, _ in bad)} named "
                          f"left are on the subject's right in the pose ({detail}; checked "
                          f"on {where}); fix the names, or write a map with `mtanno skeleton "
                          f"guess FILE --swap-sides -o MAP.toml` and pass --skeleton MAP.toml",
                          path=rig.source)
    for what, _, _ in bad:  # the pose decides: swap the limbs named the wrong way round
        keys = _LEG_KEYS if what == "legs" else _ARM_KEYS
        j = {**j, **{s + k: j[o + k] for k in keys for s, o in (("l", "r"), ("r", "l"))}}
    checked = [w for w, s in (("legs", legs), ("arms", arms)) if s is not None and s > _SIDE_OK]
    label, slug = _convention(t)
    named = f"sides from the names{' (swapped)' if swap_sides else ''}"
    sides = (f"sides from the pose on {where}: the {' and '.join(w for w, _, _ in bad)} "
             f"named left lie on the subject's right" + (
                 f", the {' and '.join(checked)} named as they lie" if checked else "")
             if bad else
             f"{named}, {' and '.join(checked)} confirmed by the pose on {where}" if checked
             else f"{named}, not confirmed by the pose ({where} gave no clear left/right)")
    how = (f"generated from the joint names ({label}) and the tree: limbs anchored on the "
           f"knees and elbows, pelvis where the legs and the spine meet; {sides}; heading "
           f"axis from the hips")
    joints = {k: t.names[j[k]] for k in CANONICAL_JOINTS}
    return SkeletonMap(
        name=f"guessed-{slug}", format="bvh", joints=joints,
        detect=tuple(sorted(set(joints.values()))),
        heading_node=joints["root"],
        heading_axis=heading_axis(t.rest, j["lhip"], j["rhip"], t.names, rig.source),
        path="generated", description=f"generated for a {label} BVH rig", how=how)


def guess_map(rig: Rig, channels: Channels | None = None, *, swap_sides: bool = False,
              method: str = "auto") -> SkeletonMap:
    """A skeleton map for a BVH rig no map file fits.

    ``method``: ``"names"`` places the joints from their names and the tree (module
    docstring) and refuses sides the pose contradicts ("mirrored naming");
    ``"hierarchy"`` from the hierarchy and pose alone
    (:func:`mtanno.io.topology.hierarchy_map`), for rigs whose names say nothing;
    ``"auto"`` (what :func:`choose_map` does) from the names, the pose deciding the sides,
    else from the hierarchy. ``channels`` (the motion) give the pose on up to 64 frames;
    without them the rest pose is used. ``swap_sides`` maps the joints named left to the
    right canonical joints and vice versa (names only). Raises one :class:`MtannoError`
    saying what could not be placed and why.
    """
    if rig.kind != "bvh":
        raise MtannoError(f"automatic skeleton maps are made for BVH rigs, not "
                          f"{rig.kind.upper()}", path=rig.source)
    if method not in METHODS:
        raise MtannoError(f"unknown method '{method}' (known: {', '.join(METHODS)})")
    if swap_sides and method == "hierarchy":
        raise MtannoError("{swap_sides} swaps the sides the joint names give; a map made "
                          "from the hierarchy takes them from the pose",
                          options=("swap_sides",))
    fix = "pass {skeleton} MAP.toml (docs/formats.md)"
    if method == "hierarchy":
        try:
            return hierarchy_map(rig, channels)
        except HierarchyError as exc:
            raise MtannoError(f"this BVH rig {exc.message}; {fix}", path=rig.source,
                              options=("skeleton",)) from None
    try:
        return _names_map(rig, channels, swap_sides=swap_sides,
                          strict=method == "names" or swap_sides)
    except _NamesFailed as names:
        failed = names
    head = "no skeleton map fits this BVH rig and it cannot be mapped automatically"
    if method == "names" or swap_sides:
        raise MtannoError(f"{head}: {failed.detail}; {fix}", path=rig.source,
                          options=("skeleton",))
    try:
        return hierarchy_map(rig, channels, names_note=failed.note)
    except HierarchyError as exc:
        names = failed.note if failed.missing > 8 else f"the joint names {failed.detail}"
        raise MtannoError(f"{head}: from its hierarchy, {exc.reason}; {names}; {fix}",
                          path=rig.source, options=("skeleton",)) from None


def choose_map(rig: Rig, skeleton: str | os.PathLike | None = None,
               channels: Channels | None = None) -> SkeletonMap:
    """The skeleton map :func:`mtanno.io.read_motion` uses: ``skeleton`` (a file or a map
    name) when given, else the first map on the search path that fits the rig, else, for
    a BVH rig, one made by :func:`guess_map`. The map's ``how`` says which and why."""
    if skeleton is not None:
        m = select_map(rig.kind, rig.names, skeleton, source=rig.source)
        return replace(m, how=f"given with --skeleton {skeleton}")
    for m in available_maps():
        if m.fits(rig):
            where = "built-in" if os.path.dirname(m.path) == str(builtin_dir()) else "map file"
            return replace(m, how=f"{where} map chosen because the rig has all its "
                                  f"{len(m.detect)} detect nodes")
    if rig.kind != "bvh":
        return select_map(rig.kind, rig.names, None, source=rig.source)  # raises
    return guess_map(rig, channels)


def map_toml(smap: SkeletonMap, *, source: str = "", version: str = "") -> str:
    """The text of a skeleton map file that :func:`~mtanno.io.rigs.load_map` reads back to
    the same map (name, format, detect nodes, heading and joints), with comments saying
    where it came from and how it was made."""
    def s(x: str) -> str:
        # a JSON string is a TOML basic string, if characters beyond U+FFFF stay as they
        # are (JSON's surrogate-pair escapes are no TOML) and DEL is escaped (TOML's rule)
        return json.dumps(x, ensure_ascii=False).replace("\x7f", "\\u007f")

    def lst(xs) -> str:
        return "[" + ", ".join(s(x) for x in xs) + "]"

    made = f" (mtanno {version})" if version else ""
    lines = [f"# Skeleton map generated by `mtanno skeleton guess`{made}"
             + (f" from {source}" if source else "") + ".",
             "# Check each joint before keeping it (docs/formats.md, skeleton maps);",
             "# drop it in ~/.config/mtanno/skeletons/ or pass it with --skeleton.",
             ]
    if smap.how:
        lines += ["# " + part.strip() for part in smap.how.split(";")]
    axis = ", ".join(repr(float(a)) for a in smap.heading_axis)
    lines += [
        f"name = {s(smap.name)}",
        f"description = {s(smap.description)}",
        f"format = {s(smap.format)}",
        f"detect = {lst(smap.detect)}",
        "# F40 (root turning): heading = G_node · axis, the vector from the right to the",
        "# left hip in the rest pose, in the pelvis frame",
        f"heading = {{ node = {s(smap.heading_node)}, axis = [{axis}] }}",
        "",
        "[joints]",
    ]
    lines += [f"{k} = {s(smap.joints[k])}" for k in CANONICAL_JOINTS if k in smap.joints]
    return "\n".join(lines) + "\n"
