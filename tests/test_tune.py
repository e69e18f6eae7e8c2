"""``mtanno tune`` (issue 10) on the synthetic test world: deterministic for a seed, its
configuration round-trips through ``annotate --classes``, it opens no file outside its
training inputs, it scores what annotate does; bad input gives one line."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from world import assert_one_line, cli

from mtanno.annotate import ClassConfig, label_document, load_class_config
from mtanno.errors import MtannoError
from mtanno.evaluation.metrics import evaluate_annotations
from mtanno.labels.segments import Segment
from mtanno.templates.training import collect_sources
from mtanno.tuning import METHODS, TuneOptions, tune, tune_files, write_tuned
from mtanno.tuning.cv import HeldOut, make_folds
from mtanno.tuning.score import count
from mtanno.tuning.search import Params, Tuner
from mtanno.util.provenance import sha256_file


def _sources(world):
    return collect_sources(manifest=world.manifest, features_dir=world.feats, split="train")


def _config_body(path: Path) -> str:
    """The configuration without its first comment line (it holds the command line)."""
    return path.read_text().split("\n", 1)[1]


def test_tune_is_deterministic_for_a_seed(world, tmp_path):
    a = tune(_sources(world), world.mt, TuneOptions(seed=3, n_jobs=1))
    b = tune(_sources(world), world.mt, TuneOptions(seed=3, n_jobs=2))
    assert a.params == b.params and a.steps == b.steps
    for d, r in (("a", a), ("b", b)):
        (tmp_path / d).mkdir()
        write_tuned(tmp_path / d / "t.toml", r)
    assert (tmp_path / "a/t.toml").read_text() == (tmp_path / "b/t.toml").read_text()
    for f in sorted((tmp_path / "a/t.templates").glob("*.json")) if a.extra_templates else []:
        assert f.read_bytes() == (tmp_path / "b/t.templates" / f.name).read_bytes()
    assert (tmp_path / "a/t.verify.parquet").read_bytes() == \
        (tmp_path / "b/t.verify.parquet").read_bytes()


def test_tune_options_are_checked_when_made():
    """:class:`TuneOptions` refuses bad values when it is made, naming the option, and keeps
    the methods in :data:`METHODS` order."""
    assert TuneOptions(methods=list(reversed(METHODS))).methods == METHODS
    assert TuneOptions(background=["a"], evidence=["cost"]).background == ("a",)
    for bad, message in ((dict(methods=["magic"]), "unknown method"),
                         (dict(documents="mixed"), r"unknown documents= 'mixed'"),
                         (dict(unknown_weight=math.inf), "unknown weight must be a finite"),
                         (dict(verify="eyes"), r"unknown verify= 'eyes'"),
                         (dict(evidence=()), r"evidence= must name some of"),
                         (dict(evidence=["luck"]), r"evidence= must name some of"),
                         (dict(seed=-1), r"seed= must be an integer ≥ 0"),
                         (dict(n_jobs=0), r"n_jobs= must be an integer ≥ 1")):
        with pytest.raises(MtannoError, match=message):
            TuneOptions(**bad)


def test_tune_with_keyframes_matches_inside_their_windows(world, tmp_path):
    """tune --keyframes: held-out documents matched only inside the queries' windows (as
    annotate --keyframes does); the same file whatever --jobs is, it lists the queries
    among its inputs, and annotate reads it back with the same queries."""
    kf = tmp_path / "kf"
    r = cli("learn-keyframes", "--mt", world.mt, "--manifest", world.manifest,
            "--features-dir", world.feats, "--split", "train", "--method", "hard", "-o", kf,
            "-q")
    assert r.exit_code == 0, r.output
    train = ["--manifest", world.manifest, "--features-dir", world.feats, "--split", "train"]
    for jobs in ("1", "2"):
        (tmp_path / f"j{jobs}").mkdir()
        r = cli("tune", "--mt", world.mt, "--keyframes", kf, *train, "-o",
                tmp_path / f"j{jobs}" / "t1.toml", "--jobs", jobs, "-q")
        assert r.exit_code == 0, r.output
    assert _config_body(tmp_path / "j1/t1.toml") == _config_body(tmp_path / "j2/t1.toml")
    (tmp_path / "j1/t1.toml").rename(tmp_path / "t1.toml")
    (tmp_path / "j1/t1.verify.parquet").rename(tmp_path / "t1.verify.parquet")
    text = (tmp_path / "t1.toml").read_text()
    assert all(str(q) in text for q in sorted(kf.glob("*.json")))
    r = cli("annotate", "--mt", world.mt, "--classes", tmp_path / "t1.toml", "--keyframes", kf,
            world.docfeats, "-o", tmp_path / "a.csv")
    assert r.exit_code == 0, r.output


def test_tuned_configuration_round_trips_through_annotate(world, tmp_path):
    cfg_path = tmp_path / "tuned.toml"
    r = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
            world.feats, "--split", "train", "-o", cfg_path, "--seed", "1", "-q")
    assert r.exit_code == 0, r.output
    cfg = load_class_config(cfg_path)
    # the API's run (tune_files) writes the command's configuration, and says where the
    # extra templates went
    api = tmp_path / "api" / "tuned.toml"
    api.parent.mkdir()
    result = tune_files([], world.mt, api, TuneOptions(seed=1), manifest=world.manifest,
                        features_dir=world.feats, split="train")
    assert _config_body(api) == _config_body(cfg_path)
    assert result.extra_folder == (tmp_path / "api" / "tuned.templates" if result.extra_templates
                                   else None)
    want = result.params.config()
    for key in ("default_tau", "tau", "resolve", "refine", "slack", "frame_weight",
                "segment_cost", "delta", "reject", "default_reject"):
        assert getattr(cfg, key) == getattr(want, key), key
    assert set(cfg.templates) == set(result.extra_templates)
    out = tmp_path / "a.csv"
    r = cli("annotate", "--mt", world.mt, "--classes", cfg_path, world.docfeats, "-o", out)
    assert r.exit_code == 0, r.output
    prov = json.loads((tmp_path / "a.csv.meta.json").read_text())
    assert prov["delta"] == cfg.delta
    assert prov.get("methods", {}).get("resolve") == cfg.resolve or not cfg.resolve
    # the configuration's text is what class_config_text makes of what it holds
    assert "[decoder]" in cfg_path.read_text() and "cross-validated" in cfg_path.read_text()
    # it names the templates it was tuned with; annotating with those gives no warning
    assert cfg.tuned_with == {p.stem: sha256_file(p) for p in world.mt.glob("*.json")}
    assert "warning" not in r.output


def test_annotate_warns_when_the_templates_are_not_those_tuned_with(world, tmp_path):
    cfg_path = tmp_path / "tuned.toml"
    assert cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
               world.feats, "--split", "train", "-o", cfg_path, "-q").exit_code == 0
    mt2 = world.copy(world.mt, tmp_path / "mt2")
    changed = sorted(mt2.glob("*.json"))[0]
    changed.write_text(changed.read_text() + "\n")  # same template, another file
    r = cli("annotate", "--mt", mt2, "--classes", cfg_path, world.docfeats,
            "-o", tmp_path / "a.csv", "-q")
    assert r.exit_code == 0, r.output
    warnings = [x for x in r.output.splitlines() if "warning" in x]
    assert warnings == [f"annotate: warning: the template(s) of {changed.stem} are not those "
                        f"{cfg_path} was tuned with (SHA-256 in its [tuned_with]): its "
                        f"thresholds may not suit them; run mtanno tune again"]
    text = cfg_path.read_text()
    untuned = sorted(world.mt.glob("*.json"))[-1].stem
    (tmp_path / "u.toml").write_text("\n".join(x for x in text.splitlines()
                                               if not x.startswith(f"{untuned} = ")) + "\n")
    r = cli("annotate", "--mt", world.mt, "--classes", tmp_path / "u.toml", world.docfeats,
            "-o", tmp_path / "b.csv", "-q")
    assert r.exit_code == 0, r.output
    assert [x for x in r.output.splitlines() if "warning" in x] == [
        f"annotate: warning: the class(es) {untuned} are not in the [tuned_with] of "
        f"{tmp_path / 'u.toml'}: tune did not see their templates"]
    # a hand-written configuration (no [tuned_with]) is never warned about
    (tmp_path / "h.toml").write_text("[tau]\ndefault = 0.1\n")
    r = cli("annotate", "--mt", mt2, "--classes", tmp_path / "h.toml", world.docfeats,
            "-o", tmp_path / "c.csv", "-q")
    assert r.exit_code == 0 and "warning" not in r.output


def test_methods_can_be_disabled_and_ablated(world, tmp_path):
    r = tune(_sources(world), world.mt, TuneOptions(seed=0, ablation=True))
    assert set(r.ablation) == {f"without-{m}" for m in METHODS} | {"none"}
    none = r.ablation["none"].params
    assert not none.resolve and not none.refine and none.frame_weight == 0
    assert none.delta == 0.05 and len(set(none.tau.values())) == 1 and not none.reject
    assert not r.ablation["none"].extra_templates and r.ablation["none"].methods == []
    assert not r.ablation["without-resolve"].params.resolve
    assert r.ablation["without-delta"].params.delta == 0.05
    assert not r.ablation["without-reject"].params.reject
    assert r.ablation["without-frames"].params.frame_weight == 0
    assert r.ablation["without-segments"].params.segment_cost == 0
    assert none.segment_cost == 0
    assert not r.ablation["without-templates"].extra_templates
    assert len(set(r.ablation["without-tau"].params.tau.values())) == 1
    # the search with everything disabled is what tune finds with no methods at all
    assert tune(_sources(world), world.mt, TuneOptions(methods=[], seed=0)).params == none
    with pytest.raises(MtannoError, match="unknown method"):
        TuneOptions(methods=["magic"])
    r2 = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
             world.feats, "--split", "train", "-o", tmp_path / "t.toml", "--disable", "resolve",
             "--disable", "templates", "-q")
    assert r2.exit_code == 0, r2.output
    cfg = load_class_config(tmp_path / "t.toml")
    assert not cfg.resolve and not cfg.templates


_AUDIT = r"""
import json, sys
opened = []
def hook(event, args):
    if event == "open" and isinstance(args[0], str):
        opened.append([args[0], str(args[1])])
sys.addaudithook(hook)
from mtanno.cli import main
try:
    main(sys.argv[2:], prog_name="mtanno")
except SystemExit as exc:
    code = exc.code
with open(sys.argv[1], "w") as f:
    json.dump({"code": code, "opened": opened}, f)
"""


@pytest.mark.parametrize("mode", ["manifest", "truth"])
def test_tune_reads_only_its_training_inputs(world, tmp_path, mode):
    out = tmp_path / "tuned.toml"
    if mode == "manifest":
        args = ["--manifest", world.manifest, "--features-dir", world.feats, "--split", "train"]
        allowed = {str(world.manifest), *(s.path for s in _sources(world))}
    else:  # the composed documents and their truth (the world's dev actor)
        args = ["--truth", world.truth, world.docfeats]
        allowed = {str(world.truth), f"{world.truth}.meta.json", *map(str, world.doc_files)}
    allowed |= {str(p) for p in world.mt.glob("*.json")}
    log = tmp_path / "opened.json"
    r = subprocess.run([sys.executable, "-c", _AUDIT, str(log), "tune", "--mt", str(world.mt),
                        *map(str, args), "-o", str(out), "-q"], capture_output=True, text=True)
    got = json.loads(log.read_text())
    assert got["code"] in (0, None), r.stderr
    root = str(world.root)
    read = {p for p, m in got["opened"] if p.startswith(root) and "r" in m and "+" not in m}
    assert any(p.endswith(".parquet") for p in read), "no feature file seen (audit hook?)"
    assert read <= allowed, sorted(read - allowed)
    written = {p for p, m in got["opened"] if any(c in m for c in "wxa+")}
    assert not {p for p in written if p.startswith(root)}, "a file of the world was written"
    assert any(p.startswith(str(tmp_path)) for p in written)
    # the configuration names exactly the training files it was tuned on
    text = out.read_text()
    assert all(p in text for p in allowed if p.endswith(".parquet"))


def test_scores_equal_evaluate():
    names = ["a", "b", "c"]
    truth = [(0, 0, 9), (1, 10, 25), (0, 26, 30), (2, 31, 39)]
    out = [(0, 2, 12), (1, 13, 20), (1, 18, 27), (2, 35, 39), (0, 5, 6)]
    got = count(truth, out, n_labels=3, n_frames=40)
    rep = evaluate_annotations([Segment("d", a + 1, b + 1, names[p]) for p, a, b in truth],
                               [Segment("d", a + 1, b + 1, names[p]) for p, a, b in out]).as_dict()
    assert got.frame() == pytest.approx((rep["frame"]["P"], rep["frame"]["R"], rep["frame"]["F"]))
    assert got.segment() == pytest.approx((rep["segment"]["P"], rep["segment"]["R"],
                                           rep["segment"]["F"]))


def test_scores_refuse_segments_outside_the_labels_and_frames():
    """A negative label or frame would be taken from the end of the arrays without a word,
    one past them raise IndexError: both are refused, as are reversed segments."""
    from mtanno.tuning.score import covered_fraction

    truth = [(0, 0, 9), (1, 10, 25)]
    assert count(truth, [(1, 10, 39)], n_labels=3, n_frames=40).frame_correct == 16
    for bad in ([(3, 0, 5)], [(-1, 0, 5)], [(0, -3, 5)], [(0, 5, 40)], [(0, 6, 4)]):
        with pytest.raises(MtannoError, match=r"output segments need labels in 0\.\.2, "):
            count(truth, bad, n_labels=3, n_frames=40)
        with pytest.raises(MtannoError, match="truth segments need"):
            count(bad, truth, n_labels=3, n_frames=40)
    for bad in ([(0, 5)], [(0, 5, 6), (1, 2)]):
        with pytest.raises(MtannoError, match=r"must be \(label, first, last\) tuples"):
            count(truth, bad, n_labels=3, n_frames=40)
    assert covered_fraction([(0, 9)], [(1, 5, 20)], 40) == (5, 10)
    with pytest.raises(MtannoError, match="spans need 0 ≤ first ≤ last < 40"):
        covered_fraction([(30, 40)], [], 40)
    with pytest.raises(MtannoError, match="output segments need 0 ≤ first ≤ last < 40"):
        covered_fraction([(0, 9)], [(1, -5, 3)], 40)


def test_ignored_frames_are_neither_right_nor_wrong():
    """Frames of a class that has no template in a fold: output there is not scored, an
    output segment wholly inside them is not counted; the counts equal those of the
    documents with the ignored frames cut out when no segment spans the cut."""
    truth = [(0, 0, 9), (1, 20, 29)]
    ignore = np.zeros(30, bool)
    ignore[10:20] = True
    out = [(0, 2, 12), (1, 12, 16), (1, 18, 29)]
    got = count(truth, out, n_labels=2, n_frames=30, ignore=ignore)
    assert (got.frame_correct, got.frame_predicted, got.frame_support) == (18, 18, 20)
    assert (got.seg_correct, got.seg_predicted, got.seg_found, got.seg_support) == (2, 2, 2, 2)
    # cut out: (0, 2, 9), (1, 20, 29) on the 20 kept frames
    cut = count([(0, 0, 9), (1, 10, 19)], [(0, 2, 9), (1, 10, 19)], n_labels=2, n_frames=20)
    assert vars(cut) == vars(got)
    # without the mask, the same output is wrong on the ignored frames
    plain = count(truth, out, n_labels=2, n_frames=30)
    assert plain.frame_predicted == 28 and plain.seg_predicted == 3
    with pytest.raises(MtannoError, match="must not touch ignored frames"):
        count([(0, 5, 12)], out, n_labels=2, n_frames=30, ignore=ignore)
    with pytest.raises(MtannoError, match="boolean mask of 30 frames"):
        count(truth, out, n_labels=2, n_frames=30, ignore=ignore[:20])


def test_a_class_without_a_template_in_a_fold_is_an_unknown_motion_there():
    """Its held-out frames leave F1 and F2 alone and count in the unknown-class rate."""
    fold, prepared = _fold_data()
    fold.held_out.truth.append(("c", 0, 0))  # no template of c anywhere
    fold.held_out.truth[0] = ("a", 1, 14)
    only_ab = Tuner([fold], prepared, classes=["a", "b"], unknown_weight=0.0)
    fd = only_ab.folds[0]
    assert fd.absent == {"c": [(0, 0)]} and fd.ignore.sum() == 1
    assert all(only_ab.names[c] != "c" for c, _, _ in fd.truth)
    p = Params(delta=0.05, resolve=True, tau={"a": 0.5, "b": 0.5}, groups={"a": 2, "b": 1})
    ev = only_ab.evaluate(p, per_class=True)
    assert ev.counts.frame_support == 59
    segs = only_ab.fold_segments(fd, p, ["a", "b"])
    covered = any(a <= 0 <= b for _, a, b in segs)
    assert ev.per_class_unknown["c"] == (int(covered), 1)


def _fold_data(L=60):
    """One fold with two held-out documents and hand-made Δ curves of two classes (two
    templates of class a)."""
    from mtanno.tuning.cv import Fold

    def curve(matches):
        d, s = np.full(L, math.inf), np.full(L, -1, np.int64)
        for end, (a, v) in matches.items():
            d[end], s[end] = v, a
        return d, s, np.zeros(L)

    held = HeldOut(np.zeros((3, L), np.uint8), np.array([0, 30, L]), ["d1", "d2"],
                   [("a", 0, 14), ("b", 15, 29), ("b", 30, 44), ("a", 45, 59)])
    fold = Fold("f", [], held)
    match = {}
    for delta in (0.05,):
        match[(delta, 1, 0)] = curve({14: (1, 0.04), 59: (46, 0.09), 35: (31, 0.01)})
        match[(delta, 2, 0)] = curve({13: (0, 0.02)})
        match[(delta, 2, 1)] = curve({58: (47, 0.03)})
    prepared = {("f", "a"): {"groups": {1: 1, 2: 2}, "match": match},
                ("f", "b"): {"groups": {1: 1}, "match": {(0.05, 1, 0): curve(
                    {29: (16, 0.05), 44: (31, 0.02), 50: (40, 0.11)})}}}
    return fold, prepared


@pytest.mark.parametrize("resolve", [True, False])
def test_tuner_scores_what_annotate_does(resolve):
    fold, prepared = _fold_data()
    tuner = Tuner([fold], prepared, classes=["a", "b"], unknown_weight=0.0)
    p = Params(delta=0.05, resolve=resolve, refine=True, slack=2, tau={"a": 0.1, "b": 0.13},
               reject={"b": 0.1}, groups={"a": 2, "b": 1})
    got = tuner.fold_segments(tuner.folds[0], p, ["a", "b"])
    # annotate's way: per document, label_document on the same curves with the config
    cfg = ClassConfig(tau={"a": 0.1, "b": 0.13}, reject={"b": 0.1}, resolve=resolve,
                      refine=True, slack=2)
    want = []
    for a, b in ((0, 30), (30, 60)):
        names, arrays = [], []
        for cls, keys in (("a", [(1, 0), (2, 0), (2, 1)]), ("b", [(1, 0)])):
            for k in keys:
                d, s, _ = prepared[("f", cls)]["match"][(0.05, *k)]
                rel = np.where(s[a:b] >= 0, s[a:b] - a, -1)
                names.append(cls)
                arrays.append((cls, d[a:b], rel, None))
        rows, _, _ = label_document("x", names, iter(arrays), b - a, config=cfg)
        want += [(["a", "b"].index(r.label), r.start + a, r.end + a) for r in rows]
    assert sorted(got) == sorted(want)
    assert want  # the curves do label something


def test_folds_leave_one_performer_out(world):
    from mtanno.templates.training import load_examples

    examples = load_examples(_sources(world))
    folds = make_folds(examples, seed=0)
    assert [f.name for f in folds] == ["a", "b"]
    for f in folds:
        assert {e.performer for e in f.train} == {"a", "b"} - {f.name}
        assert all(e.performer == f.name for e in f.held_examples)
        # every held-out clip appears once per composition order, with exact truth
        lengths = sorted(e.X.shape[1] for e in f.held_examples) * 2
        assert sorted(b - a + 1 for _, a, b in f.held_out.truth) == sorted(lengths)
    sep = make_folds(examples, documents="separate", seed=0)
    assert all(len(f.held_out.names) == len(f.held_examples) for f in sep)


def test_tune_bad_input_one_line(world, tmp_path):
    base = ["tune", "--manifest", world.manifest, "--features-dir", world.feats,
            "--split", "train", "-o", tmp_path / "t.toml"]
    assert_one_line(cli(*base, "--mt", tmp_path / "none"), tmp_path / "none", codes=(2,))
    r = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
            world.feats, "--split", "nosuch", "-o", tmp_path / "t.toml")
    assert_one_line(r, world.manifest, codes=(2,))
    r = cli(*base, "--mt", world.mt, "--disable", "magic")
    assert r.exit_code == 2 and "magic" in r.output
    # the output may not be one of the inputs
    r = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
            world.feats, "--split", "train", "-o", world.manifest)
    assert_one_line(r, world.manifest, codes=(2,))
    assert not (tmp_path / "t.toml").exists()


def test_tune_without_examples_of_a_class(world, tmp_path):
    m = tmp_path / "m.csv"
    rows = world.manifest.read_text().splitlines()
    m.write_text("\n".join([rows[0]] + [r for r in rows[1:] if ",squat," not in r]) + "\n")
    r = cli("tune", "--mt", world.mt, "--manifest", m, "--features-dir", world.feats,
            "--split", "train", "-o", tmp_path / "t.toml")
    line = assert_one_line(r, "squat", codes=(2,))
    assert "no training examples of class(es) squat" in line


def test_tune_warns_about_classes_it_cannot_cross_validate(world, tmp_path):
    """A class whose examples all come from one performer: no fold scores it (its frames
    are an unknown motion where it is held out), and tune says so."""
    m = tmp_path / "m.csv"
    rows = world.manifest.read_text().splitlines()
    m.write_text("\n".join([rows[0]] + [r for r in rows[1:] if ",squat," not in r
                                         or r.split(",")[1] == "a"]) + "\n")
    r = cli("tune", "--mt", world.mt, "--manifest", m, "--features-dir", world.feats,
            "--split", "train", "-o", tmp_path / "t.toml", "-q")
    assert r.exit_code == 0, r.output
    assert "warning: class(es) squat could not be cross-validated" in r.output
    assert "squat: not cross-validated" in (tmp_path / "t.toml").read_text()
    r = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
            world.feats, "--split", "train", "-o", tmp_path / "all.toml", "-q")
    assert r.exit_code == 0 and "warning" not in r.output


def test_tune_names_truth_documents_without_a_feature_file(world, tmp_path):
    """As learn-mt and learn-keyframes: the truth table's documents that are not among the
    inputs are named in one note (none with -q), and their segments are not used."""
    docs = world.doc_files
    given, left = docs[:1], sorted(p.stem for p in docs[1:])
    r = cli("tune", "--mt", world.mt, "--truth", world.truth, *given, "-o", tmp_path / "t.toml")
    assert r.exit_code == 0, r.output
    notes = [x for x in r.output.splitlines() if "are ignored" in x]
    assert notes == [f"tune: note: the truth table's segments of {len(left)} document(s) "
                     f"without a feature file among the inputs are ignored: "
                     f"{', '.join(left[:10])}" + (f" and {len(left) - 10} more"
                                                  if len(left) > 10 else "")]
    text = (tmp_path / "t.toml").read_text()
    assert all(str(p) in text for p in given) and not any(str(p) in text for p in docs[1:])
    r = cli("tune", "--mt", world.mt, "--truth", world.truth, *given, "-o", tmp_path / "q.toml",
            "-q")
    assert r.exit_code == 0 and r.output == ""


def test_time_scaled_template_keeps_the_nearest_columns():
    from mtanno.templates.model import MotionTemplate
    from mtanno.templates.tempo import scale_columns, time_scaled

    assert scale_columns(10, 0.6).tolist() == [0, 2, 4, 5, 7, 9]
    assert scale_columns(4, 1.5).tolist() == [0, 1, 1, 2, 3, 3]
    assert scale_columns(3, 0.1).tolist() == [0, 2]  # never fewer than 2 columns
    V = np.array([[0.0, 1.0, 0.5, 1.0, 0.0], [1.0, 1.0, 0.0, 0.0, 0.25]])
    mt = MotionTemplate("c", ["f1", "f2"], V, np.array([1.0, 2.0, 1.0, 0.5, 1.5]),
                        params={"examples": 3})
    s = time_scaled(mt, 0.6)
    assert s.values.tolist() == V[:, [0, 2, 4]].tolist()
    assert s.weights.tolist() == [1.0, 1.0, 1.5]
    assert s.class_name == "c" and s.params == {"examples": 3, "time_scale": 0.6}
    assert mt.values.shape == (2, 5) and "time_scale" not in mt.params  # a copy
    with pytest.raises(Exception, match="factor"):
        time_scaled(mt, 0.0)


def test_time_scaled_template_matches_a_fast_performance(world):
    """A performance three times faster than the training examples is shorter than half
    the template, so the template cannot match it (DTW steps (1,1), (1,2), (2,1)); its
    copy at 0.6 times the length can, and prepare_fold_class matches both."""
    from mtanno.templates.match import PreparedTemplate, pack_document
    from mtanno.templates.model import quantize
    from mtanno.templates.tempo import time_scaled
    from mtanno.templates.training import load_examples
    from mtanno.tuning.search import prepare_fold_class

    examples = load_examples(_sources(world))
    cls = examples[0].class_name
    train = [e for e in examples if e.class_name == cls]
    fast = np.ascontiguousarray(train[0].X[:, ::3])
    offsets = np.array([0, fast.shape[1]])
    got = prepare_fold_class(cls, train, fast, offsets, deltas=[0.05], groups=(), learn={},
                             spans=None, evidence=True, scales=(0.6, 1.6))
    m = got["match"]
    assert set(m) == {(0.05, 1, 0), (0.05, 0, 0.6), (0.05, 0, 1.6)}
    assert m[(0.05, 1, 0)][2] is not None and m[(0.05, 0, 0.6)][2] is None
    assert np.isinf(m[(0.05, 1, 0)][0]).all()
    assert np.isfinite(m[(0.05, 0, 0.6)][0][-1])
    from mtanno.templates.learn import learn_template

    q = quantize(time_scaled(learn_template(train, class_name=cls), 0.6), 0.05)
    d, _ = PreparedTemplate(q.values, q.weights).run(pack_document(fast, fast.shape[0]),
                                                     offsets)
    np.testing.assert_array_equal(m[(0.05, 0, 0.6)][0], d)


def _with_scaled(prepared, L=60):
    """The fold data of :func:`_fold_data` with time-scaled curves of class a: the copy at
    0.6 finds the second document's a (frames 45–59), which no template of a reaches."""
    match = prepared[("f", "a")]["match"]
    for k in (1, 2):
        d, s, e = match[(0.05, k, 0)]
        d = d.copy()
        d[59] = math.inf
        match[(0.05, k, 0)] = (d, s, e)
    d, s = np.full(L, math.inf), np.full(L, -1, np.int64)
    d[59], s[59] = 0.02, 45
    match[(0.05, 0, 0.6)] = (d, s, None)
    d2 = np.full(L, math.inf)
    d2[20], s2 = 0.01, np.where(np.arange(L) == 20, 16, -1)
    match[(0.05, 0, 1.6)] = (d2, s2, None)  # a false match inside b
    for f in (0.6, 1.6):  # b's copies match nothing
        prepared[("f", "b")]["match"][(0.05, 0, f)] = (np.full(L, math.inf),
                                                       np.full(L, -1, np.int64), None)
    return prepared


@pytest.mark.parametrize("resolve", [True, False])
def test_tuner_matches_time_scaled_templates_as_annotate_does(resolve):
    fold, prepared = _fold_data()
    prepared = _with_scaled(prepared)
    tuner = Tuner([fold], prepared, classes=["a", "b"], unknown_weight=0.0)
    p = Params(delta=0.05, resolve=resolve, tau={"a": 0.1, "b": 0.13},
               groups={"a": 1, "b": 1}, scales={"a": (0.6,)}, frame_weight=0.5 * resolve)
    assert tuner._templates(tuner.folds[0], "a", p) == [(1, 0), (0, 0.6)]
    got = tuner.fold_segments(tuner.folds[0], p, ["a", "b"])
    cfg = ClassConfig(tau={"a": 0.1, "b": 0.13}, resolve=resolve,
                      frame_weight=0.5 * resolve)
    want = []
    for a, b in ((0, 30), (30, 60)):
        names, arrays = [], []
        for cls, k in (("a", (1, 0)), ("a", (0, 0.6)), ("b", (1, 0))):
            d, s, e = prepared[("f", cls)]["match"][(0.05, *k)]
            ev = prepared[("f", cls)]["match"][(0.05, 1, 0)][2]  # a copy's evidence
            names.append(cls)
            arrays.append((cls, d[a:b], np.where(s[a:b] >= 0, s[a:b] - a, -1), ev[a:b]))
        rows, _, _ = label_document("x", names, iter(arrays), b - a, config=cfg)
        want += [(["a", "b"].index(r.label), r.start + a, r.end + a) for r in rows]
    assert sorted(got) == sorted(want)
    assert (0, 45, 59) in got


def test_search_keeps_a_time_scaled_template_only_where_it_pays():
    fold, prepared = _fold_data()
    tuner = Tuner([fold], _with_scaled(prepared), classes=["a", "b"], unknown_weight=0.0)
    params, ev, steps = tuner.search(delta=0.05, methods=["templates", "resolve"])
    assert params.scales == {"a": (0.6,)}  # not 1.6: its match lies inside a b
    assert any(s.startswith("time-scaled templates a ×0.6:") for s in steps)
    without = tuner.search(delta=0.05, methods=["resolve"])[1]
    assert ev.J > without.J


def test_tune_writes_the_time_scaled_copies_of_the_class_templates(world, tmp_path,
                                                                   monkeypatch):
    """The chosen tempo factors become further templates of the class: its template from
    MT/ time-scaled, written beside the configuration and read back by annotate."""
    from mtanno.templates.store import load_template, load_template_folder
    from mtanno.templates.tempo import time_scaled

    original = Tuner.search

    def search(self, **kw):
        p, ev, steps = original(self, **kw)  # (tempo not matched: templates are off)
        return p.copy(scales={self.classes[0]: (0.6, 1.6)}), ev, steps

    monkeypatch.setattr(Tuner, "search", search)
    r = tune(_sources(world), world.mt,
             TuneOptions(seed=0, methods=[m for m in METHODS if m != "templates"],
                         confidence=False))  # (the scales were not matched in the folds)
    c = r.classes[0]
    mt = load_template_folder(world.mt)[c]
    assert [x.params["time_scale"] for x in r.extra_templates[c]] == [0.6, 1.6]
    for got, f in zip(r.extra_templates[c], (0.6, 1.6)):
        want = time_scaled(mt, f)
        np.testing.assert_array_equal(got.values, want.values)
        np.testing.assert_array_equal(got.weights, want.weights)
    cfg_path = tmp_path / "t.toml"
    write_tuned(cfg_path, r)
    cfg = load_class_config(cfg_path)
    files = cfg.template_paths()[c]
    assert [load_template(f).params["time_scale"] for f in files] == [0.6, 1.6]
    out = tmp_path / "a.csv"
    res = cli("annotate", "--mt", world.mt, "--classes", cfg_path, world.docfeats, "-o", out)
    assert res.exit_code == 0, res.output
    prov = json.loads((tmp_path / "a.csv.meta.json").read_text())
    assert sum(str(f) in json.dumps(prov) for f in files) == 2


def test_matched_columns_are_what_the_matcher_expands_to():
    from mtanno.templates.match import PreparedTemplate
    from mtanno.templates.tempo import matched_columns

    w = np.array([0.4, 1.5, 2.49, 2.5, 1.0])
    assert matched_columns(w) == 1 + 2 + 2 + 3 + 1
    V = np.array([[0.0, 1.0, 0.5, 1.0, 0.0]])
    assert PreparedTemplate(V, w).K == matched_columns(w)


@pytest.mark.parametrize("cost, kept, text", [(3, {"a": (0.6,)}, "a ×0.6"), (4, {}, "none")])
def test_time_scaled_copies_stay_within_their_column_budget(cost, kept, text):
    """All copies together may have 15 % of the templates' columns (here 3 of 20): a copy
    of 4 columns is not tried, however much it would raise J."""
    fold, prepared = _fold_data()
    columns = {"a": 10, "b": 10, ("a", 0.6): cost, ("a", 1.6): 16, ("b", 0.6): 1,
               ("b", 1.6): 1}
    tuner = Tuner([fold], _with_scaled(prepared), classes=["a", "b"], unknown_weight=0.0,
                  columns=columns)
    params, _, steps = tuner.search(delta=0.05, methods=["templates", "resolve"])
    assert params.scales == kept
    used = cost if kept else 0
    assert any(s.startswith(f"time-scaled templates {text} ({used} of 3 columns)")
               for s in steps), steps


def test_annotate_skips_the_evidence_that_a_copy_cannot_change():
    """A time-scaled copy's columns are its template's, so annotate does not compute its
    frame evidence; the rows equal those with every template's evidence taken."""
    from mtanno.annotate import ClassModel, annotate_document, class_deltas, evidence_covered
    from mtanno.annotate.decode import frame_evidence
    from mtanno.templates.match import pack_document
    from mtanno.templates.tempo import scale_columns

    rng = np.random.default_rng(3)
    f, K = 12, 20

    def template():
        V = rng.integers(0, 2, size=(f, K)).astype(float)
        V[rng.random((f, K)) < 0.3] = 0.5
        return V

    Va, Vb = template(), template()
    idx = scale_columns(K, 0.6)
    models = [ClassModel("a", Va, np.ones(K)), ClassModel("b", Vb, np.ones(K)),
              ClassModel("a", Va[:, idx].copy(), np.ones(len(idx))),
              ClassModel("a", Va.copy(), np.ones(K)), ClassModel("b", Va, np.ones(K))]
    assert evidence_covered(models) == {2, 3}  # the copy, and the duplicate after the first
    X = np.concatenate([Va, Vb[:, ::2], Va[:, ::2], Vb], axis=1)
    X = np.where(X == 0.5, rng.integers(0, 2, size=X.shape), X).astype(np.uint8)
    cfg = ClassConfig(default_tau=0.3, resolve=True, refine=True, frame_weight=0.5)
    rows, _, _ = annotate_document("d", X, models, config=cfg)
    packed = pack_document(X, f)
    full = [(c.name, d, s, frame_evidence(packed, c.values))
            for c, (d, s) in zip(models, class_deltas(X, models))]
    want, _, _ = label_document("d", [c.name for c in models], iter(full), X.shape[1],
                                config=cfg)
    assert rows == want and rows
    with pytest.raises(MtannoError, match="evidence of a template of every class"):
        label_document("d", ["a"], iter([("a", full[0][1], full[0][2], None)]), X.shape[1],
                       config=cfg)


# ------------------------------------------------------------------ issue 34: size


def test_the_search_matches_all_templates_only_at_the_delta_it_chose(world, monkeypatch):
    """tune keeps template (1, 0) at every δ and the other templates only at the δ the
    search chose (fetched then), and finds what a tuner given everything at once finds."""
    from mtanno.tuning import run
    from mtanno.tuning.search import GROUPS, prepare_fold_class

    seen = {}
    original = Tuner.search

    def search(self, **kw):
        got = original(self, **kw)
        seen["tuner"], seen["result"] = self, got
        return got

    monkeypatch.setattr(Tuner, "search", search)
    result = tune(_sources(world), world.mt, TuneOptions(seed=2, n_jobs=1, confidence=False))
    monkeypatch.setattr(Tuner, "search", original)
    tuner = seen["tuner"]
    chosen = result.params.delta
    for fd in tuner.folds:
        for delta, _c, k, i in fd.match:
            assert delta == chosen or (k, i) == (1, 0)
        assert {(k, i) for d, c, k, i in fd.match if d == chosen and c == fd.classes[0]} \
            > {(1, 0)}
    # the same search with every template matched at every δ beforehand
    templates, layout, examples, _ = run._tune_inputs(_sources(world), world.mt, None)
    folds = make_folds(examples, seed=2)
    learn = {c: run._learn_params(templates[c]) for c in templates}
    prepared = {}
    for f in folds:
        for c in templates:
            train = [e for e in f.train if e.class_name == c]
            if train:
                prepared[(f.name, c)] = prepare_fold_class(
                    c, train, f.held_out.X, f.held_out.offsets, deltas=run._deltas(METHODS, {}),
                    groups=GROUPS, learn=learn[c], spans=None, evidence=True,
                    scales=run.TEMPO_SCALES)
    columns = {k: v for k, v in (tuner.columns or {}).items()}
    whole = Tuner(folds, prepared, classes=list(templates), columns=columns)
    params, ev, steps = whole.search(delta=0.05)
    assert params == result.params and steps == result.steps
    assert ev.J == result.evaluation.J


def _old_subset(fd, docs):
    """The materialised subset of a fold (what tune built before issue 34): every array
    of every template sliced up front."""
    idx = np.concatenate([np.arange(fd.offsets[d], fd.offsets[d + 1]) for d in docs])
    lengths = [int(fd.offsets[d + 1] - fd.offsets[d]) for d in docs]
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    shift = np.concatenate([np.full(n, offsets[j] - fd.offsets[d])
                            for j, (d, n) in enumerate(zip(docs, lengths))])
    return {key: (d[idx], np.where(st[idx] >= 0, st[idx] + shift, -1),
                  None if ev is None else ev[idx]) for key, (d, st, ev) in fd.match.items()}


def test_a_class_left_out_reads_its_documents_from_the_fold_arrays():
    """The run with a class left out sees the fold's arrays sliced to the documents that
    hold the class (no copies kept), exactly the arrays a materialised subset held."""
    from mtanno.tuning.folddata import _sub_arrays

    fold, prepared = _fold_data()
    fold.held_out.X = np.zeros((3, 90), np.uint8)
    fold.held_out.offsets = np.array([0, 30, 60, 90])
    fold.held_out.names = ["d1", "d2", "d3"]
    fold.held_out.truth = [("a", 0, 14), ("b", 15, 29), ("b", 30, 44), ("b", 45, 59),
                           ("a", 60, 89)]
    for got in prepared.values():  # Δ curves of 90 frames with matches in every document
        for key, (d, s, ev) in got["match"].items():
            d2, s2 = np.concatenate([d, d[:30]]), np.concatenate([s, np.where(s[:30] >= 0,
                                                                             s[:30] + 60, -1)])
            got["match"][key] = (d2, s2, np.concatenate([ev, ev[:30]]))
    tuner = Tuner([fold], prepared, classes=["a", "b"])
    fd = tuner.folds[0]
    sub = fd.hidden["a"]
    assert sub is not fd and sub.n_frames == 60 and list(sub.offsets) == [0, 30, 60]
    old = _old_subset(fd, [0, 2])
    for key, (d, s, ev) in old.items():
        d2, s2, ev2 = sub.match[key]
        assert np.array_equal(d, d2) and np.array_equal(s, s2) and np.array_equal(ev, ev2)
    p = Params(delta=0.05, resolve=True, tau={"a": 0.5, "b": 0.5}, groups={"a": 2, "b": 1},
               frame_weight=0.3)
    for want, got in zip(tuner.decoder_arrays(sub, p), _sub_arrays(sub, tuner.decoder_arrays(fd, p))):
        assert np.array_equal(want, got)
    # the run without a class is scored once for the candidates that differ only in it
    ev = tuner.evaluate(p, per_class=True)
    cached = dict(tuner._hidden)
    p2 = p.copy(tau={"a": 0.3, "b": 0.5})
    tuner.evaluate(p2)
    assert len(tuner._hidden) == len(cached) + 1  # b's run again, a's (without a) reused
    tuner._hidden.clear()
    assert tuner.evaluate(p, per_class=True) == ev


def test_learning_subset_spreads_over_the_performers(world):
    from mtanno.templates.training import load_examples
    from mtanno.tuning.cv import learning_subset

    examples = load_examples(_sources(world))
    one = [e for e in examples if e.class_name == examples[0].class_name]
    assert learning_subset(one, None) == list(range(len(one)))
    assert learning_subset(one, 0) == list(range(len(one)))
    assert learning_subset(one, len(one)) == list(range(len(one)))
    got = learning_subset(one, 2, seed=1)
    assert len(got) == 2 and got == sorted(got)
    assert len({one[i].performer for i in got}) == 2  # one of each performer first
    assert learning_subset(one, 2, seed=1) == got
    # the same draw in a fold that holds only some of the examples: a nested order
    part = [e for e in one if e.performer == one[got[0]].performer]
    assert [part[i] for i in learning_subset(part, 1, seed=1)] == [one[got[0]]]
    with pytest.raises(MtannoError, match="max examples"):
        learning_subset(one, -1)


def test_tune_learns_each_template_from_at_most_max_examples(world, monkeypatch, tmp_path):
    """--max-examples bounds the examples every template of the search is learned from,
    and the configuration says so."""
    from mtanno.tuning import run

    sizes = []
    original = run.learn_fold_class

    def learn_fold_class(cls, train, **kw):
        sizes.append(len(train))
        return original(cls, train, **kw)

    monkeypatch.setattr(run, "learn_fold_class", learn_fold_class)
    r = tune(_sources(world), world.mt,
             TuneOptions(seed=1, n_jobs=1, confidence=False, max_examples=1))
    assert sizes and max(sizes) == 1 and r.max_examples == 1
    write_tuned(tmp_path / "t.toml", r)
    assert "templates learned from at most 1 examples each" in (tmp_path / "t.toml").read_text()
    sizes.clear()
    r = tune(_sources(world), world.mt,
             TuneOptions(seed=1, n_jobs=1, confidence=False, max_examples=0))
    assert max(sizes) > 1 and r.max_examples is None


@pytest.mark.parametrize("jobs", [1, 2])
def test_the_best_candidate_is_found_without_scoring_every_run(jobs):
    """_best scores the runs with a class left out only while a candidate can still win,
    and returns what scoring everything returns: the first of the highest J, or nothing
    when none beats the current point by eps."""
    fold, prepared = _fold_data()
    fold.held_out.truth.append(("c", 0, 0))
    tuner = Tuner([fold], prepared, classes=["a", "b"], unknown_weight=0.5, jobs=jobs)
    base = Params(delta=0.05, resolve=True, tau={"a": 0.5, "b": 0.5}, groups={"a": 1, "b": 1})
    cands = [base.copy(tau={"a": ta, "b": tb}, resolve=r, groups={"a": g, "b": 1})
             for ta in (0.05, 0.1, 0.3, 0.5) for tb in (0.05, 0.13, 0.5) for r in (True, False)
             for g in (1, 2)]
    cands += cands[:5]  # equals later in the list: the first must win
    full = [tuner.evaluate(c) for c in cands]
    top = max(e.J for e in full)
    first = next(i for i, e in enumerate(full) if e.J == top)
    runs = []
    if jobs == 1:  # count the runs scored (in this process)
        segments = tuner.fold_segments
        tuner.fold_segments = lambda fd, p, classes, arrays=None: runs.append(len(classes)) or \
            segments(fd, p, classes, arrays)
    try:
        tuner._hidden.clear()
        got, ev = tuner._best(cands)
        assert got == cands[first] and ev == full[first]
        if jobs == 1:  # every run with all classes, and far fewer with one left out
            assert runs.count(2) == len(cands) and 0 < runs.count(1) < len(cands)
        for current, eps in ((full[first], 0.0), (full[-1], 0.0), (full[-1], 0.01)):
            got, ev = tuner._best(cands, current, eps)
            if top > current.J + eps:
                assert got == cands[first] and ev == full[first]
            else:
                assert got is None and ev is None
    finally:
        tuner._close_pool()


# ------------------------------------------------------------------ issue 34: one thing


def test_a_configuration_folder_moves_and_is_renamed_as_one(world, tmp_path):
    """tune -o DIR/: the configuration, its extra templates and its bank in one folder,
    named relative to each other; moved and renamed it annotates as before; rewritten, it
    keeps no template of the earlier run; a folder of other files is refused."""
    import shutil

    from mtanno.templates.store import load_template_folder
    from mtanno.templates.tempo import time_scaled
    from mtanno.tuning.write import check_tuned_output

    r = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
            world.feats, "--split", "train", "-o", f"{tmp_path / 'cli'}/", "--seed", "1", "-q")
    assert r.exit_code == 0, r.output
    assert {p.name for p in (tmp_path / "cli").iterdir()} <= {"classes.toml", "templates",
                                                              "verify.parquet"}
    result = tune(_sources(world), world.mt, TuneOptions(seed=1, n_jobs=1))
    mts = load_template_folder(world.mt)
    cls = sorted(mts)[0]
    result.extra_templates = {cls: [time_scaled(mts[cls], 0.6)]}  # a template to refer to
    out = tmp_path / "a" / "tuned"
    write_tuned(f"{out}/", result)
    assert {p.name for p in out.iterdir()} == {"classes.toml", "templates", "verify.parquet"}
    cfg = load_class_config(out)  # the folder itself
    assert cfg.path == str(out / "classes.toml") and cfg.confidence.bank_file == "verify.parquet"
    assert cfg.templates == {cls: [f"templates/{cls}.1.json"]}
    assert cfg.poses is False and cfg.feature_set == "mr06-ak40"  # the world has no poses
    first = tmp_path / "first.csv"
    assert cli("annotate", "--mt", world.mt, "--classes", out, world.docfeats, "-o",
               first, "-q").exit_code == 0
    moved = tmp_path / "b" / "renamed"
    moved.parent.mkdir()
    shutil.move(out, moved)
    again = tmp_path / "again.csv"
    r = cli("annotate", "--mt", world.mt, "--classes", moved, world.docfeats, "-o", again, "-q")
    assert r.exit_code == 0, r.output
    assert again.read_text() == first.read_text()
    # rewritten in place without extra templates: none of the earlier run stays
    result.extra_templates = {}
    write_tuned(f"{moved}/", result)
    assert not (moved / "templates").exists()
    assert "[templates]" not in (moved / "classes.toml").read_text()
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(MtannoError, match="folder of other files"):
        check_tuned_output(other)
    r = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
            world.feats, "--split", "train", "-o", other, "-q")
    assert r.exit_code == 2 and "folder of other files" in r.output
    assert_one_line(r, other)


def test_the_configuration_says_what_its_inputs_need(world, tmp_path):
    """[inputs] round trips; a bad one is one line naming it; a folder without
    classes.toml is not a configuration."""
    from mtanno.annotate import class_config_text

    cfg = ClassConfig(poses=True, feature_set="ak40")
    path = tmp_path / "c.toml"
    path.write_text(class_config_text(cfg))
    back = load_class_config(path)
    assert back.poses is True and back.feature_set == "ak40" and back.needs_poses
    for text, msg in (("[inputs]\nposes = 1\n", "poses must be true or false"),
                      ("[inputs]\nlegs = true\n", "unknown key 'legs' in \\[inputs\\]")):
        path.write_text(text)
        with pytest.raises(MtannoError, match=msg):
            load_class_config(path)
    with pytest.raises(MtannoError, match="no classes.toml in it"):
        load_class_config(tmp_path)


def test_features_follow_the_configuration(world, tmp_path):
    """features --classes CONFIG computes what the configuration's [inputs] need."""
    from mtanno.annotate import class_config_text
    from mtanno.features.store import read_features

    cfg = tmp_path / "c.toml"
    cfg.write_text(class_config_text(ClassConfig(poses=True, feature_set="ak40")))
    clip = sorted(world.clips.rglob("*.amc"))[0]
    r = cli("features", clip, "-o", tmp_path / "f", "--classes", cfg, "-q")
    assert r.exit_code == 0, r.output
    got = next((tmp_path / "f").glob("*.parquet"))
    assert read_features(got, poses=True).poses is not None
    r = cli("features", clip, "-o", tmp_path / "g", "--classes", cfg, "--feature-set",
            "mrc05", "-q")
    assert r.exit_code == 2 and "is not the feature set of the class configuration" in r.output
    assert_one_line(r, cfg)
