"""Feature files, the format the features stage writes and every later stage reads: the one
validating reader, the writer, :class:`FeatureLayout` and :func:`check_layout` (the one
compatibility check). Finding the feature files an input names is
:mod:`mtanno.features.inputs`.

Feature file (``docs/formats.md`` has the full schema): one row per analysis frame (30 Hz),
column ``native_frame`` (int32, 1-based frame of the source file the row was taken from) and
one boolean column per feature, named as in :data:`mtanno.features.FEATURE_NAMES`. The
Parquet key-value metadata ``mtanno`` holds a JSON object describing where the features
came from (source path and SHA-256, frame rates, frame mapping, skeleton map, feature set,
mtanno version). Optionally (``mtanno features --poses``) a pose block follows: float32
columns ``pose.<joint>.<x|y|z>`` holding the normalised canonical joint positions of every
row (:mod:`mtanno.features.poses`, in leg lengths), described by the metadata's ``poses``
entry; readers skip it unless asked (``read_features(..., poses=True)``). The metadata's
optional ``invalid`` entry lists the rows that carry no evidence (a marker file's frames
whose joints could not be computed) as [first, last] pairs, 1-based inclusive; a file
without it has every row valid (:attr:`FeatureFile.valid`).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mtanno.errors import JSONError, MtannoError, parse_json, read_input
from mtanno.features import _parquet
from mtanno.features._poseblock import (
    POSE_PREFIX,
    check_pose_columns,
    check_pose_meta,
    pose_columns,
    text_field,
)
from mtanno.util.output import write_bytes

__all__ = ["FEATURES_SCHEMA", "POSE_PREFIX", "FeatureFile", "FeatureLayout",
           "check_layout", "common_layout", "pose_columns", "read_feature_matrix",
           "read_features", "write_features"]

FEATURES_SCHEMA = "mtanno.features/1"
#: Feature files of documents with at least this many frames are zstd-compressed.
COMPRESS_FROM_FRAMES = 1024
META_KEY = b"mtanno"


@dataclass
class FeatureFile:
    """A feature file read back (and validated): matrix, names, kept native frames, metadata.

    Attributes
    ----------
    X:
        (features × frames) uint8 matrix of 0/1 at the analysis rate.
    names:
        Feature (row) names.
    native_frames:
        1-based native frame of each column.
    meta:
        The ``mtanno`` metadata object (see ``docs/formats.md``).
    path:
        The file read.
    sha256:
        SHA-256 of the file's bytes, when asked for.
    poses:
        (frames × 22 × 3) float32 normalised joint positions in leg lengths (canonical
        joint order, :mod:`mtanno.features.poses`), when read with ``poses=True`` from a
        file that has a pose block; else None.
    """

    X: np.ndarray
    names: list[str]
    native_frames: np.ndarray
    meta: dict
    path: str
    sha256: str | None = None
    poses: np.ndarray | None = None

    @property
    def has_poses(self) -> bool:
        """True if the file has a pose block (read or not; its metadata says so and its
        columns were checked when the file was read)."""
        return isinstance(self.meta.get("poses"), dict)

    @property
    def valid(self) -> np.ndarray:
        """(frames,) bool: the rows that carry evidence (all, unless the metadata's
        ``invalid`` runs say otherwise; checked when the file was read)."""
        out = np.ones(self.X.shape[1], dtype=bool)
        for a, b in self.meta.get("invalid") or ():
            out[a - 1:b] = False
        return out

    @property
    def document(self) -> str:
        """Document name: the feature file's stem (= the motion file's stem)."""
        return Path(self.path).stem

    @property
    def fps(self) -> float:
        """Analysis frame rate (validated when the file was read)."""
        return float(self.meta["analysis_fps"])

    @property
    def feature_set(self) -> str:
        return str(self.meta["feature_set"])

    @property
    def layout(self) -> FeatureLayout:
        """What the file's features are (set, names, rate), for :func:`check_layout`."""
        return FeatureLayout(self.feature_set, tuple(self.names), self.fps,
                             f"feature file {self.path}")


@dataclass(frozen=True)
class FeatureLayout:
    """Which features a matrix has: feature set, feature names in row order, frame rate.

    Templates, indexes and feature files each have one; data can only be compared when
    their layouts are equal (:func:`check_layout`). ``source`` names where the layout comes
    from, for error messages (it is not compared).
    """

    feature_set: str
    names: tuple[str, ...]
    fps: float
    source: str = ""

    def key(self) -> tuple:
        return (self.feature_set, self.names, self.fps)


def check_layout(have: FeatureLayout | FeatureFile, want: FeatureLayout, *,
                 path: str | None = None) -> None:
    """The one compatibility check: ``have`` (a feature file, or any layout) must have the
    features of ``want`` — same feature set, same feature names in the same order, same
    frame rate. Otherwise one :class:`MtannoError` names ``path`` (the feature file's path
    by default), the first difference and ``want.source``."""
    if isinstance(have, FeatureFile):
        path = path or have.path
        have = have.layout
    of = f" of {want.source}" if want.source else ""
    if have.feature_set != want.feature_set:
        raise MtannoError(f"feature set {have.feature_set!r} differs from "
                          f"{want.feature_set!r}{of} (recompute with mtanno features "
                          f"--feature-set, or use matching templates)", path=path)
    if have.names != want.names:
        k = next((i for i, (a, b) in enumerate(zip(have.names, want.names)) if a != b),
                 min(len(have.names), len(want.names)))
        here = repr(have.names[k]) if k < len(have.names) else "missing"
        there = repr(want.names[k]) if k < len(want.names) else "missing"
        how = ("the same features in another order" if sorted(have.names) == sorted(want.names)
               else f"{len(have.names)} vs {len(want.names)} features")
        raise MtannoError(f"feature {k + 1} is {here} here but {there}{of} ({how})",
                          path=path)
    if have.fps != want.fps:
        raise MtannoError(f"frame rate {have.fps:g} Hz differs from {want.fps:g} Hz{of}",
                          path=path)


def common_layout(layouts: Sequence[FeatureLayout]) -> FeatureLayout:
    """The layout most of ``layouts`` share, to check the others against: the most common
    one; on a tie the one at the standard analysis rate (30 Hz) of a built-in feature set
    with its own feature names, then the first. So in a batch with one odd file it is the
    odd file that is named, not a good one."""
    if not layouts:
        raise MtannoError("no feature files")
    counts: dict[tuple, int] = {}
    first: dict[tuple, FeatureLayout] = {}
    for lay in layouts:
        counts[lay.key()] = counts.get(lay.key(), 0) + 1
        first.setdefault(lay.key(), lay)

    def standard(lay: FeatureLayout) -> bool:
        from mtanno.features.compute import FEATURE_SETS

        fs = FEATURE_SETS.get(lay.feature_set)
        return lay.fps == 30.0 and fs is not None and tuple(fs.names) == lay.names

    order = list(first)
    best = max(order, key=lambda k: (counts[k], standard(first[k]), -order.index(k)))
    return first[best]


def _check_meta(meta, spath: str) -> dict:
    """Validate the ``mtanno`` metadata object of a feature file (written or read)."""
    if not isinstance(meta, dict):
        raise MtannoError(f"mtanno metadata must be a JSON object, got {type(meta).__name__}",
                          path=spath)
    if meta.get("schema") != FEATURES_SCHEMA:
        raise MtannoError(f"unsupported feature file schema {meta.get('schema')!r} "
                          f"(expected {FEATURES_SCHEMA})", path=spath)
    if "analysis_fps" not in meta:
        raise MtannoError("mtanno metadata lacks analysis_fps (the frame rate of the rows)",
                          path=spath)
    fps = meta["analysis_fps"]
    if not _positive_number(fps):
        raise MtannoError(f"analysis_fps in the mtanno metadata must be a positive number, "
                          f"got {fps!r}", path=spath)
    text_field(meta.get("feature_set"), "feature_set in the mtanno metadata must be a "
               "non-empty string", spath)
    version = meta.get("feature_set_version", 1)
    if isinstance(version, bool) or not isinstance(version, int):
        raise MtannoError(f"feature_set_version in the mtanno metadata must be an integer, "
                          f"got {version!r}", path=spath)
    groups = meta.get("groups")
    if groups is not None and not (isinstance(groups, dict) and all(
            isinstance(v, list) and all(isinstance(n, str) for n in v) for v in groups.values())):
        raise MtannoError("groups in the mtanno metadata must map group names to lists of "
                          "feature names", path=spath)
    if "poses" in meta:
        check_pose_meta(meta["poses"], spath)
    return meta


def write_features(path: str | os.PathLike, X: np.ndarray, names: list[str] | tuple[str, ...],
                   native_frames: np.ndarray, meta: dict, *,
                   poses: np.ndarray | None = None) -> None:
    """Write a (features × frames) 0/1 matrix as a feature file, atomically.

    ``native_frames`` are 1-based; ``meta`` is stored as JSON under the key ``mtanno``
    (``schema`` is filled in; ``analysis_fps`` and ``feature_set`` are required, as
    :func:`read_features` requires them).

    ``poses``: (frames × 22 × 3) normalised joint positions of the same frames, in leg
    lengths (:func:`mtanno.features.poses.normalize_poses`), stored as the float32 pose
    block (``docs/formats.md``); ``meta["poses"]`` describes them (filled in with
    :func:`mtanno.features.poses.pose_metadata` when absent). Without ``poses`` the file is
    exactly what it was before pose blocks existed.
    """
    X = np.asarray(X)
    if X.ndim != 2 or X.shape[0] != len(names):
        raise MtannoError(f"feature matrix must be ({len(names)} × frames), got {X.shape}")
    names = tuple(names)
    if len(set(names)) != len(names) or "native_frame" in names:
        raise MtannoError("feature names must be unique and differ from 'native_frame'",
                          path=str(path))
    if any(nm.startswith(POSE_PREFIX) for nm in names):
        raise MtannoError(f"feature names must not begin with {POSE_PREFIX!r} (the pose "
                          f"columns' prefix)", path=str(path))
    if poses is not None and "poses" not in meta:
        from mtanno.features.poses import pose_metadata

        meta = {**meta, "poses": pose_metadata()}
    meta = _check_meta({"schema": FEATURES_SCHEMA, **meta}, str(path))
    n = X.shape[1]
    native_frames = np.asarray(native_frames, dtype=np.int32)
    if native_frames.shape != (n,):
        raise MtannoError(f"native_frames must have one frame per column ({n}), got "
                          f"{native_frames.shape}", path=str(path))
    cols, flat = _pose_block(meta, poses, n, str(path))
    text = json.dumps(meta, sort_keys=True)
    schema = _schema(names, cols).with_metadata({META_KEY: text})
    # every feature row as packed bits, little-endian: Parquet's PLAIN booleans and Arrow's
    # boolean arrays alike; each row's bytes together, also for a matrix in Fortran order
    # (packbits keeps the memory order of its input)
    bits = np.ascontiguousarray(np.packbits(X != 0, axis=1, bitorder="little"))
    short = 0 < n < min(COMPRESS_FROM_FRAMES, _parquet.MOST_ROWS)
    created_by = (_parquet.available_floats() if cols else _parquet.available()) \
        if short else None
    if created_by is not None:  # a short clip: its bytes assembled directly (see _parquet)
        write_bytes(path, _parquet.encode(names, native_frames, bits, n, META_KEY,
                                          text.encode("utf-8"), _parquet.arrow_schema(schema),
                                          created_by, float_names=cols, floats=flat))
        return
    buf = pa.py_buffer(bits)
    stride = bits.shape[1]
    columns = [pa.array(native_frames)]
    columns += [pa.Array.from_buffers(pa.bool_(), n, [None, buf.slice(i * stride, stride)])
                for i in range(len(names))]
    columns += [pa.array(row) for row in flat]
    table = pa.Table.from_arrays(columns, schema=schema)
    # No column statistics or dictionaries (readers take whole columns); zstd only for
    # documents long enough to gain from it: a clip of a few seconds compresses by a few
    # percent, and the codec's per-column set-up was most of its writing time (archives of
    # short clips are written thousands at a time).
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, write_statistics=False, use_dictionary=False,
                   compression="zstd" if n >= COMPRESS_FROM_FRAMES else "none")
    write_bytes(path, sink.getvalue())


_NO_POSES = np.empty((0, 0), dtype=np.float32)


def _pose_block(meta: dict, poses: np.ndarray | None, n: int, spath: str,
                ) -> tuple[tuple[str, ...], np.ndarray]:
    """The pose columns of a file being written and their values (one contiguous float32
    row per column), or no columns and an empty array for a file without poses; poses of
    the wrong shape, NaN, infinite or beyond float32 are refused."""
    if "poses" not in meta:
        return (), _NO_POSES
    joints = meta["poses"]["joints"]
    if poses is None:
        raise MtannoError("the metadata describes poses but none were given", path=spath)
    P = np.asarray(poses)
    if P.shape != (n, len(joints), 3):
        raise MtannoError(f"poses must be (frames × {len(joints)} × 3) = ({n} × "
                          f"{len(joints)} × 3), got {P.shape}", path=spath)
    with np.errstate(over="ignore", invalid="ignore"):  # beyond float32: refused below
        P = P.astype(np.float32)
    if not np.isfinite(P).all():
        raise MtannoError("poses contain NaN or infinite values (or values beyond float32)",
                          path=spath)
    cols = tuple(pose_columns(joints))
    return cols, np.ascontiguousarray(P.reshape(n, len(cols)).T)


_SCHEMAS: dict[tuple[tuple[str, ...], tuple[str, ...]], pa.Schema] = {}


def _schema(names: tuple[str, ...], pose_names: tuple[str, ...] = ()) -> pa.Schema:
    """The Arrow schema of a feature file with these feature (and pose) columns (built
    once)."""
    schema = _SCHEMAS.get((names, pose_names))
    if schema is None:
        if len(_SCHEMAS) > 16:
            _SCHEMAS.clear()
        schema = _SCHEMAS[names, pose_names] = pa.schema(
            [pa.field("native_frame", pa.int32())] + [pa.field(nm, pa.bool_()) for nm in names]
            + [pa.field(nm, pa.float32()) for nm in pose_names])
    return schema


#: Largest native frame number (and frame count) a feature file may give: the column is
#: int32 (docs/formats.md), and tables refuse frames beyond 2³¹.
MAX_NATIVE_FRAME = 2**31 - 1


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _positive_number(x) -> bool:
    """A JSON number (not a boolean) that is finite and > 0: a frame rate."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x)) \
        and x > 0


def _check_against_rows(meta: dict, names: list[str], native: np.ndarray, spath: str) -> None:
    """What the metadata says about the rows must be true of them (a file whose metadata
    contradicts its rows is refused, not used with one or the other): ``analysis_frames``
    is the number of rows; ``native_frames`` is a frame count no kept ``native_frame``
    exceeds (both at most :data:`MAX_NATIVE_FRAME`); ``native_fps`` is a positive number;
    ``feature_ids`` has one distinct id per feature column and ``groups`` name only
    feature columns, each once; and a file with exactly a built-in feature set's columns
    has that set's ids and groups."""
    def bad(msg: str) -> MtannoError:
        return MtannoError(msg, path=spath)

    rows = int(native.size)
    if native.size and native.max() > MAX_NATIVE_FRAME:
        raise bad(f"native_frame must be at most {MAX_NATIVE_FRAME}; rows "
                  f"{_rows(native > MAX_NATIVE_FRAME)} are not")
    if "analysis_frames" in meta:
        n = meta["analysis_frames"]
        if not _is_int(n) or n != rows:
            raise bad(f"analysis_frames in the mtanno metadata is {n!r} but the file has "
                      f"{rows} rows")
    if "native_frames" in meta:
        n = meta["native_frames"]
        if not _is_int(n) or not 0 <= n <= MAX_NATIVE_FRAME:
            raise bad(f"native_frames in the mtanno metadata must be a frame count in "
                      f"0..{MAX_NATIVE_FRAME}, got {n!r}")
        if rows and native.max() > n:
            raise bad(f"native_frame {int(native.max())} (row {int(native.argmax()) + 1}) is "
                      f"beyond native_frames {n}, the frame count of the motion file")
    nfps = meta.get("native_fps")
    if "native_fps" in meta and not _positive_number(nfps):
        raise bad(f"native_fps in the mtanno metadata must be a positive number, got {nfps!r}")
    ids = meta.get("feature_ids")
    if "feature_ids" in meta and not (
            isinstance(ids, list) and len(ids) == len(names)
            and all(isinstance(i, str) and i for i in ids) and len(set(ids)) == len(ids)):
        raise bad(f"feature_ids in the mtanno metadata must list one distinct id per feature "
                  f"column ({len(names)})")
    _check_invalid(meta, rows, bad)
    groups = meta.get("groups") or {}
    columns = set(names)
    for g, members in groups.items():
        if not g:
            raise bad("groups in the mtanno metadata: a group without a name")
        if len(set(members)) != len(members):
            raise bad(f"group '{g}' in the mtanno metadata names a feature twice")
        stray = [m for m in members if m not in columns]
        if stray:
            raise bad(f"group '{g}' in the mtanno metadata names '{stray[0]}', which is not "
                      "a feature column of the file")
    from mtanno.features.compute import FEATURE_SETS

    fs = FEATURE_SETS.get(meta["feature_set"])
    if fs is not None and tuple(names) == fs.names:  # the set's own columns: its own table
        if "feature_ids" in meta and ids != [f.id for f in fs.features]:
            k = next(i for i, (a, f) in enumerate(zip(ids, fs.features)) if a != f.id)
            raise bad(f"feature_ids in the mtanno metadata give {ids[k]!r} for column "
                      f"'{names[k]}', which is {fs.features[k].id} in {fs.name}")
        want = {g: [fs.names[i] for i in rows_] for g, rows_ in fs.groups.items()}
        if "groups" in meta and meta["groups"] != want:
            raise bad(f"groups in the mtanno metadata differ from those of {fs.name} "
                      f"({', '.join(want)})")


def _check_invalid(meta: dict, rows: int, bad) -> None:
    """``invalid`` (optional): [first, last] row pairs, 1-based inclusive, ascending and
    disjoint, within the file's rows."""
    if "invalid" not in meta:
        return
    runs = meta["invalid"]
    if not (isinstance(runs, list) and all(
            isinstance(r, list) and len(r) == 2 and all(_is_int(x) for x in r) for r in runs)):
        raise bad("invalid in the mtanno metadata must be a list of [first, last] row pairs")
    last = 0
    for a, b in runs:
        if not last < a <= b <= rows:
            raise bad(f"invalid in the mtanno metadata: rows {a}-{b} are not ascending, "
                      f"disjoint rows within 1..{rows}")
        last = b


def _rows(mask: np.ndarray) -> str:
    rows = np.flatnonzero(mask)[:3] + 1
    more = " …" if mask.sum() > 3 else ""
    return ", ".join(str(r) for r in rows) + more


_COLUMN_KINDS = {"boolean": pa.types.is_boolean, "integer": pa.types.is_integer}


def _column(table: pa.Table, name: str, kind: str, spath: str, note: str = "",
            ) -> pa.ChunkedArray:
    """Column ``name`` of a feature file's table, refused unless of the ``kind`` (a key
    of :data:`_COLUMN_KINDS`) and without nulls (``note`` ends that message)."""
    col = table.column(name)
    if not _COLUMN_KINDS[kind](col.type):
        raise MtannoError(f"column '{name}' is {col.type}, not {kind}", path=spath)
    if col.null_count:
        nulls = col.is_null().to_numpy(zero_copy_only=False)
        raise MtannoError(f"column '{name}' has {col.null_count} null value(s) (rows "
                          f"{_rows(nulls)}){note}", path=spath)
    return col


def _is_motion_file(path: str, data) -> bool:
    """True if a file that is no Parquet file is a motion file (by its suffix, or by its
    first bytes: :func:`mtanno.io.formats.looks_like_motion`)."""
    from mtanno.io.formats import looks_like_motion  # (on this error path only)

    return looks_like_motion(path, bytes(memoryview(data)[:4096]))


def read_features(path: str | os.PathLike, *, sha256: bool = False,
                  poses: bool = False) -> FeatureFile:
    """Read and validate a feature file written by :func:`write_features` (or ``mtanno
    features``): the one reader every command uses.

    Everything later stages rely on is checked here, once, so a malformed file is one
    :class:`MtannoError` naming it (and the batch it is part of can go on): the ``mtanno``
    metadata is a JSON object of the right schema with a positive ``analysis_fps`` and a
    ``feature_set``; ``native_frame`` is an integer column without nulls, ≥ 1, never
    decreasing and below 2³¹; every feature column is boolean without nulls, names unique;
    and what the metadata says of the rows is true of them (``analysis_frames``,
    ``native_frames``, ``native_fps``, ``feature_ids``, ``groups``:
    :func:`_check_against_rows`). The file is
    read once; with ``sha256`` its hash is computed from the same bytes
    (``FeatureFile.sha256``), for indexes that record what they were built from.

    A pose block (``pose.*`` columns, ``docs/formats.md``) is checked against the
    metadata's ``poses`` entry from the schema alone (every column there, float32, none
    other) and otherwise not read; with ``poses`` it is read into ``FeatureFile.poses``
    ((frames × 22 × 3) float32, None for a file without one), refused if it holds a null,
    NaN or infinite value.
    """
    spath = str(path)
    data = read_input(path, what="feature file")
    try:
        pf = pq.ParquetFile(pa.BufferReader(data), pre_buffer=False)
        schema = pf.schema_arrow
        wanted = None
        if not poses and any(c.startswith(POSE_PREFIX) for c in schema.names):
            wanted = list(dict.fromkeys(c for c in schema.names if not c.startswith(POSE_PREFIX)))
        table = pf.read(columns=wanted, use_threads=False)
    except (pa.ArrowException, OSError, ValueError, IndexError) as exc:
        if _is_motion_file(spath, data):
            raise MtannoError("this is a motion file: run `mtanno features` first (later "
                              "stages read its Parquet feature file)", path=spath) from None
        raise MtannoError(f"not a readable Parquet feature file ({exc})", path=spath) from None
    raw = (schema.metadata or {}).get(META_KEY)
    if raw is None:
        raise MtannoError("Parquet file has no mtanno metadata (not written by mtanno "
                          "features?)", path=spath)
    try:
        meta = parse_json(raw)
    except JSONError as exc:
        raise MtannoError(f"mtanno metadata is not valid JSON ({exc.message})",
                          path=spath) from None
    meta = _check_meta(meta, spath)
    names = [c for c in schema.names if c != "native_frame" and not c.startswith(POSE_PREFIX)]
    if "native_frame" not in schema.names or not names:
        raise MtannoError("feature file lacks the native_frame column or feature columns",
                          path=spath)
    if len(set(schema.names)) != len(schema.names):
        dup = sorted({c for c in schema.names if schema.names.count(c) > 1})
        raise MtannoError(f"column(s) {', '.join(dup)} appear twice", path=spath)
    pose_cols = check_pose_columns(meta, schema, spath)
    X = np.empty((len(names), table.num_rows), dtype=np.uint8)
    for i, name in enumerate(names):
        col = _column(table, name, "boolean", spath, "; features must be true or false")
        X[i] = col.to_numpy(zero_copy_only=False)
    native = _column(table, "native_frame", "integer", spath).to_numpy().astype(np.int64)
    if native.size and native.min() < 1:
        raise MtannoError(f"native_frame must be ≥ 1 (1-based frames of the motion file); "
                          f"rows {_rows(native < 1)} are not", path=spath)
    if native.size > 1 and np.any(np.diff(native) < 0):
        raise MtannoError(f"native_frame decreases at row(s) {_rows(np.diff(native) < 0)}",
                          path=spath)
    _check_against_rows(meta, names, native, spath)
    meta["analysis_fps"] = float(meta["analysis_fps"])
    return FeatureFile(X=X, names=names, native_frames=native, meta=meta, path=spath,
                       sha256=hashlib.sha256(data).hexdigest() if sha256 else None,
                       poses=_pose_values(table, pose_cols, spath) if poses and pose_cols
                       else None)


def _pose_values(table: pa.Table, columns: list[str], spath: str) -> np.ndarray:
    """(frames × joints × 3) float32 poses from the checked pose ``columns`` of ``table``;
    a null, NaN or infinite value is refused, naming the column and rows."""
    n = table.num_rows
    flat = np.empty((n, len(columns)), dtype=np.float32)
    for k, c in enumerate(columns):
        col = table.column(c)
        if col.null_count:
            nulls = col.is_null().to_numpy(zero_copy_only=False)
            raise MtannoError(f"pose column '{c}' has {col.null_count} null value(s) (rows "
                              f"{_rows(nulls)})", path=spath)
        flat[:, k] = col.to_numpy()
    bad = ~np.isfinite(flat)
    if bad.any():
        k = int(np.flatnonzero(bad.any(axis=0))[0])
        raise MtannoError(f"pose column '{columns[k]}' has NaN or infinite values (rows "
                          f"{_rows(bad[:, k])})", path=spath)
    return flat.reshape(n, len(columns) // 3, 3)


def read_feature_matrix(path: str | os.PathLike) -> np.ndarray:
    """The (features × frames) uint8 matrix of a feature file, rows in F01…F40 order."""
    return read_features(path).X
