"""Keyframe queries: what they are, their gap bounds and window extension, checked
when made.

A keyframe query ([MBS09] §5; thesis ch. 4; docs/method.md §5) is a sequence of keyframes
V_1 … V_n, each a fuzzy feature vector in {0, 1, *} over the features of ONE feature group
(upper, lower, mix …), taken from template column q_j, and gap bounds
(dmin_j, dmax_j) in frames at 30 Hz between V_j and V_{j+1}. A document segment is
relevant if it has frames t_1 ≤ … ≤ t_n with the features at t_j matching V_j and
dmin_j ≤ t_{j+1} − t_j ≤ dmax_j. A condition over several groups at one moment is written as
several keyframes at the same position with gap (0, 0).

Gap bounds are given either explicitly or by a stiffness s ∈ (0, 1] and the template
distance d = q_{j+1} − q_j: dmin = ⌈s·d⌉, dmax = ⌊d/s⌋, in exact rational arithmetic
(10·0.3 in binary floating point is 3.0000000000000004, whose ceiling is 4).

The candidate windows a query gives for annotation are its hits widened by
``factor·(q_1 − 1) + offset`` frames on the left and ``factor·(K − q_n) + offset`` on the
right (K = template length): [MBS09]'s annotation uses factor 2, offset 0; the reference
implementation's classification driver factor 3, offset 3. Explicit widths can be given
instead.

The query's JSON file is :mod:`mtanno.keyframes.store`, folders of them
:mod:`mtanno.keyframes.folders`, its text form :mod:`mtanno.keyframes.describe`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from typing import Any

from mtanno.errors import MtannoError
from mtanno.templates.model import is_number

__all__ = [
    "SCHEMA", "Extension", "Gap", "Keyframe", "KeyframeQuery", "check_features_known",
    "feature_groups_of", "stiffness_bounds", "tolerant_patterns",
]

SCHEMA = "mtanno.keyframes/1"
#: Upper gap bound used for "no upper bound" inside the kernels (frames).
UNBOUNDED = 1 << 40
#: Largest template length (columns at 30 Hz, an hour) and window extension (frames) a
#: query may give: more is no learned query, and would overflow the kernels' frame numbers.
MAX_TEMPLATE_LENGTH = 108_000
MAX_EXTENSION = 1 << 30


def stiffness_bounds(distance: int, stiffness: Fraction | float | str) -> tuple[int, int]:
    """(dmin, dmax) = (⌈s·d⌉, ⌊d/s⌋) for template distance ``distance`` ≥ 0 and stiffness
    s ∈ (0, 1], computed exactly (docs/method.md §5). A float is read by its shortest
    decimal form (0.3 is 3/10)."""
    s = _fraction(stiffness)
    if not 0 < s <= 1:
        raise MtannoError(f"stiffness must lie in (0, 1], got {stiffness}")
    if distance < 0:
        raise MtannoError(f"template distance must be ≥ 0, got {distance}")
    return math.ceil(s * distance), math.floor(distance / s)


def _fraction(value: Fraction | float | int | str) -> Fraction:
    if isinstance(value, Fraction):
        return value
    if isinstance(value, bool):
        raise MtannoError(f"not a number: {value!r}")
    if isinstance(value, float):
        if not math.isfinite(value):
            raise MtannoError(f"not a finite number: {value!r}")
        return Fraction(repr(value))
    try:
        return Fraction(value)
    except (ValueError, ZeroDivisionError, TypeError):
        raise MtannoError(f"not a number or fraction: {value!r}") from None


@dataclass(frozen=True)
class Gap:
    """Bounds on t_{j+1} − t_j in frames; ``dmax`` None = no upper bound. ``stiffness``
    records the stiffness the bounds came from (kept for the file; None if explicit)."""

    dmin: int
    dmax: int | None
    stiffness: Fraction | None = None

    def __post_init__(self):
        for name in ("dmin", "dmax"):
            v = getattr(self, name)
            if v is None and name == "dmax":
                continue
            if not isinstance(v, int) or isinstance(v, bool) or v < 0:
                raise MtannoError(f"gap {name} must be an integer ≥ 0, got {v!r}")
        if self.dmax is not None and self.dmin > self.dmax:
            raise MtannoError(f"gap dmin {self.dmin} > dmax {self.dmax}")

    @classmethod
    def from_stiffness(cls, distance: int, stiffness) -> Gap:
        s = _fraction(stiffness)
        lo, hi = stiffness_bounds(distance, s)
        return cls(lo, hi, s)

    @property
    def upper(self) -> int:
        """dmax, or a huge number for "no upper bound" (for the kernels)."""
        return UNBOUNDED if self.dmax is None else self.dmax

    def text(self) -> str:
        hi = "∞" if self.dmax is None else str(self.dmax)
        s = "" if self.stiffness is None else f" (s={_fraction_text(self.stiffness)})"
        return f"{self.dmin}..{hi}{s}"


def _fraction_text(s: Fraction) -> str | float:
    f = float(s)
    return f if Fraction(repr(f)) == s else f"{s.numerator}/{s.denominator}"


@dataclass(frozen=True)
class Keyframe:
    """One keyframe: ``vector`` has one of ``0``, ``1``, ``*`` per feature of ``group``
    (in the group's feature order); ``position`` is the 1-based template column.
    ``mismatches`` is how many of the fixed entries may differ at a matching frame (0:
    all must agree, as in [MBS09]; 1 or 2: [MRC05]'s mismatch tolerance, for keyframes that
    must carry over to performers who differ in a feature or two)."""

    group: str
    vector: str
    position: int
    mismatches: int = 0

    def pattern(self) -> tuple[int, int]:
        """(mask, value) over the group's bits: bit k = the group's k-th feature."""
        mask = value = 0
        for k, c in enumerate(self.vector):
            if c != "*":
                mask |= 1 << k
                value |= (c == "1") << k
        return mask, value

    def patterns(self) -> list[tuple[int, int]]:
        """(mask, value) patterns whose union is the frames this keyframe matches: the
        pattern itself, or with ``mismatches`` = m every way of freeing m fixed bits."""
        return tolerant_patterns(*self.pattern(), self.mismatches)

    @property
    def fixed(self) -> int:
        """Number of non-wildcard entries."""
        return sum(c != "*" for c in self.vector)


def tolerant_patterns(mask: int, value: int, mismatches: int) -> list[tuple[int, int]]:
    """Patterns matching the vectors that differ from (mask, value) in at most
    ``mismatches`` fixed bits: every way of freeing that many bits of ``mask``."""
    if mismatches <= 0:
        return [(mask, value)]
    from itertools import combinations

    bits = [1 << k for k in range(mask.bit_length()) if mask >> k & 1]
    out = []
    for free in combinations(bits, min(mismatches, len(bits))):
        m = mask
        for b in free:
            m &= ~b
        out.append((m, value & m))
    return out


@dataclass(frozen=True)
class Extension:
    """How far candidate windows are widened (frames): ``factor·(q_1 − 1) + offset`` on
    the left and ``factor·(K − q_n) + offset`` on the right, or explicit ``left``/``right``
    widths when those are set."""

    factor: int = 2
    offset: int = 0
    left: int | None = None
    right: int | None = None

    def __post_init__(self):
        for name in ("factor", "offset", "left", "right"):
            v = getattr(self, name)
            if v is None:
                continue
            if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= MAX_EXTENSION:
                raise MtannoError(f"extension {name} must be an integer in 0..{MAX_EXTENSION}, "
                                  f"got {v!r}")
        if (self.left is None) != (self.right is None):
            raise MtannoError("extension needs both left and right, or factor/offset")

    def widths(self, first: int, last: int, length: int) -> tuple[int, int]:
        """(left, right) widening in frames for keyframe positions ``first``..``last`` of a
        template of ``length`` columns."""
        if self.left is not None:
            return self.left, int(self.right)
        return (self.factor * (first - 1) + self.offset,
                self.factor * max(0, length - last) + self.offset)

    def to_dict(self) -> dict:
        if self.left is not None:
            return {"left": self.left, "right": self.right}
        return {"factor": self.factor, "offset": self.offset}


#: [MBS09]'s annotation widening (the reference annotation script): 2·(q1−1), 2·(K−qn).
ANNOTATION_EXTENSION = Extension(2, 0)


@dataclass(frozen=True)
class KeyframeQuery:
    """A keyframe query of one class (see the module docstring).

    Attributes
    ----------
    class_name, feature_set, fps:
        The class, the feature set and analysis rate of the features it applies to.
    groups:
        Group name → feature names (group order) of every group the keyframes use.
    keyframes:
        V_1 … V_n in order (positions non-decreasing).
    gaps:
        n − 1 gap bounds; ``gaps[j]`` is between ``keyframes[j]`` and ``keyframes[j+1]``.
    template_length:
        K, the number of columns of the class template the positions refer to.
    extension:
        Widening of hits into candidate windows.
    provenance:
        How the query was made (method, seed, parameters, training files, fitness …).
    """

    class_name: str
    feature_set: str
    groups: Mapping[str, tuple[str, ...]]
    keyframes: tuple[Keyframe, ...]
    gaps: tuple[Gap, ...]
    template_length: int
    extension: Extension = ANNOTATION_EXTENSION
    fps: float = 30.0
    provenance: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "groups", {str(g): tuple(f) for g, f in self.groups.items()})
        object.__setattr__(self, "keyframes", tuple(self.keyframes))
        object.__setattr__(self, "gaps", tuple(self.gaps))
        _validate(self)

    @property
    def n(self) -> int:
        return len(self.keyframes)

    def widths(self) -> tuple[int, int]:
        """(left, right) widening of hits into candidate windows, in frames."""
        return self.extension.widths(self.keyframes[0].position, self.keyframes[-1].position,
                                     self.template_length)

    def features(self, kf: Keyframe) -> tuple[str, ...]:
        return self.groups[kf.group]

    def to_dict(self) -> dict[str, Any]:
        kfs = []
        for j, kf in enumerate(self.keyframes):
            d: dict[str, Any] = {"group": kf.group, "position": kf.position,
                                 "vector": kf.vector}
            if kf.mismatches:
                d["mismatches"] = kf.mismatches
            if j:
                g = self.gaps[j - 1]
                if g.stiffness is not None:
                    d["stiffness"] = _fraction_text(g.stiffness)
                else:
                    d["gap"] = [g.dmin, g.dmax]
            kfs.append(d)
        used = [g for g in self.groups if any(k.group == g for k in self.keyframes)]
        return {
            "schema": SCHEMA, "class": self.class_name, "feature_set": self.feature_set,
            "fps": float(self.fps), "template_length": self.template_length,
            "extension": self.extension.to_dict(),
            "groups": {g: list(self.groups[g]) for g in used},
            "keyframes": kfs, "provenance": self.provenance,
        }

    def with_provenance(self, **items) -> KeyframeQuery:
        return replace(self, provenance={**self.provenance, **items})


def _validate(q: KeyframeQuery, text: str | None = None, path: str | None = None) -> None:
    def bad(msg: str, key: str | None = None, nth: int = 0) -> MtannoError:
        line = _line_of(text, key, nth) if text is not None and key else None
        return MtannoError(msg, path=path, line=line)

    if not isinstance(q.class_name, str) or not q.class_name.strip():
        raise bad("class must be a non-empty string", "class")
    if not isinstance(q.feature_set, str) or not q.feature_set:
        raise bad("feature_set must be a non-empty string", "feature_set")
    if not is_number(q.fps) or not math.isfinite(q.fps) or q.fps <= 0:
        raise bad(f"fps must be a positive number, got {q.fps!r}", "fps")
    K = q.template_length
    if not isinstance(K, int) or isinstance(K, bool) or not 1 <= K <= MAX_TEMPLATE_LENGTH:
        raise bad(f"template_length must be an integer in 1..{MAX_TEMPLATE_LENGTH}, got {K!r}",
                  "template_length")
    recorded = _recorded_length(q.provenance)
    if recorded is not None and K != recorded[1]:
        raise bad(f"template_length is {K} but the provenance records {recorded[0]} "
                  f"{recorded[1]} (the template the positions refer to)", "template_length")
    for g, feats in q.groups.items():
        if not feats or not all(isinstance(f, str) and f for f in feats):
            raise bad(f"group '{g}' must list its feature names", "groups")
        if len(set(feats)) != len(feats):
            raise bad(f"group '{g}' names a feature twice", "groups")
        if len(feats) > 62:
            raise bad(f"group '{g}' has {len(feats)} features; at most 62", "groups")
    if not q.keyframes:
        raise bad("a keyframe query needs at least one keyframe", "keyframes")
    if len(q.gaps) != len(q.keyframes) - 1:
        raise bad(f"{len(q.keyframes)} keyframes need {len(q.keyframes) - 1} gaps, got "
                  f"{len(q.gaps)}", "keyframes")
    prev = None
    for j, kf in enumerate(q.keyframes, 1):
        where = f"keyframe {j}"
        if kf.group not in q.groups:
            known = ", ".join(q.groups) or "none"
            raise bad(f"{where}: unknown group '{kf.group}' (groups of this file: {known})",
                      "group", j - 1)
        n = len(q.groups[kf.group])
        if not isinstance(kf.vector, str) or any(c not in "01*" for c in kf.vector):
            raise bad(f"{where}: vector must be a string of 0, 1 and *", "vector", j - 1)
        if len(kf.vector) != n:
            raise bad(f"{where}: vector has {len(kf.vector)} entries but group '{kf.group}' "
                      f"has {n} features", "vector", j - 1)
        m = kf.mismatches
        if not isinstance(m, int) or isinstance(m, bool) or not 0 <= m <= 2:
            raise bad(f"{where}: mismatches must be 0, 1 or 2, got {m!r}", "vector", j - 1)
        if m and kf.fixed <= 2 * m + 1:
            raise bad(f"{where}: {m} mismatch(es) allowed but only {kf.fixed} fixed entries "
                      f"(need at least {2 * m + 2})", "vector", j - 1)
        p = kf.position
        if not isinstance(p, int) or isinstance(p, bool) or not 1 <= p <= K:
            raise bad(f"{where}: position must be an integer in 1..{K} (template length), "
                      f"got {p!r}", "position", j - 1)
        if prev is not None and p < prev:
            raise bad(f"{where}: position {p} is before the previous keyframe's {prev} "
                      "(positions may not decrease)", "position", j - 1)
        prev = p
    if q.keyframes and all(kf.fixed == 0 for kf in q.keyframes):
        raise bad("every keyframe is all wildcards: the query constrains nothing", "keyframes")


def _recorded_length(prov: Any) -> tuple[str, int] | None:
    """(where, length) of the template a learned query's positions refer to, as its
    provenance records it (learn-keyframes: ``hard_template.length`` for the hard method,
    else ``template.length``); None when the provenance records none (a query written by
    hand)."""
    if not isinstance(prov, dict):
        return None
    for key in ("hard_template", "template"):
        info = prov.get(key)
        n = info.get("length") if isinstance(info, dict) else None
        if isinstance(n, int) and not isinstance(n, bool):
            return f"{key}.length", n
    return None


def _line_of(text: str, key: str, nth: int = 0) -> int | None:
    """1-based line of the ``nth`` (0-based) ``"key":`` in JSON text, for messages."""
    needle = json.dumps(key) + ":"
    pos = -1
    for _ in range(nth + 1):
        pos = text.find(needle, pos + 1)
        if pos < 0:
            return None
    return text.count("\n", 0, pos) + 1


def feature_groups_of(feature_set: str) -> dict[str, tuple[str, ...]]:
    """Group name → feature names of a built-in feature set's index groups."""
    from mtanno.features import get_feature_set

    fs = get_feature_set(feature_set)
    return {g: tuple(fs.names[i] for i in rows) for g, rows in fs.groups.items()}


def check_features_known(q: KeyframeQuery, names: Sequence[str], *, feature_set: str | None,
                         what: str, path: str | None = None) -> None:
    """The query must be for ``feature_set`` and every feature it uses must be among
    ``names`` (those of an index or a feature file, named by ``what`` in the message)."""
    if feature_set is not None and feature_set != q.feature_set:
        raise MtannoError(f"keyframes of class '{q.class_name}' are for feature set "
                          f"'{q.feature_set}' but the {what} holds '{feature_set}'", path=path)
    known = set(names)
    for g, feats in q.groups.items():
        for f in feats:
            if f not in known:
                raise MtannoError(f"keyframes of class '{q.class_name}': group '{g}' uses "
                                  f"feature '{f}', which the {what} lacks", path=path)
