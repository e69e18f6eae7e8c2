"""Issue 25, the frictions still open: query by example finds its own source first, one
exit-code rule for batches, guessed skeleton maps keep outputs up to date, learn-keyframes
leaves no empty folder when interrupted."""

from __future__ import annotations

import numpy as np
import pytest
from world import cli

from mtanno.index import example_query, index_from_matrices, search
from mtanno.index.example import drop_short_segments

# --- query by example: the example's own occurrence ranks first with score 0 ------------

FEATURES = ["a", "b", "c", "d", "e"]
GROUPS = {"g": ["a", "b", "c"], "h": ["d", "e"]}


def _random_doc(rng: np.random.Generator, frames: int) -> np.ndarray:
    """A (features × frames) 0/1 matrix of runs of 1–20 frames, with one- and two-frame
    flickers (the transients query by example smooths away)."""
    X = np.zeros((len(FEATURES), frames), np.uint8)
    for f in range(len(FEATURES)):
        t, v = 0, int(rng.integers(2))
        while t < frames:
            n = int(rng.integers(1, 3)) if rng.random() < 0.3 else int(rng.integers(3, 21))
            X[f, t:t + n] = v
            t, v = t + n, 1 - v
    return X


def _random_index(rng: np.random.Generator, n_docs: int = 8):
    docs = {f"doc{i:02d}": _random_doc(rng, int(rng.integers(20, 120))) for i in range(n_docs)}
    return index_from_matrices(docs, FEATURES, GROUPS), docs


def _smoothed_runs(codes: np.ndarray, min_segment: int) -> tuple[list[int], list[int]]:
    """Brute force: (lengths, values) of a code sequence's runs after the transients are
    given to their neighbours (the first and last runs stay, however short)."""
    starts = [t for t in range(len(codes)) if t == 0 or codes[t] != codes[t - 1]]
    lengths = [b - a for a, b in zip(starts, starts[1:] + [len(codes)])]
    return drop_short_segments(np.array(lengths), codes[starts], min_segment, keep_ends=True)


def _oracle(docs, names, X_ex, chosen, a, b, min_segment):
    """Every hit of a one-group query by example, found by scanning each document's
    smoothed runs frame by frame, with score and trimmed frames; ranked."""
    def codes_of(X):
        out = np.zeros(X.shape[1], np.int64)
        for k, f in enumerate(chosen):
            out |= X[FEATURES.index(f)].astype(np.int64) << k
        return out

    ex_len, ex_val = _smoothed_runs(codes_of(X_ex), min_segment)
    ends = np.cumsum(ex_len)
    runs = [(int(e - n), int(e), v) for n, e, v in zip(ex_len, ends, ex_val)
            if e > a and e - n <= b]
    q = [(min(e, b + 1) - max(s, a), v, e - s) for s, e, v in runs]
    if len(q) > 1 and q[-1][0] < min_segment:
        q = q[:-1]
    if len(q) > 1 and q[0][0] < min_segment:
        q = q[1:]
    qlen, qval, whole = zip(*q)
    L = len(q)
    out = []
    for d, name in enumerate(names):
        lengths, vals = _smoothed_runs(codes_of(docs[name]), min_segment)
        starts = np.r_[0, np.cumsum(lengths)]
        for k in range(len(vals) - L + 1):
            if tuple(vals[k:k + L]) != qval:
                continue
            h = lengths[k:k + L]
            want = list(qlen)
            want[0], want[-1] = whole[0], whole[-1]  # the cut's runs, whole
            score = sum(abs(x - y) for x, y in zip(h, want))
            s, e = int(starts[k]), int(starts[k + L]) - 1
            if L > 1:
                s = max(s, int(starts[k + 1]) - qlen[0])
                e = min(e, int(starts[k + L - 1]) + qlen[-1] - 1)
            out.append((score, d, s, e))
    return sorted(out)


def _random_cut(rng):
    """A random index, its documents and names, a source document, its features and a cut
    (first, last frame) of it."""
    index, docs = _random_index(rng)
    names = [d.name for d in index.documents]
    src = names[int(rng.integers(len(names)))]
    X = docs[src]
    a = int(rng.integers(X.shape[1]))
    return index, docs, names, src, X, a, int(rng.integers(a, X.shape[1]))


@pytest.mark.parametrize("seed", range(4))
def test_example_query_equals_brute_force_and_finds_itself_first(seed):
    """Issue 25: `query --example X --frames 40:100 --features F` ranked the example's own
    clip 24th (score 77): the cut's partial first and last segments were compared with the
    document's whole runs, and the example was smoothed (transients dropped) while the
    documents were not. Now, for random cuts, feature subsets of one group and
    --min-segment values, the hits equal a brute-force scan of the smoothed documents and
    the source's hit covering the cut is first with score 0."""
    rng = np.random.default_rng(seed)
    for _ in range(60):
        index, docs, names, src, X, a, b = _random_cut(rng)
        group = GROUPS["g"] if rng.random() < 0.7 else GROUPS["h"]
        chosen = [f for f in group if rng.random() < 0.6] or [group[0]]
        min_segment = int(rng.integers(1, 5))
        hits = search(index, example_query(index, X, FEATURES, chosen, frames=(a, b),
                                           min_segment=min_segment))
        want = _oracle(docs, names, X, chosen, a, b, min_segment)
        got = [(float(s), int(d), int(st), int(e))
               for s, d, st, e in zip(hits.score, hits.doc, hits.start, hits.end)]
        assert got == [(float(s), d, st, e) for s, d, st, e in want]
        assert hits.score[0] == 0
        own = [i for i, d in enumerate(hits.doc) if names[d] == src
               and hits.start[i] <= b and hits.end[i] >= a]
        assert own and hits.score[own[0]] == 0
        # ranked first, or after documents identical to the source around the cut
        assert np.all(hits.score[:own[0] + 1] == 0)


def test_example_query_over_groups_finds_itself_first():
    """Features of both groups: each group's hits are intersected on frames; the source
    still has a hit overlapping the cut, with score 0, and nothing ranks before it with a
    worse score."""
    rng = np.random.default_rng(7)
    for _ in range(150):
        index, _, names, src, X, a, b = _random_cut(rng)
        chosen = [f for f in FEATURES if rng.random() < 0.5] or ["a", "d"]
        hits = search(index, example_query(index, X, FEATURES, chosen, frames=(a, b),
                                           min_segment=int(rng.integers(1, 5))))
        own = [i for i, d in enumerate(hits.doc) if names[d] == src
               and hits.start[i] <= b and hits.end[i] >= a]
        assert own, (src, a, b, chosen)
        assert hits.score[own[0]] == 0 and np.all(hits.score[:own[0] + 1] == 0)


def test_bandai_example_ranks_its_own_clip_first(tmp_path):
    """The reported query on real Bandai set-1 clips: `--frames 40:100 --features
    root_behind_frontal_plane` (and random cuts, other features) ranks the example's own
    clip first with score 0."""
    from conftest import SHARED
    from data_cache import bandai_clips

    from mtanno.features.batch import plan_batch, run_batch
    from mtanno.index import build_index
    from mtanno.index.core import read_feature_doc

    if not (SHARED / "data" / "bandai").is_dir():
        pytest.skip("../shared/data/bandai is not present")
    clips = [p for p in bandai_clips("set1.tar.xz")
             if p.stem.split("_")[1] in {"bow", "walk", "dash"}][::3][:12]
    summary = run_batch(plan_batch(clips, tmp_path / "features"), n_jobs=1)
    assert summary.count("written") == len(clips), summary.line()
    files = sorted((tmp_path / "features").rglob("*.parquet"))
    index = build_index(files, tmp_path / "index")
    rng = np.random.default_rng(3)
    feats = ["root_behind_frontal_plane", "rknee_bent", "lknee_bent", "rhand_above_neck"]
    for f in files:
        ex = read_feature_doc(f)
        n = ex.X.shape[1]
        cuts = [(39, 99)] * (n >= 100) + [tuple(sorted(rng.integers(0, n, 2))) for _ in range(3)]
        for a, b in cuts:
            chosen = [feats[0]] if (a, b) == (39, 99) else list(rng.choice(feats, 2, False))
            hits = search(index, example_query(index, ex.X, ex.names, chosen,
                                               frames=(int(a), int(b)), min_segment=3))
            top = index.documents[int(hits.doc[0])].name
            assert (top, hits.score[0]) == (ex.name, 0), (ex.name, a, b, chosen, top)


# --- exit codes: one rule for batches ----------------------------------------------------

def _lines(r) -> list[str]:
    return [m for m in r.output.splitlines() if m.startswith("mtanno: ")]


def test_features_goes_on_past_a_missing_path_or_an_unknown_type(world, tmp_path):
    """Issue 25: a missing path beside good ones aborted `features` with exit 2 while a
    corrupt file was skipped with exit 1. Now every bad input of a batch is one line and
    the others are written (exit 1); exit 2 only when no input is usable, as `info` gives
    for the one file it reads; a run that wrote nothing leaves no output folder."""

    good = world.clips / "squat"
    c3d = tmp_path / "take.fbx"
    c3d.write_bytes(b"\x02\x50" + bytes(510))
    for bad, words in ((tmp_path / "nope.amc", "no such file or directory"),
                       (c3d, "unknown motion file type '.fbx'")):
        out = tmp_path / f"out_{bad.suffix[1:]}"
        r = cli("features", good, bad, "-o", out)
        assert r.exit_code == 1, r.output
        assert _lines(r) == [f"mtanno: {bad}: {words} (expected .amc, .bvh or .c3d)"
                             if bad == c3d else f"mtanno: {bad}: {words}"]
        assert len(list(out.glob("*.parquet"))) == len(list(good.glob("*.amc"))) > 0
        assert "1 failed" in r.output
        alone = tmp_path / f"alone_{bad.suffix[1:]}"
        r = cli("features", bad, "-o", alone)
        assert r.exit_code == 2 and len(_lines(r)) == 1 and words in r.output
        assert not alone.exists()
    r = cli("info", c3d)
    assert r.exit_code == 2 and "unknown motion file type '.fbx'" in r.output
    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / "x.bvh").write_text("junk\n")
    r = cli("features", corrupt, "-o", tmp_path / "nothing")
    assert r.exit_code == 1 and "0 written" in r.output
    assert not (tmp_path / "nothing").exists()


@pytest.mark.parametrize("command", ["annotate", "index", "index add", "retrieve",
                                     "evaluate-retrieval"])
def test_batches_go_on_past_a_missing_path(world, tmp_path, command):
    """The same rule in the other batch commands: the missing path is one line, the good
    input is processed, exit code 1; the missing path alone is exit code 2."""

    missing = tmp_path / "nope.parquet"

    def run(*inputs):
        if command == "annotate":
            return cli("annotate", "--mt", world.mt, *inputs, "-o", tmp_path / "a.csv", "-q")
        if command == "index":
            return cli("index", *inputs, "-o", tmp_path / "idx", "-q")
        if command == "index add":
            idx = tmp_path / "idx_add"
            if not idx.exists():
                world.copy(world.index, idx)
            return cli("index", "add", idx, *inputs, "-q")
        if command == "retrieve":
            return cli("retrieve", "--mt", world.template, *inputs, "-o", tmp_path / "h.csv",
                       "-q")
        return cli("evaluate-retrieval", "--mt", world.mt, "--truth", world.truth, *inputs,
                   "-o", tmp_path / "e.csv")

    r = run(world.doc_files[0], missing)
    assert r.exit_code == 1, r.output
    assert _lines(r) == [f"mtanno: {missing}: no such feature file or folder"]
    if command != "index add":
        assert any(tmp_path.glob("[aihe]*.*")) or (tmp_path / "idx").is_dir()
    if command != "index add":
        r = run(missing)
        assert r.exit_code == 2 and len(_lines(r)) == 1, r.output


def test_retrieve_takes_the_template_folder_annotate_takes(world, tmp_path):
    """Issue 25: `retrieve --mt MT/` refused the folder `annotate --mt MT/` takes. Each
    class is retrieved; a first column names it, ranks count per class, and each class's
    rows equal a retrieve of its template alone."""
    import csv


    out = tmp_path / "all.csv"
    r = cli("retrieve", "--mt", world.mt, world.docfeats, "--tau", "0.2", "-o", out, "-q")
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(out.open()))
    classes = sorted(p.stem for p in world.mt.glob("*.json"))
    assert list(rows[0]) == ["class", "doc", "start", "end", "start_native", "end_native",
                             "cost", "rank"]
    assert sorted({r["class"] for r in rows}) <= classes and len({r["class"] for r in rows}) > 1
    for cls in {r["class"] for r in rows}:
        one = tmp_path / f"{cls}.csv"
        r = cli("retrieve", "--mt", world.mt / f"{cls}.json", world.docfeats, "--tau", "0.2",
                "-o", one, "-q")
        assert r.exit_code == 0
        alone = list(csv.DictReader(one.open()))
        assert [{k: v for k, v in x.items() if k != "class"} for x in rows
                if x["class"] == cls] == alone


def test_an_interrupted_learn_keyframes_leaves_no_empty_folder(world, tmp_path, monkeypatch):
    """Issue 25: learn-keyframes interrupted (Ctrl-C) before it wrote a class left an empty
    output folder; now the folder it made is removed (mtanno.util.output.output_folder)."""
    import mtanno.keyframes.learn

    started = []

    def interrupted(*args, **kwargs):
        started.append(1)
        raise KeyboardInterrupt

    monkeypatch.setattr(mtanno.keyframes.learn, "learn_keyframes", interrupted)
    out = tmp_path / "new" / "kf"
    r = cli("learn-keyframes", "--mt", world.mt, world.feats, "-o", out, "--runs", "2", "-q")
    assert started and r.exit_code != 0
    assert not out.exists() and not out.parent.exists()


# --- guessed skeleton maps: outputs stay up to date ---------------------------------------

def test_a_guessed_map_output_is_up_to_date_on_the_second_run(tmp_path):
    """Issue 25: a BVH no built-in map fits (its map is guessed from names and tree) was
    recomputed by every `features` run: the up-to-date check looked for a map file that
    fits and found none. Now the guessed map's content hash is compared (the guess is a
    function of the file): the second run writes nothing; --force still recomputes."""
    from conftest import SHARED
    from data_cache import bandai_clips
    from test_rig_guess import BANDAI_CONVENTIONS, parse_bvh

    if not (SHARED / "data" / "bandai").is_dir():
        pytest.skip("../shared/data/bandai is not present")
    clip = next(p for p in bandai_clips("set1.tar.xz")
                if p.name == "dataset-1_walk_normal_001.bvh")
    src = tmp_path / "in"
    src.mkdir()
    for c in ("mixamo", "unreal"):
        BANDAI_CONVENTIONS[c](parse_bvh(clip.read_text())).write(src / f"{c}.bvh")
    out = tmp_path / "out"
    r = cli("features", src, "-o", out)
    assert r.exit_code == 0 and "2 written" in r.output, r.output
    r = cli("info", src / "mixamo.bvh")
    assert "guessed" in r.output or "generated" in r.output, r.output
    r = cli("features", src, "-o", out)
    assert r.exit_code == 0 and "0 written" in r.output and "2 up to date" in r.output, r.output
    r = cli("features", src, "-o", out, "--force")
    assert "2 written" in r.output
