"""The report page (issues 24 and 33): poses and Δ curves encoded for the page, documents
matched to motion files, the rig's own bones, data files beside the page, figures not drawn
again, and the page in headless Chromium, checked by events and page state (never pixels or
fixed waits): the archive view filters, sorts and counts, stays virtual at thousands of
documents, a deep link shows its document at its frame, the player plays, seeks and steps,
keyboard review survives a reload, and the downloaded truth is what was accepted and what
evaluate --truth and learn-mt --truth read."""

from __future__ import annotations

import csv
import json
import re

import numpy as np
import pytest
from browser import needs_chromium, wait_for_file
from world import cli

from mtanno.evaluation.player import (
    POSE_QUANTUM,
    decode_curves,
    decode_poses,
    encode_curves,
    encode_poses,
    load_motion_poses,
    motion_files,
)

P = "document.querySelector('[data-mtanno-player]')"
SETTLED = f"['ready', 'none', 'error'].includes({P}.dataset.state)"


# --- encoding -------------------------------------------------------------------------------

def test_poses_round_trip_within_half_a_quantum():
    rng = np.random.default_rng(0)
    P_ = rng.uniform(-3, 3, size=(40, 22, 3))
    back = decode_poses(encode_poses(P_))
    assert back.shape == P_.shape
    assert np.abs(back - P_).max() <= POSE_QUANTUM / 2 + 1e-12
    huge = decode_poses(encode_poses(np.full((1, 22, 3), 1e6)))
    assert np.all(huge == 32767 * POSE_QUANTUM)  # clipped, not wrapped round
    # differences beyond int16 wrap modulo 2^16 both ways: every value comes back
    jumps = np.zeros((4, 5, 3))
    jumps[1::2] = 32.7
    jumps[2] = -32.7
    assert np.allclose(decode_poses(encode_poses(jumps), 5), jumps, atol=POSE_QUANTUM)
    with pytest.raises(Exception, match="poses must be"):
        encode_poses(np.zeros((3, 21)))


def test_curves_round_trip_and_keep_no_match():
    C = np.array([[0.1, np.inf, 0.3, 9.0], [np.nan, 0.0, 0.12345, 1.0]])
    back = decode_curves(encode_curves(C), 2)
    assert np.isinf(back[0, 1]) and np.isinf(back[1, 0])
    assert back[0, 3] == pytest.approx(6.5)  # clipped at 6.5
    finite = np.isfinite(C) & (C < 6.5)
    assert np.abs(back[finite] - C[finite]).max() <= 0.5e-4 + 1e-12


def test_motion_poses_are_the_pose_block_of_the_feature_files(world, tmp_path):
    """The canonical poses read from a motion file are those `features --poses` stores
    (same 30 Hz frames, same normalisation), within the page's quantum; the rig's own
    joints (the player's figure) put its canonical joints where those poses are."""
    from mtanno.features.store import read_features
    from mtanno.io import read_motion
    from mtanno.io.rigs import CANONICAL_JOINTS

    docs = sorted(world.docs.glob("*.amc"))[:2]
    assert cli("features", *docs, "-o", tmp_path / "f", "--poses", "-q").exit_code == 0
    files = motion_files([world.docs])
    assert set(files) >= {d.stem for d in docs}
    got = load_motion_poses(files, [d.stem for d in docs] + ["not_a_document"])
    own = load_motion_poses(files, [d.stem for d in docs], rig=True)
    assert sorted(got) == sorted(own) == sorted(d.stem for d in docs)
    for d in docs:
        block = read_features(tmp_path / "f" / f"{d.stem}.parquet", poses=True).poses
        assert got[d.stem].shape == block.shape
        assert np.abs(decode_poses(encode_poses(got[d.stem])) - block).max() < POSE_QUANTUM
        motion = read_motion(d)
        index = motion.smap.indices(motion.rig, CANONICAL_JOINTS)
        kept = [n for n in range(len(motion.rig.names)) if n == index[0]
                or _below(motion.rig.parents, n, index[0])]
        rig = own[d.stem]
        assert rig.positions.shape == (block.shape[0], len(kept), 3)
        at = [kept.index(n) for n in index]
        assert np.abs(rig.positions[:, at] - block).max() < 1e-5
        assert len(rig.bones) == len(kept) - 1 and set(rig.sides) <= set("lrc")
        assert rig.sides[at[1]] == "l" and rig.sides[at[2]] == "r" and rig.sides[0] == "c"


def _below(parents, node, root) -> bool:
    while node >= 0:
        if node == root:
            return True
        node = int(parents[node])
    return False


def test_motion_files_refuses_what_is_not_a_motion(world, tmp_path):
    with pytest.raises(Exception, match="not found"):
        motion_files([tmp_path / "nothing"])
    with pytest.raises(Exception, match="not a motion file"):
        motion_files([world.truth])
    twin = tmp_path / "twin"
    twin.mkdir()
    first = sorted(world.docs.glob("*.amc"))[0]
    (twin / first.name).write_bytes(first.read_bytes())
    with pytest.raises(Exception, match="two motion files of document"):
        motion_files([world.docs, twin])


@pytest.mark.parametrize("bad", ["missing", "truth"])
def test_report_motions_bad_input_is_one_line(world, tmp_path, bad):
    path = tmp_path / "missing.bvh" if bad == "missing" else world.truth
    r = cli("report", world.annotation, "-o", tmp_path / "rep", "--motions", path, "-q")
    assert r.exit_code == 2, r.output
    assert r.output.count("\n") == 1 and str(path) in r.output, r.output
    assert not (tmp_path / "rep").exists()


def _report(world, tmp_path, *extra, name="rep") -> str:
    out = tmp_path / name
    r = cli("report", world.annotation, "-o", out, "-q", *extra)
    assert r.exit_code == 0, r.output
    return (out / "index.html").read_text(encoding="utf-8")


def _page_data(page: str) -> dict:
    m = re.search(r"<script type='application/json' id='mtanno-data'>(.*?)</script>", page, re.S)
    return json.loads(m.group(1))


def _chunks(folder) -> dict[str, list]:
    out = {}
    for f in (folder / "data").glob("*.js"):
        m = re.fullmatch(r'mtannoChunk\("([0-9a-f]{20})",(.*)\);\n', f.read_text())
        assert m and f.stem == m.group(1)
        out[m.group(1)] = json.loads(m.group(2))
    return out


def test_poses_go_to_data_files_beside_a_small_page(world, tmp_path):
    """The page holds no poses: the data files do, each named by its content, decoded to
    the rig's joints; every document's entry is where the page says; nothing from the
    network."""
    page = _report(world, tmp_path, "--motions", world.docs)
    data = _page_data(page)
    docs = sorted(p.stem for p in world.doc_files)
    assert data["docs"]["name"] == docs and data["motions"] is True
    assert "<script src" not in page and "http://" not in page and "https://" not in page
    chunks = _chunks(tmp_path / "rep")
    assert sorted(chunks) == sorted(data["chunks"])
    own = load_motion_poses(motion_files([world.docs]), docs, rig=True)
    for i, d in enumerate(docs):
        entry = chunks[data["chunks"][data["docs"]["chunk"][i]]][data["docs"]["slot"][i]]
        rig = data["rigs"][data["docs"]["rig"][i]]
        back = decode_poses(entry[0], rig["joints"])
        assert np.abs(back - own[d].positions).max() <= POSE_QUANTUM / 2 + 1e-6
        assert rig["bones"] == [list(b) for b in own[d].bones] and rig["sides"] == own[d].sides
        assert data["docs"]["frames"][i] == back.shape[0]
    assert len(page.encode()) < 60_000  # the poses are not in the page
    # one file per document on request (the benchmark's other way)
    from mtanno.annotate import read_annotation_table
    from mtanno.evaluation.report import ReportOptions, write_report

    rows, prov = read_annotation_table(world.annotation)
    res = write_report(tmp_path / "per_doc", None, rows, frames=prov["documents"],
                       poses=own, options=ReportOptions(chunk_bytes=0))
    assert len(list((res.folder / "data").glob("*.js"))) == len(docs)


def test_a_report_written_twice_is_the_same_bytes(world, tmp_path):
    """Two runs of `mtanno report` on the same inputs (truth, templates, feature files,
    motions), each in its own process with its own hash seed (an earlier page took its
    colour order from a set), write the same files with the same bytes: the page, its data
    files, every table and figure (SVG without a date, its ids from a fixed salt), all but
    the time the provenance records."""
    import os
    import subprocess
    import sys

    stamp = re.compile(rb"created\W+\d{4}-\d\d-\d\dT[\d:.+-]+")
    written = []
    for seed in ("1", "2"):
        cwd = tmp_path / f"run{seed}"  # the same command line: -o rep, inputs absolute
        cwd.mkdir()
        r = subprocess.run([sys.executable, "-m", "mtanno", "report", world.annotation,
                            "--truth", world.truth, "--mt", world.mt, "--features",
                            world.docfeats, "--motions", world.docs, "-o", "rep", "-q"],
                           cwd=cwd, env={**os.environ, "PYTHONHASHSEED": seed},
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        rep = cwd / "rep"
        written.append({str(f.relative_to(rep)): stamp.sub(b"created", f.read_bytes())
                        for f in sorted(rep.rglob("*")) if f.is_file()})
    first, second = written
    assert sorted(first) == sorted(second)
    assert {"index.html", "confusion.svg", "figures.json", "review.csv"} <= set(first)
    assert any(n.startswith("data/") for n in first)
    differ = [n for n in first if first[n] != second[n]]
    assert not differ, differ


def test_rerun_draws_no_figure_and_writes_no_data_file_again(world, tmp_path):
    """Figures drawn once: a rerun whose inputs are unchanged draws none (the files keep
    their bytes and times) and keeps the data files; changed truth redraws the figures it
    feeds; a data file no longer used is removed."""
    from mtanno.annotate import read_annotation_table
    from mtanno.evaluation.report import write_report
    from mtanno.labels.truth import read_truth
    from mtanno.templates.store import load_template_folder

    rows, prov = read_annotation_table(world.annotation)
    truth, mts = read_truth(world.truth), load_template_folder(world.mt)
    poses = load_motion_poses(motion_files([world.docs]), sorted(prov["documents"]), rig=True)
    out = tmp_path / "rep"

    def run(t, p):
        return write_report(out, t, rows, frames=prov["documents"], templates=mts, poses=p)

    first = run(truth, poses)
    assert first.figures_drawn == 2 + len(mts)  # confusion, reliability, templates
    stamp = {f: f.stat().st_mtime_ns for f in out.rglob("*") if f.suffix in (".png", ".svg",
                                                                               ".js")}
    again = run(truth, poses)
    assert again.figures_drawn == 0
    assert {f: f.stat().st_mtime_ns for f in stamp} == stamp
    changed = run([type(t)(t.doc, t.start, max(t.start, t.end - 5), t.label) for t in truth],
                  poses)
    assert changed.figures_drawn == 2  # the confusion matrix and the reliability diagram
    one = sorted(poses)[:1]
    run(truth, {d: poses[d] for d in one})
    assert len(list((out / "data").glob("*.js"))) == 1  # the other documents' file is gone


def test_delta_curves_in_the_data_files_are_the_annotations(world, tmp_path):
    """With --mt and --features each document's data holds every class's Δ over it, the
    templates quantized with the annotation's δ, and the page the classes' τ."""
    from mtanno.annotate import class_deltas, class_models
    from mtanno.features.store import read_features
    from mtanno.templates.store import load_template_folder

    cfg = tmp_path / "c.toml"
    names = sorted(p.stem for p in world.mt.glob("*.json"))
    cfg.write_text(f"[decoder]\ndelta = 0.25\n[tau]\ndefault = 0.13\n{names[0]} = 0.07\n")
    ann = tmp_path / "a.csv"
    assert cli("annotate", "--mt", world.mt, "--classes", cfg, world.docfeats, "-o", ann,
               "-q").exit_code == 0
    out = tmp_path / "rep"
    r = cli("report", ann, "--truth", world.truth, "-o", out, "--mt", world.mt, "--features",
            world.docfeats, "-q")
    assert r.exit_code == 0, r.output
    data = _page_data((out / "index.html").read_text())
    curves = data["curves"]
    models, _ = class_models(load_template_folder(world.mt), delta=0.25)
    assert curves["classes"] == [m.name for m in models]
    assert curves["tau"] == [0.07 if m.name == names[0] else 0.13 for m in models]
    chunks = _chunks(out)
    for i, d in enumerate(data["docs"]["name"]):
        entry = chunks[data["chunks"][data["docs"]["chunk"][i]]][data["docs"]["slot"][i]]
        got = decode_curves(entry[1], len(models))
        want = np.array([c for c, _ in class_deltas(
            read_features(world.docfeats / f"{d}.parquet").X, models)])
        assert got.shape == want.shape
        assert np.array_equal(np.isinf(got), ~np.isfinite(want))
        ok = np.isfinite(want)
        assert np.abs(got[ok] - np.minimum(want[ok], 6.5)).max() <= 0.5e-4 + 1e-9


# --- the page in a browser ------------------------------------------------------------------



def _shown(browser, doc: str) -> None:
    browser.wait_for(f"{P}.dataset.doc === {json.dumps(doc)} && {SETTLED}",
                     f"the player showing {doc}")


def _archive(tmp_path, n_docs: int, *, seed: int = 0):
    """An annotation table of ``n_docs`` documents (no motions): 0–3 rows each of five
    labels, confidences in [0, 1] (some missing). Returns its path and rows."""
    rng = np.random.default_rng(seed)
    labels = ["run", "walk", "jump", "wave left", "kick"]
    rows = []
    for i in range(n_docs):
        n = int(rng.integers(60, 900))
        for _ in range(int(rng.integers(0, 4))):
            s = int(rng.integers(1, n - 20))
            conf = "" if rng.random() < 0.1 else f"{rng.random():.3f}"
            rows.append([f"clip_{i:05d}", s, min(n, s + int(rng.integers(10, 200))),
                         labels[int(rng.integers(5))], f"{rng.random() * 0.2:.4f}", conf])
    path = tmp_path / "archive.csv"
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["doc", "start", "end", "label", "cost", "confidence"])
        w.writerows(rows)
    return path, rows


def _rendered(browser) -> list[str]:
    return browser.evaluate("[...document.querySelectorAll('[data-mtanno-doc]')]"
                            ".map(e => e.dataset.mtannoDoc)")


def _all_listed(browser) -> list[str]:
    """Every document of the list, scrolled through from top to bottom (virtualised: only
    the rows in view exist)."""
    seen: dict[str, None] = {}
    browser.evaluate("document.getElementById('mtanno-list').scrollTop = 0")
    while True:
        browser.evaluate("mtanno.render()")
        seen.update(dict.fromkeys(_rendered(browser)))
        at_end = browser.evaluate(
            "(() => { const l = document.getElementById('mtanno-list'); const t = l.scrollTop;"
            " l.scrollTop = t + l.clientHeight; return l.scrollTop === t; })()")
        if at_end:
            return list(seen)


def _filter(browser, text: str) -> int:
    browser.evaluate(f"(() => {{ const f = document.getElementById('mtanno-filter');"
                     f" f.value = {json.dumps(text)}; f.dispatchEvent(new Event('input'));"
                     " })()")
    return int(browser.evaluate("document.getElementById('mtanno-list').dataset.mtannoCount"))


@needs_chromium
def test_archive_filters_sorts_and_counts_exactly(tmp_path, browser):
    """Filter by a label leaves exactly the documents holding it; by name, confidence range
    and label:none likewise; the counts per class follow the filter; sorts."""
    path, rows = _archive(tmp_path, 300)
    out = tmp_path / "rep"
    assert cli("report", path, "-o", out, "-q").exit_code == 0
    browser.open((out / "index.html").as_uri())
    docs = sorted({r[0] for r in rows})
    assert int(browser.evaluate("document.getElementById('mtanno-list').dataset"
                                ".mtannoCount")) == len(docs)
    assert len(_rendered(browser)) < len(docs)  # virtual: only the rows in view exist
    holding = sorted({r[0] for r in rows if r[3] == "walk"})
    assert _filter(browser, "label:walk") == len(holding)
    assert sorted(_all_listed(browser)) == holding
    counts = browser.evaluate("[...document.querySelectorAll('#mtanno-counts button')]"
                              ".map(b => b.textContent)")
    walk = [r for r in rows if r[3] == "walk"]
    assert f"walk {len(walk)} rows, {len(holding)} docs" in counts
    spaced = sorted({r[0] for r in rows if r[3] == "wave left"})
    assert _filter(browser, 'label:"wave left"') == len(spaced)
    assert _filter(browser, "doc:clip_001") == len([d for d in docs if "clip_001" in d])
    assert _filter(browser, "label:none") == 0  # every document here has a row
    # a confidence range: documents with a row inside it, label and range on one row
    _filter(browser, "label:run")
    browser.evaluate("(() => { const a = document.getElementById('mtanno-conf-min');"
                     " a.value = '0.5'; a.dispatchEvent(new Event('input')); })()")
    want = sorted({r[0] for r in rows if r[3] == "run" and r[5] and float(r[5]) >= 0.5})
    assert sorted(_all_listed(browser)) == want
    browser.evaluate("(() => { const a = document.getElementById('mtanno-conf-min');"
                     " a.value = '0'; a.dispatchEvent(new Event('input')); })()")
    _filter(browser, "")
    # least confident first: the first document holds the least confident row
    first = browser.evaluate("mtanno.data.docs.name[mtanno.shown[0]]")
    least = min((float(r[5]), r[0]) for r in rows if r[5])
    assert first == least[1]
    browser.evaluate("(() => { const s = document.getElementById('mtanno-sort');"
                     " s.value = 'name'; s.dispatchEvent(new Event('change')); })()")
    assert _all_listed(browser)[:5] == docs[:5]


@needs_chromium
def test_ten_thousand_documents_stay_virtual(tmp_path, browser):
    path, rows = _archive(tmp_path, 13_000, seed=1)  # 10 000 documents or so hold a row
    out = tmp_path / "rep"
    assert cli("report", path, "-o", out, "-q").exit_code == 0
    browser.open((out / "index.html").as_uri())
    assert browser.evaluate("document.getElementById('mtanno-list').dataset"
                            ".mtannoCount") == str(len({r[0] for r in rows}))
    assert 5 < len(_rendered(browser)) < 100
    browser.evaluate("(() => { const l = document.getElementById('mtanno-list');"
                     " l.scrollTop = l.scrollHeight; mtanno.render(); })()")
    last = browser.evaluate("mtanno.data.docs.name[mtanno.shown[mtanno.shown.length - 1]]")
    assert last in _rendered(browser) and len(_rendered(browser)) < 100
    # a deep link to a document far down the list: selected, scrolled to, at its frame
    far = sorted({r[0] for r in rows})[-3]
    browser.open(f"{(out / 'index.html').as_uri()}#doc={far}&frame=5")
    _shown(browser, far)
    assert browser.evaluate(f"{P}.dataset.frame") == "5"
    assert browser.evaluate("document.querySelector('.doc.current').dataset.mtannoDoc") == far


@needs_chromium
def test_deep_link_shows_the_document_at_the_frame_and_autoplay_plays(world, tmp_path,
                                                                       browser):
    _report(world, tmp_path, "--motions", world.docs)
    page = (tmp_path / "rep" / "index.html").as_uri()
    doc = sorted(p.stem for p in world.doc_files)[-1]
    browser.open(f"{page}#doc={doc}&frame=17")
    _shown(browser, doc)
    assert browser.evaluate(f"{P}.dataset.frame") == "17"
    assert browser.evaluate(f"{P}.dataset.state") == "ready"
    assert browser.evaluate("document.querySelector('.doc.current').dataset.mtannoDoc") == doc
    browser.open(f"{page}#doc={doc}&frame=3&autoplay")
    browser.wait_for(f"+{P}.dataset.frame > 8", "the player plays")
    browser.evaluate(f"{P}.querySelector('button.play').click()")  # pause
    # a click and a drag on the timeline seek; the arrow keys step
    frames, half, quarter = browser.evaluate(
        f"(() => {{ const c = {P}.querySelector('canvas.timeline');"
        " const r = c.getBoundingClientRect(), y = r.top + 3;"
        " c.dispatchEvent(new PointerEvent('pointerdown', {clientX: r.left + r.width / 2,"
        " clientY: y, bubbles: true})); const half = +c.parentNode.dataset.frame;"
        " c.dispatchEvent(new PointerEvent('pointermove', {clientX: r.left + r.width / 4,"
        " clientY: y, bubbles: true})); const q = +c.parentNode.dataset.frame;"
        " c.dispatchEvent(new PointerEvent('pointerup', {bubbles: true}));"
        " return [+c.parentNode.dataset.frames, half, q]; })()")
    assert abs(half - frames / 2) <= 1 + frames / 1000
    assert abs(quarter - frames / 4) <= 1 + frames / 1000
    browser.evaluate("document.getElementById('mtanno-list').focus()")
    browser.key("ArrowRight")
    assert int(browser.evaluate(f"{P}.dataset.frame")) == quarter + 1
    browser.key("ArrowLeft", shift=True)
    assert int(browser.evaluate(f"{P}.dataset.frame")) == quarter - 9
    assert f"#doc={doc}&frame={quarter - 9}" in browser.evaluate("location.hash")
    # another document selected from the list: its player is shown (the event fires)
    other = sorted(p.stem for p in world.doc_files)[0]
    ms = browser.evaluate(
        "new Promise(ok => { const p = document.querySelector('[data-mtanno-player]');"
        " p.addEventListener('mtanno:shown', e => ok(e.detail.ms), {once: true});"
        f" document.querySelector('[data-mtanno-doc={json.dumps(other)}]').click(); }})")
    assert ms >= 0
    _shown(browser, other)
    assert browser.evaluate("document.documentElement.scrollWidth <= "
                            "document.documentElement.clientWidth")  # no horizontal bar


def _rows_in_order(browser) -> list[list]:
    """The review order: the documents shown, each one's matching rows in time order, as
    [doc, start, end, label]."""
    return browser.evaluate(
        "mtanno.shown.flatMap(d => mtanno.matching(d)).map(r => [mtanno.data.docs.name["
        "mtanno.data.rows.doc[r]], mtanno.data.rows.start[r], mtanno.data.rows.end[r],"
        " mtanno.data.labels[mtanno.data.rows.label[r]]])")


@needs_chromium
def test_keyboard_review_survives_a_reload_and_downloads_as_truth(world, tmp_path, browser):
    _report(world, tmp_path, "--motions", world.docs)
    browser.open((tmp_path / "rep" / "index.html").as_uri())
    order = _rows_in_order(browser)
    assert len(order) >= 5
    browser.evaluate("document.getElementById('mtanno-list').focus()")
    browser.key("j")                      # the first row
    browser.key("a")                      # accepted; on to the second
    browser.key("x")                      # rejected; on to the third
    browser.key("l")                      # relabel the third
    assert browser.evaluate("document.activeElement.classList.contains('label')")
    browser.send("Input.insertText", {"text": "squat"}, session=True)
    browser.key("Enter")                  # committed: relabelled rows are accepted
    browser.key("j")
    browser.key("u")                      # the fourth stays undecided
    browser.key("j")
    browser.key(" ")                      # the fifth plays
    browser.wait_for(f"+{P}.dataset.frame > {order[4][1]} || {order[4][1]} === {order[4][2]}",
                     "the row plays")
    assert browser.evaluate("document.body.dataset.truthRows") == "2"
    browser.reload()
    assert browser.evaluate("document.body.dataset.truthRows") == "2"
    decided = browser.evaluate("mtanno.shown.flatMap(d => mtanno.matching(d))"
                               ".map(r => mtanno.decision(r))")
    assert decided[:4] == ["accept", "reject", "accept", ""]
    browser.evaluate("document.getElementById('download-truth').click()")
    got = wait_for_file(tmp_path / "downloads" / "truth.csv")
    with open(got, newline="") as fh:
        reader = csv.DictReader(fh)
        table = [tuple(r.values()) for r in reader]
    # the format scripts/experiment_review.sh simulates (bandai_folds.py review)
    assert reader.fieldnames == ["doc", "start", "end", "label", "fps"]
    want = sorted([(*map(str, order[0][:3]), order[0][3], "30"),
                   (*map(str, order[2][:3]), "squat", "30")])
    assert sorted(table) == want
    r = cli("evaluate", world.annotation, "--truth", got)
    assert r.exit_code == 0, r.output
    r = cli("learn-mt", "--truth", got, world.docfeats, "-o", tmp_path / "mts", "-q")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "mts" / "squat.json").exists()


@needs_chromium
def test_accept_every_row_above_a_confidence(tmp_path, browser):
    path, rows = _archive(tmp_path, 60, seed=3)
    out = tmp_path / "rep"
    assert cli("report", path, "-o", out, "-q").exit_code == 0
    browser.open((out / "index.html").as_uri())
    browser.evaluate("(() => { document.getElementById('mtanno-accept-p').value = '0.7';"
                     " document.getElementById('mtanno-accept-above').click(); })()")
    want = {(r[0], r[1], r[2], r[3]) for r in rows if r[5] and float(r[5]) >= 0.7}
    assert browser.evaluate("document.body.dataset.truthRows") == str(len(want))
    _filter(browser, "label:kick")  # on the rows shown only
    browser.evaluate("(() => { document.getElementById('mtanno-accept-p').value = '0';"
                     " document.getElementById('mtanno-accept-above').click(); })()")
    more = {(r[0], r[1], r[2], r[3]) for r in rows if r[5] and r[3] == "kick"}
    assert browser.evaluate("document.body.dataset.truthRows") == str(len(want | more))


@needs_chromium
def test_delta_curves_and_pose_blocks_in_the_player(world, tmp_path, browser):
    """Poses from the feature files' pose blocks (canonical bones), Δ curves drawn for the
    selected document, its Δ at the frame said."""
    feats = tmp_path / "f"
    assert cli("features", world.docs, "-o", feats, "--poses", "-q").exit_code == 0
    _report(world, tmp_path, "--mt", world.mt, "--features", feats)
    browser.open((tmp_path / "rep" / "index.html").as_uri())
    browser.wait_for(f"{P}.dataset.state === 'ready'", "the first document's motion")
    assert browser.evaluate(f"{P}.querySelector('canvas.curves').hidden") is False
    assert " Δ " in browser.evaluate(f"{P}.querySelector('.where').textContent")
    assert browser.evaluate("mtanno.data.rigs.length") == 1
    assert browser.evaluate("mtanno.data.rigs[0].joints") == 22


@needs_chromium
def test_cmu_trials_annotated_with_hdm05_templates_play_in_the_page(tmp_path, browser):
    """Issue 24's acceptance on real data: CMU subject 02 trials annotated with HDM05
    templates, reported without truth and with their motions; each document plays, a
    review row shows its segment's first frame, no horizontal scrollbar at 1400 px."""
    from conftest import require_data

    data = require_data()
    hdm = data / "hdm05_cut"
    rows = [ln.split(",") for ln in (hdm / "clips.csv").read_text().splitlines()[1:]]
    classes = ("squat1Reps", "hopBothLegs1hops", "jogLeftCircle4StepsRstart")
    clips = [hdm / r[0] for r in rows if r[2] in classes and r[1] == "bd"][:12]
    train = tmp_path / "train"
    for c in clips:
        assert cli("features", c, "-o", train / c.parent.name, "-q").exit_code == 0
    assert cli("learn-mt", train, "-o", tmp_path / "mt", "-q").exit_code == 0
    trials = [data / "cmu_02" / f"02_0{i}.amc" for i in (1, 4, 5)]
    assert cli("features", *trials, "-o", tmp_path / "cmu", "-q").exit_code == 0
    r = cli("annotate", "--mt", tmp_path / "mt", tmp_path / "cmu", "-o", tmp_path / "a.csv",
            "--tau", "0.3", "-q")
    assert r.exit_code == 0, r.output
    out = tmp_path / "rep"
    r = cli("report", tmp_path / "a.csv", "-o", out, "-q",
            *(a for t in trials for a in ("--motions", t)))
    assert r.exit_code == 0, r.output
    page = out.joinpath("index.html").as_uri()
    for t in trials:
        browser.open(f"{page}#doc={t.stem}&autoplay")
        _shown(browser, t.stem)
        assert browser.evaluate(f"{P}.dataset.state") == "ready"
        browser.wait_for(f"+{P}.dataset.frame > 5", "the document plays")
    assert browser.evaluate("document.documentElement.scrollWidth <= "
                            "document.documentElement.clientWidth")
    assert "`" not in browser.evaluate("document.body.innerText")  # no literal Markdown
    if browser.evaluate("mtanno.data.rows.doc.length"):
        browser.evaluate(f"{P}.querySelector('button.play').click()")
        browser.evaluate("document.getElementById('mtanno-list').focus()")
        browser.key("j")
        start = browser.evaluate("mtanno.data.rows.start[mtanno.currentRow]")
        assert browser.evaluate(f"+{P}.dataset.frame") == start


def test_a_motion_that_cannot_be_read_is_reported_and_the_page_written(world, tmp_path):
    """One rule for batches: a broken motion file is one line naming it, its document has
    no motion (the page says so), the others play; exit code 1."""
    docs = tmp_path / "docs"
    docs.mkdir()
    amcs = sorted(world.docs.glob("*.amc"))
    for f in amcs:
        (docs / f.name).write_bytes(f.read_bytes())
    (docs / amcs[0].name).write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 1 2\n")
    asf = next(world.docs.glob("*.asf"))
    (docs / asf.name).write_bytes(asf.read_bytes())
    r = cli("report", world.annotation, "-o", tmp_path / "rep", "--motions", docs, "-q")
    assert r.exit_code == 1, r.output
    assert r.output.count("\n") == 1 and amcs[0].name in r.output, r.output
    data = _page_data((tmp_path / "rep" / "index.html").read_text(encoding="utf-8"))
    shown = [d for d, c in zip(data["docs"]["name"], data["docs"]["chunk"]) if c >= 0]
    assert sorted(shown) == sorted(a.stem for a in amcs[1:])
    assert f"no motion for 1 of {len(amcs)} document(s): {amcs[0].stem}" in \
        (tmp_path / "rep" / "index.html").read_text(encoding="utf-8")


def test_motions_after_one_flag_and_an_asf_elsewhere(world, tmp_path):
    """`--motions a.amc b.amc` puts b.amc among the annotation tables: one line saying to
    repeat the flag; an AMC without an ASF beside it plays with --asf."""
    amcs = sorted(world.docs.glob("*.amc"))
    r = cli("report", world.annotation, "-o", tmp_path / "rep", "--motions", amcs[0], amcs[1])
    assert r.exit_code == 2 and "give --motions before each motion file" in r.output
    alone = tmp_path / "alone"
    alone.mkdir()
    (alone / amcs[0].name).write_bytes(amcs[0].read_bytes())
    r = cli("report", world.annotation, "-o", tmp_path / "a", "--motions", alone, "-q")
    assert r.exit_code == 1 and "asf" in r.output.lower(), r.output
    page = _report(world, tmp_path, "--motions", alone, "--asf", next(world.docs.glob("*.asf")),
                   name="b")
    assert sum(c >= 0 for c in _page_data(page)["docs"]["chunk"]) == 1


def test_an_empty_motion_path_is_refused_and_unannotated_twins_are_ignored(world, tmp_path):
    r = cli("report", world.annotation, "-o", tmp_path / "rep", "--motions", "", "-q")
    assert r.exit_code == 2 and "an empty motion path" in r.output
    twin = tmp_path / "twin"
    twin.mkdir()
    other = sorted(world.docs.glob("*.amc"))[0]
    for folder in (twin, tmp_path / "twin2"):
        folder.mkdir(exist_ok=True)
        (folder / "not_annotated.amc").write_bytes(other.read_bytes())
    files = motion_files([world.docs, twin, tmp_path / "twin2"],
                         [p.stem for p in world.doc_files])
    assert "not_annotated" not in files and len(files) == len(world.doc_files)
