"""Plots (mtanno.plot, asserted on the plotted data with the Agg backend), ``mtanno show``,
``info --features``, ``mt plot`` and ``mtanno report`` (files, tables, confusion matrix, and
the page in a real browser)."""

from __future__ import annotations

import csv
import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from mtanno.annotate import Annotation
from mtanno.cli import main
from mtanno.features.store import write_features
from mtanno.labels.segments import Segment

matplotlib = pytest.importorskip("matplotlib", reason="the 'plot' extra is not installed")
matplotlib.use("Agg")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


# --- plot functions -------------------------------------------------------------------------

def test_plot_delta_draws_delta_with_gaps_and_tau():
    from mtanno.plot import plot_delta

    delta = np.array([np.inf, 0.3, 0.1, np.inf, 0.05])
    ax = plot_delta(delta, label="squat", tau=0.13)
    ax = plot_delta(delta * 2, label="kick", tau=0.13, ax=ax)
    x, y = ax.lines[0].get_data()
    assert x.tolist() == [1, 2, 3, 4, 5]
    assert np.array_equal(y, [np.nan, 0.3, 0.1, np.nan, 0.05], equal_nan=True)
    taus = [line for line in ax.lines if line.get_label() == "τ = 0.13"]
    assert len(taus) == 1 and taus[0].get_ydata()[0] == 0.13  # drawn once
    assert [line.get_label() for line in ax.lines] == ["squat", "τ = 0.13", "kick"]
    assert np.array_equal(ax.lines[2].get_ydata(), 2 * y, equal_nan=True)


def test_plot_template_features_confusion_timeline():
    from mtanno.plot import plot_confusion, plot_features, plot_template, plot_timeline
    from mtanno.templates.model import MotionTemplate

    mt = MotionTemplate("squat", ["a", "b"], np.array([[0.0, 0.5, 1.0], [1.0, 1.0, 0.2]]),
                        np.ones(3), feature_set="x")
    ax = plot_template(mt)
    assert np.array_equal(ax.images[0].get_array(), mt.values)
    assert [t.get_text() for t in ax.get_yticklabels()] == ["a", "b"]
    X = np.array([[0, 1, 1], [1, 0, 0]], np.uint8)
    ax = plot_features(X, ["F1 g:a", "F2 g:b"], first_frame=7)
    assert np.array_equal(ax.images[0].get_array(), X)
    assert ax.images[0].get_extent()[:2] == [6.5, 9.5]
    M = np.array([[5, 1], [0, 3]])
    ax = plot_confusion(M, ["squat", "none"])
    assert sorted(t.get_text() for t in ax.texts) == ["1", "3", "5"]
    assert np.allclose(ax.images[0].get_array(), [[5 / 6, 1 / 6], [0, 1]])
    ax = plot_timeline({"truth": [(1, 10, "squat")], "annotation": [(3, 8, "squat"),
                                                                     (6, 12, "kick")]},
                       n_frames=12)
    bars = [(c.get_paths()[0].vertices[:, 0].min(), c.get_paths()[0].vertices[:, 0].max())
            for c in ax.collections]
    assert bars == [(0.5, 10.5), (2.5, 8.5), (5.5, 12.5)]


def test_save_figure_formats(tmp_path):
    from mtanno.errors import MtannoError
    from mtanno.plot import plot_delta, save_figure

    ax = plot_delta(np.array([0.1, 0.2]))
    save_figure(ax, tmp_path / "d.png")
    save_figure(ax, tmp_path / "d.svg")
    assert (tmp_path / "d.png").read_bytes()[:4] == b"\x89PNG"
    assert b"<svg" in (tmp_path / "d.svg").read_bytes()[:500]
    with pytest.raises(MtannoError, match="must end in .png, .svg or .pdf"):
        save_figure(ax, tmp_path / "d.gif")


def test_missing_matplotlib_says_how_to_install(monkeypatch, tmp_path, world):
    import builtins

    real = builtins.__import__

    def no_mpl(name, *a, **k):
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ImportError(name)
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_mpl)
    r = run("mt", "plot", world.template, "-o", tmp_path / "t.png")
    assert r.exit_code == 2 and "pip install 'mtanno[plot]'" in r.output
    r = run("report", world.annotation, "--truth", world.truth, "-o", tmp_path / "rep")
    assert r.exit_code == 2 and "pip install 'mtanno[plot]'" in r.output
    assert not (tmp_path / "t.png").exists() and not (tmp_path / "rep").exists()


# --- feature inspection ---------------------------------------------------------------------

@pytest.fixture
def handmade(tmp_path):
    """A 6-frame feature file: knee features of a tiny squat, one always on, one never."""
    names = ["rknee_bent", "lknee_bent", "up", "never"]
    X = np.array([[0, 0, 1, 1, 1, 0],
                  [0, 1, 1, 1, 0, 0],
                  [1, 1, 1, 1, 1, 1],
                  [0, 0, 0, 0, 0, 0]], np.uint8)
    path = tmp_path / "tiny.parquet"
    write_features(path, X, names, np.arange(1, 24, 4),
                   {"analysis_fps": 30.0, "feature_set": "custom",
                    "feature_ids": ["F01", "F02", "F03", "F04"],
                    "groups": {"lower": ["rknee_bent", "lknee_bent"], "upper": ["up", "never"]}})
    return path


def test_info_features_lists_ids_names_groups(handmade):
    r = run("info", handmade, "--features")
    assert r.exit_code == 0
    assert r.output.splitlines() == ["id   name        group", "F01  rknee_bent  lower",
                                     "F02  lknee_bent  lower", "F03  up          upper",
                                     "F04  never       upper"]
    r = run("info", handmade.with_suffix(".amc"), "--features")
    assert r.exit_code == 2 and "--features goes with a feature file" in r.output


def test_show_text_timeline(handmade, tmp_path):
    r = run("show", handmade)
    assert r.exit_code == 0, r.output
    assert r.output.splitlines() == [
        "tiny: frames 1-6 of 6 at 30 Hz, 1 frame per column",
        "                      1",
        "F01 lower:rknee_bent  ..###.",
        "F02 lower:lknee_bent  .###..",
        "F03 upper:up          ######",
        "F04 upper:never       ......"]
    r = run("show", handmade, "--frames", "2:5", "--features", "lknee_bent,F01")
    assert r.output.splitlines()[2:] == ["F02 lower:lknee_bent  ###.",
                                         "F01 lower:rknee_bent  .###"]
    assert r.output.splitlines()[1].strip() == "2"
    # blocks of frames: '+' where the feature is on in part of the block
    r = run("show", handmade, "--width", "10")
    assert r.exit_code == 0
    from mtanno.info import text_timeline

    X = np.array([[0, 0, 1, 1, 1, 0]] * 1, np.uint8)
    assert text_timeline(X, ["k"], width=3) == ["   1", "k  .#+"]
    assert text_timeline(np.zeros((1, 25), np.uint8), ["k"], width=1)[1] == "k  ."
    r = run("show", handmade, "--features", "nope")
    assert r.exit_code == 2 and "unknown feature 'nope'" in r.output
    r = run("show", handmade, "--frames", "4:9")
    assert r.exit_code == 2 and "not a range inside 1:6" in r.output
    r = run("show", handmade, "--features", "F01,F02", "--plot", tmp_path / "k.png")
    assert r.exit_code == 0 and (tmp_path / "k.png").read_bytes()[:4] == b"\x89PNG"


def test_mt_plot(world, tmp_path):
    r = run("mt", "plot", world.template, "-o", tmp_path / "squat.svg", "--delta", "0.1")
    assert r.exit_code == 0, r.output
    assert b"<svg" in (tmp_path / "squat.svg").read_bytes()[:500]
    r = run("mt", "plot", world.template, "-o", world.template)
    assert r.exit_code == 2 and "would overwrite an input" in r.output


# --- report ---------------------------------------------------------------------------------

def test_confusion_matrix_counts_frames_with_none():
    from mtanno.evaluation.report import confusion_matrix

    truth = [Segment("d", 1, 4, "a"), Segment("d", 5, 8, "b")]
    ann = [Annotation("d", 0, 4, "a", 0.1), Annotation("d", 6, 7, "b", 0.1)]
    M, labels, overlapped = confusion_matrix(truth, ann, {"d": 10})
    assert labels == ["a", "b", "none"] and not overlapped
    assert M.tolist() == [[4, 0, 0], [1, 2, 1], [0, 0, 2]]
    # overlapping rows: a frame counts for the covering segment with the smaller cost
    ann = [Annotation("d", 0, 5, "a", 0.2), Annotation("d", 4, 7, "b", 0.1)]
    M, _, overlapped = confusion_matrix(truth, ann, {"d": 8})
    assert overlapped and M.tolist() == [[4, 0, 0], [0, 4, 0], [0, 0, 0]]


def test_report_files_and_tables(world, tmp_path):
    single = tmp_path / "single.csv"
    assert run("annotate", "--mt", world.mt, world.docfeats, "-o", single, "-q",
               "--single-label").exit_code == 0
    out = tmp_path / "rep"
    r = run("report", single, "--truth", world.truth, "-o", out, "--mt", world.mt,
            "--features", world.docfeats)
    assert r.exit_code == 0, r.output
    assert f"-> {out / 'index.html'}" in r.output
    names = {p.name for p in out.iterdir()}
    for stem in ["confusion", "reliability",
                 *(f"template_{p.stem}" for p in world.mt.glob("*.json"))]:
        assert {f"{stem}.png", f"{stem}.svg"} <= names, stem
    assert {"index.html", "per_class.csv", "per_class.md", "per_class.tex", "confusion.csv",
            "per_class.csv.meta.json", "figures.json", "data"} <= names
    assert not any(n.startswith(("timeline_", "delta_")) for n in names)  # drawn in the page
    rows = list(csv.DictReader((out / "per_class.csv").open()))
    ev = run("evaluate", single, "--truth", world.truth, "-o", tmp_path / "ev.csv")
    assert rows == list(csv.DictReader((tmp_path / "ev.csv").open()))  # = mtanno evaluate
    md = (out / "per_class.md").read_text().splitlines()
    assert md[0].startswith("| class | P1 |") and len(md) == 2 + len(rows)
    tex = (out / "per_class.tex").read_text()
    assert tex.startswith("\\begin{tabular}") and tex.count("\\\\") == 1 + len(rows)
    assert "walk2Steps" in tex and f"{float(rows[-1]['F1']):.3f}" in tex
    conf = list(csv.DictReader((out / "confusion.csv").open()))
    assert conf[-1]["truth"] == "none" and list(conf[0])[-1] == "none"
    total = sum(int(v) for row in conf for k, v in row.items() if k != "truth")
    from mtanno.features.store import read_features

    assert total == sum(read_features(p).X.shape[1] for p in world.doc_files)
    page = (out / "index.html").read_text()
    # confusion, reliability of the confidence, templates; each a file beside the page
    assert page.count("<img ") == 2 + len(list(world.mt.glob("*.json")))
    assert "src='confusion.png'" in page and "src='reliability.png'" in page
    assert "AUROC" in page and "segments overlap" not in page
    assert ev.exit_code == 0


def test_report_counts_documents_as_its_page_does(world, tmp_path):
    """Issue 31 (3): the command said "6 documents, 10 rows" (documents with rows) while
    its page said "10 document(s)" (documents annotated). Both now say the documents
    annotated and how many of them have rows, with and without truth."""
    import html
    import re

    docs = sorted(p.stem for p in world.doc_files)
    ann = tmp_path / "a.csv"  # the rows of one document only; the provenance records both
    lines = world.annotation.read_text().splitlines(keepends=True)
    kept = [ln for ln in lines[1:] if ln.startswith(docs[0] + ",")]
    ann.write_text(lines[0] + "".join(kept))
    shutil.copyfile(f"{world.annotation}.meta.json", f"{ann}.meta.json")
    for truth in ((), ("--truth", world.truth)):
        out = tmp_path / f"rep{len(truth)}"
        r = run("report", ann, *truth, "-o", out)
        assert r.exit_code == 0, r.output
        said = re.search(r"report: (.*); \d+ files -> ", r.output).group(1)
        assert said.startswith(f"{len(docs)} documents (1 with rows), {len(kept)} rows, ")
        page = html.unescape((out / "index.html").read_text())
        assert said + "; frames at 30 Hz" in page
        assert ("frame F1" in said) == bool(truth)


def test_report_takes_the_annotations_delta_and_taus(world, tmp_path):
    """A tuned annotation (δ 0.25, a τ of its own for one class, a further template for
    another): the report's Δ curves take the annotation's δ and τ (the page's data), and
    the page says which classes had further templates; --tau and --delta replace them."""
    import json
    import re

    import mtanno.evaluation.report as report
    from mtanno.annotate import class_deltas, class_models
    from mtanno.evaluation.player import decode_curves
    from mtanno.features.store import read_features
    from mtanno.templates.store import load_template_folder

    names = sorted(p.stem for p in world.mt.glob("*.json"))
    own, extra = names[0], names[1]
    cfg = tmp_path / "c.toml"
    extra_file = world.mt / f"{extra}.json"
    cfg.write_text(f'[decoder]\ndelta = 0.25\n[tau]\ndefault = 0.13\n{own} = 0.07\n'
                   f'[templates]\n{extra} = ["{extra_file}"]\n')
    ann = tmp_path / "a.csv"
    assert run("annotate", "--mt", world.mt, "--classes", cfg, world.docfeats, "-o", ann,
               "-q").exit_code == 0
    prov = json.loads((tmp_path / "a.csv.meta.json").read_text())
    assert report.annotation_parameters([{}, prov]) == {
        "tau": 0.13, "tau_per_class": {own: 0.07}, "delta": 0.25, "extra_templates": [extra]}
    doc = world.doc_files[0]

    def page(out, *extra_args):
        r = run("report", ann, "--truth", world.truth, "-o", out, "--mt", world.mt,
                "--features", doc, *extra_args)
        assert r.exit_code == 0, r.output
        text = (out / "index.html").read_text()
        data = json.loads(re.search(r"id='mtanno-data'>(.*?)</script>", text, re.S).group(1))
        i = data["docs"]["name"].index(doc.stem)
        js = (out / "data" / f"{data['chunks'][data['docs']['chunk'][i]]}.js").read_text()
        entry = json.loads(js[js.index(",") + 1:-3])[data["docs"]["slot"][i]]
        return text, data["curves"], decode_curves(entry[1], len(data["curves"]["classes"]))

    text, curves, got = page(tmp_path / "rep")
    assert f"also matched further templates of {extra}" in text
    assert dict(zip(curves["classes"], curves["tau"]))[own] == 0.07
    for delta, args in ((0.25, ()), (0.05, ("--tau", "0.2", "--delta", "0.05"))):
        text, curves, got = page(tmp_path / f"rep{delta}", *args)
        models, _ = class_models(load_template_folder(world.mt), delta=delta)
        want = np.array([c for c, _ in class_deltas(read_features(doc).X, models)])
        ok = np.isfinite(want)
        assert np.abs(got[ok] - np.minimum(want[ok], 6.5)).max() <= 0.5e-4 + 1e-9
    assert curves["tau"] == [0.2] * len(curves["classes"]) and curves["default"] == 0.2


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return shutil.which(name)
    return None


def test_report_page_loads_every_image_in_a_browser(world, tmp_path):
    """The page opened in headless Chromium from its folder: every image (files beside the
    page, loaded lazily) decodes, none missing. Chromium is a Debian package: apt-get
    install chromium."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from browser import Browser

    binary = _chromium()
    if binary is None:
        pytest.skip("headless Chromium not found (Debian: apt-get install chromium); the "
                    "report page is checked in a browser only where it is installed")
    out = tmp_path / "rep"
    assert run("report", world.annotation, "--truth", world.truth, "-o", out, "-q",
               "--mt", world.mt).exit_code == 0
    n_images = (out / "index.html").read_text().count("<img ")
    # confusion matrix, reliability of the confidence, a heat map per template
    assert n_images == 2 + len(list(world.mt.glob("*.json")))
    b = Browser(binary, tmp_path / "profile")
    try:
        b.open((out / "index.html").as_uri())
        loaded = b.evaluate(
            "Promise.all([...document.images].map(i => { i.loading = 'eager';"
            " return i.decode().then(() => i.naturalWidth > 0, () => false); }))")
        assert loaded == [True] * n_images
        # the table of contents leads to every section
        anchors = b.evaluate("[...document.querySelectorAll('nav.toc a')].map(a =>"
                             " !!document.getElementById(a.hash.slice(1)))")
        assert anchors and all(anchors)
    finally:
        b.close()


def test_report_without_truth_summarises_and_lists_rows_for_review(world, tmp_path):
    """Issue 24: an archive nobody has labelled — per class segments, duration and share,
    the annotation's timelines, and every row, the least confident first."""
    from mtanno.annotate import read_annotation_table

    out = tmp_path / "rep"
    r = run("report", world.annotation, "-o", out, "-q")
    assert r.exit_code == 0, r.output
    rows, prov = read_annotation_table(world.annotation)
    frames = prov["documents"]
    summary = {s["class"]: s for s in csv.DictReader((out / "summary.csv").open())}
    for lab in {a.label for a in rows}:
        mine = [a for a in rows if a.label == lab]
        covered = sum(len({f for a in mine if a.doc == d for f in range(a.start, a.end + 1)})
                      for d in frames)
        assert int(summary[lab]["segments"]) == len(mine)
        assert int(summary[lab]["frames"]) == covered
        assert float(summary[lab]["share"]) == pytest.approx(covered / sum(frames.values()),
                                                             abs=1e-4)
    review = list(csv.DictReader((out / "review.csv").open()))
    assert len(review) == len(rows)
    conf = [float(x["confidence"]) for x in review]
    assert conf == sorted(conf)
    page = (out / "index.html").read_text()
    assert "Classes in the annotation" in page and "id=\"archive\"" in page
    assert not (out / "per_class.csv").exists() and not (out / "confusion.csv").exists()
    assert page.count("<img ") == 0  # the timelines are drawn in the page
