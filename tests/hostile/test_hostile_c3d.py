"""Hostile C3D files (issue 36): truncated, a header that lies about its counts, zero
markers, every value NaN or 1e30, markers with names no set knows, the most markers a
header can declare, labels in other scripts. Each is one ``mtanno:`` line naming the file
(exit 2 for ``info``, the file failing alone in a ``features`` batch, exit 1), and the
batch writes the good file beside them. The files are made from a synthetic motion's
virtual markers in temporary folders."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from c3d_support import write_c3d
from virtual_markers import place_markers
from world import assert_one_line, cli

from mtanno import synthetic
from mtanno.io import read_channels
from mtanno.io.markerset import marker_name


@pytest.fixture(scope="module")
def markers(tmp_path_factory):
    root = tmp_path_factory.mktemp("hostile_c3d")
    rig, ch = read_channels(synthetic.write_pair(root, stem="m", n_frames=60, seed=4))
    labels, pts = place_markers(rig, ch)
    return labels, np.stack([pts[..., 0], -pts[..., 2], pts[..., 1]], axis=-1)


def _patched(path, offset: int, fmt: str, value):
    data = bytearray(path.read_bytes())
    data[offset:offset + struct.calcsize(fmt)] = struct.pack(fmt, value)
    path.write_bytes(bytes(data))
    return path


def _hostile(folder, markers) -> dict[str, tuple]:
    """name → (path, words of its one line)."""
    labels, P = markers
    folder.mkdir(parents=True, exist_ok=True)
    good = write_c3d(folder / "good.c3d", labels, P)
    data = good.read_bytes()
    out = {}
    t = folder / "truncated.c3d"
    t.write_bytes(data[:len(data) - 3000])
    out["truncated"] = (t, "holds")
    h = folder / "header.c3d"  # word 1 of the header: the marker count
    out["header"] = (_patched(_copy(good, h), 2, "<H", 9000), "not a readable C3D file")
    d = folder / "datablock.c3d"  # word 9: the first block of the data, beyond the file
    out["datablock"] = (_patched(_copy(good, d), 16, "<H", 60000), "holds 0")
    out["zero"] = (write_c3d(folder / "zero.c3d", [], np.zeros((5, 0, 3))),
                   "the file holds no markers (POINT:USED is 0)")
    out["nan"] = (write_c3d(folder / "nan.c3d", labels, np.full_like(P, np.nan)),
                  "cannot be computed in any frame")
    out["huge"] = (write_c3d(folder / "huge.c3d", labels, np.full_like(P, 1e30)),
                   "cannot be computed in any frame")
    other = ["Marker" + str(k) for k in range(len(labels))]
    out["unknown"] = (write_c3d(folder / "unknown.c3d", other, P),
                      "no marker set fits these markers")
    out["many"] = (write_c3d(folder / "many.c3d", [f"M{k}" for k in range(2000)],
                             np.ones((2, 65535, 3))),
                   "declares 65535 markers; mtanno reads C3D files of at most 4095")
    cjk = ["标记" + str(k) for k in range(len(labels))]
    out["scripts"] = (write_c3d(folder / "scripts.c3d", cjk, P),
                      "no marker set fits these markers (labels: 标记0")
    return out


def _copy(src, dst):
    dst.write_bytes(src.read_bytes())
    return dst


def test_each_hostile_c3d_file_is_one_line(tmp_path, markers):
    for name, (path, words) in _hostile(tmp_path / "in", markers).items():
        r = cli("info", path)
        line = assert_one_line(r, path, codes=(2,))
        assert words in line, (name, line)
        assert "Traceback" not in r.output


def test_a_batch_goes_on_past_every_hostile_c3d_file(tmp_path, markers):
    bad = _hostile(tmp_path / "in", markers)
    out = tmp_path / "out"
    r = cli("features", tmp_path / "in", "-o", out)
    assert r.exit_code == 1, r.output
    assert "1 written" in r.output and f"{len(bad)} failed" in r.output
    assert sorted(p.name for p in out.iterdir()) == ["good.parquet"]
    lines = [ln for ln in r.output.splitlines() if ln.startswith("mtanno:")]
    assert len(lines) == len(bad) and "Traceback" not in r.output


def test_labels_in_other_scripts_with_a_known_marker_name_are_read(tmp_path, markers):
    """A subject prefix in another script (Иван:LKNE) is only a prefix; a set given as a
    map from the set's names to labels in another script reads them too."""
    labels, P = markers
    names = [marker_name(x) for x in labels]
    prefixed = write_c3d(tmp_path / "ivan.c3d", ["Иван:" + n for n in names], P)
    r = cli("info", prefixed)
    assert r.exit_code == 0 and "subject        Иван:" in r.output, r.output
    greek = write_c3d(tmp_path / "greek.c3d", ["Σ" + n for n in names], P)
    mapping = tmp_path / "greek.toml"
    mapping.write_text('base = "vicon-41"\n[markers]\n' + "".join(
        f'{n} = "Σ{n}"\n' for n in names), encoding="utf-8")
    r = cli("info", greek, "--markers", mapping)
    assert r.exit_code == 0 and "LKNE (ΣLKNE) -> lknee" in r.output, r.output
