"""The fold and selection logic of the Bandai review loop (issue 24, scripts/bandai_folds.py
``review`` used by scripts/experiment_review.sh), on a tiny synthetic archive: the K
reviewed clips per content come from the held-out style only, are removed from its test
documents, K = 0 gives the original fold, and the seeded draw is reproducible. No real data:
the feature files are one-column Parquet tables of a few rows (only their row counts are
read)."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from mtanno.labels.truth import read_truth

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bandai_folds.py"
CONTENTS = ("run", "walk", "wave-left-hand")
TAKES = 4  # clips per (style, content)


@pytest.fixture(scope="module")
def folds_mod():
    spec = importlib.util.spec_from_file_location("bandai_folds", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def archive(tmp_path_factory, folds_mod):
    """FEATS/<style>/dataset-2_<content>_<style>_<take>.parquet for every style, and the
    folds of ``folds --per 2``."""
    root = tmp_path_factory.mktemp("bandai")
    feats = root / "feats"
    for i, style in enumerate(folds_mod.STYLES):
        (feats / style).mkdir(parents=True)
        for j, content in enumerate(CONTENTS):
            for take in range(1, TAKES + 1):
                n = 5 + i + 2 * j + take
                pq.write_table(pa.table({"F01": [0] * n}),
                               feats / style / f"dataset-2_{content}_{style}_{take:03d}.parquet")
    folds_mod.folds(feats, root / "folds", per=2, seed=0)
    return feats, root / "folds"


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _review(folds_mod, archive, tmp_path, style, k, seed=0, name="out"):
    feats, folds = archive
    out = tmp_path / name
    folds_mod.review(folds / style, out, k, seed, feats)
    return out


def test_k0_is_the_original_fold(folds_mod, archive, tmp_path):
    _, folds = archive
    out = _review(folds_mod, archive, tmp_path, "elderly", 0)
    for f in ("train.csv", "truth.csv"):
        assert (out / f).read_bytes() == (folds / "elderly" / f).read_bytes()
    assert _rows(out / "reviewed.csv") == []
    truth = _rows(folds / "elderly" / "truth.csv")
    assert (out / "documents.txt").read_text().splitlines() == [
        f"elderly/{r['doc']}.parquet" for r in truth]


@pytest.mark.parametrize("k", [1, 2])
def test_reviewed_clips_come_from_the_held_out_style_and_leave_its_test(folds_mod, archive,
                                                                        tmp_path, k):
    feats, folds = archive
    held = "feminine"
    out = _review(folds_mod, archive, tmp_path, held, k)
    reviewed = _rows(out / "reviewed.csv")
    # k whole clips per content, all of the held-out style, in the downloaded truth format
    assert list(reviewed[0]) == ["doc", "start", "end", "label", "fps"]
    assert sorted(r["label"] for r in reviewed) == sorted(CONTENTS * k)
    fold_truth = {r["doc"]: r for r in _rows(folds / held / "truth.csv")}
    for r in reviewed:
        assert f"_{held}_" in r["doc"] and r["doc"] in fold_truth
        assert (r["start"], r["end"], r["fps"]) == ("1", fold_truth[r["doc"]]["end"], "30")
    segs = read_truth(out / "reviewed.csv")  # what learn-mt --truth reads
    assert len(segs) == len(CONTENTS) * k
    # removed from the test documents and their truth, every other clip kept
    names = {r["doc"] for r in reviewed}
    test = _rows(out / "truth.csv")
    assert names.isdisjoint(r["doc"] for r in test)
    assert {r["doc"] for r in test} | names == set(fold_truth)
    assert (out / "documents.txt").read_text().splitlines() == [
        f"{held}/{r['doc']}.parquet" for r in test]
    # training: the fold's manifest plus the reviewed clips as performer `held`
    fold_train = (folds / held / "train.csv").read_text().splitlines()
    train = (out / "train.csv").read_text().splitlines()
    assert train[:len(fold_train)] == fold_train
    added = [line.split(",") for line in train[len(fold_train):]]
    assert sorted(f[0] for f in added) == sorted(f"{held}/{n}.bvh" for n in names)
    assert {f[2] for f in added} == {held}
    assert all(f"_{held}_" not in line for line in fold_train)
    # learn-mt's truth table: the same examples, whole clips with their frame counts
    tt = _rows(out / "train_truth.csv")
    assert [(r["doc"], r["label"]) for r in tt] == [
        (Path(line.split(",")[0]).stem, line.split(",")[1]) for line in train[1:]]
    for r in tt:
        style = r["doc"].rsplit("_", 2)[1]
        n = pq.ParquetFile(feats / style / f"{r['doc']}.parquet").metadata.num_rows
        assert (r["start"], r["end"], r["fps"]) == ("1", str(n), "30")


def test_the_seeded_draw_is_reproducible_and_nested(folds_mod, archive, tmp_path):
    a = _rows(_review(folds_mod, archive, tmp_path, "active", 2, name="a") / "reviewed.csv")
    b = _rows(_review(folds_mod, archive, tmp_path, "active", 2, name="b") / "reviewed.csv")
    assert a == b
    one = _rows(_review(folds_mod, archive, tmp_path, "active", 1, name="c") / "reviewed.csv")
    assert {r["doc"] for r in one} < {r["doc"] for r in a}
    draws = {tuple(r["doc"] for r in folds_mod.draw_reviewed(
        _rows(archive[1] / "active" / "truth.csv"), "active", 2, seed)) for seed in range(8)}
    assert len(draws) > 1  # the seed matters
    # more than a content holds: all of its clips
    all_clips = folds_mod.draw_reviewed(_rows(archive[1] / "active" / "truth.csv"), "active",
                                        TAKES + 3, 0)
    assert len(all_clips) == len(CONTENTS) * TAKES
