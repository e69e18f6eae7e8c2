"""The 40 annotation features as a data table (docs/method/features.md §0 and §5).

One row per feature, in F01…F40 order. A row names the *measure* (how a real value per
frame is computed from joint positions, see :mod:`mtanno.features.measures`), the canonical
joints it reads, the body unit its thresholds are multiples of, the switch-on test (strict,
the paper's θ1) and the stay-on test (lenient, θ2), and the velocity window in
milliseconds. Thresholds are ``(op, k)`` meaning ``measure op k·unit``, or
``("in", lo, hi)`` meaning ``lo·unit ≤ measure ≤ hi·unit``; angles are in degrees and need no
unit. Velocity thresholds are in units per second.

Everything here is what the reference implementation computes (docs/method/features.md §7
lists where it differs from the [MR06] paper's Table 6).
"""

from __future__ import annotations

from typing import NamedTuple

#: Name and version of this feature set, stored in every feature file.
FEATURE_SET = "mr06-ak40"
FEATURE_SET_VERSION = 1


class Feature(NamedTuple):
    """One relational feature (see module docstring for the fields' meaning; ``params``
    are extra measure parameters and ``paper`` the feature's name in its paper's table,
    both used by the [MRC05] set of :mod:`mtanno.features.table31`)."""

    id: str
    name: str
    ref_name: str
    group: str
    mirror: str | None
    measure: str
    joints: tuple[str, ...]
    unit: str | None
    on: tuple
    off: tuple
    window_ms: int = 0
    params: tuple[float, ...] = ()
    paper: str = ""


_F = Feature
# fmt: off
FEATURES: tuple[Feature, ...] = (
    # --- AK upper (F01–F14), docs/method/features.md §5.2 ---
    _F("F01", "rhand_forward", "handRightToFrontRelTorso", "upper", "F02", "move_plane",
       ("neck", "rhip", "lhip", "rwrist"), "hlL", (">", 1.8), (">", 1.3), 250),
    _F("F02", "lhand_forward", "handLeftToFrontRelTorso", "upper", "F01", "move_plane",
       ("neck", "rhip", "lhip", "lwrist"), "hlL", (">", 1.8), (">", 1.3), 250),
    _F("F03", "rhand_above_neck", "handRightRaisedRelSpine", "upper", "F04", "nplane",
       ("chest", "neck", "rwrist", "neck"), "cl", (">=", 0.2), (">=", 0.0)),
    _F("F04", "lhand_above_neck", "handLeftRaisedRelSpine", "upper", "F03", "nplane",
       ("chest", "neck", "lwrist", "neck"), "cl", (">=", 0.2), (">=", 0.0)),
    _F("F05", "rhand_upward", "handRightToTopRelSpine", "upper", "F06", "move_dir",
       ("chest", "neck", "rwrist", "neck"), "hlL", (">", 1.8), (">", 1.3), 250),
    _F("F06", "lhand_upward", "handLeftToTopRelSpine", "upper", "F05", "move_dir",
       ("chest", "neck", "lwrist", "neck"), "hlL", (">", 1.8), (">", 1.3), 250),
    _F("F07", "relbow_bent", "elbowRightBent", "upper", "F08", "angle",
       ("rshoulder", "relbow", "rwrist", "relbow"), None, ("in", 0, 110), ("in", 0, 120)),
    _F("F08", "lelbow_bent", "elbowLeftBent", "upper", "F07", "angle",
       ("lshoulder", "lelbow", "lwrist", "lelbow"), None, ("in", 0, 110), ("in", 0, 120)),
    _F("F09", "hands_apart", "handsApartRelShoulders", "upper", None, "nplane_abs",
       ("lshoulder", "rshoulder", "rwrist", "lwrist"), "sw", (">=", 2.5), (">=", 2.0)),
    _F("F10", "hands_approaching", "handsMoveTogether", "upper", None, "move_dir",
       ("lwrist", "rwrist", "lwrist", "rwrist"), "hl", (">=", 1.4), (">=", 1.2), 100),
    _F("F11", "rhand_away_from_root", "handRightMoveApartRelRoot", "upper", "F12", "move_dir",
       ("rwrist", "root", "root", "rwrist"), "hl", (">=", 1.4), (">=", 1.2), 0),
    _F("F12", "lhand_away_from_root", "handLeftMoveApartRelRoot", "upper", "F11", "move_dir",
       ("lwrist", "root", "root", "lwrist"), "hl", (">=", 1.4), (">=", 1.2), 0),
    _F("F13", "rhand_fast", "handRightHighVel", "upper", "F14", "fast",
       ("rfingers",), "hl", (">=", 2.5), (">=", 2.0), 100),
    _F("F14", "lhand_fast", "handLeftHighVel", "upper", "F13", "fast",
       ("lfingers",), "hl", (">=", 2.5), (">=", 2.0), 100),
    # --- AK lower (F15–F26), docs/method/features.md §5.1 ---
    _F("F15", "rfoot_behind_lleg", "footRightBackRelLegLeft", "lower", "F16", "plane",
       ("root", "lhip", "lankle", "rankle"), "hl", (">=", 0.375), (">=", 0.0)),
    _F("F16", "lfoot_behind_rleg", "footLeftBackRelLegRight", "lower", "F15", "plane",
       ("root", "rankle", "rhip", "lankle"), "hl", (">=", 0.375), (">=", 0.0)),
    _F("F17", "rfoot_raised", "footRightRaisedRelYBodyMin", "lower", "F18", "raised",
       ("rtoes",), "hl", (">=", 1.2), (">=", 1.0)),
    _F("F18", "lfoot_raised", "footLeftRaisedRelYBodyMin", "lower", "F17", "raised",
       ("ltoes",), "hl", (">=", 1.2), (">=", 1.0)),
    _F("F19", "feet_apart", "feetApartRelHips", "lower", None, "nplane_abs",
       ("lhip", "rhip", "rankle", "lankle"), "hl", (">=", 2.1), (">=", 1.8)),
    _F("F20", "rknee_bent", "kneeRightBent", "lower", "F21", "angle",
       ("rhip", "rknee", "rankle", "rknee"), None, ("in", 0, 110), ("in", 0, 120)),
    _F("F21", "lknee_bent", "kneeLeftBent", "lower", "F20", "angle",
       ("lhip", "lknee", "lankle", "lknee"), None, ("in", 0, 110), ("in", 0, 120)),
    _F("F22", "feet_crossed", "footCrossover", "lower", None, "crossover",
       ("lhip", "rhip", "lankle", "rankle"), "hw", ("<=", -0.125), ("<=", 0.0)),
    _F("F23", "feet_moving_together", "feetMoveTogetherRelHips", "lower", None, "move_diff",
       ("lhip", "rhip", "lankle", "rankle"), "hl", (">=", 1.5), (">=", 1.3), 100),
    _F("F24", "feet_moving_apart", "feetMoveApartRelHips", "lower", None, "move_diff",
       ("lhip", "rhip", "rankle", "lankle"), "hl", (">=", 1.5), (">=", 1.3), 100),
    _F("F25", "rfoot_fast", "footRightHighVel", "lower", "F26", "fast",
       ("rtoes", "rankle"), "hl", (">=", 2.5), (">=", 2.0), 100),
    _F("F26", "lfoot_fast", "footLeftHighVel", "lower", "F25", "fast",
       ("ltoes", "lankle"), "hl", (">=", 2.5), (">=", 2.0), 100),
    # --- AK mix (F27–F39) and F40, docs/method/features.md §5.3 ---
    _F("F27", "rhumerus_abducted", "humerusRightAbductRelSpine", "mix", "F28", "angle",
       ("neck", "root", "relbow", "rshoulder"), None, ("<", 150), ("<", 155)),
    _F("F28", "lhumerus_abducted", "humerusLeftAbductRelSpine", "mix", "F27", "angle",
       ("neck", "root", "lelbow", "lshoulder"), None, ("<", 150), ("<", 155)),
    _F("F29", "rfemur_abducted", "femurRightAbductRelSpine", "mix", "F30", "angle",
       ("neck", "root", "rhip", "rknee"), None, (">", 50), (">", 45)),
    _F("F30", "lfemur_abducted", "femurLeftAbductRelSpine", "mix", "F29", "angle",
       ("neck", "root", "lhip", "lknee"), None, (">", 50), (">", 45)),
    _F("F31", "root_behind_frontal_plane", "rootBehindFeetLeftRightNeck", "mix", None, "plane",
       ("lankle", "neck", "rankle", "root"), "hl", ("<", -0.5), ("<", -0.35)),
    _F("F32", "spine_horizontal", "spineHorizontalRelY", "mix", None, "angle_up",
       ("neck", "root"), None, ("in", 70, 110), ("in", 60, 120)),
    _F("F33", "rhand_lowered", "handRightLowRelYBodyMin", "mix", "F34", "raised",
       ("rfingers", "rfingers", "rwrist"), "hl", ("<", 1.2), ("<", 1.4)),
    _F("F34", "lhand_lowered", "handLeftLowRelYBodyMin", "mix", "F33", "raised",
       ("lfingers", "lfingers", "lwrist"), "hl", ("<", 1.2), ("<", 1.4)),
    _F("F35", "shoulders_rotated_right", "shouldersRotatedRightRelHip", "mix", "F36",
       "plane_diff", ("rhip", "lhip", "neck", "lshoulder", "rshoulder"), "hlL",
       (">", 0.40), (">", 0.35)),
    _F("F36", "shoulders_rotated_left", "shouldersRotatedLeftRelHip", "mix", "F35",
       "plane_diff", ("rhip", "lhip", "neck", "lshoulder", "rshoulder"), "hlL",
       ("<", -0.40), ("<", -0.35)),
    _F("F37", "body_y_extent_small", "bodyExtentRelY", "mix", None, "extent_y",
       (), "BL", ("<=", 0.8), ("<=", 0.9)),
    _F("F38", "body_xz_extent_large", "bodyExtentExtremitiesRelXZ", "mix", None, "extent_xz",
       ("lankle", "rankle", "lwrist", "rwrist", "headtop", "root"), "hl",
       (">=", 3.25), (">=", 3.0)),
    _F("F39", "root_fast", "rootHighVel", "mix", None, "fast",
       ("root",), "hl", (">=", 2.3), (">=", 2.0), 0),
    _F("F40", "root_turning_fast", "rootHighAngVel", "mix", None, "heading_rate",
       (), None, (">=", 100), (">=", 50)),
)
# fmt: on

#: Feature names in F01…F40 order (Parquet column names).
FEATURE_NAMES: tuple[str, ...] = tuple(f.name for f in FEATURES)

#: Index groups (docs/method.md §2): upper F01–F14, lower F15–F26, mix F27–F40.
GROUPS: dict[str, tuple[int, ...]] = {
    g: tuple(i for i, f in enumerate(FEATURES) if f.group == g) for g in ("upper", "lower", "mix")
}

#: Left/right pairs as (row, row) with row = 0-based feature index, each pair once.
MIRROR_PAIRS: tuple[tuple[int, int], ...] = tuple(
    (i, int(f.mirror[1:]) - 1) for i, f in enumerate(FEATURES)
    if f.mirror is not None and i < int(f.mirror[1:]) - 1
)


def mirror_permutation() -> list[int]:
    """Row order that swaps every left/right pair ([MR06] §5.4)."""
    perm = list(range(len(FEATURES)))
    for a, b in MIRROR_PAIRS:
        perm[a], perm[b] = b, a
    return perm


def feature_index(name: str) -> int:
    """0-based row of a feature given by name (``rknee_bent``) or id (``F20``)."""
    for i, f in enumerate(FEATURES):
        if name in (f.name, f.id, f.ref_name):
            return i
    from mtanno.errors import MtannoError

    raise MtannoError(f"unknown feature '{name}'")
