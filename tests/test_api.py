"""The public API of ``import mtanno`` (issue 9): the README's notebook example on the
synthetic test world gives what the commands give."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import mtanno
from mtanno.annotate import read_annotations
from mtanno.features.store import read_features
from mtanno.templates.store import load_template_folder


def test_import_is_light_and_names_the_api():
    code = ("import sys, mtanno; assert 'numba' not in sys.modules, 'numba imported'; "
            "print(sorted(mtanno.__all__))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    for name in ("read_motion", "compute_features", "learn_templates", "load_templates",
                 "annotate_documents", "evaluate_annotation"):
        assert name in r.stdout and callable(getattr(mtanno, name))
    with pytest.raises(AttributeError):
        mtanno.no_such_thing  # noqa: B018


def test_notebook_example_equals_the_commands(world):
    clip = world.clips / "squat" / "SYN_a_squat_001.amc"
    X = mtanno.compute_features(mtanno.read_motion(clip))
    assert np.array_equal(X, read_features(world.feats / "squat" / "SYN_a_squat_001.parquet").X)
    assert np.array_equal(mtanno.compute_features(clip, feature_set="mrc05"),
                          mtanno.compute_features(mtanno.read_motion(clip), feature_set="mrc05"))

    mts = mtanno.learn_templates(manifest=world.manifest, features_dir=world.feats,
                                 split="train")
    cli_mts = load_template_folder(world.mt)
    assert list(mts) == list(cli_mts)
    for name, mt in mts.items():  # learn-mt wrote the same templates
        assert np.array_equal(mt.values, cli_mts[name].values)
        assert np.array_equal(mt.weights, cli_mts[name].weights)

    result = mtanno.annotate_documents(world.docfeats, mts)
    assert not result.failed
    assert result.rows == read_annotations(world.annotation)  # = mtanno annotate
    from_folder = mtanno.annotate_documents(world.docfeats, mtanno.load_templates(world.mt))
    assert from_folder.rows == result.rows

    report = mtanno.evaluate_annotation(result, truth=world.truth)
    from_file = mtanno.evaluate_annotation(world.annotation, world.truth)
    assert report.as_dict() == from_file.as_dict()
    assert report.documents == sorted(p.stem for p in world.doc_files)
    assert "overall" in report.table() and 0 < report.frame.F <= 1

    single = mtanno.annotate_documents(world.docfeats, world.mt, single_label=True, tau=0.2)
    assert not single.failed and single.rows != result.rows
    with pytest.raises(mtanno.MtannoError, match="annotations must be"):
        mtanno.evaluate_annotation([1, 2], world.truth)


def test_annotate_documents_applies_a_class_configuration_as_the_command_does(world, tmp_path):
    """A tuned-style configuration (δ, per-class τ, a further template): the API gives the
    rows of `mtanno annotate --classes`, warns as the command does, and leaves the
    configuration object passed to it as it was."""
    from click.testing import CliRunner

    from mtanno.annotate import load_class_config, read_annotations
    from mtanno.cli import main
    from mtanno.templates.store import save_template
    from mtanno.templates.tempo import time_scaled
    from mtanno.util.provenance import sha256_file

    names = sorted(p.stem for p in world.mt.glob("*.json"))
    mts = load_template_folder(world.mt)
    save_template(tmp_path / "extra.json", time_scaled(mts[names[0]], 0.6))
    cfg_path = tmp_path / "c.toml"
    cfg_path.write_text(
        f"[decoder]\nresolve = true\ndelta = 0.25\n[tau]\ndefault = 0.12\n{names[1]} = 0.08\n"
        f'[templates]\n{names[0]} = ["extra.json"]\n[tuned_with]\n'
        + "".join(f'{n} = "{sha256_file(world.mt / (n + ".json"))}"\n' for n in names))
    out = tmp_path / "a.csv"
    r = CliRunner().invoke(main, ["annotate", "--mt", str(world.mt), "--classes", str(cfg_path),
                                  str(world.docfeats), "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    cfg = load_class_config(cfg_path)
    got = mtanno.annotate_documents(world.docfeats, world.mt, config=cfg)
    assert got.rows == read_annotations(out)
    without = mtanno.annotate_documents(world.docfeats, world.mt, config=cfg, delta=0.05)
    assert without.rows != got.rows  # the configuration's δ was used
    # the templates are not those tuned with: a warning, as annotate prints
    changed = dict(mts)
    changed[names[0]] = time_scaled(mts[names[0]], 1.0)
    changed[names[0]].path = str(tmp_path / "extra.json")
    with pytest.warns(UserWarning, match=f"the template\\(s\\) of {names[0]} are not those"):
        mtanno.annotate_documents(world.docfeats, changed, config=cfg, tau=0.2)
    assert cfg.default_tau == 0.12  # tau=0.2 did not change the object passed


def test_annotate_to_is_the_command_from_file_names_to_files(world, tmp_path):
    """``mtanno.annotate.annotate_to`` writes what ``mtanno annotate -o`` wrote (the world's
    annotation table), says the run in words, and speaks in parameter names."""
    from mtanno.annotate import annotate_to

    seen = []
    run = annotate_to([world.docfeats], world.mt, outputs=[tmp_path / "a.csv"],
                      on_start=lambda setup, missing, n: seen.append((missing, n)),
                      progress=lambda path, error: seen.append(error))
    n = len(world.doc_files)
    assert seen == [([], n), *[None] * n]
    assert run.exit_code == 0 and run.documents == n and run.failed == 0
    assert run.written == [tmp_path / "a.csv"] and run.what.startswith(f"{n} documents, ")
    assert read_annotations(tmp_path / "a.csv") == read_annotations(world.annotation)

    folder = annotate_to([world.docfeats, tmp_path / "none"], world.mt, out_dir=tmp_path / "out")
    assert folder.exit_code == 1 and len(folder.missing) == 1 and folder.failed == 0
    assert folder.written == [tmp_path / "out"]
    with pytest.raises(mtanno.MtannoError, match=r"^give outputs= \(one table"):
        annotate_to([world.docfeats], world.mt)
    with pytest.raises(mtanno.MtannoError, match=r"^force= goes with out_dir="):
        annotate_to([world.docfeats], world.mt, outputs=[tmp_path / "b.csv"], force=True)


def test_annotate_options_are_checked_and_shared(world, tmp_path):
    """:class:`AnnotateOptions` refuses bad values when it is made, naming the option;
    ``load_annotation_setup`` and ``annotate_to`` read the same value, and
    ``annotate_files``, which takes the setup loaded, refuses the options that load it."""
    from mtanno.annotate import AnnotateOptions, annotate_files, load_annotation_setup

    for bad, message in ((dict(tau=-1), "tau must be a number"),
                         (dict(min_confidence=2), "min_confidence must be a number in"),
                         (dict(dbar_variant="fast"), r"unknown dbar_variant= 'fast'"),
                         (dict(match_variant="x"), r"unknown match_variant= 'x'"),
                         (dict(n_jobs=0), r"n_jobs= must be a positive integer")):
        with pytest.raises(mtanno.MtannoError, match=message):
            AnnotateOptions(**bad)
    o = AnnotateOptions(tau=0.2, single_label=True, min_confidence=0.25)
    setup = load_annotation_setup(world.mt, o)
    assert (setup.config.default_tau, setup.single_label, setup.min_confidence) == (0.2, True,
                                                                                     0.25)
    assert setup.options(n_jobs=2) == AnnotateOptions(single_label=True, min_confidence=0.25,
                                                      n_jobs=2)
    run = mtanno.annotate.annotate_to([world.docfeats], world.mt, o,
                                      outputs=[tmp_path / "a.csv"])
    batch = setup.annotate(sorted(world.doc_files))
    assert run.exit_code == 0 and batch.rows  # the same annotation both ways
    assert read_annotations(tmp_path / "a.csv") == batch.rows
    assert batch.rows != read_annotations(world.annotation)  # the options made a difference
    with pytest.raises(mtanno.MtannoError, match=r"^tau= and delta= go with "
                                                 "load_annotation_setup"):
        annotate_files(world.doc_files, setup.models, layout=setup.layout,
                       options=AnnotateOptions(tau=0.2, delta=0.1))


def test_extract_to_is_the_features_command(world, tmp_path):
    """``mtanno.features.batch.extract_to`` writes the world's feature files, and a run
    that writes nothing leaves no folder behind."""
    from mtanno.features.batch import ExtractOptions, extract_to

    clip = world.clips / "squat" / "SYN_a_squat_001.amc"
    started = []
    summary = extract_to([clip], tmp_path / "f", on_start=started.append)
    assert started == [1] and summary.line().startswith("1 written")
    assert np.array_equal(read_features(tmp_path / "f" / "SYN_a_squat_001.parquet").X,
                          read_features(world.feats / "squat" / "SYN_a_squat_001.parquet").X)
    with pytest.raises(mtanno.MtannoError, match=r"output folder name \(outdir=\) is empty"):
        extract_to([clip], " ")
    (tmp_path / "empty").mkdir()
    with pytest.raises(mtanno.MtannoError, match=r"no \.amc, \.bvh or \.c3d files"):
        extract_to([tmp_path / "empty"], tmp_path / "new" / "out")
    bad = tmp_path / "bad.amc"
    bad.write_text("not a motion\n")
    assert extract_to([bad], tmp_path / "new" / "out").failed
    assert not (tmp_path / "new").exists()
    # the options: an up-to-date output skipped, rewritten with force; bad values refused
    # when the options are made
    seen = []
    again = extract_to([clip], tmp_path / "f", ExtractOptions(force=False),
                       progress=lambda o: seen.append(o.status))
    assert again.line().startswith("0 written") and seen == ["skipped"]
    forced = extract_to([clip], tmp_path / "f", options=ExtractOptions(force=True, n_jobs=2))
    assert forced.line().startswith("1 written")
    for bad_options, message in ((dict(feature_set="ak41"), "unknown feature set 'ak41'"),
                                 (dict(up="x"), "up axis must be one of y, z"),
                                 (dict(n_jobs=0), r"n_jobs= must be a positive integer")):
        with pytest.raises(mtanno.MtannoError, match=message):
            ExtractOptions(**bad_options)
