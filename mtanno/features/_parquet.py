"""The bytes of a short feature file, written directly: identical to pyarrow's, much faster.

A feature file of a short clip (fewer than :data:`MOST_ROWS` analysis frames, written without
compression) has a fixed shape: one row group, one PLAIN data page per column, every column
nullable without nulls, no statistics, no dictionary. pyarrow spends about half a
millisecond encoding such a file — more than the kernels spend computing its features, for a
clip of a few seconds — most of it setting up a writer for each of the 41 columns. Here the
file is assembled from its parts (Parquet's thrift compact protocol), with what depends on
the feature names alone built once.

A file may end with float32 columns (the pose block of ``mtanno features --poses``,
``docs/formats.md``), encoded the same way: one PLAIN page of little-endian floats each.

The result must be byte for byte what :func:`pyarrow.parquet.write_table` writes with the
options of :func:`mtanno.features.store.write_features`. :func:`available` checks that once per
process, on reference tables encoded both ways with the pyarrow in use; when they differ (a
pyarrow that writes another footer), every file is written by pyarrow. Files with float
columns are checked apart (:func:`available_floats`), so that a pyarrow whose float columns
differ still has the boolean files written here. ``tests/test_store.py`` and
``tests/test_poses_block.py`` compare the two for every row count.
"""

from __future__ import annotations

import base64
import struct

import numpy as np

#: Files of fewer rows than this are written here (the rest, zstd-compressed, by pyarrow).
MOST_ROWS = 1024

_INT32, _BOOLEAN, _FLOAT = 1, 0, 4  # parquet physical types
_BYTES = [bytes((i,)) for i in range(256)]


def _varint(v: int) -> bytes:
    if v < 0x80:
        return _BYTES[v]
    if v < 0x4000:
        return bytes(((v & 0x7F) | 0x80, v >> 7))
    out = bytearray()
    while v >= 0x80:
        out.append((v & 0x7F) | 0x80)
        v >>= 7
    out.append(v)
    return bytes(out)


def _zz(v: int) -> bytes:
    """A non-negative i32/i64 in the compact protocol (zigzag varint)."""
    return _varint(v << 1)


def _binary(b: bytes) -> bytes:
    return _varint(len(b)) + b


def _list_header(size: int, elem_type: int) -> bytes:
    return bytes([(size << 4) | elem_type]) if size < 15 else \
        bytes([0xF0 | elem_type]) + _varint(size)


def _page_header(size: int, n: int) -> bytes:
    """PageHeader of a DATA_PAGE (v1) of ``n`` values, PLAIN, RLE levels, empty
    statistics."""
    s = _zz(size)
    return (b"\x15\x00\x15" + s + b"\x15" + s + b"\x2c\x15" + _zz(n)
            + b"\x15\x00\x15\x06\x15\x06\x1c\x00\x00\x00")


class _Layout:
    """What a feature file's bytes owe to its column names alone."""

    def __init__(self, names: tuple[str, ...], float_names: tuple[str, ...] = ()):
        cols = ([("native_frame", _INT32)] + [(nm, _BOOLEAN) for nm in names]
                + [(nm, _FLOAT) for nm in float_names])
        self.n_columns = len(cols)
        schema = [b"\x35\x00\x18" + _binary(b"schema") + b"\x15" + _zz(len(cols)) + b"\x00"]
        # ColumnChunk up to ColumnMetaData.num_values, per column
        self.chunk_head = []
        for name, ptype in cols:
            raw = name.encode("utf-8")
            schema.append(b"\x15" + _zz(ptype) + b"\x25\x02\x18" + _binary(raw) + b"\x00")
            self.chunk_head.append(b"\x26\x00\x1c\x15" + _zz(ptype) + b"\x19\x25\x06\x00\x19\x18"
                                   + _binary(raw) + b"\x15\x00\x16")
        self.schema = b"\x15\x04\x19" + _list_header(len(schema), 12) + b"".join(schema)
        self.orders = b"\x19" + _list_header(len(cols), 12) + b"\x1c\x00\x00" * len(cols)


_LAYOUTS: dict[tuple[tuple[str, ...], tuple[str, ...]], _Layout] = {}


def encode(names: tuple[str, ...], native_frames: np.ndarray, bits: np.ndarray, n: int,
           meta_key: bytes, meta_json: bytes, arrow_schema: bytes, created_by: bytes, *,
           float_names: tuple[str, ...] = (), floats: np.ndarray | None = None) -> bytes:
    """The Parquet file of a feature table: ``native_frames`` (n int32) and one boolean
    column per name, ``bits`` holding row i's values packed little-endian
    (``np.packbits(..., axis=1, bitorder="little")``), then one float32 column per
    ``float_names``, row i of ``floats`` (len(float_names) × n) holding its values;
    key-value metadata ``meta_key`` → ``meta_json`` and ARROW:schema → ``arrow_schema``
    (the serialized Arrow schema), ``created_by`` as pyarrow writes it. For 1 ≤ n <
    :data:`MOST_ROWS`."""
    layout = _LAYOUTS.get((names, float_names))
    if layout is None:
        if len(_LAYOUTS) > 16:
            _LAYOUTS.clear()
        layout = _LAYOUTS[names, float_names] = _Layout(names, float_names)
    levels = _varint(n << 1) + b"\x01"  # definition levels: one RLE run of n ones
    levels = struct.pack("<i", len(levels)) + levels
    body0 = levels + np.asarray(native_frames, dtype="<i4").tobytes()
    head0 = _page_header(len(body0), n)
    size_b = len(levels) + bits.shape[1]
    head_b = _page_header(size_b, n) + levels
    parts = [b"PAR1", head0, body0]
    for row in bits:
        parts.append(head_b)
        parts.append(row.tobytes())
    size_f = len(levels) + 4 * n
    head_f = _page_header(size_f, n) + levels
    if float_names:
        for row in np.ascontiguousarray(floats, dtype="<f4").reshape(len(float_names), n):
            parts.append(head_f)
            parts.append(row.tobytes())
    # footer: FileMetaData
    zn = _zz(n)
    tail = b"\x49\x1c\x15\x00\x15\x00\x15\x02\x00\x3c\x29\x06\x19\x26\x00" + zn + b"\x00\x00\x00"
    chunk0 = len(head0) + len(body0)
    chunk_b = len(head_b) - len(levels) + size_b
    chunk_f = len(head_f) - len(levels) + size_f
    mid0 = zn + b"\x16" + _zz(chunk0) + b"\x16" + _zz(chunk0) + b"\x26"
    mid_b = zn + b"\x16" + _zz(chunk_b) + b"\x16" + _zz(chunk_b) + b"\x26"
    mid_f = zn + b"\x16" + _zz(chunk_f) + b"\x16" + _zz(chunk_f) + b"\x26"
    heads = layout.chunk_head
    chunks = [heads[0] + mid0 + _zz(4) + tail]
    offset = 4 + chunk0
    first_float = layout.n_columns - len(float_names)
    for k in range(1, layout.n_columns):
        mid, size = (mid_b, chunk_b) if k < first_float else (mid_f, chunk_f)
        chunks.append(heads[k] + mid + _zz(offset) + tail)
        offset += size
    total = _zz(offset - 4)
    footer = b"".join([
        layout.schema, b"\x16", zn,
        b"\x19\x1c\x19", _list_header(layout.n_columns, 12), *chunks,
        b"\x16", total, b"\x16", zn, b"\x26\x08\x16", total, b"\x00",
        b"\x19\x2c\x18", _binary(meta_key), b"\x18", _binary(meta_json), b"\x00",
        b"\x18", _binary(b"ARROW:schema"), b"\x18", _binary(arrow_schema), b"\x00",
        b"\x18", _binary(created_by), layout.orders, b"\x00"])
    parts.append(footer)
    parts.append(struct.pack("<i", len(footer)))
    parts.append(b"PAR1")
    return b"".join(parts)


def arrow_schema(schema) -> bytes:
    """The ARROW:schema value Parquet files carry: the serialized schema, base64."""
    return base64.b64encode(schema.serialize().to_pybytes())


_CHECKED: bytes | None | bool = False  # False: not yet; None: differs; bytes: created_by
_CHECKED_FLOATS: bytes | None | bool = False  # the same for files with float columns


def available() -> bytes | None:
    """``created_by`` of the pyarrow in use when :func:`encode` gives its bytes exactly (checked
    once per process on reference tables), else None."""
    global _CHECKED
    if _CHECKED is False:
        _CHECKED = _check(floats=False)
    return _CHECKED


def available_floats() -> bytes | None:
    """:func:`available` for files with float32 columns (checked apart, once per process)."""
    global _CHECKED_FLOATS
    if _CHECKED_FLOATS is False:
        _CHECKED_FLOATS = _check(floats=True)
    return _CHECKED_FLOATS


def _check(*, floats: bool) -> bytes | None:
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        rng = np.random.default_rng(12)
        created_by = None
        for n, k in ((1, 1), (7, 3), (76, 40), (1023, 17)):
            names = tuple(f"f{i}é" for i in range(k))
            X = rng.integers(0, 2, (k, n)).astype(bool)
            native = np.arange(1, n + 1, dtype=np.int32) * 4
            float_names = tuple(f"p.{i}ü" for i in range(k + 2)) if floats else ()
            F = (rng.normal(0.0, 3.0, (len(float_names), n)) * 10.0 ** rng.integers(
                -40, 30, (len(float_names), n))).astype(np.float32)
            meta = json.dumps({"n": n, "text": "ünïcode"}, sort_keys=True)
            table = pa.table({"native_frame": pa.array(native),
                              **{nm: pa.array(X[i]) for i, nm in enumerate(names)},
                              **{nm: pa.array(F[i]) for i, nm in enumerate(float_names)}})
            table = table.replace_schema_metadata({b"mtanno": meta})
            sink = pa.BufferOutputStream()
            pq.write_table(table, sink, write_statistics=False, use_dictionary=False,
                           compression="none")
            want = sink.getvalue().to_pybytes()
            if created_by is None:
                created_by = pq.ParquetFile(pa.BufferReader(want)).metadata.created_by.encode()
            got = encode(names, native, np.packbits(X, axis=1, bitorder="little"), n,
                         b"mtanno", meta.encode(), arrow_schema(table.schema), created_by,
                         float_names=float_names, floats=F)
            if got != want:
                return None
        return created_by
    except Exception:  # anything unexpected: leave the writing to pyarrow
        return None
