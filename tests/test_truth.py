"""Segment tables: reading, rate conversion, converters."""

from __future__ import annotations

import pytest
from conftest import DATA, require_data

from mtanno.errors import MtannoError
from mtanno.labels.segments import Segment, by_document
from mtanno.labels.truth import read_truth, to_analysis_frame, truth_from_mocap6, write_truth


def test_rate_conversion():
    # docs/method.md §8: ceil(frame / ratio)
    assert [to_analysis_frame(f, 120) for f in (1, 4, 5, 8, 9)] == [1, 1, 2, 2, 3]
    assert to_analysis_frame(17, 30) == 17
    assert to_analysis_frame(3, 60) == 2


def test_round_trip_and_fps_column(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("doc,start,end,label,fps\na,1,120,jump,120\nb,3,9,squat,\n")
    segs = read_truth(p)
    assert segs == [Segment("a", 1, 30, "jump"), Segment("b", 3, 9, "squat")]
    write_truth(tmp_path / "u.csv", segs)
    assert read_truth(tmp_path / "u.csv") == segs
    assert by_document(segs)["a"] == [Segment("a", 1, 30, "jump")]


@pytest.mark.parametrize("text,msg,line", [
    ("doc,start,label\n", "needs the columns", 1),
    ("doc,start,end,label\na,x,3,j\n", "start must be an integer", 2),
    ("doc,start,end,label\na,1,3,j\na,5,2,j\n", "start 5 is after end 2", 3),
    ("doc,start,end,label\n,1,3,j\n", "empty doc", 2),
])
def test_bad_tables(tmp_path, text, msg, line):
    p = tmp_path / "t.csv"
    p.write_text(text)
    with pytest.raises(MtannoError, match=msg) as e:
        read_truth(p)
    assert str(e.value).startswith(f"{p}:{line}:")


def test_mocap6_labels():
    require_data()
    segs = truth_from_mocap6(DATA / "cmu_mocap6" / "labels.json")
    docs = by_document(segs)
    assert set(docs) == {"13_29", "13_30", "13_31"}
    assert docs["13_29"][0] == Segment("13_29", 1, 117, "JumpJack")  # 468 / 4
    assert docs["13_29"][-1].end == 1148  # ceil(4592 / 4)
