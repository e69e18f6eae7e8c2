"""The bytes of a short feature file, written directly: identical to pyarrow's, much faster.

A feature file of a short clip (fewer than :data:`MOST_ROWS` analysis frames, written without
compression) has a fixed shape: one row group, one PLAIN data page per column, every column
nullable without nulls, no statistics, no dictionary. pyarrow spends about half a
millisecond encoding such a file — more than the kernels spend computing its features, for a
clip of a few seconds — most of it setting up a writer for each of the 41 columns. Here the
file is assembled from its parts (Parquet's thrift compact protocol), with what depends on
the feature names alone built once.

The result must be byte for byte what :func:`pyarrow.parquet.write_table` writes with the
options of :func:`mtanno.util.store.write_features`. :func:`available` checks that once per
process, on reference tables encoded both ways with the pyarrow in use; when they differ (a
pyarrow that writes another footer), every file is written by pyarrow.
``tests/test_store.py`` compares the two for every row count.
"""

from __future__ import annotations

import base64
import struct

import numpy as np

#: Files of fewer rows than this are written here (the rest, zstd-compressed, by pyarrow).
MOST_ROWS = 1024

_INT32, _BOOLEAN = 1, 0  # parquet physical types
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

    def __init__(self, names: tuple[str, ...]):
        cols = [("native_frame", _INT32)] + [(nm, _BOOLEAN) for nm in names]
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


_LAYOUTS: dict[tuple[str, ...], _Layout] = {}


def encode(names: tuple[str, ...], native_frames: np.ndarray, bits: np.ndarray, n: int,
           meta_key: bytes, meta_json: bytes, arrow_schema: bytes, created_by: bytes) -> bytes:
    """The Parquet file of a feature table: ``native_frames`` (n int32) and one boolean
    column per name, ``bits`` holding row i's values packed little-endian
    (``np.packbits(..., axis=1, bitorder="little")``); key-value metadata ``meta_key`` →
    ``meta_json`` and ARROW:schema → ``arrow_schema`` (the serialized Arrow schema),
    ``created_by`` as pyarrow writes it. For 1 ≤ n < :data:`MOST_ROWS`."""
    layout = _LAYOUTS.get(names)
    if layout is None:
        if len(_LAYOUTS) > 16:
            _LAYOUTS.clear()
        layout = _LAYOUTS[names] = _Layout(names)
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
    # footer: FileMetaData
    zn = _zz(n)
    tail = b"\x49\x1c\x15\x00\x15\x00\x15\x02\x00\x3c\x29\x06\x19\x26\x00" + zn + b"\x00\x00\x00"
    chunk0 = len(head0) + len(body0)
    chunk_b = len(head_b) - len(levels) + size_b
    mid0 = zn + b"\x16" + _zz(chunk0) + b"\x16" + _zz(chunk0) + b"\x26"
    mid_b = zn + b"\x16" + _zz(chunk_b) + b"\x16" + _zz(chunk_b) + b"\x26"
    heads = layout.chunk_head
    chunks = [heads[0] + mid0 + _zz(4) + tail]
    offset = 4 + chunk0
    for k in range(1, layout.n_columns):
        chunks.append(heads[k] + mid_b + _zz(offset) + tail)
        offset += chunk_b
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


def available() -> bytes | None:
    """``created_by`` of the pyarrow in use when :func:`encode` gives its bytes exactly (checked
    once per process on reference tables), else None."""
    global _CHECKED
    if _CHECKED is False:
        _CHECKED = _check()
    return _CHECKED


def _check() -> bytes | None:
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
            meta = json.dumps({"n": n, "text": "ünïcode"}, sort_keys=True)
            table = pa.table({"native_frame": pa.array(native),
                              **{nm: pa.array(X[i]) for i, nm in enumerate(names)}})
            table = table.replace_schema_metadata({b"mtanno": meta})
            sink = pa.BufferOutputStream()
            pq.write_table(table, sink, write_statistics=False, use_dictionary=False,
                           compression="none")
            want = sink.getvalue().to_pybytes()
            if created_by is None:
                created_by = pq.ParquetFile(pa.BufferReader(want)).metadata.created_by.encode()
            got = encode(names, native, np.packbits(X, axis=1, bitorder="little"), n,
                         b"mtanno", meta.encode(), arrow_schema(table.schema), created_by)
            if got != want:
                return None
        return created_by
    except Exception:  # anything unexpected: leave the writing to pyarrow
        return None
