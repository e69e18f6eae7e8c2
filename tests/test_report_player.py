"""The report page's stick-figure player and review-to-truth (issue 24, parts 2 and 3):
pose encoding, documents matched to motion files, bad inputs, and the page in headless
Chromium (players advance with #autoplay, a click on the timeline or a review row seeks,
"Download truth" writes a truth CSV that learn-mt and evaluate read)."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest
from browser import Browser, chromium, wait_for_file
from world import cli

from mtanno.evaluation.player import (
    POSE_QUANTUM,
    decode_poses,
    encode_poses,
    load_motion_poses,
    motion_files,
)


def test_poses_round_trip_within_half_a_quantum():
    rng = np.random.default_rng(0)
    P = rng.uniform(-3, 3, size=(40, 22, 3))
    back = decode_poses(encode_poses(P))
    assert back.shape == P.shape
    assert np.abs(back - P).max() <= POSE_QUANTUM / 2 + 1e-12
    huge = decode_poses(encode_poses(np.full((1, 22, 3), 1e6)))
    assert np.all(huge == 32767 * POSE_QUANTUM)  # clipped, not wrapped round
    with pytest.raises(Exception, match="poses must be"):
        encode_poses(np.zeros((3, 21, 3)))


def test_motion_poses_are_the_pose_block_of_the_feature_files(world, tmp_path):
    """The poses a player shows from a motion file are those `features --poses` stores
    (same 30 Hz frames, same normalisation), within the embedding's quantum."""
    from mtanno.features.store import read_features

    docs = sorted(world.docs.glob("*.amc"))[:2]
    assert cli("features", *docs, "-o", tmp_path / "f", "--poses", "-q").exit_code == 0
    files = motion_files([world.docs])
    assert set(files) >= {d.stem for d in docs}
    got = load_motion_poses(files, [d.stem for d in docs] + ["not_a_document"])
    assert sorted(got) == sorted(d.stem for d in docs)
    for d in docs:
        block = read_features(tmp_path / "f" / f"{d.stem}.parquet", poses=True).poses
        assert got[d.stem].shape == block.shape
        assert np.abs(decode_poses(encode_poses(got[d.stem])) - block).max() < POSE_QUANTUM


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


def _report(world, tmp_path, *extra) -> str:
    out = tmp_path / "rep"
    r = cli("report", world.annotation, "-o", out, "-q", *extra)
    assert r.exit_code == 0, r.output
    return (out / "index.html").read_text(encoding="utf-8")


def test_page_embeds_a_player_per_document_compactly(world, tmp_path):
    page = _report(world, tmp_path, "--motions", world.docs)
    docs = sorted(p.stem for p in world.doc_files)
    found = re.findall(r"data-mtanno-player data-doc='([^']+)' data-frames='(\d+)'", page)
    assert sorted(d for d, _ in found) == docs
    assert "<script src" not in page and "http://" not in page and "https://" not in page
    # about 2 bytes a coordinate in base 64: 66 coordinates a frame
    frames = sum(int(n) for _, n in found)
    assert len(page.encode()) < 200_000 + frames * 66 * 2 * 4 / 3 * 1.05
    plain = _report(world, tmp_path / "b")
    assert "<div class='player'" not in plain and "download-truth" in plain


def test_a_document_without_motion_is_named(world, tmp_path):
    one = sorted(world.docs.glob("*.amc"))[0]
    page = _report(world, tmp_path, "--motions", one)
    assert page.count("data-mtanno-player data-doc") == 1
    assert f"No motion for {len(world.doc_files) - 1} document(s)" in page


needs_chromium = pytest.mark.skipif(
    chromium() is None, reason="headless Chromium not found (Debian: apt-get install "
    "chromium); the page is checked in a browser only where it is installed")


@pytest.fixture
def browser(tmp_path):
    b = Browser(chromium(), tmp_path / "profile", downloads=tmp_path / "downloads")
    yield b
    b.close()


PLAYERS = "[...document.querySelectorAll('[data-mtanno-player]')]"


@needs_chromium
def test_players_play_seek_and_follow_the_review_list(world, tmp_path, browser):
    _report(world, tmp_path, "--motions", world.docs)
    page = (tmp_path / "rep" / "index.html").as_uri()
    browser.open(page + "#autoplay")
    n = browser.evaluate(f"{PLAYERS}.length")
    assert n == len(world.doc_files)  # a page without players fails here
    browser.wait_for(f"{PLAYERS}.every(p => +p.dataset.frame > 5)", "every player advances")
    # no horizontal scrollbar at 1400 px
    assert browser.evaluate("document.documentElement.scrollWidth <= "
                            "document.documentElement.clientWidth")

    browser.open(page)
    assert browser.evaluate(f"{PLAYERS}.every(p => p.dataset.frame === '1')")
    # a click on the middle of a timeline seeks to the middle of its document
    half, frames = browser.evaluate(
        "(() => { const p = document.querySelector('[data-mtanno-player]');"
        " const c = p.querySelector('canvas.timeline'); const r = c.getBoundingClientRect();"
        " c.dispatchEvent(new MouseEvent('click', {clientX: r.left + r.width / 2,"
        " clientY: r.top + 2, bubbles: true}));"
        " return [+p.dataset.frame, +p.dataset.frames]; })()")
    assert abs(half - frames / 2) <= 1 + frames / 1000
    # a click on a review row shows its segment's first frame, then plays it
    rows = browser.evaluate("document.querySelectorAll('tr.review.playable').length")
    assert rows > 0
    for i in (0, rows // 2, rows - 1):
        doc, start, shown = browser.evaluate(
            f"(() => {{ const tr = document.querySelectorAll('tr.review.playable')[{i}];"
            " tr.querySelector('td').click(); const d = tr.dataset.doc;"
            " const p = [...document.querySelectorAll('[data-mtanno-player]')]"
            ".find(e => e.dataset.doc === d);"
            " return [d, +tr.querySelector('input.start').value, +p.dataset.frame]; })()")
        assert abs(shown - start) <= 1, (doc, start, shown)
    browser.wait_for(
        "(() => { const tr = document.querySelectorAll('tr.review.playable')[" + str(rows - 1)
        + "]; const p = [...document.querySelectorAll('[data-mtanno-player]')].find(e =>"
        " e.dataset.doc === tr.dataset.doc); return +p.dataset.frame >"
        " +tr.querySelector('input.start').value || tr.querySelector('input.start').value"
        " === tr.querySelector('input.end').value; })()", "the segment plays")


def _set(row: int, selector: str, value) -> str:
    return (f"(() => {{ const e = document.querySelectorAll('tr.review')[{row}]"
            f".querySelector('{selector}'); e.value = {value!r};"
            " e.dispatchEvent(new Event('change', {bubbles: true})); return true; })()")


@needs_chromium
def test_download_truth_is_read_by_learn_mt_and_evaluate(world, tmp_path, browser):
    _report(world, tmp_path, "--motions", world.docs)
    browser.open((tmp_path / "rep" / "index.html").as_uri())
    rows = browser.evaluate("[...document.querySelectorAll('tr.review')].map(tr => "
                            "[tr.dataset.doc, +tr.querySelector('input.start').value, "
                            "+tr.querySelector('input.end').value, "
                            "tr.querySelector('input.label').value])")
    assert len(rows) >= 4
    browser.evaluate(_set(0, "select.decision", "accept"))
    browser.evaluate(_set(1, "select.decision", "reject"))
    browser.evaluate(_set(2, "input.label", "squat"))       # a relabel accepts the row
    browser.evaluate(_set(3, "input.start", str(rows[3][1] + 2)))  # so does a moved start
    assert browser.evaluate("document.body.dataset.truthRows") == "3"
    browser.evaluate("document.getElementById('download-truth').click()")
    got = wait_for_file(tmp_path / "downloads" / "truth.csv")
    with open(got, newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [tuple(r.values()) for r in table] == [
        (rows[0][0], str(rows[0][1]), str(rows[0][2]), rows[0][3], "30"),
        (rows[2][0], str(rows[2][1]), str(rows[2][2]), "squat", "30"),
        (rows[3][0], str(rows[3][1] + 2), str(rows[3][2]), rows[3][3], "30")]
    r = cli("evaluate", world.annotation, "--truth", got)
    assert r.exit_code == 0, r.output
    r = cli("learn-mt", "--truth", got, world.docfeats, "-o", tmp_path / "mts", "-q")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "mts" / "squat.json").exists()

    browser.evaluate("document.getElementById('accept-rest').click()")
    assert browser.evaluate("document.body.dataset.truthRows") == str(len(rows) - 1)


@needs_chromium
def test_cmu_trials_annotated_with_hdm05_templates_play_in_the_page(tmp_path, browser):
    """Issue 24's acceptance on real data: CMU subject 02 trials annotated with HDM05
    templates, reported without truth and with their motions; every player advances, a
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
    browser.open(out.joinpath("index.html").as_uri() + "#autoplay")
    assert browser.evaluate(f"{PLAYERS}.length") == len(trials)
    browser.wait_for(f"{PLAYERS}.every(p => +p.dataset.frame > 5)", "every player advances")
    assert browser.evaluate("document.documentElement.scrollWidth <= "
                            "document.documentElement.clientWidth")
    assert "`" not in browser.evaluate("document.body.innerText")  # no literal Markdown
    if browser.evaluate("document.querySelectorAll('tr.review.playable').length"):
        start, shown = browser.evaluate(
            "(() => { const tr = document.querySelector('tr.review.playable');"
            " tr.querySelector('td').click(); const p = [...document.querySelectorAll("
            "'[data-mtanno-player]')].find(e => e.dataset.doc === tr.dataset.doc);"
            " return [+tr.querySelector('input.start').value, +p.dataset.frame]; })()")
        assert abs(shown - start) <= 1


def test_a_motion_that_cannot_be_read_is_reported_and_the_page_written(world, tmp_path):
    """One rule for batches: a broken motion file is one line naming it, its document gets
    no player (the page says so), the others play; exit code 1."""
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
    page = (tmp_path / "rep" / "index.html").read_text(encoding="utf-8")
    assert page.count("data-mtanno-player data-doc") == len(amcs) - 1
    assert f"No motion for 1 document(s): {amcs[0].stem}" in page


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
    page = _report(world, tmp_path / "b", "--motions", alone, "--asf",
                   next(world.docs.glob("*.asf")))
    assert page.count("data-mtanno-player data-doc") == 1


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
