"""Property-based hostile inputs (issue 8): hypothesis mutates the bytes of real files — an
HDM05 AMC clip, a Bandai BVH clip (the shared data; mtanno's synthetic AMC and a small
hand-written BVH where it is absent), an mtanno feature file (Parquet), a template (JSON)
and a truth table (CSV) — and the commands reading them must either accept the file or
report it in one line, without a traceback, with the good file of the batch processed,
no input changed and no temporary left. Few examples each, so the suite stays fast."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from world import assert_one_line, checksums, cli, temporaries

from mtanno import synthetic
from mtanno.features.store import read_features
from mtanno.util.tables import read_table

SETTINGS = settings(max_examples=10, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow])

#: One mutation: (operation, where as a fraction of the file, bytes).
_MUTATION = st.tuples(st.sampled_from(["set", "insert", "delete", "truncate", "swap"]),
                      st.floats(0, 1, allow_nan=False), st.binary(min_size=1, max_size=6))
MUTATIONS = st.lists(_MUTATION, min_size=1, max_size=4)


def mutate(data: bytes, mutations) -> bytes:
    buf = bytearray(data)
    for op, where, chunk in mutations:
        i = min(int(where * len(buf)), max(len(buf) - 1, 0))
        if op == "set":
            buf[i:i + len(chunk)] = chunk
        elif op == "insert":
            buf[i:i] = chunk
        elif op == "delete":
            del buf[i:i + 1 + chunk[0] % 64]
        elif op == "truncate":
            del buf[i:]
        elif op == "swap" and len(buf) > 1:
            j = (i + 1 + chunk[0]) % len(buf)
            buf[i], buf[j] = buf[j], buf[i]
    return bytes(buf)


def _real(path: Path) -> Path | None:
    return path if path.is_file() else None


@pytest.fixture(scope="module")
def motion_sources(tmp_path_factory):
    """(AMC, its ASF) and a BVH file: real ones when ../shared/data is present."""
    from conftest import DATA

    d = tmp_path_factory.mktemp("motion")
    amc = _real(DATA / "hdm05_cut" / "hopBothLegs1hops" / "HDM_bk_hopBothLegs1hops_020_120.amc")
    asf = _real(DATA / "hdm05_cut" / "HDM_bk.asf")
    if amc is None or asf is None:
        asf = d / "synth.asf"
        asf.write_text(synthetic.asf_text())
        amc = d / "synth.amc"
        amc.write_text(synthetic.amc_text(60, 3))
    bvh = None
    if DATA.is_dir():
        from data_cache import bandai_clips

        clips = bandai_clips("set1.tar.xz")
        bvh = min(clips, key=lambda p: p.stat().st_size) if clips else None
    if bvh is None:  # a rig that a shipped skeleton map fits (the CMU BVH layout)
        from test_bvh import CGSPEED_LIKE

        bvh = d / "cmu_like.bvh"
        bvh.write_text(CGSPEED_LIKE + " ".join(["0"] * (6 + 3 * 30)) + "\n")
    return amc, asf, bvh


def _features_batch(good: Path, data: bytes, asf: Path | None, suffix: str) -> None:
    """``features`` over a folder with the good file and the mutated one."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = tmp / "in"
        src.mkdir()
        if asf is not None:
            shutil.copyfile(asf, src / asf.name)
        shutil.copyfile(good, src / f"{good.stem}{suffix}")
        bad = src / f"{good.stem}_zz{suffix}"
        bad.write_bytes(data)
        before = checksums(src)
        r = cli("features", src, "-o", tmp / "out")
        if r.exit_code == 0:
            read_features(tmp / "out" / f"{bad.stem}.parquet")
        else:
            assert_one_line(r, bad, codes=(1,))
            assert not (tmp / "out" / f"{bad.stem}.parquet").exists()
        read_features(tmp / "out" / f"{good.stem}.parquet")  # the good file was processed
        assert checksums(src) == before
        assert temporaries(tmp) == []


@SETTINGS
@given(mutations=MUTATIONS)
def test_mutated_amc(motion_sources, mutations):
    amc, asf, _ = motion_sources
    _features_batch(amc, mutate(amc.read_bytes(), mutations), asf, ".amc")


@SETTINGS
@given(mutations=MUTATIONS)
def test_mutated_bvh(motion_sources, mutations):
    _, _, bvh = motion_sources
    _features_batch(bvh, mutate(bvh.read_bytes(), mutations), None, ".bvh")


@SETTINGS
@given(mutations=MUTATIONS)
def test_mutated_feature_file(world, mutations):
    data = mutate(world.doc_files[0].read_bytes(), mutations)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        good = world.copy(world.doc_files[1], tmp / "in" / "good.parquet")
        bad = tmp / "in" / "bad.parquet"
        bad.write_bytes(data)
        before = checksums(tmp / "in")
        r = cli("retrieve", "--mt", world.template, good, bad, "-o", tmp / "h.csv", "--tau",
                "0.5")
        if r.exit_code != 0:
            assert_one_line(r, bad, codes=(1,))
        assert "good" in {row["doc"] for row in read_table(tmp / "h.csv").rows}
        r = cli("info", bad)
        if r.exit_code != 0:
            assert_one_line(r, bad, codes=(2,))
        assert checksums(tmp / "in") == before and temporaries(tmp) == []


@SETTINGS
@given(mutations=MUTATIONS)
def test_mutated_template(world, mutations):
    data = mutate(world.template.read_bytes(), mutations)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bad = tmp / "bad.json"
        bad.write_bytes(data)
        before = checksums(tmp)
        for args in (["retrieve", "--mt", bad, world.doc_files[0], "-o", tmp / "h.csv"],
                     ["mt", "show", bad, "--picture"]):
            r = cli(*args)
            if r.exit_code != 0:
                assert_one_line(r, bad, codes=(2,))
        assert {k: v for k, v in checksums(tmp).items() if "h.csv" not in k} == before
        assert temporaries(tmp) == []


@SETTINGS
@given(mutations=MUTATIONS)
def test_mutated_truth_table(world, mutations):
    data = mutate(world.truth.read_bytes(), mutations)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bad = tmp / "truth.csv"
        bad.write_bytes(data)
        r = cli("evaluate", world.annotation, "--truth", bad, "--json", tmp / "r.json")
        if r.exit_code != 0:
            assert_one_line(r, bad, codes=(2,))
            assert not (tmp / "r.json").exists()
        assert bad.read_bytes() == data and temporaries(tmp) == []
