"""Skeleton maps made from a BVH rig's hierarchy and pose alone, for rigs whose joint names
say nothing (``Bone01``…, ``j00``…, names in another language or script, names no
convention knows): :func:`hierarchy_map`, which :func:`mtanno.io.guess.guess_map` falls
back on when the names do not place the 22 canonical joints.

A humanoid's tree has a shape of its own, whatever its joints are called:

* the **pelvis** is the joint where two legs and the spine meet: two branches of at least
  three bones of non-zero length and about the same length (within 20 %), and a third
  that holds the **shoulder branch**, the joint where two arms (again such a pair) and the
  neck branch off. Of all such pairs of joints the one whose legs, arms, spine and head
  together are longest wins, so fingers, face joints, IK helpers, props and tails are
  left out;
* a limb is followed from its branch along the child with the longest chain below it
  (the longest finger, the toes), and joints at one place (zero-length bones, End Sites
  of zero length) count as one point;
* a **leg** breaks at its two longest consecutive bones, thigh and shin: hip, knee, ankle;
  toes = the chain's tip. An **arm** likewise (upper arm and forearm: shoulder, elbow,
  wrist), unless a hand is recognisable: then the wrist is the last joint where fingers
  branch off (side chains that lie along the bone, twist bones, do not count), or above
  it the end of the last two long bones (at least half the arm's longest) when the
  fingers branch off a palm joint; this also holds where the clavicle is longer than the
  forearm (the CMU rigs); fingers = the tip of the longest finger;
* the **spine** is the path from the pelvis to the shoulder branch: belly = its first joint,
  chest = its last one that does not sit on the neck; neck = the first joint of the neck
  branch; head top = the tip highest along the spine (not an eye or the jaw); head = the
  joint below it, or the head top's own joint when its End Site has zero length (the
  Bandai rig);
* **left and right** from the pose (up to 64 frames of the motion, else the rest pose):
  ``cross(up, forward)`` points to the subject's left, with up = pelvis → neck and forward
  = ankles → toes (toes point forward; where the feet give no direction, the bent knees
  do). So neither the children's order, nor bones that point along −X on one side
  (mirrored joint axes, as in the Bandai rig), nor a rest pose that is not a T-pose (the
  Bandai rest pose points most bones along X, the legs along the spine) changes the
  result; a rig
  reflected in X is read as the mirror image it shows (its features are the original's
  with left and right swapped);
* the **heading axis** (F40): the rest-pose vector from the right to the left hip in the
  pelvis frame, snapped to a coordinate axis within 10°, as for maps made from names.

A rig without that shape is not a humanoid and is refused with the reason, in one line
(:class:`HierarchyError`): no joint with three branches, no pair of legs, no shoulder
branch above the pelvis, legs that do not point away from the spine (four legs).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.rigs import CANONICAL_JOINTS, SkeletonMap
from mtanno.io.skeleton import Channels, Rig, forward_kinematics

__all__ = ["hierarchy_map", "HierarchyError", "sample_positions", "rest_positions",
           "heading_axis", "side_score"]

#: Frames of the motion the pose is read on (evenly spread over the clip).
MAX_FRAMES = 64
#: A heading axis within this many degrees of a coordinate axis is snapped to it.
SNAP_DEG = 10.0
#: Mean cosine that decides a pair's sides (below it in size: no clear left and right).
SIDE_OK = 0.3
_SAME_POINT = 1e-5   # bones shorter than this fraction of the body have zero length
_PAIR = 0.2          # two legs (two arms) differ in length by at most this fraction
_MIN_BONES = 3       # a leg or an arm has at least three bones of non-zero length
# legs point away from the spine: mean cosine of the leg and spine directions below these
# (humans: -0.7 to -1.0 on every Bandai set 1 clip, -1 in a T-pose; four legs: about 0)
_UPRIGHT_REST = -0.5
_UPRIGHT_POSE = -0.4
_TWIST_SPAN = 0.1    # a twist bone projects onto its bone within [-0.1, 1.1] of its length
_TWIST_OFF = 0.15    # ... and lies within 0.15 of the bone's length from its line
_LONG = 0.5          # upper arm and forearm: at least half the arm's longest bone


class HierarchyError(MtannoError):
    """A rig that :func:`hierarchy_map` cannot map; :attr:`reason` says why in one clause
    (``no joint has three branches …``), for a message that also gives the names' part."""

    def __init__(self, reason: str, *, path: str | None = None):
        self.reason = reason
        super().__init__(f"cannot be mapped from its hierarchy: {reason}", path=path)


def rest_positions(rig: Rig) -> np.ndarray:
    """(nodes × 3) positions with every rotation zero: the offsets summed from the root
    (the root's frame; for BVH the pose the file's offsets describe)."""
    rest = np.zeros((rig.n_nodes, 3))
    for j, p in enumerate(rig.parents):  # parents come first
        rest[j] = (rest[int(p)] if p >= 0 else 0.0) + rig.offsets[j]
    return rest


def sample_positions(rig: Rig, channels: Channels | None) -> tuple[np.ndarray, str]:
    """World positions of every node on up to :data:`MAX_FRAMES` frames spread evenly over
    the motion, or the rest pose without one; and where they come from, for messages
    (``64 frames``, ``the rest pose``)."""
    if channels is not None and channels.n_frames:
        idx = np.unique(np.linspace(0, channels.n_frames - 1,
                                    min(channels.n_frames, MAX_FRAMES)).astype(np.int64))
        pos, _ = forward_kinematics(rig, channels.angles[idx], channels.trans[idx],
                                    channels.has_trans)
        return pos, f"{len(idx)} frame{'s' if len(idx) != 1 else ''}"
    return rest_positions(rig)[None], "the rest pose"


def heading_axis(rest: np.ndarray, lhip: int, rhip: int, names: Sequence[str],
                 source: str | None) -> tuple[float, float, float]:
    """Unit vector from the right to the left hip in the rest pose (the pelvis frame: every
    rotation is zero there), snapped to a coordinate axis within :data:`SNAP_DEG`."""
    v = rest[lhip] - rest[rhip]
    n = float(np.linalg.norm(v))
    if n == 0.0:
        raise MtannoError(f"the hips {names[lhip]} and {names[rhip]} are at the same "
                          "point in the rest pose: no heading axis; pass {skeleton} MAP.toml",
                          path=source, options=("skeleton",))
    k = int(np.argmax(np.abs(v)))
    if abs(v[k]) / n >= math.cos(math.radians(SNAP_DEG)):
        axis = [0.0, 0.0, 0.0]
        axis[k] = 1.0 if v[k] > 0 else -1.0
        return (axis[0], axis[1], axis[2])
    u = v / n
    return (float(u[0]), float(u[1]), float(u[2]))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def side_score(pos: np.ndarray, up: np.ndarray, fwd: np.ndarray, a: int, b: int,
               ) -> float | None:
    """Mean cosine between ``pos[a] - pos[b]`` and the subject's left, ``cross(up, fwd)``,
    over the frames where both have a length (``up``, ``fwd``: frames × 3); None when no
    frame gives a usable direction."""
    left = np.cross(up, fwd)
    side = pos[:, a] - pos[:, b]
    den = np.linalg.norm(left, axis=1) * np.linalg.norm(side, axis=1)
    ok = den > 1e-9 * max(float(np.max(den, initial=0.0)), 1e-300)
    ok &= np.linalg.norm(fwd, axis=1) > 1e-3 * np.linalg.norm(up, axis=1)
    if not ok.any():
        return None
    return float(np.mean(np.sum(left[ok] * side[ok], axis=1) / den[ok]))


class _Body:
    """The rig as a tree with bone lengths measured on the sampled frames."""

    def __init__(self, rig: Rig, pos: np.ndarray):
        self.rig = rig
        self.names = list(rig.names)
        self.parents = [int(p) for p in rig.parents]
        n = len(self.names)
        self.children: list[list[int]] = [[] for _ in range(n)]
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(j)
        self.pos = pos
        self.seg = np.zeros(n)  # bone length from the parent (median over frames)
        self.reach = np.zeros(n)  # longest chain below the joint
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.seg[j] = float(np.median(np.linalg.norm(pos[:, j] - pos[:, p], axis=1)))
        for j in range(n - 1, 0, -1):  # children after their parents
            p = self.parents[j]
            if p >= 0:
                self.reach[p] = max(self.reach[p], self.seg[j] + self.reach[j])
        self.size = float(self.reach.max(initial=0.0))
        self.eps = _SAME_POINT * self.size

    def length(self, c: int) -> float:
        """Length of the longest chain through ``c`` from its parent."""
        return float(self.seg[c] + self.reach[c])

    def chain(self, c: int) -> list[int]:
        """``c`` and the joints below it along the longest chain (first in file order on
        a tie)."""
        out = [c]
        while self.children[c]:
            c = max(self.children[c], key=lambda k: (self.length(k), -k))
            out.append(c)
        return out

    def bones(self, c: int) -> int:
        """Bones of non-zero length on the longest chain through ``c``."""
        return sum(1 for j in self.chain(c) if self.seg[j] > self.eps)

    def groups(self, nodes: list[int]) -> list[list[int]]:
        """A chain split into points: each joint with the zero-length ones below it."""
        out: list[list[int]] = []
        for k, j in enumerate(nodes):
            if k == 0 or self.seg[j] > self.eps:
                out.append([j])
            else:
                out[-1].append(j)
        return out

    def below(self, j: int) -> list[int]:
        """``j`` and every node below it."""
        out, stack = [], [j]
        while stack:
            k = stack.pop()
            out.append(k)
            stack.extend(self.children[k])
        return out

    def path(self, a: int, b: int) -> list[int]:
        """Nodes from ancestor ``a`` down to ``b``, both included."""
        out = [b]
        while out[-1] != a:
            out.append(self.parents[out[-1]])
        return out[::-1]

    def is_below(self, j: int, a: int) -> bool:
        while j >= 0:
            if j == a:
                return True
            j = self.parents[j]
        return False

    def apart(self, a: int, b: int) -> bool:
        """True if ``a`` and ``b`` are not at one point in every frame."""
        return float(np.max(np.linalg.norm(self.pos[:, a] - self.pos[:, b], axis=1))) \
            > self.eps


def _pair(body: _Body, cands: list[int]) -> tuple[int, int] | None:
    """The two branches among ``cands`` (each with at least three bones) of about the same
    length, the longest such pair; None when there is none."""
    best, key = None, None
    for a, b in combinations(cands, 2):
        la, lb = body.length(a), body.length(b)
        if min(la, lb) < (1.0 - _PAIR) * max(la, lb):
            continue
        k = (min(la, lb), -(a + b))
        if key is None or k > key:
            best, key = (a, b), k
    return best


def _highest_tip(body: _Body, c: int, up: np.ndarray) -> int:
    """The tip below ``c`` highest along ``up`` (frames × 3) on average."""
    tips = [j for j in body.below(c) if not body.children[j]]
    return max(tips, key=lambda j: (float(np.mean(np.sum(body.pos[:, j] * up, axis=1))), -j))


@dataclass
class _Shape:
    """Pelvis, shoulder branch, the first joints of the legs and arms, the head top, and
    the length of it all (the candidate with the longest wins)."""

    pelvis: int
    chest: int
    legs: tuple[int, int]
    arms: tuple[int, int]
    head_tip: int
    total: float


def _find_shape(body: _Body) -> _Shape:
    """The (pelvis, shoulder branch) pair whose legs, arms, spine and head are longest."""
    limb = [body.bones(j) >= _MIN_BONES for j in range(len(body.names))]
    forks = [j for j, ch in enumerate(body.children) if len(ch) >= 3]
    if not forks:
        raise HierarchyError("no joint has three branches (two legs and a spine)")
    best: _Shape | None = None
    pelvises = []  # joints with two legs and a third branch
    for p in forks:
        kids = body.children[p]
        if not any(_pair(body, [j for j in kids if j != s and limb[j]]) for s in kids):
            continue
        pelvises.append(p)
        for c in forks:
            if c == p or not body.is_below(c, p):
                continue
            spine_child = body.path(p, c)[1]
            legs = _pair(body, [j for j in kids if j != spine_child and limb[j]])
            arms = _pair(body, [j for j in body.children[c] if limb[j]])
            if legs is None or arms is None:
                continue
            rest = [j for j in body.children[c] if j not in arms]
            if not rest:
                continue
            up = _unit(body.pos[:, c] - body.pos[:, p])
            tip = max((_highest_tip(body, j, up) for j in rest),
                      key=lambda j: (float(np.mean(np.sum(body.pos[:, j] * up, axis=1))), -j))
            spine = body.path(p, c)
            total = (sum(body.length(j) for j in (*legs, *arms))
                     + float(sum(body.seg[j] for j in spine[1:]))
                     + float(sum(body.seg[j] for j in body.path(c, tip)[1:])))
            if best is None or total > best.total:
                best = _Shape(p, c, legs, arms, tip, total)
    if best is None:
        if not pelvises:
            raise HierarchyError("no joint has two legs (two chains of three or more bones "
                                 "of about the same length) and a spine")
        raise HierarchyError(f"no joint above {body.names[pelvises[0]]} (where two legs and "
                             "the spine would meet) where two arms and the neck branch off")
    return best


def _leg(body: _Body, c: int) -> tuple[int, int, int, int]:
    """Hip, knee, ankle, toes of the leg that starts at ``c``: the two longest consecutive
    bones are thigh and shin; toes = the chain's tip."""
    nodes = body.chain(c)
    g = body.groups(nodes)
    i = max(range(len(g) - 2), key=lambda k: (body.seg[g[k + 1][0]] + body.seg[g[k + 2][0]],
                                             -k))
    return g[i][0], g[i + 1][0], g[i + 2][0], nodes[-1]


def _twist_like(body: _Body, side: int, at: int, nxt: int) -> bool:
    """True if every joint of the side branch ``side`` of joint ``at`` lies along the bone
    ``at`` → ``nxt`` (a twist or roll bone), or at ``at`` itself."""
    nodes = body.below(side)
    d = body.pos[:, nodes] - body.pos[:, at, None]               # frames × k × 3
    if float(np.max(np.linalg.norm(d, axis=2))) <= body.eps:
        return True
    a = body.pos[:, nxt] - body.pos[:, at]                        # frames × 3
    aa = np.maximum(np.sum(a * a, axis=1), 1e-300)[:, None]
    t = np.sum(d * a[:, None], axis=2) / aa
    off = np.linalg.norm(d - t[..., None] * a[:, None], axis=2) / np.sqrt(aa)
    return bool(np.all((t >= -_TWIST_SPAN) & (t <= 1 + _TWIST_SPAN) & (off <= _TWIST_OFF)))


def _arm(body: _Body, c: int) -> tuple[int, int, int, int, bool]:
    """Shoulder, elbow, wrist, fingers of the arm that starts at ``c``, and whether the
    wrist was found where the fingers branch off (else at the two longest bones)."""
    nodes = body.chain(c)
    g = body.groups(nodes)
    long = _LONG * max(body.seg[k[0]] for k in g)
    for w in range(len(g) - 2, 1, -1):  # the last joint where fingers branch off
        nxt = g[w + 1][0]
        if any(s != nodes[nodes.index(j) + 1] and not _twist_like(body, s, j, nxt)
               for j in g[w] for s in body.children[j]):
            # fingers may branch off a palm joint below the wrist: the wrist ends the
            # last two long bones (upper arm, forearm) at or above the branch
            w = next((k for k in range(w, 1, -1) if body.seg[g[k][0]] >= long
                      and body.seg[g[k - 1][0]] >= long), 0)
            if w:
                return g[w - 2][0], g[w - 1][0], g[w][0], nodes[-1], True
            break
    hip, knee, ankle, tip = _leg(body, c)
    return hip, knee, ankle, tip, False


def _head(body: _Body, chest: int, tip: int) -> tuple[int, int]:
    """Neck and head on the path from the shoulder branch to the head top ``tip``."""
    nodes = body.path(chest, tip)[1:]
    g = body.groups(nodes)
    if len(g) < 2:
        raise HierarchyError(f"the neck ({body.names[nodes[0]]}) has no joint above it "
                             "for the head")
    if len(g[-1]) > 1:   # the head top sits on a joint (an End Site of zero length)
        return nodes[0], g[-1][0]
    if len(g) < 3:
        raise HierarchyError(f"no joint between the neck ({body.names[nodes[0]]}) and the "
                             f"head top ({body.names[tip]})")
    return nodes[0], g[-2][0]


def hierarchy_map(rig: Rig, channels: Channels | None = None, *,
                  names_note: str = "") -> SkeletonMap:
    """A skeleton map for a humanoid BVH rig from its hierarchy and pose alone (module
    docstring). ``channels`` (the motion) give the pose on up to 64 frames, else the rest
    pose is used; ``names_note`` says why the names were not used, for the map's
    ``how``. Raises :class:`HierarchyError` naming why a rig is not a humanoid's or its
    sides cannot be told."""
    pos, where = sample_positions(rig, channels)
    body = _Body(rig, pos)
    if body.size <= 0.0:
        raise HierarchyError("every joint is at one point")
    shape = _find_shape(body)
    p, c = shape.pelvis, shape.chest
    legs = [_leg(body, j) for j in shape.legs]
    arms = [_arm(body, j) for j in shape.arms]
    neck, head = _head(body, c, shape.head_tip)
    spine = body.path(p, c)[1:]
    chest = next((j for j in reversed(spine) if body.apart(j, neck)), None)
    if chest is None or chest == spine[0]:
        raise HierarchyError(f"the spine from the pelvis ({body.names[p]}) to the shoulders "
                             f"({body.names[c]}) has too few joints for a belly and a chest")
    # legs point away from the spine (a four-legged rig's are square to it)
    up = pos[:, neck] - pos[:, p]
    legdir = _unit(sum(_unit(pos[:, a] - pos[:, h]) for h, _, a, _ in legs))
    upright = float(np.mean(np.sum(legdir * _unit(up), axis=1)))
    rest = rest_positions(rig)
    rlegdir = _unit(sum(_unit(rest[a] - rest[h]) for h, _, a, _ in legs))
    rest_upright = float(np.dot(rlegdir, _unit(rest[neck] - rest[p])))
    if upright > _UPRIGHT_POSE and rest_upright > _UPRIGHT_REST:
        seen = (f"{rest_upright:+.2f} in the rest pose" if where == "the rest pose" else
                f"{upright:+.2f} on {where}, {rest_upright:+.2f} in the rest pose")
        raise HierarchyError(f"the legs do not point away from the spine (mean cosine of "
                             f"their directions {seen}): four legs, not two?")
    # sides: cross(up, forward) points to the subject's left
    fwd = sum(pos[:, t] - pos[:, a] for _, _, a, t in legs)
    legs_s = side_score(pos, up, fwd, legs[0][0], legs[1][0])
    by = "toes point forward"
    if legs_s is None or abs(legs_s) < SIDE_OK:
        fwd = sum(pos[:, k] - (pos[:, h] + pos[:, a]) / 2 for h, k, a, _ in legs)
        legs_s = side_score(pos, up, fwd, legs[0][0], legs[1][0])
        by = "knees bend forward"
    arms_s = side_score(pos, up, fwd, arms[0][0], arms[1][0])
    for what, s in (("legs", legs_s), ("arms", arms_s)):
        if s is None or abs(s) < SIDE_OK:
            raise HierarchyError(f"cannot tell the left {what[:-1]} from the right: the pose "
                                 f"on {where} gives no clear forward direction (feet, knees)")
    lleg, rleg = legs if legs_s > 0 else legs[::-1]
    larm, rarm = arms if arms_s > 0 else arms[::-1]
    j = {"root": p, "belly": spine[0], "chest": chest, "neck": neck, "head": head,
         "headtop": shape.head_tip}
    for s, leg, arm in (("l", lleg, larm), ("r", rleg, rarm)):
        j.update(zip((s + "hip", s + "knee", s + "ankle", s + "toes"), leg))
        j.update(zip((s + "shoulder", s + "elbow", s + "wrist", s + "fingers"), arm[:4]))
    shared: dict[int, str] = {}
    for k in CANONICAL_JOINTS:
        if j[k] in shared:
            raise HierarchyError(f"{shared[j[k]]} and {k} fall on one joint "
                                 f"({body.names[j[k]]})")
        shared[j[k]] = k
    n = body.names
    fingers = [a[4] for a in arms]
    arms_how = ("shoulder, elbow, wrist: the wrist where the fingers branch off and the two "
                "joints above it" if all(fingers) else
                "shoulder, elbow, wrist at each arm's two longest bones" if not any(fingers)
                else "shoulder, elbow, wrist at the two longest bones of one arm, the other's "
                "wrist where the fingers branch off")
    how = "; ".join((
        "generated from the hierarchy and rest pose"
        + (f" ({names_note})" if names_note else ""),
        f"pelvis {n[p]} where two legs and the spine meet, shoulder branch {n[c]} where "
        "two arms and the neck branch off",
        "hip, knee, ankle at each leg's two longest bones", arms_how,
        f"sides from the pose on {where} ({by})",
        "heading axis from the hips"))
    joints = {k: n[j[k]] for k in CANONICAL_JOINTS}
    return SkeletonMap(
        name="guessed-hierarchy", format="bvh", joints=joints,
        detect=tuple(sorted(set(joints.values()))), heading_node=joints["root"],
        heading_axis=heading_axis(rest, j["lhip"], j["rhip"], n, rig.source),
        path="generated", description="generated from the hierarchy and rest pose of a BVH rig",
        how=how)
