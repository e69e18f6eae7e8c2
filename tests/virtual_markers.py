"""Virtual markers on the bones of an ASF/AMC motion: the 41-marker Vicon set placed as a
real placement puts it, rigidly on the bones, for checking the marker model
(:mod:`mtanno.io.markerjoints`) against the skeleton the motion was made with.

Placement (centimetres, in the rest pose of the CMU/HDM05 ASF: X to the subject's left,
Y up, Z forward; right-side markers mirror the left ones), each marker fixed to one bone
(it moves with that bone's global rotation), independent of the recipes that read them:

* pelvis: the hip joint centres placed from the ASIS by Bell et al. (1990) — inter-ASIS
  width PW = hip distance / 0.72, the hips 0.30·PW below and 0.19·PW behind the ASIS
  mid-point, in the root's axes — the PSIS 0.7·PW behind the ASIS, 9 cm apart (the
  recipes use Harrington et al. 2007, a different regression);
* knee and ankle markers lateral of the joint centre on the flexion axis (5.5 and 4.2 cm:
  half a joint width plus the marker radius), thigh and shank markers laterally on the
  lower third of the segment (7 and 5 cm out);
* heel behind and below the ankle, toe marker on top of the forefoot at the ball, fifth
  metatarsal marker lateral of it;
* C7 and the jugular notch 7 and 6.5 cm behind / in front of the top of the thorax, T10
  and the xiphoid 9.5 and 10.5 cm behind / in front of the mid-back point (not
  symmetrically: the recipes' means are off by about a centimetre), a back marker on the
  right scapula;
* head markers on a band at mid-head, 8.5 cm in front and 9 cm behind, 5 cm to each side;
* acromion markers 4.5 cm above the shoulder joint centre, elbow markers 3.8 cm out on
  the elbow's flexion axis on the lateral side (the side (shoulder − elbow) × (wrist −
  elbow) points to on the left arm, in the motion's own flexed frames), wrist-bar markers
  7 cm either side of the wrist (1 cm on the back of the wrist), hand markers on the back
  of the hand just short of the knuckles (radial side), upper-arm and forearm markers
  4–4.5 cm off the bone.
"""

from __future__ import annotations

import numpy as np

from mtanno.io.skeleton import Channels, Rig, forward_kinematics

LEFT = ["LFHD", "LBHD", "LSHO", "LUPA", "LELB", "LFRM", "LWRA", "LWRB", "LFIN", "LFWT", "LBWT",
        "LTHI", "LKNE", "LSHN", "LANK", "LHEE", "LTOE", "LMT5"]
CENTRE = ["C7", "T10", "CLAV", "STRN", "RBAC"]


def _rot(axis: int, a: np.ndarray) -> np.ndarray:
    """(frames × 3 × 3) right-handed rotations about ``axis`` by angles ``a``."""
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def bone_frames(rig: Rig, ch: Channels) -> tuple[np.ndarray, np.ndarray]:
    """(positions frames × nodes × 3, global rotations frames × nodes × 3 × 3): forward
    kinematics with the rotations kept (mtanno's kernel gives positions only; both agree)."""
    F, J = ch.angles.shape[:2]
    G = np.zeros((F, J, 3, 3))
    for j in range(J):
        L = np.broadcast_to(rig.pre[j], (F, 3, 3))
        for k in range(3):
            L = L @ _rot(int(rig.axes[j, k]), ch.angles[:, j, k])
        L = L @ rig.post[j]
        p = rig.parents[j]
        G[:, j] = L if p < 0 else G[:, p] @ L
    P, _ = forward_kinematics(rig, ch.angles, ch.trans, ch.has_trans)
    return P, G


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _perp(v, d) -> np.ndarray:
    """``v`` without its component along unit ``d``, normalised."""
    v = np.asarray(v, float)
    return _unit(v - (v @ d) * d)


def _specs(rig: Rig) -> dict[str, tuple[str, float, np.ndarray]]:
    """Marker → (bone, place along the bone 0..1 from its proximal joint, offset in rest
    coordinates, cm) for the left side and the centre (module docstring)."""
    ix = rig.names.index
    off = rig.offsets
    X, Y, Z = np.eye(3)
    out: dict[str, tuple[str, float, np.ndarray]] = {}
    # pelvis, on the root: Bell et al. (1990) placement from the hip joint centres
    hl, hr = off[ix("lhipjoint")], off[ix("rhipjoint")]
    pw = np.linalg.norm(hl - hr) / 0.72
    mid_asis = (hl + hr) / 2 + 0.30 * pw * Y + 0.19 * pw * Z
    out["LFWT"] = ("root", 0.0, mid_asis + pw / 2 * X)
    out["LBWT"] = ("root", 0.0, mid_asis - 0.7 * pw * Z + 4.5 * X)
    # legs: lateral on the flexion axis of knee and ankle (the femur's axis rotation)
    femur = _unit(off[ix("lfemur")])
    lat = _perp(rig.pre[ix("ltibia")] @ X, femur)
    lat = lat if lat[0] > 0 else -lat
    out["LTHI"] = ("lfemur", 0.6, 7.0 * lat)
    out["LKNE"] = ("lfemur", 1.0, 5.5 * lat)
    out["LSHN"] = ("ltibia", 0.6, 5.0 * lat)
    out["LANK"] = ("ltibia", 1.0, 4.2 * lat)
    foot = _unit(off[ix("lfoot")])
    up_f = _perp(Y, foot)
    lat_f = _perp(X, foot)
    out["LHEE"] = ("lfoot", 0.0, -5.5 * foot - 3.0 * up_f)
    out["LTOE"] = ("lfoot", 1.0, 1.5 * up_f)
    out["LMT5"] = ("lfoot", 0.9, 3.5 * lat_f + 0.5 * up_f)
    # trunk and head
    out["C7"] = ("thorax", 1.0, 2 * Y - 7 * Z)
    out["CLAV"] = ("thorax", 1.0, -2 * Y + 6.5 * Z)
    out["T10"] = ("upperback", 1.0, 1 * Y - 9.5 * Z)
    out["STRN"] = ("upperback", 1.0, -2 * Y + 10.5 * Z)
    out["RBAC"] = ("upperback", 0.8, -8 * X - 9 * Z)
    out["LFHD"] = ("head", 0.5, 5 * X + 8.5 * Z)
    out["LBHD"] = ("head", 0.5, 5.5 * X - 1 * Y - 9 * Z)
    # arms: acromion above the shoulder joint; elbow on its flexion axis; wrist bar across
    # the wrist's flexion axis (radial-ulnar), on the back of the wrist
    out["LSHO"] = ("lclavicle", 1.0, 0.5 * X + 4.5 * Y)
    arm = _unit(off[ix("lhumerus")])
    flex = _perp(rig.pre[ix("lradius")] @ X, arm)
    out["LELB"] = ("lhumerus", 1.0, 3.8 * flex)
    out["LUPA"] = ("lhumerus", 0.5, 4.5 * _perp(np.cross(arm, flex), arm))
    out["LFRM"] = ("lradius", 0.6, 4.0 * _perp(np.cross(arm, flex), arm))
    fore = _unit(off[ix("lwrist")])
    ru = _perp(rig.pre[ix("lhand")] @ X, fore)
    back = _unit(np.cross(fore, ru))
    out["LWRA"] = ("lwrist", 1.0, 7.0 * ru + 1.0 * back)
    out["LWRB"] = ("lwrist", 1.0, -7.0 * ru + 1.0 * back)
    out["LFIN"] = ("lhand", 0.9, 1.5 * back + 1.5 * ru)
    return out


def _mirror(spec: tuple[str, float, np.ndarray]) -> tuple[str, float, np.ndarray]:
    bone, t, o = spec
    return ("r" + bone[1:] if bone[0] == "l" else bone, t, o * np.array([-1.0, 1.0, 1.0]))


def place_markers(rig: Rig, ch: Channels, *, prefix: str = "Virtual:",
                  ) -> tuple[list[str], np.ndarray]:
    """(labels, points frames × 41 × 3 in millimetres, rig world axes) of the virtual
    markers of a CMU/HDM05-style ASF/AMC motion (module docstring)."""
    P, G = bone_frames(rig, ch)
    specs = _specs(rig)
    for name in LEFT:
        specs["R" + name[1:]] = _mirror(specs[name])
    ix = rig.names.index
    for side, sign in (("l", 1.0), ("r", -1.0)):  # the lateral epicondyle, from the motion
        S, E, W = (P[:, ix(f"{side}{b}")] for b in ("clavicle", "humerus", "wrist"))
        axis = np.einsum("fji,fj->fi", G[:, ix(f"{side}humerus")],
                         np.cross(S - E, W - E))  # in the humerus' rest frame
        bone, t, o = specs[f"{side.upper()}ELB"]
        if sign * float(np.sum(axis @ o)) < 0:
            specs[f"{side.upper()}ELB"] = (bone, t, -o)
    labels, cols = [], []
    unit_mm = 10.0  # the ASF reader's positions are centimetres
    for name, (bone, t, o) in specs.items():
        j = rig.names.index(bone)
        p = int(rig.parents[j])
        base = P[:, p] if p >= 0 else P[:, j]
        local = t * rig.offsets[j] + o if p >= 0 else o
        cols.append(base + np.einsum("fij,j->fi", G[:, j], local))
        labels.append(prefix + name)
    return labels, np.stack(cols, axis=1) * unit_mm
