"""Keyframe queries: what they are, their JSON files, and how they read as a table.

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

File format (``mtanno.keyframes/1``, ``docs/formats.md``)::

    {"schema": "mtanno.keyframes/1", "class": "squat1Reps", "feature_set": "mr06-ak40",
     "fps": 30.0, "template_length": 47,
     "extension": {"factor": 2, "offset": 0},
     "groups": {"mix": ["F27 name", …], "upper": [...]},
     "keyframes": [
       {"group": "mix", "position": 15, "vector": "1111*000000*1*"},
       {"group": "mix", "position": 25, "vector": "…", "stiffness": 0.7},
       {"group": "upper", "position": 32, "vector": "…", "gap": [5, 9]}],
     "provenance": {...}}

The gap to the previous keyframe is on each keyframe after the first: ``"stiffness"`` (a
number or a fraction string such as ``"1/3"``) or ``"gap": [dmin, dmax]`` (``dmax`` null:
no upper bound). Positions are 1-based template columns and may not decrease.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from mtanno.errors import MtannoError, read_json

__all__ = [
    "SCHEMA", "Extension", "Gap", "Keyframe", "KeyframeQuery", "format_query",
    "keyframe_files", "load_class_keyframes", "load_keyframes", "load_keyframe_folder",
    "save_keyframes", "stiffness_bounds", "tolerant_patterns",
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
    if not _is_number(q.fps) or not math.isfinite(q.fps) or q.fps <= 0:
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


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


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


# --------------------------------------------------------------------------- JSON I/O

_KEYS = {"schema", "class", "feature_set", "fps", "template_length", "extension", "groups",
         "keyframes", "provenance", "comment"}
_KF_KEYS = {"group", "position", "vector", "mismatches", "stiffness", "gap", "comment"}


def parse_keyframes(d: Any, *, text: str | None = None, path: str | None = None,
                    ) -> KeyframeQuery:
    """A :class:`KeyframeQuery` from a parsed JSON object (see the module docstring);
    every problem is an :class:`MtannoError` naming ``path`` and, where known, the line."""
    def bad(msg: str, key: str | None = None, nth: int = 0) -> MtannoError:
        line = _line_of(text, key, nth) if text is not None and key else None
        return MtannoError(msg, path=path, line=line)

    if not isinstance(d, dict):
        raise MtannoError("a keyframe file must hold one JSON object", path=path, line=1)
    if d.get("schema") != SCHEMA:
        raise bad(f"unsupported keyframe schema {d.get('schema')!r} (expected {SCHEMA!r})",
                  "schema")
    unknown = sorted(set(d) - _KEYS)
    if unknown:
        raise bad(f"unknown key '{unknown[0]}' (known: {', '.join(sorted(_KEYS))})",
                  unknown[0])
    missing = [k for k in ("class", "feature_set", "fps", "template_length", "extension",
                           "groups", "keyframes") if k not in d]
    if missing:
        raise bad(f"missing field(s): {', '.join(missing)}")
    groups = d["groups"]
    if not isinstance(groups, dict) or not all(
            isinstance(v, list) and all(isinstance(f, str) for f in v) for v in groups.values()):
        raise bad("'groups' must map group names to lists of feature names", "groups")
    ext = d["extension"]
    if not isinstance(ext, dict) or not ext or set(ext) - {"factor", "offset", "left", "right"}:
        raise bad("'extension' must be {\"factor\": F, \"offset\": O} or "
                  "{\"left\": L, \"right\": R}", "extension")
    try:
        extension = (Extension(0, 0, ext.get("left"), ext.get("right"))
                     if "left" in ext or "right" in ext
                     else Extension(ext.get("factor", 2), ext.get("offset", 0)))
    except MtannoError as exc:
        raise bad(exc.message, "extension") from None
    raw = d["keyframes"]
    if not isinstance(raw, list):
        raise bad("'keyframes' must be a list", "keyframes")
    keyframes, gaps = [], []
    for j, k in enumerate(raw, 1):
        where = f"keyframe {j}"
        if not isinstance(k, dict):
            raise bad(f"{where} must be an object", "keyframes")
        extra = sorted(set(k) - _KF_KEYS)
        if extra:
            raise bad(f"{where}: unknown key '{extra[0]}' (known: {', '.join(sorted(_KF_KEYS))})",
                      "group", j - 1)
        for key in ("group", "position", "vector"):
            if key not in k:
                raise bad(f"{where} lacks '{key}'", "group", j - 1)
        if not isinstance(k["group"], str):
            raise bad(f"{where}: group must be a name", "group", j - 1)
        if not isinstance(k["vector"], str):
            raise bad(f"{where}: vector must be a string of 0, 1 and *", "vector", j - 1)
        vector = "".join(k["vector"].split())
        keyframes.append(Keyframe(k["group"], vector, k["position"], k.get("mismatches", 0)))
        has_s, has_g = "stiffness" in k, "gap" in k
        if j == 1:
            if has_s or has_g:
                raise bad("keyframe 1 has no previous keyframe: no stiffness or gap allowed",
                          "group", 0)
            continue
        if has_s == has_g:
            raise bad(f"{where} needs either 'stiffness' or 'gap' (to keyframe {j - 1})",
                      "group", j - 1)
        try:
            if has_s:
                p0, p1 = keyframes[-2].position, keyframes[-1].position
                if not all(isinstance(p, int) and not isinstance(p, bool) for p in (p0, p1)):
                    raise MtannoError("position must be an integer")
                if p1 < p0:
                    raise MtannoError(f"position {p1} is before the previous keyframe's "
                                      f"{p0} (positions may not decrease)")
                s = k["stiffness"]
                if not (_is_number(s) or isinstance(s, str)):
                    raise MtannoError(f"stiffness must be a number in (0, 1], got {s!r}")
                gaps.append(Gap.from_stiffness(p1 - p0, s))
            else:
                g = k["gap"]
                if not (isinstance(g, list) and len(g) == 2):
                    raise MtannoError("gap must be [dmin, dmax] (dmax null: unbounded)")
                gaps.append(Gap(g[0], g[1]))
        except MtannoError as exc:
            raise bad(f"{where}: {exc.message}", "stiffness" if has_s else "gap",
                      _count_before(raw, j - 1, "stiffness" if has_s else "gap")) from None
    prov = d.get("provenance", {})
    if not isinstance(prov, dict):
        raise bad("'provenance' must be an object", "provenance")
    fps = d["fps"]
    fields = dict(class_name=d["class"], feature_set=d["feature_set"],
                  groups={str(g): tuple(v) for g, v in groups.items()},
                  keyframes=tuple(keyframes), gaps=tuple(gaps),
                  template_length=d["template_length"], extension=extension, fps=fps,
                  provenance=prov)
    _validate(SimpleNamespace(**fields), text, path)  # with line numbers
    return KeyframeQuery(**fields)


def _count_before(raw: list, j: int, key: str) -> int:
    return sum(1 for k in raw[:j] if isinstance(k, dict) and key in k)


def load_keyframes(path: str | os.PathLike) -> KeyframeQuery:
    """Read and validate a keyframe query file (``mtanno.keyframes/1``)."""
    spath = str(path)
    d, text = read_json(path, what="keyframe file")
    return parse_keyframes(d, text=text, path=spath)


def _load_folder(folder: str | os.PathLike) -> dict[str, tuple[Path, KeyframeQuery]]:
    """Class name → (file, query) of every keyframe file of ``folder`` (or of one file), in
    file order; two files of one class are an error."""
    p = Path(folder)
    if not p.exists():
        raise MtannoError("keyframe folder or file not found", path=str(p))
    paths = keyframe_files(p)
    if not paths:
        raise MtannoError("no keyframe files (*.json) in this folder", path=str(p))
    out: dict[str, tuple[Path, KeyframeQuery]] = {}
    for f in paths:
        q = load_keyframes(f)
        if q.class_name in out:
            raise MtannoError(f"class '{q.class_name}' has two keyframe files: "
                              f"{out[q.class_name][0]} and {f}")
        out[q.class_name] = (f, q)
    return out


def load_keyframe_folder(folder: str | os.PathLike) -> dict[str, KeyframeQuery]:
    """Class name → query of every ``*.json`` in ``folder`` (or of one file). Two files
    of one class are an error."""
    return {c: q for c, (_, q) in _load_folder(folder).items()}


def keyframe_files(folder: str | os.PathLike) -> list[Path]:
    """The keyframe files of a folder (``*.json``, sorted), or the one file given."""
    p = Path(folder)
    return sorted(p.glob("*.json")) if p.is_dir() else [p]


def load_class_keyframes(folder: str | os.PathLike, classes: Sequence[str], *,
                         feature_set: str, fps: float | None = None,
                         ) -> tuple[dict[str, KeyframeQuery], list[dict], list[str], list[str]]:
    """The keyframe queries of a folder for annotating ``classes``: (class → query for the
    classes that have one; the files read with their SHA-256, for provenance; classes
    without a query; queries of classes not among ``classes``). Queries must be for
    ``feature_set`` and, when ``fps`` is given (the templates' frame rate), at that rate:
    their gaps and extensions count frames at it."""
    from mtanno.util.tables import sha256_file

    queries, files = {}, []
    for f, q in _load_folder(folder).values():
        if q.feature_set != feature_set:
            raise MtannoError(f"keyframes of class '{q.class_name}' are for feature set "
                              f"'{q.feature_set}' but the templates use '{feature_set}'",
                              path=str(f))
        if fps is not None and float(q.fps) != float(fps):
            raise MtannoError(f"keyframes of class '{q.class_name}' are at {q.fps:g} Hz but "
                              f"the templates at {float(fps):g} Hz", path=str(f))
        queries[q.class_name] = q
        if q.class_name in classes:
            files.append({"path": str(f), "sha256": sha256_file(f), "class": q.class_name})
    missing = [c for c in classes if c not in queries]
    extra = sorted(set(queries) - set(classes))
    return {c: queries[c] for c in classes if c in queries}, files, missing, extra


def dumps(q: KeyframeQuery) -> str:
    """JSON text meant to be read and edited: one line per keyframe and per group."""
    from mtanno.util.tables import json_compact, json_list_lines, json_object_lines

    layouts = {"keyframes": lambda v: json_list_lines(json_compact(k) for k in v),
               "groups": lambda v: json_object_lines(v, level=1),
               "provenance": _dumps_provenance}
    return json_object_lines(q.to_dict(), layouts) + "\n"


def _dumps_provenance(prov: dict) -> str:
    """One line per provenance entry; a list of objects (the training clips) one line per
    object."""
    from mtanno.util.tables import json_compact, json_list_lines, json_object_lines

    if not prov:
        return "{}"

    def objects(v: list) -> str:
        return json_list_lines((json_compact(x) for x in v), level=2)

    return json_object_lines(prov, {k: objects for k, v in prov.items() if isinstance(v, list)
                                    and v and all(isinstance(x, dict) for x in v)}, level=1)


def save_keyframes(path: str | os.PathLike, q: KeyframeQuery) -> None:
    """Write ``q`` as JSON to ``path`` atomically."""
    from mtanno.util.output import atomic_path

    _validate(q)
    text = dumps(q)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")


# --------------------------------------------------------------------------- display


def format_query(q: KeyframeQuery, *, path: str | None = None) -> str:
    """A readable description of a query: header, one row per keyframe (position, group,
    gap to the previous one, vector), then a table with one row per feature fixed by some
    keyframe and one column per keyframe (``1``, ``0`` or ``·`` for a wildcard)."""
    left, right = q.widths()
    head = [f"keyframes      {path}" if path else None,
            f"class          {q.class_name}",
            f"feature set    {q.feature_set}, {q.fps:g} Hz",
            f"template       {q.template_length} columns",
            f"keyframes      {q.n}",
            f"windows        hits widened by {left} frames left, {right} right "
            f"({_ext_text(q)})"]
    prov = q.provenance
    if prov.get("method"):
        fit = prov.get("fitness") or {}
        extra = ""
        if fit:
            extra = (f"; training P {fit.get('P', float('nan')):.3f} R "
                     f"{fit.get('R', float('nan')):.3f} F{fit.get('beta', 2):g} "
                     f"{fit.get('F', float('nan')):.3f}")
        seed = f", seed {prov['seed']}" if "seed" in prov else ""
        head.append(f"learned by     {prov['method']}{seed}{extra}")
    out = [h for h in head if h is not None]
    out.append("")
    out.append("  #  pos  group    gap to previous    vector")
    for j, kf in enumerate(q.keyframes):
        gap = q.gaps[j - 1].text() if j else ""
        tol = f"  (≤{kf.mismatches} mismatch{'es' if kf.mismatches > 1 else ''})" \
            if kf.mismatches else ""
        out.append(f"{j + 1:3d}  {kf.position:3d}  {kf.group:<7s}  {gap:<17s}  {kf.vector}{tol}")
    rows = []
    for g, feats in q.groups.items():
        for k, name in enumerate(feats):
            cells = []
            for kf in q.keyframes:
                c = kf.vector[k] if kf.group == g else " "
                cells.append("·" if c == "*" else c)
            if any(c in "01" for c in cells):
                rows.append((f"{g}:{name}", cells))
    if rows:
        width = max(len(r[0]) for r in rows)
        out.append("")
        out.append(" " * (width + 2) + " ".join(f"{j + 1:>2d}" for j in range(q.n)))
        for name, cells in rows:
            out.append(f"{name:<{width}s}  " + " ".join(f"{c:>2s}" for c in cells))
    return "\n".join(out)


def _ext_text(q: KeyframeQuery) -> str:
    e = q.extension
    if e.left is not None:
        return "explicit widths"
    off = f" + {e.offset}" if e.offset else ""
    return f"{e.factor}·(q1−1){off} and {e.factor}·(K−qn){off}"


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
