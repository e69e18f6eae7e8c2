"""Every mocap file in ../shared/data converts without error (issue acceptance)."""

from __future__ import annotations

import pytest
from conftest import DATA, require_data
from data_cache import unpack_archive

from mtanno.features.batch import plan_batch, run_batch
from mtanno.features.store import read_features


def _convert(inputs, out, **kw):
    jobs = plan_batch(inputs, out, **kw)
    summary = run_batch(jobs, n_jobs=2)
    failed = [o.message for o in summary.failed]
    assert not failed, "\n".join(failed[:10])
    return jobs


def test_hdm05_cmu02_and_mocap6(tmp_path):
    require_data()
    jobs = _convert([DATA / "hdm05_cut", DATA / "cmu_02"], tmp_path / "a")
    assert len(jobs) == 232 + 10
    jobs6 = _convert([DATA / "cmu_mocap6"], tmp_path / "m6", asf=DATA / "cmu_02" / "02.asf")
    assert len(jobs6) == 3
    ff = read_features(tmp_path / "m6" / "13_29.parquet")
    assert ff.meta["native_frames"] == 4592 and ff.X.shape[1] == 1148  # ceil(4592/4)


@pytest.mark.parametrize("archive", ["set1", "set2-active", "set2-elderly", "set2-feminine",
                                     "set2-masculine", "set2-normal"])
def test_bandai_archives(tmp_path, archive):
    require_data()
    folder = unpack_archive(DATA / "bandai" / f"{archive}.tar.xz")
    jobs = _convert([folder], tmp_path / archive)
    assert len(jobs) > 150
    ff = read_features(jobs[0].dst)
    assert ff.meta["native_fps"] == 30.0 and ff.meta["skeleton_map"] == "bandai-bvh"
    assert ff.X.shape[1] == ff.meta["native_frames"]
