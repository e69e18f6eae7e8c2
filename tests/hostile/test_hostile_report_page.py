"""Hostile names and motions on the report page (issue 31, finding 9: the report page, and
"motions that do not match the annotation"):

* a label or document name holding ``<!--<script>`` (or ``</script>``) does not swallow the
  page's script: every ``<`` of the embedded JSON is written ``\\u003c``;
* a document named ``__proto__`` (or ``constructor``) is a document like any other: the page
  keys nothing by name in a plain object;
* a label beginning with ``=``, ``+``, ``-`` or ``@`` is never written into the downloaded
  truth CSV, where a spreadsheet would evaluate it: such rows are refused (the page says how
  many and why), a relabel to such a label is refused, and what is written is read back by
  ``evaluate --truth`` and ``learn-mt --truth``;
* a label with a line break keeps it through the review fields into the download;
* documents ``a/b`` and ``a_b`` (classes too) never share a file;
* a motion that is not the annotated one (shorter, three times longer, another rig, 60 000
  frames) is said per document on the page and on standard error, and not played.
"""

from __future__ import annotations

import csv
import json
import re

import numpy as np
from browser import needs_chromium, wait_for_file
from test_hostile_motion import bvh_text
from world import cli

from mtanno.labels.truth import read_truth

HOSTILE = "x<!--<script>"
P = "document.querySelector('[data-mtanno-player]')"



def _annotation(tmp_path, rows, name="a.csv"):
    path = tmp_path / name
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["doc", "start", "end", "label", "cost", "confidence"])
        w.writerows(rows)
    return path


def _data(page: str) -> dict:
    m = re.search(r"<script type='application/json' id='mtanno-data'>(.*?)</script>", page, re.S)
    return json.loads(m.group(1))


def test_script_markup_in_names_stays_data(tmp_path):
    ann = _annotation(tmp_path, [[HOSTILE, 1, 20, "</script><!--<script>", 0.1, 0.5],
                                 ["plain", 1, 30, "walk", 0.1, 0.9]])
    out = tmp_path / "rep"
    r = cli("report", ann, "-o", out, "-q")
    assert r.exit_code == 0, r.output
    page = (out / "index.html").read_text()
    m = re.search(r"<script type='application/json' id='mtanno-data'>(.*?)</script>", page, re.S)
    assert "<" not in m.group(1) and "\\u003c!--\\u003cscript" in m.group(1)
    data = json.loads(m.group(1))
    assert data["docs"]["name"] == ["plain", HOSTILE]
    assert "</script><!--<script>" in data["labels"]
    assert page.count("<script") == 2  # the data and the page's script, nothing else


@needs_chromium
def test_script_markup_in_names_leaves_the_script_running(tmp_path, browser):
    ann = _annotation(tmp_path, [[HOSTILE, 1, 20, "</script><!--<script>", 0.1, 0.5],
                                 ["plain", 1, 30, "walk", 0.1, 0.9]])
    out = tmp_path / "rep"
    assert cli("report", ann, "-o", out, "-q").exit_code == 0
    browser.open((out / "index.html").as_uri())
    assert browser.evaluate("document.getElementById('mtanno-list').dataset.mtannoCount") == "2"
    names = browser.evaluate("[...document.querySelectorAll('[data-mtanno-doc]')]"
                             ".map(e => e.dataset.mtannoDoc)")
    assert sorted(names) == ["plain", HOSTILE]
    assert browser.evaluate("document.body.dataset.truthRows") == "0"  # review.js ran too


@needs_chromium
def test_proto_is_a_document_like_any_other(tmp_path, browser):
    names = ["__proto__", "constructor", "hasOwnProperty", "toString"]
    ann = _annotation(tmp_path, [[n, 1, 10 + i, "__proto__" if i % 2 else "walk", 0.1, 0.5]
                                 for i, n in enumerate(names)])
    out = tmp_path / "rep"
    assert cli("report", ann, "-o", out, "-q").exit_code == 0
    browser.open((out / "index.html").as_uri() + "#doc=__proto__&frame=4")
    browser.wait_for(f"{P}.dataset.doc === '__proto__'", "the document __proto__")
    assert browser.evaluate(f"{P}.dataset.frame") == "4"
    assert browser.evaluate(f"{P}.dataset.frames") == "10"
    assert browser.evaluate("document.getElementById('mtanno-list').dataset.mtannoCount") == "4"
    for i, n in enumerate(names):
        assert browser.evaluate(f"mtanno.docNamed({json.dumps(n)})") == i
    assert browser.evaluate("mtanno.docNamed('valueOf')") == -1
    browser.evaluate("(() => { const f = document.getElementById('mtanno-filter');"
                     " f.value = 'label:__proto__'; f.dispatchEvent(new Event('input')); })()")
    assert browser.evaluate("document.getElementById('mtanno-list').dataset.mtannoCount") == "2"
    assert browser.evaluate("Object.getPrototypeOf({}) === Object.prototype && "
                            "({}).walk === undefined")


@needs_chromium
def test_formula_labels_are_refused_and_the_rest_reads_back(world, tmp_path, browser):
    """Rows whose label (or document) begins with = + - @ are accepted on the page but
    never written; a relabel to such a label is refused; every cell of the download is
    plain, and the download is read by evaluate --truth and learn-mt --truth."""
    from mtanno.annotate import read_annotation_table

    rows, prov = read_annotation_table(world.annotation)
    evil = ["=HYPERLINK(\"http://x\")", "+1", "-2", "@SUM(A1)"]
    table = []
    for i, a in enumerate(rows):
        label = evil[i] if i < len(evil) else a.label
        table.append([a.doc, a.start + 1, a.end + 1, label, a.cost, a.confidence])
    ann = _annotation(tmp_path, table)
    out = tmp_path / "rep"
    assert cli("report", ann, "-o", out, "-q").exit_code == 0
    browser.open((out / "index.html").as_uri())
    browser.evaluate("(() => { document.getElementById('mtanno-accept-p').value = '0';"
                     " document.getElementById('mtanno-accept-above').click(); })()")
    with_conf = [t for t in table if t[5] == t[5]]
    plain = [t for t in with_conf if t[3] not in evil]
    assert browser.evaluate("document.body.dataset.truthRows") == str(len(plain))
    assert "not written" in browser.evaluate("document.getElementById('truth-refused')"
                                             ".textContent")
    # a relabel to a formula is refused, the row keeps its label
    browser.evaluate("mtanno.setRow(mtanno.rowsOf(mtanno.current)[0])")
    bad = browser.evaluate(
        "(() => { const i = document.querySelector('#mtanno-rows tr.current input.label');"
        " i.value = '=1+1'; i.dispatchEvent(new Event('change', {bubbles: true}));"
        " return [i.classList.contains('bad'), mtanno.data.labels[mtanno.data.rows.label["
        "mtanno.currentRow]]]; })()")
    assert bad[0] is True
    browser.evaluate("document.getElementById('download-truth').click()")
    got = wait_for_file(tmp_path / "downloads" / "truth.csv")
    with open(got, newline="") as fh:
        cells = [c for row in csv.reader(fh) for c in row]
    assert not any(c[:1] in ("=", "+", "-", "@", "\t", "\r") for c in cells)
    assert len(read_truth(got)) == len(plain)
    assert cli("evaluate", world.annotation, "--truth", got).exit_code == 0
    r = cli("learn-mt", "--truth", got, world.docfeats, "-o", tmp_path / "mts", "-q")
    assert r.exit_code == 0, r.output


@needs_chromium
def test_a_label_with_a_line_break_survives_review(tmp_path, browser):
    ann = _annotation(tmp_path, [["doc1", 1, 20, "two\nlines", 0.1, 0.5],
                                 ["doc1", 30, 40, "walk", 0.1, 0.6]])
    out = tmp_path / "rep"
    assert cli("report", ann, "-o", out, "-q").exit_code == 0
    browser.open((out / "index.html").as_uri())
    browser.evaluate("document.getElementById('mtanno-list').focus()")
    browser.key("j")
    assert browser.evaluate("mtanno.data.labels[mtanno.data.rows.label[mtanno.currentRow]]") \
        == "two\nlines"
    # its end moved in the review field: accepted, the label untouched
    browser.evaluate("(() => { const i = document.querySelector('#mtanno-rows tr.current"
                     " input.end'); i.value = '18'; i.dispatchEvent(new Event('change',"
                     " {bubbles: true})); })()")
    # its label field left as shown (⏎ for the line break): the label stays two lines
    browser.evaluate("(() => { const i = document.querySelector('#mtanno-rows tr.current"
                     " input.label'); i.dispatchEvent(new Event('change', {bubbles: true}));"
                     " })()")
    browser.evaluate("document.getElementById('download-truth').click()")
    got = wait_for_file(tmp_path / "downloads" / "truth.csv")
    segs = read_truth(got)
    assert [(s.doc, s.start, s.end, s.label) for s in segs] == [("doc1", 1, 18, "two\nlines")]


def test_similar_names_never_share_a_file(tmp_path):
    """Documents a/b and a_b keep their own motions; classes a/b and a_b their own
    template figures."""
    from mtanno.annotate import Annotation
    from mtanno.evaluation.page import file_stems
    from mtanno.evaluation.player import decode_poses
    from mtanno.evaluation.report import write_report
    from mtanno.templates.model import MotionTemplate

    stems = file_stems(["a/b", "a_b", "A_b", "x", ".hidden", "", "é"])
    assert len(set(stems.values())) == 7 and len({s.lower() for s in stems.values()}) == 7
    assert stems["x"] == "x" and all("/" not in s and not s.startswith(".") and s
                                     for s in stems.values())
    rows = [Annotation("a/b", 0, 9, "a/b", 0.1, 0.5), Annotation("a_b", 0, 9, "a_b", 0.1, 0.5)]
    poses = {"a/b": np.zeros((10, 22, 3)), "a_b": np.ones((10, 22, 3))}
    mts = {n: MotionTemplate(n, ["f1", "f2"], np.array([[0.0, 1.0], [1.0, v]]), np.ones(2),
                             feature_set="x") for n, v in (("a/b", 0.0), ("a_b", 1.0))}
    res = write_report(tmp_path / "rep", None, rows, frames={"a/b": 10, "a_b": 10},
                       poses=poses, templates=mts)
    figures = sorted(p.name for p in res.folder.glob("template_*.png"))
    assert len(figures) == 2
    page = (res.folder / "index.html").read_text()
    assert all(f in page for f in figures)
    data = _data(page)
    chunks = {}
    for f in (res.folder / "data").glob("*.js"):
        chunks[f.stem] = json.loads(f.read_text()[len('mtannoChunk("') + 22:-3])
    for i, d in enumerate(data["docs"]["name"]):
        entry = chunks[data["chunks"][data["docs"]["chunk"][i]]][data["docs"]["slot"][i]]
        assert np.array_equal(decode_poses(entry[0]), poses[d])


def _frames_of(amc_text: str) -> list[str]:
    """The frame blocks of an AMC text (each from its number line)."""
    return re.split(r"(?m)^(?=\d+\s*$)", amc_text)


def _amc(text: str, blocks: list[str]) -> str:
    head = _frames_of(text)[0]
    out = [head]
    for k, b in enumerate(blocks, 1):
        out.append(f"{k}\n" + b.split("\n", 1)[1])
    return "".join(out)


def test_motions_that_are_not_the_annotated_ones_are_said_and_not_played(world, tmp_path):
    """Per document, on standard error and on the page: a shorter motion, one three times
    as long, one of 60 000 frames, and another rig's file of the same length (caught by
    the SHA-256 its feature file records); the matching document still plays; exit 1."""
    docs = sorted(world.docs.glob("*.amc"))
    names = [d.stem for d in docs]
    motions = tmp_path / "motions"
    motions.mkdir()
    asf = next(world.docs.glob("*.asf"))
    (motions / asf.name).write_bytes(asf.read_bytes())
    text = docs[0].read_text()
    blocks = _frames_of(text)[1:]
    cases = {"shorter": blocks[: len(blocks) // 3], "longer": blocks * 3,
             "huge": [blocks[0]] * 60_000}
    for case, b in cases.items():
        (motions / f"{case}.amc").write_text(_amc(text, b))
    (motions / f"{names[0]}.amc").write_bytes(docs[0].read_bytes())   # the right one
    (motions / f"{names[1]}.bvh").write_text(bvh_text(len(_frames_of(docs[1].read_text())) - 1))
    from mtanno.annotate import read_annotation_table

    rows, prov = read_annotation_table(world.annotation)
    n = prov["documents"]
    table = [[a.doc, a.start + 1, a.end + 1, a.label, a.cost, a.confidence] for a in rows]
    for case in cases:  # the annotation of documents named like the bad motions
        table.append([case, 1, n[names[0]], "squat", 0.1, 0.5])
    ann = _annotation(tmp_path, table)
    meta = {"documents": {**n, **{c: n[names[0]] for c in cases}}}
    (tmp_path / "a.csv.meta.json").write_text(json.dumps(meta))
    out = tmp_path / "rep"
    r = cli("report", ann, "-o", out, "--motions", motions, "--features", world.docfeats)
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.splitlines() if ln.startswith("mtanno:")]
    assert len(lines) == 4, r.output
    said = {c: next(ln for ln in lines if f"{c}.amc" in ln) for c in cases}
    assert "shorter" in said["shorter"] and "3.0× as long" in said["longer"]
    assert f"the annotation of 'huge' {n[names[0]]}" in said["huge"]
    assert any(f"{names[1]}.bvh" in ln and "not the file the features" in ln for ln in lines)
    page = (out / "index.html").read_text()
    data = _data(page)
    docs_ = data["docs"]
    for i, d in enumerate(docs_["name"]):
        if d == names[0]:
            assert docs_["chunk"][i] >= 0 and not docs_["note"][i]
        else:
            assert docs_["chunk"][i] == -1 and "not played" in docs_["note"][i], d
    assert "is not the annotated one and is not played" in page
    # no poses of the 60 000 frames in the data files
    assert sum(f.stat().st_size for f in (out / "data").glob("*.js")) < 200_000
