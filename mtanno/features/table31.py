"""The 31 relational features of [MRC05] (§3 and Table 1) as data tables.

Two tables, in the reference implementation's order (``features_spec.mat`` entries 1–31 =
lower Fℓ 1–11, upper Fu 12–23, mix Fm 24–31; ``docs/method/features31.md`` §1):

* :data:`FEATURES31_REFERENCE` (feature set ``mrc05-reference``) is what the reference
  implementation computes, including the bugs of ``docs/method/features31.md`` §5; it
  reproduces the golden outputs in ``../shared/data/reference/features31*/`` bit for bit.
* :data:`FEATURES31` (feature set ``mrc05``, the default) is the same with the three bugs
  that change results fixed (``docs/method/features31.md`` §5.1–5.3, ``docs/index.md``):

  1. feet fast (entries 10/11) get the hysteresis the reference meant: switch on above
     1.25, stay on above 1.0 femur lengths per second (the reference passed the 1.25
     threshold in the wrong argument, so both tests were the 1.0 test);
  2. left foot raised (entry 4) uses the left femur (the reference uses the right);
  3. root fast (entry 27) uses the 100 ms window and a threshold of 1.0 left humerus length
     per second (the reference read its window of 12 *samples* as 12 ms, L = 2, and
     left the threshold at 1 cm/s unscaled, so the feature is on on ~95 % of all frames).

The quirks of ``docs/method/features31.md`` §5.4–5.9 are design choices of the reference,
not bugs, and both sets keep them; the feature *names* say what is computed (entry 1 is
``rfoot_behind_lleg``, as the reference tests "behind", where the paper's Table 1 says "in
front").

A row has the fields of :class:`mtanno.features.table.Feature` plus ``params`` (measure
parameters) and ``paper`` (the Table 1 name, e.g. ``Fl7``). Measures used only here
(``docs/method/features31.md`` §4): ``height`` (Y(q) − Y(p), joints (q, p)), ``angle_max``
(larger of two angles, joints (a, b, c, d, e, f, g, h): angle(P_a − P_b, P_c − P_d) and
angle(P_e − P_f, P_g − P_h)) and ``touch`` (capsule tests: joints are (a, b, q) triples —
segment a→b, point q — and params are (c, ball_a, ball_b) triples: q touches where its
distance is ≤ k·c·ℓ(t), ℓ(t) = |P_b(t) − P_a(t)|, k the test's threshold; the feature is the
OR of the triples).
Rows whose ``on`` and ``off`` tests are equal have no hysteresis (the hysteresis of two equal
tests returns the test unchanged). Length units: ``femR``/``femL`` femur, ``hw`` hip width,
``hl``/``hlL`` right/left humerus, ``cl`` chest–neck, ``sw`` shoulder width, all from frame 1
(``docs/method/features31.md`` §2); speeds are in units per second; ``None`` means an
absolute value (degrees, or cm/s for the reference's root speed).
"""

from __future__ import annotations

from mtanno.features.table import Feature

#: Names (stored in feature files as ``feature_set``) and versions of the two tables.
FEATURE_SET31 = "mrc05"
FEATURE_SET31_REFERENCE = "mrc05-reference"
FEATURE_SET31_VERSION = 1


#: The 31-set's rows use the same :class:`~mtanno.features.table.Feature` record.
Feature31 = Feature


def _leg_touch(q1: str, q2: str) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """Capsule triples of handRight/LeftAnyLegTouch (docs/method/features31.md §3.3,
    entries 24/25): for each hand point, the shins (radius 0.5 × shin) and the feet
    (1.5 × foot)."""
    joints: list[str] = []
    params: list[float] = []
    for q in (q1, q2):
        for a, b, c in (("lknee", "lankle", 0.5), ("rknee", "rankle", 0.5),
                        ("lankle", "ltoes", 1.5), ("rankle", "rtoes", 1.5)):
            joints += [a, b, q]
            params += [c, 1.0, 1.0]
    return tuple(joints), tuple(params)


_F = Feature31
_RLEG, _RLEG_P = _leg_touch("rfingers", "rwrist")
_LLEG, _LLEG_P = _leg_touch("lfingers", "lwrist")
_HANDS = ("rfingers", "rwrist", "lfingers", "rfingers", "rwrist", "lwrist",
          "lfingers", "lwrist", "rfingers", "lfingers", "lwrist", "rwrist")
_BALLS2 = (1.0, 1.0, 1.0) * 4
_BENT_ON, _BENT_OFF = ("in", 0, 110), ("in", 0, 120)
# One row per line (the file is exempt from the line length): id, name, ref_name, group, mirror,
# measure, joints, unit, on, off[, window_ms][, params=][, paper=].
# fmt: off
FEATURES31_REFERENCE: tuple[Feature31, ...] = (
    # --- lower body Fℓ (entries 1–11), docs/method/features31.md §3.1 ---
    _F("F01", "rfoot_behind_lleg", "footRightBack", "lower", "F02", "plane", ("root", "lhip", "lankle", "rtoes"), "femR", (">=", 0.25), (">=", 0.0), paper="Fl1"),
    _F("F02", "lfoot_behind_rleg", "footLeftBack", "lower", "F01", "plane", ("root", "rankle", "rhip", "ltoes"), "femL", (">=", 0.25), (">=", 0.0), paper="Fl2"),
    _F("F03", "rfoot_raised", "footRightLift", "lower", "F04", "height", ("rtoes", "root"), "femR", (">=", -1.2), (">=", -1.4), paper="Fl3"),
    _F("F04", "lfoot_raised", "footLeftLift", "lower", "F03", "height", ("ltoes", "root"), "femR", (">=", -1.2), (">=", -1.4), paper="Fl4"),
    _F("F05", "rleg_sideways", "footRightSideways", "lower", "F06", "nplane", ("lhip", "rhip", "rankle", "rhip"), "hw", (">=", 1.2), (">=", 1.0), paper="Fl9"),
    _F("F06", "lleg_sideways", "footLeftSideways", "lower", "F05", "nplane", ("rhip", "lhip", "lankle", "lhip"), "hw", (">=", 1.2), (">=", 1.0), paper="Fl10"),
    _F("F07", "rknee_bent", "kneeRightAngle", "lower", "F08", "angle", ("rhip", "rknee", "rankle", "rknee"), None, _BENT_ON, _BENT_OFF, paper="Fl7"),
    _F("F08", "lknee_bent", "kneeLeftAngle", "lower", "F07", "angle", ("lhip", "lknee", "lankle", "lknee"), None, _BENT_ON, _BENT_OFF, paper="Fl8"),
    _F("F09", "legs_crossed", "footCrossover", "lower", None, "crossover", ("lhip", "rhip", "lankle", "rankle"), "hw", ("<=", -0.125), ("<=", 0.0), paper="Fl11"),
    _F("F10", "rfoot_fast", "footRightHighVel", "lower", "F11", "fast", ("rtoes", "rankle"), "femR", (">", 1.0), (">", 1.0), 100, paper="Fl5"),
    _F("F11", "lfoot_fast", "footLeftHighVel", "lower", "F10", "fast", ("ltoes", "lankle"), "femL", (">", 1.0), (">", 1.0), 100, paper="Fl6"),
    # --- upper body Fu (entries 12–23), docs/method/features31.md §3.2 ---
    _F("F12", "rhand_front", "handRightFront", "upper", "F13", "plane", ("root", "lshoulder", "rshoulder", "rwrist"), "hl", (">=", 1.15), (">=", 1.0), paper="Fu1"),
    _F("F13", "lhand_front", "handLeftFront", "upper", "F12", "plane", ("root", "lshoulder", "rshoulder", "lwrist"), "hlL", (">=", 1.15), (">=", 1.0), paper="Fu2"),
    _F("F14", "rhand_raised", "handRightLift", "upper", "F15", "nplane", ("chest", "neck", "rwrist", "neck"), "cl", (">=", 0.15), (">=", -1.0), paper="Fu3"),
    _F("F15", "lhand_raised", "handLeftLift", "upper", "F14", "nplane", ("chest", "neck", "lwrist", "neck"), "cl", (">=", 0.15), (">=", -1.0), paper="Fu4"),
    _F("F16", "rarm_sideways", "handRightSideways", "upper", "F17", "nplane", ("lshoulder", "rshoulder", "rwrist", "rshoulder"), "sw", (">=", 0.5), (">=", 0.4), paper="Fu5"),
    _F("F17", "larm_sideways", "handLeftSideways", "upper", "F16", "nplane", ("rshoulder", "lshoulder", "lwrist", "lshoulder"), "sw", (">=", 0.5), (">=", 0.4), paper="Fu6"),
    _F("F18", "relbow_bent", "elbowRightAngle", "upper", "F19", "angle", ("rshoulder", "relbow", "rwrist", "relbow"), None, _BENT_ON, _BENT_OFF, paper="Fu7"),
    _F("F19", "lelbow_bent", "elbowLeftAngle", "upper", "F18", "angle", ("lshoulder", "lelbow", "lwrist", "lelbow"), None, _BENT_ON, _BENT_OFF, paper="Fu8"),
    _F("F20", "arms_crossed", "handCrossover", "upper", None, "crossover", ("lshoulder", "rshoulder", "lwrist", "rwrist"), "sw", ("<=", -0.125), ("<=", 0.0), paper="Fu11"),
    _F("F21", "hands_touching", "handTouch", "upper", None, "touch", _HANDS, None, ("<=", 0.75), ("<=", 1.0), params=_BALLS2, paper="Fu12"),
    _F("F22", "rhand_fast", "handRightHighVel", "upper", "F23", "fast", ("rfingers",), "hl", (">", 1.25), (">", 1.0), 100, paper="Fu9"),
    _F("F23", "lhand_fast", "handLeftHighVel", "upper", "F22", "fast", ("lfingers",), "hlL", (">", 1.25), (">", 1.0), 100, paper="Fu10"),
    # --- mix Fm (entries 24–31, no hysteresis), docs/method/features31.md §3.3 ---
    _F("F24", "rhand_touching_leg", "handRightAnyLegTouch", "mix", "F25", "touch", _RLEG, None, ("<=", 1.0), ("<=", 1.0), params=_RLEG_P, paper="Fm1"),
    _F("F25", "lhand_touching_leg", "handLeftAnyLegTouch", "mix", "F24", "touch", _LLEG, None, ("<=", 1.0), ("<=", 1.0), params=_LLEG_P, paper="Fm2"),
    _F("F26", "torso_bent", "torsoBent", "mix", None, "angle_max", ("neck", "root", "lknee", "lhip", "neck", "root", "rknee", "rhip"), None, ("<=", 110), ("<=", 110), paper="Fm7"),
    _F("F27", "root_fast", "velPoint_root", "mix", None, "fast", ("root",), None, (">", 1.0), (">", 1.0), 12, paper="Fm8"),
    _F("F28", "rhand_touching_head", "distPointSegment_neck_headtop_rfingers", "mix", "F29", "touch", ("neck", "headtop", "rfingers"), None, ("<=", 1.0), ("<=", 1.0), params=(1.0, 0.0, 1.0), paper="Fm3"),
    _F("F29", "lhand_touching_head", "distPointSegment_neck_headtop_lfingers", "mix", "F28", "touch", ("neck", "headtop", "lfingers"), None, ("<=", 1.0), ("<=", 1.0), params=(1.0, 0.0, 1.0), paper="Fm4"),
    _F("F30", "rhand_touching_hip", "distPointSegment_lhip_rhip_rfingers", "mix", "F31", "touch", ("lhip", "rhip", "rfingers"), None, ("<=", 1.0), ("<=", 1.0), params=(1.0, 1.0, 1.0), paper="Fm5"),
    _F("F31", "lhand_touching_hip", "distPointSegment_lhip_rhip_lfingers", "mix", "F30", "touch", ("lhip", "rhip", "lfingers"), None, ("<=", 1.0), ("<=", 1.0), params=(1.0, 1.0, 1.0), paper="Fm6"),
)
# fmt: on


def _fixed() -> tuple[Feature31, ...]:
    """The reference table with the bugs of docs/method/features31.md §5.1–5.3 fixed."""
    rows = list(FEATURES31_REFERENCE)
    by_id = {f.id: i for i, f in enumerate(rows)}
    rows[by_id["F04"]] = rows[by_id["F04"]]._replace(unit="femL")
    for fid in ("F10", "F11"):
        rows[by_id[fid]] = rows[by_id[fid]]._replace(on=(">", 1.25))
    rows[by_id["F27"]] = rows[by_id["F27"]]._replace(unit="hlL", window_ms=100)
    return tuple(rows)


FEATURES31: tuple[Feature31, ...] = _fixed()

#: Index groups of [MRC05] §5.3: Fℓ (11), Fu (12), Fm (8), as 0-based rows.
GROUPS31: dict[str, tuple[int, ...]] = {
    g: tuple(i for i, f in enumerate(FEATURES31_REFERENCE) if f.group == g)
    for g in ("lower", "upper", "mix")
}
