"""The motion template's JSON file and folders of template files.

JSON file (``docs/templates.md`` has the full schema), schema ``mtanno.template/1``: one
object with the class name, feature set and names, frame rate, length, ``values`` as a
list of rows — one row of K numbers per feature, in ``feature_names`` order — and
``weights`` (K numbers), plus how the template was made (training files with SHA-256,
learning parameters, iterations, final cost). Numbers are written in Python's shortest
round-trip form, so a load reproduces the template bit for bit. A template folder holds
one ``CLASS.json`` per class (``learn-mt -o``; :func:`load_template_folder`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError, read_json
from mtanno.templates.model import (
    SCHEMA,
    MotionTemplate,
    check_feature_names,
    check_template,
    is_number,
)
from mtanno.util.output import atomic_path
from mtanno.util.tables import json_compact, json_list_lines, json_object_lines

__all__ = ["class_file", "load_one_template", "load_template", "load_template_folder",
           "save_template", "template_files"]


def _dumps(mt: MotionTemplate) -> str:
    """JSON text meant to be read: one line per scalar field, per training file, per
    feature name, per 10 weights and per feature row of ``values``."""
    layouts = {
        "training": lambda v: json_list_lines(json_compact(t) for t in v) if v else "[]",
        "feature_names": lambda v: json_list_lines(json_compact(n) for n in v),
        "weights": lambda v: json_list_lines(", ".join(repr(x) for x in v[i:i + 10])
                                             for i in range(0, len(v), 10)),
        "values": lambda v: json_list_lines("[" + ", ".join(repr(x) for x in row) + "]"
                                            for row in v),
    }
    return json_object_lines(mt.to_dict(), layouts) + "\n"


def save_template(path: str | os.PathLike, mt: MotionTemplate) -> None:
    """Write ``mt`` as JSON to ``path`` atomically (a crash leaves no partial file)."""
    check_template(mt)
    check_feature_names(mt, str(path))
    text = _dumps(mt)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")


_REQUIRED = ("schema", "class", "kind", "feature_set", "fps", "quantized", "delta",
             "feature_names", "weights", "values")


def _line_of(text: str, key: str) -> int | None:
    """1-based line of the first ``"key":`` in the JSON text (for error messages)."""
    needle = json.dumps(key) + ":"
    pos = text.find(needle)
    return None if pos < 0 else text.count("\n", 0, pos) + 1


def load_template(path: str | os.PathLike) -> MotionTemplate:
    """Read and validate a template JSON file; every problem is an :class:`MtannoError`
    naming the file (and the line where it is known)."""
    spath = str(path)
    d, text = read_json(path, what="template file")
    if not isinstance(d, dict):
        raise MtannoError("a template file must hold one JSON object", path=spath, line=1)
    if d.get("schema") != SCHEMA:
        raise MtannoError(f"unsupported template schema {d.get('schema')!r} (expected "
                          f"{SCHEMA!r})", path=spath, line=_line_of(text, "schema"))
    missing = [k for k in _REQUIRED if k not in d]
    if missing:
        raise MtannoError(f"missing field(s): {', '.join(missing)}", path=spath)

    def field_error(key: str, msg: str) -> MtannoError:
        return MtannoError(msg, path=spath, line=_line_of(text, key))

    names = d["feature_names"]
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise field_error("feature_names", "feature_names must be a non-empty list of strings")
    values = d["values"]
    if not isinstance(values, list) or len(values) != len(names):
        raise field_error("values", f"values must be a list of {len(names)} rows (one per "
                          f"feature name), got "
                          f"{len(values) if isinstance(values, list) else type(values).__name__}")
    weights = d["weights"]
    if not isinstance(weights, list) or not weights:
        raise field_error("weights", "weights must be a non-empty list of numbers")
    K = len(weights)
    if not all(is_number(x) for x in weights):
        raise field_error("weights", "weights must be numbers")
    for r, row in enumerate(values):
        if not isinstance(row, list) or not all(is_number(x) for x in row):
            raise field_error("values", f"values row {r + 1} ({names[r]}) must be a list of "
                              f"numbers")
        if len(row) != K:
            raise field_error("values", f"values row {r + 1} ({names[r]}) has {len(row)} "
                              f"entries, expected {K} (one per weight)")
    if "length" in d and d["length"] != K:
        raise field_error("length", f"length is {d['length']!r} but there are {K} columns")
    for key in ("fps", "delta", "final_cost"):
        if key in d and d[key] is not None and not is_number(d[key]):
            raise field_error(key, f"{key} must be a number")
    vline = _line_of(text, "values")
    lines = text.splitlines()

    def line_of(key: str, row: int | None) -> int | None:
        """The line of a field, or of a values row when the rows are one per line (as
        :func:`save_template` writes them)."""
        if key == "values" and row is not None and vline is not None \
                and vline + row < len(lines) and lines[vline + row].lstrip().startswith("["):
            return vline + row + 1
        return _line_of(text, key)

    mt = MotionTemplate.__new__(MotionTemplate)
    mt.class_name = d["class"]
    mt.feature_names = list(names)
    mt.values = np.array(values, dtype=np.float64).reshape(len(names), K)
    mt.weights = np.array(weights, dtype=np.float64)
    mt.feature_set = d["feature_set"]
    mt.fps = d["fps"]
    mt.kind = d["kind"]
    mt.quantized = d["quantized"]
    mt.delta = d["delta"]
    mt.training = d.get("training", [])
    mt.params = d.get("params", {})
    mt.iterations = d.get("iterations", 0)
    mt.final_cost = d.get("final_cost", 0.0)
    mt.history = d.get("history", {})
    mt.path = spath
    check_template(mt, spath, line_of=line_of)
    check_feature_names(mt, spath, _line_of(text, "feature_names"),
                        set_line=_line_of(text, "feature_set"))
    mt.fps = float(mt.fps)
    mt.final_cost = float(mt.final_cost)
    mt.delta = None if mt.delta is None else float(mt.delta)
    return mt


def class_file(folder: str | os.PathLike, class_name: str) -> Path:
    """``folder/CLASS.json``: where learn-mt and learn-keyframes write a class's template or
    keyframe query. A class name that cannot be a file name there (empty, hidden, with a path
    separator or a NUL) is an error."""
    if not class_name or class_name.startswith(".") or any(c in class_name for c in "/\\\0"):
        raise MtannoError(f"class name {class_name!r} cannot be used as a file name")
    return Path(folder) / f"{class_name}.json"


def template_files(folder: str | os.PathLike) -> list[Path]:
    """The template files of a folder (``*.json``, sorted), or the one file given."""
    root = Path(folder)
    return sorted(root.glob("*.json")) if root.is_dir() else [root]


def load_one_template(path: str | os.PathLike, *, what: str = "--mt") -> MotionTemplate:
    """The template of a file, or of a folder holding exactly one (``*.json``), as the
    folders ``annotate --mt`` takes: for commands that use one class. A folder of several
    templates is an error saying to name one (``what`` names the option)."""
    files = template_files(path)
    if Path(path).is_dir() and len(files) != 1:
        hint = (f"; name one of them, e.g. {what} {files[0]}" if files else "")
        raise MtannoError(f"this command uses one template, but the folder holds "
                          f"{len(files)}{hint}", path=str(path))
    return load_template(files[0])


def load_template_folder(path: str | os.PathLike, *,
                         classes: Sequence[str] = ()) -> dict[str, MotionTemplate]:
    """Class name → template of every ``*.json`` in a folder (or of one template file),
    sorted by class name; with ``classes`` only those (each must have a template). All
    templates must share feature set, names and frame rate (a difference is an error
    naming the file); two files of one class are an error."""
    from mtanno.features.store import check_layout

    files = template_files(path)
    if not files or not files[0].exists():
        raise MtannoError("no templates (*.json) found", path=str(path))
    out: dict[str, MotionTemplate] = {}
    layout = None
    for f in files:
        mt = load_template(f)
        if classes and mt.class_name not in classes:
            continue
        lay = mt.layout(f"template {f}")
        if layout is None:
            layout = lay
        elif lay.key() != layout.key():
            check_layout(lay, layout, path=str(f))
        if mt.class_name in out:
            raise MtannoError(f"a second template of class {mt.class_name!r} (the first: "
                              f"{out[mt.class_name].path})", path=str(f))
        out[mt.class_name] = mt
    missing = [c for c in classes if c not in out]
    if missing:
        raise MtannoError(f"no template for class(es) {', '.join(missing)}", path=str(path))
    if not out:
        raise MtannoError("no templates to use", path=str(path))
    return dict(sorted(out.items()))
