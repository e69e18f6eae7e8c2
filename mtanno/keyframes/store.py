"""The keyframe query file (``mtanno.keyframes/1``): the one validating reader
(:func:`load_keyframes`, :func:`parse_keyframes`: every problem names the file and, where
known, the line) and the writer (:func:`save_keyframes`, :func:`dumps`: JSON a person reads
and edits, one line per keyframe and per group).

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

import os
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from mtanno.errors import MtannoError, read_json
from mtanno.keyframes.model import (
    SCHEMA,
    Extension,
    Gap,
    Keyframe,
    KeyframeQuery,
    _line_of,
    _validate,
)
from mtanno.templates.model import is_number

__all__ = ["dumps", "load_keyframes", "parse_keyframes", "save_keyframes"]

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
                if not (is_number(s) or isinstance(s, str)):
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
