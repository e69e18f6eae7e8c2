"""Marker sets: which markers of a C3D file make which canonical joint (issue 36).

A marker set is a TOML file (package data ``mtanno/markersets/*.toml``, or the user's own
through ``--markers FILE.toml``; ``docs/formats.md`` has the format): the markers that
recognise it (``detect``), the rigid segments gaps are filled from (``[segments]``),
body-size numbers measured from the markers (``[sizes]``), and for each of the 22
canonical joints (and any helper point) a recipe (``[points]``): a mean of markers or
points, a point extended beyond two others, a point offset along a direction, the
Plug-in Gait chord function (a joint centre medial of a lateral marker), or the hip-joint
regression of Harrington et al. (2007). A small file may instead take another set's
recipes (``base = "vicon-41"``) and only rename its markers (``[markers]``: marker of the
set = label in the file), which is what ``mtanno markers guess`` writes.

Labels are matched without their subject prefix (``meinard:LKNE`` is ``LKNE``), so one
set fits every subject; labels no recipe uses (``*0``, a second subject's) are ignored.
The evaluation of the recipes is :mod:`mtanno.io.markerjoints`.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import sys
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.rigs import CANONICAL_JOINTS
from mtanno.io.skeleton import Rig

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["KINDS", "MarkerSet", "Recipe", "available_sets", "canonical_rig", "choose_set",
           "guess_toml", "load_set", "marker_name"]

#: Recipe kinds and the keys each takes (the kind's own key first).
KINDS: dict[str, tuple[str, ...]] = {
    "mean": ("mean",),
    "extend": ("extend", "by"),
    "offset": ("offset", "toward", "by", "times"),
    "chord": ("chord", "hinge", "away", "toward", "by", "times"),
    "axis": ("axis", "between", "side", "by", "times"),
    "hip": ("hip", "side", "asis", "psis"),
}
#: Hip-joint regressions ``hip = ...`` names.
HIP_METHODS = ("harrington2007",)


@dataclass(frozen=True)
class Recipe:
    """How one point is made: ``kind`` (a key of :data:`KINDS`), ``inputs`` (the names of
    the markers or points it reads, in the kind's order: mean → all; extend → A, B;
    offset → A, from, to; chord → marker, hinge, reference; axis → marker, proximal
    joint, distal joint; hip → left ASIS, right ASIS, left PSIS, right PSIS) and its
    numbers: ``by`` (mm, a factor for extend, or a size name in ``size``), ``times``,
    ``side`` ("away"/"toward" for chord, "left"/"right" for axis and hip)."""

    kind: str
    inputs: tuple[str, ...]
    by: float = 0.0
    size: str | None = None
    times: float = 1.0
    side: str = ""

    def text(self) -> str:
        """The recipe as one short line (``mtanno info``)."""
        i = self.inputs
        amount = (f"{self.size}" if self.size else f"{self.by:g} mm") + \
            (f" × {self.times:g}" if self.times != 1 else "")
        if self.kind == "mean":
            return "mean of " + ", ".join(i)
        if self.kind == "extend":
            return f"{i[1]} + {self.by:g} × ({i[1]} − {i[0]})"
        if self.kind == "offset":
            return f"{i[0]} moved {amount} along {i[1]} → {i[2]}"
        if self.kind == "chord":
            return (f"{amount} medial of {i[0]} (chord with {i[1]}, {self.side} "
                    f"{i[2]})")
        if self.kind == "axis":
            return (f"{amount} medial of {i[0]} along the hinge axis of {i[1]} – joint – "
                    f"{i[2]} ({self.side} side)")
        return (f"{self.side} hip centre, Harrington 2007 from ASIS {i[0]}, {i[1]} and "
                f"PSIS {i[2]}, {i[3]}")


@dataclass(frozen=True)
class Size:
    """A body-size number: the median over frames of |mean(a) − mean(b)| × times + plus
    (mm)."""

    a: tuple[str, ...]
    b: tuple[str, ...]
    times: float = 1.0
    plus: float = 0.0


@dataclass(frozen=True)
class MarkerSet:
    """A parsed marker set (module docstring). It answers what feature extraction asks of
    a skeleton map (``name``, ``path``, ``digest``, ``how``, :meth:`indices`,
    :meth:`coverage`), the joints being the rows of the motion's canonical rig."""

    name: str
    path: str
    detect: tuple[str, ...]
    segments: dict[str, tuple[str, ...]]
    sizes: dict[str, Size]
    points: dict[str, Recipe]
    heading: tuple[str, str]
    max_gap: float = 0.25
    renames: dict[str, str] = field(default_factory=dict)
    description: str = ""
    format: str = "c3d"
    #: How the set was chosen for a file, for ``mtanno info`` (not part of :attr:`digest`).
    how: str = ""

    @functools.cached_property
    def digest(self) -> str:
        """SHA-256 of what the set says (feature files record it: their features are
        recomputed when the set that made them changes)."""
        body = {"detect": self.detect, "segments": self.segments, "max_gap": self.max_gap,
                "sizes": {k: vars(v) for k, v in self.sizes.items()},
                "points": {k: vars(v) for k, v in self.points.items()},
                "heading": self.heading, "renames": self.renames, "name": self.name}
        return hashlib.sha256(json.dumps(body, sort_keys=True, default=list)
                              .encode()).hexdigest()

    @functools.cached_property
    def markers(self) -> tuple[str, ...]:
        """The marker names the recipes, sizes and segments read (every input that is not a
        point), in first-use order."""
        out: dict[str, None] = {}
        for r in self.points.values():
            out.update((n, None) for n in r.inputs if n not in self.points)
        for s in self.sizes.values():
            out.update((n, None) for n in (*s.a, *s.b))
        for seg in self.segments.values():
            out.update((n, None) for n in seg)
        return tuple(out)

    def label_of(self, marker: str) -> str:
        """The label (without subject prefix) the file gives marker ``marker``."""
        return self.renames.get(marker, marker)

    def indices(self, rig: Rig, joints: tuple[str, ...] = CANONICAL_JOINTS) -> np.ndarray:
        return np.array([rig.names.index(j) for j in joints], dtype=np.int64)

    def coverage(self, rig: Rig) -> dict[str, str | None]:
        """Canonical joint → its recipe as text."""
        return {j: self.points[j].text() for j in CANONICAL_JOINTS}

    @functools.cached_property
    def feeds(self) -> dict[str, list[str]]:
        """Marker → the canonical joints whose position it enters (directly or through
        other points), in canonical order."""
        out: dict[str, list[str]] = {m: [] for m in self.markers}
        for j in CANONICAL_JOINTS:
            for m in self._markers_of(j):
                out[m].append(j)
        return out

    def _markers_of(self, name: str) -> list[str]:
        seen: dict[str, None] = {}
        stack = [name]
        while stack:
            n = stack.pop()
            if n in self.points:
                stack.extend(self.points[n].inputs)
            else:
                seen[n] = None
        return list(seen)


def canonical_rig(source: str = "") -> Rig:
    """The rig of a marker file's motion: the 22 canonical joints as unconnected nodes, so
    that its positions are read as any rig's (:func:`mtanno.io.canonical_positions`)."""
    n = len(CANONICAL_JOINTS)
    eye = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    return Rig(kind="c3d", names=list(CANONICAL_JOINTS), parents=np.full(n, -1, np.int64),
               offsets=np.zeros((n, 3)), axes=np.zeros((n, 3), np.int64), pre=eye,
               post=eye.copy(), end_point=False, source=source)


def marker_name(label: str) -> str:
    """A label without its subject prefix (``meinard:LKNE`` → ``LKNE``) and blanks."""
    return label.rpartition(":")[2].strip()


@functools.lru_cache(maxsize=1)
def builtin_dir() -> Path:
    """Folder of the marker sets shipped with the package (package data)."""
    return Path(str(resources.files("mtanno") / "markersets"))


def _names(value, what: str, path: str) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not (isinstance(value, list) and value and all(isinstance(v, str) and v for v in value)):
        raise MtannoError(f"{what} must be a name or a list of names", path=path)
    return tuple(value)


def _number(value, what: str, path: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not np.isfinite(value):
        raise MtannoError(f"{what} must be a finite number, got {value!r}", path=path)
    return float(value)


def _recipe(name: str, spec, path: str) -> Recipe:
    """One ``[points]`` entry, checked."""
    where = f"[points] {name}"
    if not isinstance(spec, dict):
        raise MtannoError(f"{where} must be an inline table such as "
                          '{ mean = ["A", "B"] }', path=path)
    kinds = [k for k in KINDS if k in spec]
    if len(kinds) != 1:
        raise MtannoError(f"{where} must have exactly one of {', '.join(KINDS)}", path=path)
    kind = kinds[0]
    stray = sorted(set(spec) - set(KINDS[kind]))
    if stray:
        raise MtannoError(f"{where}: {kind} takes {', '.join(KINDS[kind])}, not "
                          f"{', '.join(stray)}", path=path)
    by, size = 0.0, None
    if "by" in spec:
        if isinstance(spec["by"], str) and kind in ("offset", "chord", "axis"):
            size = spec["by"]
        else:
            by = _number(spec["by"], f"{where} by", path)
    elif kind in ("extend", "offset", "chord", "axis"):
        raise MtannoError(f"{where}: {kind} needs by = …", path=path)
    times = _number(spec.get("times", 1.0), f"{where} times", path)
    if kind == "mean":
        return Recipe(kind, _names(spec["mean"], f"{where} mean", path))
    if kind == "extend":
        pair = _names(spec["extend"], f"{where} extend", path)
        if len(pair) != 2:
            raise MtannoError(f"{where}: extend takes two names [A, B]", path=path)
        return Recipe(kind, pair, by=by)
    if kind == "offset":
        toward = _names(spec.get("toward", ()) or [""], f"{where} toward", path) \
            if "toward" in spec else ()
        if len(toward) != 2:
            raise MtannoError(f"{where}: offset needs toward = [FROM, TO]", path=path)
        return Recipe(kind, (_names(spec["offset"], f"{where} offset", path)[0], *toward),
                      by=by, size=size, times=times)
    if kind == "chord":
        sides = [s for s in ("away", "toward") if s in spec]
        if len(sides) != 1:
            raise MtannoError(f"{where}: chord needs one of away = NAME or toward = NAME "
                              "(the reference point, on the joint's side or not)", path=path)
        if "hinge" not in spec:
            raise MtannoError(f"{where}: chord needs hinge = NAME (the next joint centre)",
                              path=path)
        names = (_names(spec["chord"], where, path)[0], _names(spec["hinge"], where, path)[0],
                 _names(spec[sides[0]], where, path)[0])
        return Recipe(kind, names, by=by, size=size, times=times, side=sides[0])
    if kind == "axis":
        pair = _names(spec.get("between", ()) or [""], f"{where} between", path)
        if len(pair) != 2 or spec.get("side") not in ("left", "right"):
            raise MtannoError(f"{where}: axis needs between = [PROXIMAL, DISTAL] (the joint "
                              "centres on either side) and side = \"left\" or \"right\"",
                              path=path)
        return Recipe(kind, (_names(spec["axis"], where, path)[0], *pair), by=by, size=size,
                      times=times, side=spec["side"])
    if spec["hip"] not in HIP_METHODS:
        raise MtannoError(f"{where}: unknown hip method {spec['hip']!r} (known: "
                          f"{', '.join(HIP_METHODS)})", path=path)
    side = spec.get("side")
    if side not in ("left", "right"):
        raise MtannoError(f"{where}: side must be \"left\" or \"right\"", path=path)
    asis = _names(spec.get("asis", ()) or [""], f"{where} asis", path)
    psis = _names(spec.get("psis", ()) or [""], f"{where} psis", path)
    if len(asis) != 2 or len(psis) != 2:
        raise MtannoError(f"{where}: asis and psis are [LEFT, RIGHT] marker pairs", path=path)
    return Recipe(kind, (*asis, *psis), side=side)


def _size(name: str, spec, path: str) -> Size:
    where = f"[sizes] {name}"
    if not isinstance(spec, dict) or "between" not in spec or \
            not isinstance(spec["between"], list) or len(spec["between"]) != 2:
        raise MtannoError(f"{where} must be {{ between = [A, B] }} (A, B: a marker or a list "
                          "of markers, whose mean is taken)", path=path)
    stray = sorted(set(spec) - {"between", "times", "plus"})
    if stray:
        raise MtannoError(f"{where}: unknown key(s) {', '.join(stray)}", path=path)
    a, b = (_names(v, where, path) for v in spec["between"])
    return Size(a, b, _number(spec.get("times", 1.0), f"{where} times", path),
                _number(spec.get("plus", 0.0), f"{where} plus", path))


def _check_graph(points: dict[str, Recipe], sizes: dict[str, Size], path: str) -> None:
    """Every canonical joint has a recipe, sizes named exist and read markers only, and
    no point depends on itself."""
    missing = [j for j in CANONICAL_JOINTS if j not in points]
    if missing:
        raise MtannoError(f"[points] lacks the joint(s) {', '.join(missing)} (the features "
                          f"need all of {', '.join(CANONICAL_JOINTS)})", path=path)
    for name, r in points.items():
        if r.size is not None and r.size not in sizes:
            raise MtannoError(f"[points] {name}: no size named '{r.size}' in [sizes]",
                              path=path)
    for name, s in sizes.items():
        inner = [n for n in (*s.a, *s.b) if n in points]
        if inner:
            raise MtannoError(f"[sizes] {name} reads the point '{inner[0]}'; sizes are "
                              "measured between markers", path=path)
    state: dict[str, int] = {}

    def visit(n: str, trail: tuple[str, ...]) -> None:
        if n not in points or state.get(n) == 2:
            return
        if state.get(n) == 1:
            raise MtannoError(f"[points] depend on each other in a circle: "
                              f"{' → '.join((*trail, n))}", path=path)
        state[n] = 1
        for i in points[n].inputs:
            visit(i, (*trail, n))
        state[n] = 2

    for n in points:
        visit(n, ())


def _read_toml(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MtannoError("marker set file not found", path=str(path)) from None
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MtannoError(f"not a valid TOML marker set: {exc}", path=str(path)) from None


def load_set(path: str | os.PathLike) -> MarkerSet:
    """Read one marker set file, checking every field (one :class:`MtannoError` naming
    the file and the entry)."""
    path = Path(path)
    spath = str(path)
    data = _read_toml(path)
    renames = data.get("markers", {})
    if not isinstance(renames, dict) or not all(isinstance(v, str) and v
                                                for v in renames.values()):
        raise MtannoError("[markers] must map marker names of the set to labels of the "
                          "file", path=spath)
    if "base" in data:
        base = _find(str(data["base"]), spath)
        extra = sorted(set(data) - {"base", "name", "description", "markers", "format"})
        if extra:
            raise MtannoError(f"a set with base = … only renames markers; it cannot also "
                              f"give {', '.join(extra)}", path=spath)
        unknown = sorted(set(renames) - set(base.markers))
        if unknown:
            raise MtannoError(f"[markers] renames {', '.join(unknown)}, which the set "
                              f"'{base.name}' does not use", path=spath)
        detect = tuple(renames.get(m, m) for m in base.detect)
        return MarkerSet(name=str(data.get("name", path.stem)), path=spath, detect=detect,
                         segments=base.segments, sizes=base.sizes, points=base.points,
                         heading=base.heading, max_gap=base.max_gap,
                         renames={**base.renames, **renames},
                         description=str(data.get("description", base.description)))
    if data.get("format", "c3d") != "c3d":
        raise MtannoError(f"format is {data.get('format')!r}; marker sets are for c3d files",
                          path=spath)
    points = data.get("points")
    if not isinstance(points, dict) or not points:
        raise MtannoError("a marker set needs a [points] table (or base = \"SET\")",
                          path=spath)
    recipes = {str(k): _recipe(str(k), v, spath) for k, v in points.items()}
    sizes_in = data.get("sizes", {})
    if not isinstance(sizes_in, dict):
        raise MtannoError("[sizes] must be a table", path=spath)
    sizes = {str(k): _size(str(k), v, spath) for k, v in sizes_in.items()}
    _check_graph(recipes, sizes, spath)
    segs = data.get("segments", {})
    if not isinstance(segs, dict):
        raise MtannoError("[segments] must be a table of marker lists", path=spath)
    segments = {str(k): _names(v, f"[segments] {k}", spath) for k, v in segs.items()}
    heading = _names(data.get("heading", ["rhip", "lhip"]), "heading", spath)
    if len(heading) != 2:
        raise MtannoError("heading must be [FROM, TO]: the body's left axis (F40)", path=spath)
    max_gap = _number(data.get("max_gap", 0.25), "max_gap", spath)
    if max_gap < 0:
        raise MtannoError("max_gap must be ≥ 0 seconds", path=spath)
    mset = MarkerSet(name=str(data.get("name", path.stem)), path=spath, detect=(),
                     segments=segments, sizes=sizes, points=recipes,
                     heading=(heading[0], heading[1]), max_gap=max_gap, renames=renames,
                     description=str(data.get("description", "")))
    detect = data.get("detect", [mset.label_of(m) for m in mset.markers])
    return replace(mset, detect=_names(detect, "detect", spath))


@functools.lru_cache(maxsize=16)
def _builtin(path: str, mtime: int) -> MarkerSet:
    return load_set(path)


def available_sets() -> list[MarkerSet]:
    """The built-in marker sets (package data), by file name."""
    out = []
    for f in sorted(builtin_dir().glob("*.toml")):
        out.append(_builtin(str(f), f.stat().st_mtime_ns))
    return out


def _find(override: str | os.PathLike, source: str | None = None) -> MarkerSet:
    """A marker set given as a file (``.toml``, or an existing path) or a built-in name."""
    p = Path(override)
    if p.suffix.lower() == ".toml" or p.exists():
        return load_set(p)
    for m in available_sets():
        if m.name == str(override):
            return m
    raise MtannoError(f"no marker set named '{override}' (built in: "
                      f"{', '.join(m.name for m in available_sets())}; or give a .toml file)",
                      path=source)


def _present(labels) -> set[str]:
    return {marker_name(x) for x in labels if marker_name(x)}


def choose_set(labels, override: str | os.PathLike | None = None, *,
               source: str | None = None) -> MarkerSet:
    """The marker set for a file with these labels: ``override`` (a file or a built-in
    name), else the first built-in set whose ``detect`` markers the file all has (subject
    prefixes ignored). When none fits, one :class:`MtannoError` names the joints that
    cannot be computed and how to give a set. (A batch asks once per file: the answer for
    the same labels is remembered, a given set file per modification time.)"""
    try:
        if override is not None:
            try:
                stamp = os.stat(override).st_mtime_ns
            except OSError:
                stamp = None  # a built-in name (or a missing file: _find says so)
            return _given(str(override), stamp)
        return _recognised(tuple(sorted(_present(labels))))
    except MtannoError as exc:
        if exc.path is not None or source is None:
            raise
        raise MtannoError(exc.template, path=source, options=exc.options) from None


@functools.lru_cache(maxsize=16)
def _given(override: str, stamp: int | None) -> MarkerSet:
    m = _find(override)
    return replace(m, how=f"given ({m.path})")


@functools.lru_cache(maxsize=64)
def _recognised(names: tuple[str, ...]) -> MarkerSet:
    have = set(names)
    sets = available_sets()
    for m in sets:
        if all(d in have for d in m.detect):
            return replace(m, how=f"recognised: the file has all {len(m.detect)} markers it "
                                  f"detects by")
    best = max(sets, key=lambda m: sum(m.label_of(x) in have for x in m.markers))
    shown = ", ".join(sorted(have)[:6]) + (" …" if len(have) > 6 else "") if have else "none"
    lacking = [x for x in best.markers if best.label_of(x) not in have]
    joints = [j for j in CANONICAL_JOINTS
              if any(best.label_of(x) in lacking for x in best._markers_of(j))]
    raise MtannoError(f"no marker set fits these markers (labels: {shown}); joints "
                      f"{', '.join(joints)} cannot be computed (the nearest set, "
                      f"'{best.name}', lacks {', '.join(lacking[:8])}"
                      f"{' …' if len(lacking) > 8 else ''}); write a map with `mtanno markers "
                      f"guess FILE.c3d -o MAP.toml`, edit it and pass {{markers}} MAP.toml",
                      options=("markers",))


#: Other names of the same anatomical markers (Plug-in Gait, Vicon, CMU), for the guess.
SYNONYMS = {"FWT": ("ASI", "ASIS"), "BWT": ("PSI", "PSIS"), "SHN": ("TIB", "SHANK"),
            "THI": ("THIGH",), "UPA": ("UPARM", "HUM"), "FRM": ("FOREARM", "RAD"),
            "FIN": ("HAND", "MCP", "MET2"), "TOE": ("TOE2", "MT2"), "MT5": ("MET5", "META5"),
            "HEE": ("HEEL", "CAL"), "ANK": ("LMAL", "MAL"), "KNE": ("KNEE", "LFEP"),
            "ELB": ("ELBOW", "LEP"), "WRA": ("RSP", "WRR"), "WRB": ("USP", "WRU"),
            "SHO": ("ACR", "SHOULDER"), "FHD": ("FH", "FOREHEAD"), "BHD": ("BH",),
            "CLAV": ("IJ", "STERNUM_TOP", "SUP"), "STRN": ("PX", "XIPH", "STER"),
            "C7": ("CV7",), "T10": ("TV10", "TH10"), "RBAC": ("RBAK", "BACK")}


def _guess_label(marker: str, have: dict[str, str]) -> str | None:
    """The file's label (prefix removed) for a marker of the set: the same name, then a
    synonym, ignoring case; None when the file has none."""
    if marker.upper() in have:
        return have[marker.upper()]
    side, stem = (marker[0], marker[1:]) if marker[:1] in "LR" and len(marker) > 2 \
        else ("", marker)
    for syn in SYNONYMS.get(stem, ()):
        for cand in (side + syn, (side + "_" + syn) if side else syn,
                     ("LEFT" if side == "L" else "RIGHT") + syn if side else syn):
            if cand.upper() in have:
                return have[cand.upper()]
    return None


def guess_toml(labels, *, source: str = "", version: str = "") -> tuple[str, MarkerSet, list[str]]:
    """A marker set for a file's labels, as TOML to edit: the built-in set whose markers
    the labels name best (by name or a known synonym, any case), as ``base`` with a
    ``[markers]`` table mapping each of its markers to the file's label; markers it cannot
    find are left as comments to fill in. Returns (text, the base set, markers not found)."""
    have = {marker_name(x).upper(): marker_name(x) for x in labels if marker_name(x)}
    sets = available_sets()
    base = max(sets, key=lambda m: sum(_guess_label(x, have) is not None for x in m.markers))
    found = {x: _guess_label(x, have) for x in base.markers}
    missing = [x for x, v in found.items() if v is None]
    lines = [f"# marker set guessed by mtanno {version} from {source}".rstrip(),
             "# Each marker of the base set = the label in the file (subject prefix dropped).",
             "# Fill in the markers left as comments, then pass --markers THIS.toml.",
             f'name = "guessed-{Path(source).stem or "markers"}"',
             f'base = "{base.name}"', "", "[markers]"]
    for x, v in found.items():
        lines.append(f'{x} = "{v}"' if v is not None else f'# {x} = ""   # not found')
    unused = sorted(set(have.values()) - {v for v in found.values() if v})
    if unused:
        lines += ["", "# labels of the file no recipe reads: " + ", ".join(unused[:60])
                  + (" …" if len(unused) > 60 else "")]
    return "\n".join(lines) + "\n", base, missing
