"""Feature sets and their evaluation (docs/method.md §2): :class:`FeatureSet` (a feature
table compiled once for the kernel), the named sets (:data:`FEATURE_SETS`,
:func:`get_feature_set`), and :func:`compute_features` / :func:`compute_features_native`
— joint positions (canonical joints, in the motion's length unit, at its native rate) to
boolean features at the native rate or reduced to the 30 Hz analysis rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from mtanno.errors import MtannoError
from mtanno.features import _kernels as _k
from mtanno.features.hysteresis import ANALYSIS_FPS, analysis_frames
from mtanno.features.measures import body_units, window_samples
from mtanno.features.table import (
    FEATURE_SET,
    FEATURE_SET_VERSION,
    FEATURES,
    GROUPS,
    Feature,
)
from mtanno.features.table31 import (
    FEATURE_SET31,
    FEATURE_SET31_REFERENCE,
    FEATURE_SET31_VERSION,
    FEATURES31,
    FEATURES31_REFERENCE,
    GROUPS31,
)
from mtanno.io import _limits
from mtanno.io.rigs import CANONICAL_JOINTS

__all__ = ["FEATURE_SETS", "FeatureSet", "compute_features", "compute_features_native",
           "get_feature_set"]

#: Measure kind → kernel code (mtanno.features._kernels).
MEASURE_CODES = {
    "plane": _k.PLANE, "plane_diff": _k.PLANE_DIFF, "nplane": _k.NPLANE,
    "nplane_abs": _k.NPLANE_ABS, "move_plane": _k.MOVE_PLANE, "move_dir": _k.MOVE_DIR,
    "move_diff": _k.MOVE_DIFF, "crossover": _k.CROSSOVER, "angle": _k.ANGLE,
    "angle_up": _k.ANGLE_UP, "fast": _k.FAST, "raised": _k.RAISED, "extent_y": _k.EXTENT_Y,
    "extent_xz": _k.EXTENT_XZ, "heading_rate": _k.HEADING_RATE, "height": _k.HEIGHT,
    "angle_max": _k.ANGLE_MAX, "touch": _k.TOUCH,
}
#: Joints the kernel reads for each measure (``fast``: a second one if given; ``touch``:
#: (a, b, q) triples, each with a (c, ball_a, ball_b) triple of ``params``). Fewer would
#: make it read past a row of its joint table.
MEASURE_JOINTS = {
    "plane": 4, "plane_diff": 5, "nplane": 4, "nplane_abs": 4, "move_plane": 4,
    "move_dir": 4, "move_diff": 4, "crossover": 4, "angle": 4, "angle_up": 2, "fast": 1,
    "raised": 1, "extent_y": 0, "extent_xz": 0, "heading_rate": 0, "height": 2,
    "angle_max": 8, "touch": 3,
}


@dataclass(frozen=True)
class FeatureSet:
    """A named feature table with its index groups (docs/method.md §2, [MRC05] §5.3).

    Attributes
    ----------
    name, version:
        Stored in every feature file (metadata ``feature_set``, ``feature_set_version``).
    features:
        The rows, in column order.
    groups:
        Index group name → 0-based rows.

    ``names``, ``mirror_pairs`` and ``digest`` are computed once (a batch asks for them per
    file).
    """

    name: str
    version: int
    features: tuple
    groups: dict[str, tuple[int, ...]] = field(hash=False)

    @cached_property
    def names(self) -> tuple[str, ...]:
        """Feature (column) names in order."""
        return tuple(f.name for f in self.features)

    @cached_property
    def mirror_pairs(self) -> tuple[tuple[int, int], ...]:
        """Left/right pairs as (row, row), each pair once."""
        ids = {f.id: i for i, f in enumerate(self.features)}
        return tuple((i, ids[f.mirror]) for i, f in enumerate(self.features)
                     if f.mirror is not None and i < ids[f.mirror])

    @cached_property
    def digest(self) -> str:
        """SHA-256 of the feature table (every row's definition and parameters): feature
        files record it, so outputs of a changed table are not taken as up to date."""
        import hashlib

        return hashlib.sha256(repr((self.name, self.version, self.features)).encode())\
            .hexdigest()

    def index(self, name: str) -> int:
        """0-based row of a feature given by name, id (``F07``), reference name or, for the
        31-set, its [MRC05] Table 1 name (``Fl7`` or ``Fℓ7``)."""
        key = name.strip()
        for i, f in enumerate(self.features):
            paper = getattr(f, "paper", "")
            if key in (f.name, f.id, f.ref_name) or (paper and key.replace("ℓ", "l") == paper):
                return i
        raise MtannoError(f"unknown feature '{name}' in feature set {self.name} "
                          f"(known: {', '.join(self.names)})")


#: The built-in feature sets by stored name.
FEATURE_SETS: dict[str, FeatureSet] = {
    FEATURE_SET: FeatureSet(FEATURE_SET, FEATURE_SET_VERSION, FEATURES, GROUPS),
    FEATURE_SET31: FeatureSet(FEATURE_SET31, FEATURE_SET31_VERSION, FEATURES31, GROUPS31),
    FEATURE_SET31_REFERENCE: FeatureSet(FEATURE_SET31_REFERENCE, FEATURE_SET31_VERSION,
                                        FEATURES31_REFERENCE, GROUPS31),
}
_SET_ALIASES = {"ak40": FEATURE_SET}


def get_feature_set(name: str | FeatureSet) -> FeatureSet:
    """The feature set called ``name`` (``ak40`` is an alias of ``mr06-ak40``); a
    :class:`FeatureSet` is returned as it is."""
    if isinstance(name, FeatureSet):
        return name
    key = _SET_ALIASES.get(name, name)
    if key not in FEATURE_SETS:
        known = ", ".join(["ak40", *FEATURE_SETS])
        raise MtannoError(f"unknown feature set '{name}' (known: {known})")
    return FEATURE_SETS[key]


def feature_set_mismatch(name: str, feature_names) -> str | None:
    """What is wrong with a file that says its features ``feature_names`` are of the set
    ``name`` (a template, an index manifest), or None: a set of mtanno's whose table lacks
    some of them, or a name that is none of mtanno's sets over features that all belong to
    one of them (``"bogus"`` over the 40 annotation features: no feature file of those
    features would ever match). A set of the user's own, over features of its own, is
    fine."""
    names = list(feature_names)
    try:
        fs = get_feature_set(name)
    except MtannoError:
        have = set(names)
        same = next((f.name for f in FEATURE_SETS.values() if have <= set(f.names)), None)
        if same is None:
            return None
        return (f"feature set {name!r} is none of mtanno's ({', '.join(FEATURE_SETS)}), yet "
                f"every feature is one of {same}: the set must be named as the one its "
                "features come from")
    known = set(fs.names)
    stray = [n for n in names if n not in known]
    if not stray:
        return None
    more = " …" if len(stray) > 3 else ""
    return f"feature(s) not in the {fs.name} feature set: {', '.join(stray[:3])}{more}"


class _Compiled:
    """A feature table as the kernel's arrays: measure code, joint indices (−1 padded),
    measure parameters (NaN padded), velocity window, and both tests as interval bounds
    ``lo (<|≤) value (<|≤) hi``."""

    def __init__(self, features: tuple[Feature, ...]):
        if not features:
            raise MtannoError("no features to compute")
        for f in features:
            _check_feature(f)
        self.features = features
        n = len(features)
        self.kinds = np.array([MEASURE_CODES[f.measure] for f in features], dtype=np.int64)
        width = max(2, max(len(f.joints) for f in features))  # fast: −1 for no second joint
        self.joints = np.full((n, width), -1, dtype=np.int64)
        for r, f in enumerate(features):
            self.joints[r, :len(f.joints)] = [CANONICAL_JOINTS.index(j) for j in f.joints]
        prm = [tuple(getattr(f, "params", ())) for f in features]
        self.params = np.full((n, max(1, max(len(p) for p in prm))), np.nan)
        for r, p in enumerate(prm):
            self.params[r, :len(p)] = p
        for f in features:
            if f.measure == "touch" and (f.on[0] != "<=" or f.off[0] != "<=" or f.unit):
                raise ValueError(f"touch feature {f.id} needs ('<=', k) tests without unit")

    def windows(self, fps: float) -> np.ndarray:
        return np.array([window_samples(f.window_ms, fps) for f in self.features],
                        dtype=np.int64)

    def bounds(self, units: dict[str, float], which: str):
        """((rows × 2) bounds, (rows × 2) inclusive flags) of the on or off test."""
        n = len(self.features)
        b = np.empty((n, 2))
        b[:, 0], b[:, 1] = -np.inf, np.inf
        inc = np.ones((n, 2), dtype=np.bool_)
        for r, f in enumerate(self.features):
            spec = f.on if which == "on" else f.off
            u = 1.0 if f.unit is None else units[f.unit]
            op = spec[0]
            if op == "in":
                b[r] = spec[1] * u, spec[2] * u
            elif op in (">", ">="):
                b[r, 0], inc[r, 0] = spec[1] * u, op == ">="
            else:
                b[r, 1], inc[r, 1] = spec[1] * u, op == "<="
        return b, inc


def _check_feature(f: Feature) -> None:
    """A table row the kernel can evaluate without reading past its joint and parameter
    tables: a known measure and unit, known joints, as many as the measure reads."""
    need = MEASURE_JOINTS.get(f.measure)
    if need is None:
        raise MtannoError(f"feature {f.id}: unknown measure '{f.measure}' (known: "
                          f"{', '.join(MEASURE_JOINTS)})")
    bad = [j for j in f.joints if j not in CANONICAL_JOINTS]
    if bad:
        raise MtannoError(f"feature {f.id}: unknown joint '{bad[0]}'")
    if len(f.joints) < need:
        raise MtannoError(f"feature {f.id}: measure '{f.measure}' needs {need} joints, got "
                          f"{len(f.joints)}")
    if f.measure == "touch" and (len(f.joints) % 3 or len(tuple(f.params)) != len(f.joints)):
        raise MtannoError(f"feature {f.id}: a touch feature needs (a, b, q) joint triples "
                          f"and one (c, ball_a, ball_b) parameter triple each")
    if f.unit is not None and f.unit not in _UNITS:
        raise MtannoError(f"feature {f.id}: unknown unit '{f.unit}' (known: "
                          f"{', '.join(_UNITS)})")


_UNITS = tuple(body_units(np.zeros((1, len(CANONICAL_JOINTS), 3))))
_COMPILED: dict[int, _Compiled] = {}


def _compiled(features: tuple[Feature, ...]) -> _Compiled:
    key = id(features)
    if key not in _COMPILED:
        _COMPILED[key] = _Compiled(features)
    return _COMPILED[key]


def compute_features_native(joints: np.ndarray, heading: np.ndarray, fps: float, *,
                            features: tuple[Feature, ...] = FEATURES) -> np.ndarray:
    """(features × native frames) uint8 feature matrix at the native rate
    (docs/method/features.md §4–5).

    Parameters
    ----------
    joints:
        (frames × 22 × 3) canonical joint positions in :data:`CANONICAL_JOINTS` order, any
        length unit (thresholds are relative to body measures of frame 1), Y up.
    heading:
        (frames × 3) heading vector of the root (see :class:`~mtanno.io.skeleton.Motion`).
    fps:
        Native frame rate in frames per second.
    features:
        The feature table to evaluate (default: the 40 annotation features).
    """
    joints = np.ascontiguousarray(joints, dtype=np.float64)
    heading = np.ascontiguousarray(heading, dtype=np.float64)
    _check_rate(fps, "frame rate")
    if joints.ndim != 3 or joints.shape[1:] != (len(CANONICAL_JOINTS), 3):
        raise MtannoError(f"joints must be (frames × {len(CANONICAL_JOINTS)} × 3), "
                          f"got {joints.shape}")
    n = joints.shape[0]
    if n == 0:
        raise MtannoError("motion has no frames")
    if heading.shape != (n, 3):
        raise MtannoError(f"heading must be (frames × 3), got {heading.shape}")
    if not (np.isfinite(joints).all() and np.isfinite(heading).all()):
        raise MtannoError("joint positions contain NaN or infinite values")
    if max(np.abs(joints).max(), np.abs(heading).max()) > MAX_POSITION:
        raise MtannoError(f"joint positions are absurd (beyond ±{MAX_POSITION:g}): the "
                          f"features would overflow")
    plan = _compiled(features)
    units = body_units(joints)
    on_b, on_inc = plan.bounds(units, "on")
    off_b, off_inc = plan.bounds(units, "off")
    out = np.empty((len(features), n), dtype=np.uint8)
    _k.features_kernel(joints, heading, float(fps), plan.kinds, plan.joints, plan.params,
                       plan.windows(fps), on_b, on_inc, off_b, off_inc, out)
    return out


#: Largest magnitude of a joint position (or heading component) the features take: their
#: squares and products stay far from overflow. The motion readers bound every value of a
#: file well below (mtanno.io._limits), so only the API can pass more.
MAX_POSITION = 1e15


def _check_rate(fps, what: str) -> None:
    """A rate in the range a motion file may declare (0.1 … 10 000 frames/s: 0 or NaN
    would divide by zero further on, ∞ never end, 1e-300 or 1e300 overflow the exact
    frame arithmetic)."""
    try:
        ok = not isinstance(fps, bool) and _limits.fps_in_range(float(fps))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise MtannoError(f"{what} must be a positive number of frames per second within "
                          f"{_limits.MIN_FPS:g} … {_limits.MAX_FPS:g}, got {fps!r}")


def compute_features(joints: np.ndarray, heading: np.ndarray, fps: float, *,
                     target_fps: float = ANALYSIS_FPS,
                     features: tuple[Feature, ...] = FEATURES) -> tuple[np.ndarray, np.ndarray]:
    """Features at the analysis rate: ((features × frames) uint8, kept native frame per
    column). ``features`` is the table (default the 40 annotation features; a
    :class:`FeatureSet`'s ``features`` for another set).

    The kept native frames are 0-based (see :func:`analysis_frames`).
    """
    _check_rate(target_fps, "analysis frame rate")
    native = compute_features_native(joints, heading, fps, features=features)
    keep = analysis_frames(native.shape[1], fps, target_fps)
    return np.ascontiguousarray(native[:, keep]), keep
