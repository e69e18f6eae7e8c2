"""Open-world annotation end to end on the synthetic world (issue 26): tune with background
motions, the tuned confidence and its minimum applied by annotate, the uncalibrated score
without a tuned confidence, and bad --background and --min-confidence input."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from world import assert_one_line, cli

from mtanno.annotate import read_annotation_table

BACKGROUND_CLASS = "waveRHand"  # left out of the templates: its clips are the background


@pytest.fixture(scope="module")
def tuned(world, tmp_path_factory):
    """Templates without one class, tuned with that class's clips as background."""
    root = tmp_path_factory.mktemp("open")
    mt = root / "mt"
    shutil.copytree(world.mt, mt)
    (mt / f"{BACKGROUND_CLASS}.json").unlink()
    manifest = root / "clips.csv"
    lines = world.manifest.read_text().splitlines()
    manifest.write_text("\n".join([lines[0]] + [ln for ln in lines[1:]
                                                 if f",{BACKGROUND_CLASS}," not in ln]) + "\n")
    background = world.feats / BACKGROUND_CLASS
    config = root / "tuned.toml"
    r = cli("tune", "--mt", mt, "--manifest", manifest, "--features-dir", world.feats,
            "--split", "train", "--background", background, "-o", config, "-q")
    assert r.exit_code == 0, r.output
    return root, mt, manifest, config, background


def test_tune_records_the_background_and_the_confidence(tuned):
    from mtanno.annotate import load_class_config
    from mtanno.confidence.verify import read_bank
    from mtanno.util.provenance import sha256_file

    root, mt, _, config, background = tuned
    cfg = load_class_config(config)
    files = sorted(background.glob("*.parquet"))
    assert cfg.background == {str(f): sha256_file(f) for f in files}
    conf = cfg.confidence
    assert set(conf.evidence) == {"cost", "length", "verify", "margin", "background"}
    assert 0.0 <= conf.min_confidence <= 0.8
    bank = read_bank(root / conf.bank_file)
    assert bank.representation == "features"  # the synthetic features have no poses
    assert bank.has_background and BACKGROUND_CLASS not in bank.classes
    assert conf.bank_sha256 == sha256_file(root / conf.bank_file)
    assert "AUROC" in config.read_text()


def test_annotate_gives_the_tuned_confidence_and_applies_its_minimum(world, tuned, tmp_path):
    _, mt, _, config, _ = tuned
    out = tmp_path / "a.csv"
    r = cli("annotate", "--mt", mt, "--classes", config, world.docfeats, "-o", out,
            "--min-confidence", "0", "-q")
    assert r.exit_code == 0, r.output
    rows, prov = read_annotation_table(out)
    assert rows and all(0.0 <= a.confidence <= 1.0 for a in rows)
    assert prov["confidence"]["calibrated"] is True
    assert prov["confidence"]["min_confidence"] == 0.0
    assert prov["confidence"]["bank"]["representation"] == "features"
    assert len(prov["background"]) == len(list((world.feats / BACKGROUND_CLASS).glob("*")))
    # the minimum drops exactly the rows below it
    cut = sorted(a.confidence for a in rows)[len(rows) // 2]
    out2 = tmp_path / "b.csv"
    r = cli("annotate", "--mt", mt, "--classes", config, world.docfeats, "-o", out2,
            "--min-confidence", str(cut), "-q")
    assert r.exit_code == 0, r.output
    kept, _ = read_annotation_table(out2)
    assert kept == [a for a in rows if a.confidence >= cut]


def test_without_a_tuned_confidence_the_score_is_uncalibrated(world):
    rows, prov = read_annotation_table(world.annotation)
    assert prov["confidence"] == {"calibrated": False, "score": "1 - cost/tau, clipped to [0, 1]",
                                  "min_confidence": 0.0}
    for a in rows:
        want = 0.0 if math.isinf(a.cost) else min(1.0, max(0.0, 1 - a.cost / 0.13))
        assert a.confidence == pytest.approx(want, abs=1e-6)


def test_a_pose_bank_needs_feature_files_with_poses(world, tuned, tmp_path):
    """A configuration verifying by poses, given feature files without them: each file
    fails with one line saying how to make them; exit code 1."""
    from mtanno.confidence.verify import POSE_JOINTS, build_bank, read_bank, write_bank
    from mtanno.util.provenance import sha256_file

    root, mt, _, config, _ = tuned
    old = read_bank(root / "tuned.verify.parquet")
    rng = np.random.default_rng(0)
    ex = [(c, p, rng.random((5, 3 * len(POSE_JOINTS))).astype(np.float32))
          for c, p in zip(old.labels, old.performers) if c]
    cfg_dir = tmp_path / "cfg"
    shutil.copytree(root, cfg_dir, ignore=shutil.ignore_patterns("mt"))
    write_bank(cfg_dir / "tuned.verify.parquet", build_bank(ex, representation="poses"))
    text = (cfg_dir / "tuned.toml").read_text().replace(
        json.dumps(sha256_file(root / "tuned.verify.parquet")),
        json.dumps(sha256_file(cfg_dir / "tuned.verify.parquet")))
    (cfg_dir / "tuned.toml").write_text(text)
    r = cli("annotate", "--mt", mt, "--classes", cfg_dir / "tuned.toml", world.docfeats,
            "-o", tmp_path / "a.csv")
    assert r.exit_code == 1, r.output
    assert "features --poses" in r.output and "Traceback" not in r.output


def test_bad_background_is_one_line_and_exit_2(world, tuned, tmp_path):
    _, mt, manifest, _, _ = tuned
    train = ["--manifest", manifest, "--features-dir", world.feats, "--split", "train"]
    empty = tmp_path / "empty"
    empty.mkdir()
    other = tmp_path / "mrc05"
    r = cli("features", world.clips / BACKGROUND_CLASS, "-o", other, "--feature-set", "mrc05",
            "-q")
    assert r.exit_code == 0, r.output
    other_file = sorted(other.rglob("*.parquet"))[0]
    training_clip = sorted((world.feats / "squat").glob("*.parquet"))[0]
    for bad, says in ((empty, "no feature files"), (other_file, "feature"),
                      (training_clip, "also a training file")):
        r = cli("tune", "--mt", mt, *train, "--background", bad, "-o", tmp_path / "t.toml")
        line = assert_one_line(r, bad, codes=(2,))
        assert says in line, line
        assert not (tmp_path / "t.toml").exists()


@pytest.mark.parametrize("value", ["-0.1", "1.5", "nan", "x"])
def test_bad_min_confidence_is_a_usage_error(world, value, tmp_path):
    r = cli("annotate", "--mt", world.mt, world.docfeats, "-o", tmp_path / "a.csv",
            "--min-confidence", value)
    assert r.exit_code == 2 and "--min-confidence" in r.output and "Traceback" not in r.output


def test_tune_on_annotated_documents_with_poses_verifies_by_poses(world, tmp_path):
    """--truth documents: the held-out documents are the feature files themselves, read
    with their poses, so the bank verifies by poses (auto)."""
    from mtanno.annotate import load_class_config
    from mtanno.confidence.verify import read_bank

    feats = tmp_path / "docsP"
    r = cli("features", world.docs, "-o", feats, "--poses", "-q")
    assert r.exit_code == 0, r.output
    config = tmp_path / "t.toml"
    r = cli("tune", "--mt", world.mt, "--truth", world.truth, feats, "-o", config, "-q")
    assert r.exit_code == 0, r.output
    conf = load_class_config(config).confidence
    assert read_bank(tmp_path / conf.bank_file).representation == "poses"
    r = cli("annotate", "--mt", world.mt, "--classes", config, feats, "-o", tmp_path / "a.csv",
            "--min-confidence", "0", "-q")
    assert r.exit_code == 0, r.output


def test_tune_invariance_and_evidence_are_recorded_and_used(world, tmp_path):
    """Issue 35: ``tune --invariance`` makes the bank and [confidence] record what the
    verification is blind to, annotate verifies the same way (its provenance says so);
    ``--evidence`` chooses the calibrator's evidence, the frame classifier's bank written
    beside the configuration when it is among them; a bank whose invariance differs from
    the configuration's is refused in one line."""
    from mtanno.annotate import load_class_config
    from mtanno.confidence.verify import build_bank, read_bank, write_bank
    from mtanno.util.provenance import sha256_file

    feats = tmp_path / "docsP"
    r = cli("features", world.docs, "-o", feats, "--poses", "-q")
    assert r.exit_code == 0, r.output
    config = tmp_path / "t.toml"
    r = cli("tune", "--mt", world.mt, "--truth", world.truth, feats, "-o", config, "-q",
            "--invariance", "mirror", "--invariance", "retarget",
            "--evidence", "cost", "--evidence", "verify", "--evidence", "margin",
            "--evidence", "classifier")
    assert r.exit_code == 0, r.output
    conf = load_class_config(config).confidence
    assert conf.invariance == ("retarget", "mirror")  # in INVARIANCES order
    assert set(conf.evidence) <= {"cost", "verify", "margin", "classifier"}
    assert {"verify", "classifier"} <= set(conf.evidence)
    assert conf.frames_file == "t.frames.parquet"
    assert conf.frames_sha256 == sha256_file(tmp_path / conf.frames_file)
    assert conf.frame_bank.windows.shape[0] > 0
    bank = read_bank(tmp_path / conf.bank_file)
    assert bank.representation == "poses" and bank.invariance == ("retarget", "mirror")
    assert "blind to retarget, mirror" in config.read_text()
    out = tmp_path / "a.csv"
    r = cli("annotate", "--mt", world.mt, "--classes", config, feats, "-o", out,
            "--min-confidence", "0", "-q")
    assert r.exit_code == 0, r.output
    _, prov = read_annotation_table(out)
    assert prov["confidence"]["bank"]["invariance"] == ["retarget", "mirror"]
    assert prov["confidence"]["frames"]["sha256"] == conf.frames_sha256
    # the same bank without its invariance, pinned by its SHA-256: refused, one line
    plain = build_bank([(c, p, bank.items[bank.offsets[k]:bank.offsets[k + 1]])
                        for k, (c, p) in enumerate(zip(bank.labels, bank.performers)) if c],
                       representation="poses")
    write_bank(tmp_path / conf.bank_file, plain)
    text = config.read_text().replace(conf.bank_sha256, sha256_file(tmp_path / conf.bank_file))
    config.write_text(text)
    r = cli("annotate", "--mt", world.mt, "--classes", config, feats, "-o", tmp_path / "b.csv")
    assert r.exit_code != 0 and "invariance" in r.output and "Traceback" not in r.output


def test_a_configuration_folder_holds_the_frame_classifier_bank(world, tmp_path):
    """``tune -o DIR/ --evidence classifier`` keeps the frame classifier's bank in the
    folder (``frames.parquet``), so the folder moved and renamed annotates alike."""
    import shutil

    from mtanno.annotate import load_class_config

    feats = tmp_path / "docsP"
    assert cli("features", world.docs, "-o", feats, "--poses", "-q").exit_code == 0
    r = cli("tune", "--mt", world.mt, "--truth", world.truth, feats, "-o",
            tmp_path / "tuned", "-q", "--evidence", "verify", "--evidence", "classifier")
    assert r.exit_code == 0, r.output
    conf = load_class_config(tmp_path / "tuned").confidence
    assert conf.frames_file == "frames.parquet" and (tmp_path / "tuned/frames.parquet").is_file()
    assert not list(tmp_path.glob("*.frames.parquet"))
    outs = []
    for where in (tmp_path / "tuned", tmp_path / "elsewhere" / "renamed"):
        if not where.exists():
            where.parent.mkdir()
            shutil.move(tmp_path / "tuned", where)
        out = tmp_path / f"{where.name}.csv"
        r = cli("annotate", "--mt", world.mt, "--classes", where, feats, "-o", out,
                "--min-confidence", "0", "-q")
        assert r.exit_code == 0, r.output
        outs.append(read_annotation_table(out)[0])
    assert outs[0] == outs[1]


def test_bad_invariance_and_evidence_are_usage_errors(world, tmp_path):
    train = ["--manifest", world.manifest, "--features-dir", world.feats, "--split", "train"]
    for opt, value in (("--invariance", "scale"), ("--evidence", "speed")):
        r = cli("tune", "--mt", world.mt, *train, opt, value, "-o", tmp_path / "t.toml")
        assert r.exit_code == 2 and opt in r.output and "Traceback" not in r.output
    # invariance needs verification by poses: the synthetic clips have none
    r = cli("tune", "--mt", world.mt, *train, "--invariance", "mirror", "-o",
            tmp_path / "t.toml")
    line = assert_one_line(r, "", codes=(2,))
    assert "--invariance" in line and "poses" in line, line
    assert not (tmp_path / "t.toml").exists()
