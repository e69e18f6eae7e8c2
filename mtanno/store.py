"""Files that pass between pipeline stages: Parquet feature matrices, atomic writes.

Feature file (``docs/formats.md`` has the full schema): one row per analysis frame (30 Hz),
column ``native_frame`` (int32, 1-based frame of the source file the row was taken from) and
one boolean column per feature, named as in :data:`mtanno.features.FEATURE_NAMES`. The
Parquet key-value metadata ``mtanno`` holds a JSON object describing where the features
came from (source path and SHA-256, frame rates, frame mapping, skeleton map, feature set,
mtanno version).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mtanno.errors import MtannoError, read_input

FEATURES_SCHEMA = "mtanno.features/1"
META_KEY = b"mtanno"


def sha256_file(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it over ``target`` on success.

    A crash or an exception leaves no partial ``target`` (the temporary file is removed).
    A ``target`` that exists and is not a regular file (``/dev/null``, a FIFO) is yielded
    itself and written in place: renaming over a device would replace it.
    """
    target = Path(target)
    if target.exists() and not target.is_file():
        yield target
        return
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@dataclass
class FeatureFile:
    """A feature file read back: matrix, names, kept native frames and metadata.

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
    """

    X: np.ndarray
    names: list[str]
    native_frames: np.ndarray
    meta: dict
    path: str
    sha256: str | None = None

    @property
    def document(self) -> str:
        """Document name: the feature file's stem (= the motion file's stem)."""
        return Path(self.path).stem

    @property
    def fps(self) -> float:
        return float(self.meta["analysis_fps"])


def write_features(path: str | os.PathLike, X: np.ndarray, names: list[str] | tuple[str, ...],
                   native_frames: np.ndarray, meta: dict) -> None:
    """Write a (features × frames) 0/1 matrix as a feature file, atomically.

    ``native_frames`` are 1-based; ``meta`` is stored as JSON under the key ``mtanno``
    (``schema`` is filled in).
    """
    X = np.asarray(X)
    if X.ndim != 2 or X.shape[0] != len(names):
        raise MtannoError(f"feature matrix must be ({len(names)} × frames), got {X.shape}")
    cols = {"native_frame": pa.array(np.asarray(native_frames, dtype=np.int32))}
    for i, name in enumerate(names):
        cols[name] = pa.array(X[i].astype(bool))
    table = pa.table(cols)
    meta = {"schema": FEATURES_SCHEMA, **meta}
    table = table.replace_schema_metadata({META_KEY: json.dumps(meta, sort_keys=True)})
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd")


def feature_files(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """Feature files named by ``inputs``: files as given, directories searched recursively
    for ``*.parquet`` (sorted). A missing input, a directory without feature files, or no
    file at all is an error."""
    out: list[Path] = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            found = sorted(q for q in p.rglob("*.parquet") if q.is_file())
            if not found:
                raise MtannoError("no feature files (*.parquet) in this folder", path=str(p))
            out.extend(found)
        elif p.is_file():
            out.append(p)
        else:
            raise MtannoError("no such feature file or folder", path=str(p))
    if not out:
        raise MtannoError("no feature files (*.parquet) in the inputs")
    return out


def read_features(path: str | os.PathLike, *, sha256: bool = False) -> FeatureFile:
    """Read a feature file written by :func:`write_features` (or ``mtanno features``).

    The file is read once; with ``sha256`` its hash is computed from the same bytes
    (``FeatureFile.sha256``), for indexes that record what they were built from.
    """
    spath = str(path)
    data = read_input(path, what="feature file")
    try:
        table = pq.ParquetFile(pa.BufferReader(data), pre_buffer=False).read(use_threads=False)
    except (pa.ArrowInvalid, OSError) as exc:
        raise MtannoError(f"not a readable Parquet feature file ({exc})", path=spath) from None
    raw = (table.schema.metadata or {}).get(META_KEY)
    if raw is None:
        raise MtannoError("Parquet file has no mtanno metadata (not written by mtanno "
                          "features?)", path=spath)
    try:
        meta = json.loads(raw)
    except json.JSONDecodeError:
        raise MtannoError("mtanno metadata is not valid JSON", path=spath) from None
    if meta.get("schema") != FEATURES_SCHEMA:
        raise MtannoError(f"unsupported feature file schema {meta.get('schema')!r} "
                          f"(expected {FEATURES_SCHEMA})", path=spath)
    names = [c for c in table.column_names if c != "native_frame"]
    if "native_frame" not in table.column_names or not names:
        raise MtannoError("feature file lacks the native_frame column or feature columns",
                          path=spath)
    X = np.empty((len(names), table.num_rows), dtype=np.uint8)
    for i, name in enumerate(names):
        col = table.column(name)
        if not pa.types.is_boolean(col.type):
            raise MtannoError(f"column '{name}' is {col.type}, not boolean", path=spath)
        X[i] = col.to_numpy(zero_copy_only=False)
    native = table.column("native_frame").to_numpy().astype(np.int64)
    return FeatureFile(X=X, names=names, native_frames=native, meta=meta, path=spath,
                       sha256=hashlib.sha256(data).hexdigest() if sha256 else None)


def read_feature_matrix(path: str | os.PathLike) -> np.ndarray:
    """The (features × frames) uint8 matrix of a feature file, rows in F01…F40 order."""
    return read_features(path).X
