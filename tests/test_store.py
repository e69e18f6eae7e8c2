"""Feature files: round trip, metadata, atomic writes and bad files."""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from mtanno.errors import MtannoError
from mtanno.features import FEATURE_NAMES
from mtanno.features.store import read_feature_matrix, read_features, write_features
from mtanno.util.output import atomic_path


def test_round_trip(tmp_path):
    X = (np.random.default_rng(0).random((40, 17)) < 0.5).astype(np.uint8)
    p = tmp_path / "d" / "doc.parquet"
    write_features(p, X, FEATURE_NAMES, np.arange(1, 69, 4), {"native_fps": 120.0, "feature_set": "mr06-ak40",
                                                               "analysis_fps": 30.0})
    ff = read_features(p)
    assert np.array_equal(ff.X, X) and ff.X.dtype == np.uint8
    assert ff.names == list(FEATURE_NAMES)
    assert ff.native_frames.tolist() == list(range(1, 69, 4))
    assert ff.meta["schema"] == "mtanno.features/1" and ff.fps == 30.0
    assert ff.document == "doc"
    assert np.array_equal(read_feature_matrix(p), X)
    cols = pq.read_schema(p).names
    assert cols[0] == "native_frame" and cols[1:] == list(FEATURE_NAMES)


def test_atomic_write_leaves_nothing_on_error(tmp_path):
    target = tmp_path / "x.parquet"
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("crash")
    assert list(tmp_path.iterdir()) == []


def test_write_rejects_wrong_shape(tmp_path):
    with pytest.raises(MtannoError, match="40 × frames"):
        write_features(tmp_path / "x.parquet", np.zeros((3, 4)), FEATURE_NAMES, np.arange(4), {})


def test_read_bad_files(tmp_path):
    with pytest.raises(MtannoError, match="feature file not found"):
        read_features(tmp_path / "missing.parquet")
    junk = tmp_path / "junk.parquet"
    junk.write_bytes(b"not parquet at all")
    with pytest.raises(MtannoError, match="not a readable Parquet") as e:
        read_features(junk)
    assert str(e.value).startswith(str(junk))
    plain = tmp_path / "plain.parquet"
    pq.write_table(pa.table({"a": [1, 2]}), plain)
    with pytest.raises(MtannoError, match="no mtanno metadata"):
        read_features(plain)
    other = tmp_path / "other.parquet"
    t = pa.table({"native_frame": [1]}).replace_schema_metadata(
        {b"mtanno": json.dumps({"schema": "something/9"})})
    pq.write_table(t, other)
    with pytest.raises(MtannoError, match="unsupported feature file schema"):
        read_features(other)


def test_atomic_path_writes_a_fifo_in_place(tmp_path):
    import os
    import threading

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    with atomic_path(fifo) as tmp:
        assert tmp == fifo
        tmp.write_bytes(b"hello")
    reader.join()
    assert got == [b"hello"] and fifo.is_fifo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]


# ------------------------------------------------------- short files written directly (_parquet)

def _pyarrow_bytes(X, names, native, meta) -> bytes:
    """A feature file as pyarrow writes it with write_features' options (the reference)."""
    table = pa.table({"native_frame": pa.array(np.asarray(native, dtype=np.int32)),
                      **{nm: pa.array(X[i].astype(bool)) for i, nm in enumerate(names)}})
    table = table.replace_schema_metadata(
        {b"mtanno": json.dumps({"schema": "mtanno.features/1", **meta}, sort_keys=True)})
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, write_statistics=False, use_dictionary=False,
                   compression="zstd" if X.shape[1] >= 1024 else "none")
    return sink.getvalue().to_pybytes()


def test_short_files_are_byte_identical_to_pyarrow_for_every_length(tmp_path):
    from mtanno.features import _parquet, get_feature_set

    assert _parquet.available() is not None  # the direct encoder agrees with this pyarrow
    rng = np.random.default_rng(3)
    meta = {"analysis_fps": 30.0, "feature_set": "mr06-ak40", "source": "/d/ünï cödé.amc",
            "native_frames": 0}
    sets = [FEATURE_NAMES, get_feature_set("mrc05").names]
    for n in range(1, 1030):
        names = sets[n % 2]
        X = (rng.random((len(names), n)) < rng.random()).astype(np.uint8)
        native = np.arange(n) * 4 + 1
        p = tmp_path / f"f{n}.parquet"
        write_features(p, X, names, native, {**meta, "native_frames": 4 * n})
        assert p.read_bytes() == _pyarrow_bytes(X, names, native, {**meta, "native_frames": 4 * n}), n
    assert read_features(tmp_path / "f77.parquet").X.shape == (31, 77)


def test_short_files_fall_back_to_pyarrow(tmp_path, monkeypatch):
    from mtanno.features import _parquet

    monkeypatch.setattr(_parquet, "_CHECKED", None)  # as if this pyarrow wrote other bytes
    X = (np.random.default_rng(4).random((40, 9)) < 0.5).astype(np.uint8)
    meta = {"analysis_fps": 30.0, "feature_set": "mr06-ak40"}
    write_features(tmp_path / "x.parquet", X, FEATURE_NAMES, np.arange(9) + 1, meta)
    assert (tmp_path / "x.parquet").read_bytes() == \
        _pyarrow_bytes(X, FEATURE_NAMES, np.arange(9) + 1, meta)


def test_write_rejects_duplicate_names_and_wrong_frames(tmp_path):
    names = list(FEATURE_NAMES[:3]) + [FEATURE_NAMES[0]]
    with pytest.raises(MtannoError, match="unique"):
        write_features(tmp_path / "x.parquet", np.zeros((4, 5)), names, np.arange(5) + 1,
                       {"analysis_fps": 30.0, "feature_set": "x"})
    with pytest.raises(MtannoError, match="one frame per column"):
        write_features(tmp_path / "x.parquet", np.zeros((40, 5)), FEATURE_NAMES, np.arange(4) + 1,
                       {"analysis_fps": 30.0, "feature_set": "x"})
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("n", [50, 3000])
def test_write_a_matrix_in_any_memory_order(tmp_path, n):
    """A transposed (Fortran-order) matrix is written as its rows, short or long."""
    X = (np.random.default_rng(5).random((n, 40)) < 0.5).astype(np.uint8).T
    assert not X.flags.c_contiguous
    meta = {"analysis_fps": 30.0, "feature_set": "mr06-ak40"}
    write_features(tmp_path / "x.parquet", X, FEATURE_NAMES, np.arange(n) + 1, meta)
    assert np.array_equal(read_features(tmp_path / "x.parquet").X, X)
    assert (tmp_path / "x.parquet").read_bytes() == _pyarrow_bytes(X, FEATURE_NAMES,
                                                                    np.arange(n) + 1, meta)
