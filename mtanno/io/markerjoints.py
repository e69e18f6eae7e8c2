"""Markers → the 22 canonical joints: gap filling, the recipes of a marker set, validity.

The steps, for one file (every step vectorised over frames):

1. **Markers.** Each marker the set reads is found among the file's labels without their
   subject prefix (:func:`mtanno.io.markerset.marker_name`); when several subjects carry
   the same names, the subject whose labels give most of the set's markers is used.
2. **Gaps.** A marker missing for at most ``max_gap`` seconds (0.25 s) is filled from the
   other markers of a segment it belongs to (``[segments]``) that are present over the gap
   and at its ends: its position in the frame those markers span (three or more:
   an orthonormal frame from the first three; one or two: their centroid, axes of the
   world) is interpolated linearly across the gap — the offset to its segment, not its
   world position, so a gap during a fast movement follows the body. A gap at the start
   or the end of the file keeps the offset of its one end. Longer gaps, and gaps no
   segment can fill (a whole segment lost), stay missing.
3. **Sizes.** Each body-size number is the median over the frames that have its markers.
4. **Recipes**, in dependency order (:class:`mtanno.io.markerset.Recipe`): mean; extend;
   offset; the chord function of Plug-in Gait (Vicon Plug-in Gait reference guide;
   Davis et al. 1991): the joint centre J at distance d from a lateral marker M such that
   the angle at J between M and the next joint centre P is a right angle, in the plane of
   M, P and a reference point R; the centre of a hinge joint (the elbow) from a marker on
   its axis (the lateral epicondyle): the point J at distance d from the marker M whose
   axis J → M is perpendicular to both limbs (to P − J and Q − J, P and Q the joint
   centres on either side), of the two mirror solutions the one that bends the limb
   forward (for the left side (P − J) × (Q − J) points from J to M, for the right side
   away from it) — exact for any flexion, where the chord function's plane is only right
   for a straight limb; and the hip-joint centre regression of Harrington et al.
   (2007, "Prediction of the hip joint centre in adults, children, and patients with
   cerebral palsy based on magnetic resonance imaging", J. Biomech. 40(3):595–602, the
   pelvis width and depth equations): in the pelvis frame (origin the mid-point of the
   ASIS markers, z to the right, x forward in the plane of the ASIS and the mid-PSIS,
   y up), x = −0.24·PD − 9.9 mm, y = −0.30·PW − 10.9 mm, z = ±(0.33·PW + 7.3) mm, PW
   the inter-ASIS distance and PD the distance between the ASIS and PSIS mid-points
   (medians over the file). Davis et al. (1991, "A gait analysis data collection and
   reduction technique", Hum. Mov. Sci. 10:575–587) give the older regression on leg
   length that Plug-in Gait uses by default; Harrington's needs no body measurement.
5. **Validity.** A frame is valid when every canonical joint and the heading could be
   computed. Joints of invalid frames are interpolated between the nearest valid frames
   (held at the ends), so that later stages get finite numbers; the frames are marked
   invalid and carry no evidence.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.markerset import MarkerSet, Recipe, marker_name
from mtanno.io.rigs import CANONICAL_JOINTS

__all__ = ["MarkerReport", "fill_gaps", "marker_joints", "missing_runs"]


@dataclass
class MarkerReport:
    """What a marker file's joints were made from, for ``mtanno info`` and the feature
    file's metadata.

    ``markers``: marker of the set → the file's label it was read from; ``ignored``: labels
    no recipe reads; ``subject``: the subject prefix used ("" for none); ``filled``:
    marker → frames filled; ``lost``: marker → frames still missing after filling;
    ``invalid``: joint → frames where it could not be computed; ``sizes``: size → mm;
    ``n_frames``, ``n_invalid``: frames, invalid frames; ``units``, ``up``: as read."""

    set_name: str
    set_how: str
    markers: dict[str, str]
    ignored: list[str]
    subject: str
    feeds: dict[str, list[str]]
    filled: dict[str, int] = field(default_factory=dict)
    lost: dict[str, int] = field(default_factory=dict)
    invalid: dict[str, int] = field(default_factory=dict)
    sizes: dict[str, float] = field(default_factory=dict)
    n_frames: int = 0
    n_invalid: int = 0
    units: str = ""
    up: str = ""


def _columns(mset: MarkerSet, labels, source: str | None) -> tuple[dict[str, int], str]:
    """Marker of the set → column of the file, and the subject prefix used."""
    wanted = {mset.label_of(m): m for m in mset.markers}
    by_subject: dict[str, dict[str, int]] = {}
    for k, label in enumerate(labels):
        name = marker_name(label)
        if name in wanted:
            subject = label[:len(label) - len(label.rpartition(":")[2])].strip()
            by_subject.setdefault(subject, {}).setdefault(wanted[name], k)
    if not by_subject:
        raise MtannoError(f"none of the markers of the set '{mset.name}' is in this file",
                          path=source)
    subject = max(by_subject, key=lambda s: len(by_subject[s]))  # first of equals
    return by_subject[subject], subject


def missing_runs(missing: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) frames, 0-based inclusive, of each run of True in ``missing``."""
    m = np.concatenate([[False], np.asarray(missing, bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def _frame(p: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Origin (n × 3) and rotation (n × 3 × 3, columns the axes) spanned by the partner
    markers ``p``: three or more give an orthonormal frame (NaN where they are collinear),
    fewer their centroid and the world axes."""
    if len(p) < 3:
        origin = np.mean(p, axis=0)
        return origin, np.broadcast_to(np.eye(3), (origin.shape[0], 3, 3))
    e1 = p[1] - p[0]
    e1 = e1 / np.linalg.norm(e1, axis=-1, keepdims=True)
    v = p[2] - p[0]
    e2 = v - np.sum(v * e1, axis=-1, keepdims=True) * e1
    with np.errstate(invalid="ignore", divide="ignore"):
        e2 = e2 / np.linalg.norm(e2, axis=-1, keepdims=True)
    return p[0], np.stack([e1, e2, np.cross(e1, e2)], axis=-1)


def fill_gaps(points: dict[str, np.ndarray], segments: dict[str, tuple[str, ...]],
              max_frames: int) -> dict[str, int]:
    """Fill, in place, every run of missing (NaN) frames of at most ``max_frames`` frames
    of each marker of ``points`` (name → frames × 3) from a segment it belongs to (module
    docstring, step 2); partners are markers present (in the input, not filled) over the
    run and at its ends (their present frames are never changed, so they are read in
    place). A marker that is filled is copied first. Returns marker → frames filled."""
    orig = dict(points)
    ok = {m: _present(v) for m, v in orig.items()}
    n = next(iter(orig.values())).shape[0] if orig else 0
    filled: dict[str, int] = {}
    for m in list(points):
        if ok[m].all() or not ok[m].any():
            continue  # nothing to fill, or nothing to fill from
        v = points[m] = points[m].copy()
        for a, b in missing_runs(~ok[m]):
            if b - a + 1 > max_frames:
                continue
            ends = [f for f in (a - 1, b + 1) if 0 <= f < n]
            need = np.r_[ends, np.arange(a, b + 1)]
            partners = max(([q for q in seg if q != m and q in orig and ok[q][need].all()]
                            for seg in segments.values() if m in seg), key=len, default=[])
            if not partners:
                continue
            _fill_run(v, [orig[q] for q in partners[:3]], a, b, ends)
            filled[m] = filled.get(m, 0) + b - a + 1
    return filled


def _fill_run(v: np.ndarray, partners: list[np.ndarray], a: int, b: int,
              ends: list[int]) -> None:
    """Fill frames a..b of marker ``v`` from its offsets at ``ends`` in the partners'
    frame (linear between two ends, constant from one)."""
    idx = np.asarray(ends)
    o, R = _frame([p[idx] for p in partners])
    local = np.einsum("nji,nj->ni", R, v[idx] - o)  # Rᵀ (v − o)
    frames = np.arange(a, b + 1)
    if len(ends) == 2:
        w = ((frames - ends[0]) / (ends[1] - ends[0]))[:, None]
        loc = local[0] * (1 - w) + local[1] * w
    else:
        loc = np.broadcast_to(local[0], (frames.size, 3))
    o, R = _frame([p[frames] for p in partners])
    v[frames] = o + np.einsum("nij,nj->ni", R, loc)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products (n × 1) (einsum: numpy's reductions over an axis of 3 are
    several times slower)."""
    return np.einsum("...i,...i->...", a, b)[..., None]


def _norm(v: np.ndarray) -> np.ndarray:
    return np.sqrt(_dot(v, v))


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / _norm(v)


def _mean(arrays: list[np.ndarray]) -> np.ndarray:
    out = arrays[0].copy() if len(arrays) > 1 else arrays[0]
    for a in arrays[1:]:
        out += a
    return out / len(arrays) if len(arrays) > 1 else out


def _present(v: np.ndarray) -> np.ndarray:
    """(n,) frames where the (n × 3) positions are finite."""
    return np.isfinite(v[:, 0] + v[:, 1] + v[:, 2])


def _chord(M, P, R, d: float, toward: bool) -> np.ndarray:
    """The chord function (module docstring, step 4)."""
    a = P - M
    L = _norm(a)
    a = _unit(a)
    q = _unit((R - M) - _dot(R - M, a) * a)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.clip(d / L, -1.0, 1.0)
    s = np.sqrt(1.0 - c * c)
    return M + d * (c * a + (s if toward else -s) * q)


def _axis(M, P, Q, d: float, side: str) -> np.ndarray:
    """The centre of a hinge joint from a marker on its axis (module docstring, step 4):
    J = M − d·u with u·(P − M) = u·(Q − M) = −d and |u| = 1."""
    a, b = P - M, Q - M
    aa, bb, ab = _dot(a, a), _dot(b, b), _dot(a, b)
    det = aa * bb - ab * ab
    with np.errstate(invalid="ignore", divide="ignore"):
        alpha = -d * (bb - ab) / det
        beta = -d * (aa - ab) / det
        u0 = alpha * a + beta * b
        c = np.cross(a, b)
        t = np.sqrt(np.clip(1.0 - _dot(u0, u0), 0.0, None)) / _norm(c)
    sign = 1.0 if side == "left" else -1.0
    best = None
    for s in (1.0, -1.0):
        u = _unit(u0 + s * t * c)
        J = M - d * u
        bend = _dot(np.cross(P - J, Q - J), u) * sign
        best = J if best is None else np.where(bend >= 0, J, best)
    return best


def _hip(LA, RA, LP, RP, pw: float, pd: float, side: str) -> np.ndarray:
    """Harrington et al. (2007) hip-joint centre (module docstring, step 4)."""
    origin = (LA + RA) / 2
    z = _unit(RA - LA)
    fwd = origin - (LP + RP) / 2
    x = _unit(fwd - _dot(fwd, z) * z)
    y = np.cross(z, x)
    lat = (0.33 * pw + 7.3) * (1 if side == "right" else -1)
    return origin + (-0.24 * pd - 9.9) * x + (-0.30 * pw - 10.9) * y + lat * z


def _median_distance(A: np.ndarray, B: np.ndarray) -> float:
    d = _norm(A - B)[:, 0]
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else float("nan")


def _evaluate(name: str, r: Recipe, P: dict[str, np.ndarray], sizes: dict[str, float],
              ) -> np.ndarray:
    i = [P[n] for n in r.inputs]
    d = (sizes[r.size] if r.size else r.by) * r.times
    if r.kind == "mean":
        return _mean(i)
    if r.kind == "extend":
        return i[1] + r.by * (i[1] - i[0])
    if r.kind == "offset":
        return i[0] + d * _unit(i[2] - i[1])
    if r.kind == "chord":
        return _chord(i[0], i[1], i[2], d, r.side == "toward")
    if r.kind == "axis":
        return _axis(i[0], i[1], i[2], d, r.side)
    pw = _median_distance(i[0], i[1])
    pd = _median_distance((i[0] + i[1]) / 2, (i[2] + i[3]) / 2)
    return _hip(*i, pw, pd, r.side)


def _order(points: dict[str, Recipe]) -> list[str]:
    """Point names, each after the points it reads (the set was checked for circles)."""
    out: list[str] = []
    done: set[str] = set()

    def visit(n: str) -> None:
        if n in done or n not in points:
            return
        done.add(n)
        for i in points[n].inputs:
            visit(i)
        out.append(n)

    for n in points:
        visit(n)
    return out


def _bridge(x: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``x`` (frames × 3) with its invalid frames interpolated linearly between the
    nearest valid ones, held before the first and after the last."""
    f = np.flatnonzero(valid)
    t = np.arange(x.shape[0])
    return np.stack([np.interp(t, f, x[f, k]) for k in range(3)], axis=1)


def marker_joints(mset: MarkerSet, labels, points: np.ndarray, fps: float, *,
                  source: str | None = None,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, MarkerReport]:
    """The canonical joints of one marker file (module docstring): ``labels`` and
    ``points`` (frames × markers × 3, mm, NaN where missing) as
    :func:`mtanno.io.c3d.read_c3d` gives them. Returns joints (frames × 22 × 3, mm),
    heading (frames × 3, the set's left axis), validity (frames,) and a
    :class:`MarkerReport`. A file in which some joint cannot be computed in any frame is
    one :class:`MtannoError` naming the joints and the markers they lack."""
    columns, subject = _columns(mset, labels, source)
    n = points.shape[0]
    used_labels = {labels[k] for k in columns.values()}
    report = MarkerReport(set_name=mset.name, set_how=mset.how,
                          markers={m: labels[k] for m, k in columns.items()},
                          ignored=[x for x in labels if x not in used_labels],
                          subject=subject, feeds=mset.feeds, n_frames=n)
    if n == 0:
        raise MtannoError("the file has no frames", path=source)
    nan = np.full((n, 3), np.nan)
    P: dict[str, np.ndarray] = {m: (points[:, columns[m]] if m in columns else nan)
                                for m in mset.markers}  # (views: filling copies first)
    if len(columns) < len(mset.markers) or not np.isfinite(points[:, list(columns.values())]
                                                           ).all():
        report.filled = fill_gaps(P, mset.segments, int(round(mset.max_gap * fps)))
        report.lost = {m: int((~_present(v)).sum()) for m, v in P.items()
                       if not _present(v).all()}
    sizes = {}
    for name, s in mset.sizes.items():
        A = _mean([P[x] for x in s.a])
        B = _mean([P[x] for x in s.b])
        sizes[name] = _median_distance(A, B) * s.times + s.plus
    report.sizes = sizes
    with np.errstate(invalid="ignore", divide="ignore"):
        for name in _order(mset.points):
            P[name] = _evaluate(name, mset.points[name], P, sizes)
        heading = _unit(P[mset.heading[1]] - P[mset.heading[0]])
    joints = np.stack([P[j] for j in CANONICAL_JOINTS], axis=1)
    ok_joint = np.isfinite(joints[..., 0] + joints[..., 1] + joints[..., 2])
    valid = ok_joint.all(axis=1) & _present(heading)
    report.invalid = {j: int((~ok_joint[:, k]).sum()) for k, j in enumerate(CANONICAL_JOINTS)
                      if not ok_joint[:, k].all()}
    report.n_invalid = int((~valid).sum())
    if not valid.any():
        never = [j for k, j in enumerate(CANONICAL_JOINTS) if not ok_joint[:, k].any()]
        if not never:
            raise MtannoError("no frame has every joint at once (the markers are lost in "
                              "turns)", path=source)
        lost = [mset.label_of(m) for m in mset.markers
                if m not in columns or not _present(P[m]).any()]
        raise MtannoError(f"joints {', '.join(never)} cannot be computed in any frame "
                          f"(markers absent or never seen: {', '.join(lost[:10])}"
                          f"{' …' if len(lost) > 10 else ''}); give a marker set that "
                          f"fits with {{markers}} MAP.toml (`mtanno markers guess FILE.c3d "
                          f"-o MAP.toml` writes a starting point)", path=source,
                          options=("markers",))
    if not valid.all():
        for k in range(joints.shape[1]):
            joints[:, k] = _bridge(joints[:, k], valid)
        heading = _unit(_bridge(heading, valid))
    return joints, heading, valid, report
