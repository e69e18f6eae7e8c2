#!/usr/bin/env python3
"""The Bandai set-2 leave-one-style-out protocol of scripts/experiment_bandai.sh (issue 10).

    bandai_folds.py unpack                 print the five unpacked style folders (.cache/data)
    bandai_folds.py folds FEATS OUT [--per 12] [--seed 0]

``folds`` reads the feature files ``FEATS/<style>/dataset-2_<content>_<style>_<id>.parquet``
(``mtanno features`` of each unpacked style folder) and writes, for every style S:

* ``OUT/S/train.csv`` — the training clips: ``--per`` clips per content of each of the four
  other styles, drawn with a seeded generator (``random.Random("SEED:STYLE:CONTENT")``, so
  the draw of a style does not depend on which style is held out); columns
  ``file,class,actor,take`` with ``actor`` = the style (the performer ``tune`` holds out);
* ``OUT/S/truth.csv`` — every clip of S as one document, labelled with its content over all
  its frames.

    bandai_folds.py review FOLD OUT --k K [--seed 0] [--features FEATS]

``review`` (issue 24, the review loop of scripts/experiment_review.sh) simulates a person who
reviewed ``K`` clips per content of the held-out style S of fold folder ``FOLD``
(``OUT/S`` of ``folds``; S is its name) on the report page and downloaded the truth: it
writes

* ``OUT/reviewed.csv`` — that truth CSV (``doc,start,end,label,fps``, whole clips, 1-based
  inclusive frames at 30 Hz), the format the page's "Download truth" writes; the clips are
  the first K of a seeded shuffle of each content's clips of S
  (``random.Random("SEED:review:S:CONTENT")``, :func:`draw_reviewed`), so the clips of
  K = 1 are among those of K = 2;
* ``OUT/train.csv`` — the fold's training manifest plus one row per segment of
  ``reviewed.csv`` as read back by mtanno's truth reader (actor S: ``tune`` holds the
  reviewed clips out as one more performer, as it holds out each training style);
* ``OUT/truth.csv`` and ``OUT/documents.txt`` — the clips of S that were not reviewed: the
  test documents and their truth (a document reviewed is never tested on);
* with ``--features FEATS`` (the folder of ``folds``): ``OUT/train_truth.csv`` — the same
  training examples as one truth table for ``learn-mt --truth``: a whole-clip row
  (``doc,start,end,label,fps``) per training clip of the fold, then the rows of
  ``reviewed.csv`` appended as downloaded.

K = 0 gives the fold itself: ``train.csv`` and ``truth.csv`` are byte for byte the fold's.

    bandai_folds.py pooled FEATS OUT.csv [--per 12] [--seed 0]

``pooled`` (issue 34, the training set of real size of scripts/bench_tune.py) writes one
training manifest of all five styles (columns ``file,class,actor,take``, actor = the style):
``--per`` clips per content and style, 10 contents × 5 styles × ``--per`` clips (600 for
12). Each (style, content) draws as ``folds`` does (``random.Random("SEED:STYLE:CONTENT")``,
so ``--per 12`` holds exactly the clips of the folds' training sets); where a content of a
style has fewer clips than ``--per`` (elderly has 17 of some), the draw goes round again
(each round a seeded shuffle, ``random.Random("SEED:STYLE:CONTENT:ROUND")``): clips repeat,
so that every size has the same five performers (folds) and the same classes.
"""

from __future__ import annotations

import argparse
import random
import re
import sys
from collections import defaultdict
from pathlib import Path

STYLES = ("active", "elderly", "feminine", "masculine", "normal")
_NAME = re.compile(r"dataset-2_(?P<content>.+)_(?P<style>[a-z]+)_(?P<take>\d+)$")


def unpack() -> list[Path]:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from data_cache import SHARED_DATA, unpack_archive

    return [unpack_archive(SHARED_DATA / "bandai" / f"set2-{s}.tar.xz") / "data"
            for s in STYLES]


def clips(feats: Path) -> dict[tuple[str, str], list[tuple[str, str, int]]]:
    """(style, content) → sorted (feature path relative to FEATS without suffix, take,
    frames)."""
    import pyarrow.parquet as pq

    out: dict[tuple[str, str], list] = defaultdict(list)
    for style in STYLES:
        for p in sorted((feats / style).glob("*.parquet")):
            m = _NAME.match(p.stem)
            if m is None or m["style"] != style:
                raise SystemExit(f"bandai_folds: unexpected file {p}")
            out[(style, m["content"])].append((f"{style}/{p.stem}", m["take"],
                                               pq.ParquetFile(p).metadata.num_rows))
    return out


def folds(feats: Path, out: Path, per: int, seed: int) -> None:
    data = clips(feats)
    for held in STYLES:
        d = out / held
        d.mkdir(parents=True, exist_ok=True)
        rows = ["file,class,actor,take"]
        for (style, content), items in sorted(data.items()):
            if style == held:
                continue
            rng = random.Random(f"{seed}:{style}:{content}")
            for rel, take, _ in sorted(rng.sample(items, min(per, len(items)))):
                rows.append(f"{rel}.bvh,{content},{style},{take}")
        (d / "train.csv").write_text("\n".join(rows) + "\n")
        truth = ["doc,start,end,label"]
        for (style, content), items in sorted(data.items()):
            if style == held:
                truth += [f"{Path(rel).name},1,{n},{content}" for rel, _, n in items]
        (d / "truth.csv").write_text("\n".join(truth) + "\n")
        print(f"bandai_folds: {held}: {len(rows) - 1} training clips, {len(truth) - 1} "
              f"documents -> {d}", file=sys.stderr)


def pooled(feats: Path, out: Path, per: int, seed: int) -> None:
    """Write the pooled manifest of all five styles (module docstring)."""
    if per < 1:
        raise SystemExit(f"bandai_folds: --per must be >= 1 (got {per})")
    data = clips(feats)
    rows = ["file,class,actor,take"]
    for (style, content), items in sorted(data.items()):
        got = sorted(random.Random(f"{seed}:{style}:{content}").sample(items,
                                                                        min(per, len(items))))
        rnd = 0
        while len(got) < per:
            rnd += 1
            again = list(items)
            random.Random(f"{seed}:{style}:{content}:{rnd}").shuffle(again)
            got += again[:per - len(got)]
        rows += [f"{rel}.bvh,{content},{style},{take}" for rel, take, _ in got]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(rows) + "\n")
    print(f"bandai_folds: pooled, {per} per content and style: {len(rows) - 1} training clips "
          f"-> {out}", file=sys.stderr)


def draw_reviewed(truth: list[dict[str, str]], style: str, k: int,
                  seed: int) -> list[dict[str, str]]:
    """The rows of the held-out style's truth (``doc,start,end,label`` dicts, one whole clip
    each) that a reviewer accepted: per content (label, in sorted order) the first ``k`` of
    the content's rows sorted by document and shuffled by
    ``random.Random("SEED:review:STYLE:CONTENT")`` — reproducible, independent of the other
    contents, and nested in ``k`` (a content with fewer than ``k`` clips gives them all)."""
    if k < 0:
        raise SystemExit(f"bandai_folds: --k must be >= 0 (got {k})")
    by_content: dict[str, list[dict[str, str]]] = defaultdict(list)
    for row in truth:
        by_content[row["label"]].append(row)
    reviewed: list[dict[str, str]] = []
    for content, rows in sorted(by_content.items()):
        order = sorted(rows, key=lambda r: r["doc"])
        random.Random(f"{seed}:review:{style}:{content}").shuffle(order)
        reviewed += order[:k]
    return reviewed


def _frames(feats: Path, rel: str) -> int:
    """Analysis frames (30 Hz) of the feature file FEATS/<rel>.parquet."""
    import pyarrow.parquet as pq

    return pq.ParquetFile(feats / f"{rel}.parquet").metadata.num_rows


def review(fold: Path, out: Path, k: int, seed: int, feats: Path | None = None) -> None:
    """Write OUT's files for ``k`` reviewed clips per content (module docstring)."""
    import csv

    from mtanno.labels.truth import read_truth

    train = (fold / "train.csv").read_text().splitlines()
    with open(fold / "truth.csv", newline="") as fh:
        truth = list(csv.DictReader(fh))
    style = fold.name
    reviewed = draw_reviewed(truth, style, k, seed)
    names = {r["doc"] for r in reviewed}
    out.mkdir(parents=True, exist_ok=True)
    downloaded = "doc,start,end,label,fps\n" + "".join(
        f"{r['doc']},{r['start']},{r['end']},{r['label']},30\n" for r in reviewed)
    (out / "reviewed.csv").write_text(downloaded)
    # the loop as a user runs it: the downloaded truth is read back, not the rows drawn
    whole = {r["doc"]: int(r["end"]) for r in truth}
    rows = list(train)
    for seg in read_truth(out / "reviewed.csv"):
        if seg.doc not in whole or (seg.start, seg.end) != (1, whole[seg.doc]):
            raise SystemExit(f"bandai_folds: reviewed segment {seg} is not a whole clip of "
                             f"{style} (a manifest row is a whole clip)")
        rows.append(f"{style}/{seg.doc}.bvh,{seg.label},{style},{_NAME.match(seg.doc)['take']}")
    (out / "train.csv").write_text("\n".join(rows) + "\n")
    test = [r for r in truth if r["doc"] not in names]
    (out / "truth.csv").write_text("doc,start,end,label\n" + "".join(
        f"{r['doc']},{r['start']},{r['end']},{r['label']}\n" for r in test))
    (out / "documents.txt").write_text("".join(f"{style}/{r['doc']}.parquet\n" for r in test))
    if feats is not None:
        lines = ["doc,start,end,label,fps"]
        for line in train[1:]:
            file, label = line.split(",")[:2]
            rel = str(Path(file).with_suffix(""))
            lines.append(f"{Path(rel).name},1,{_frames(feats, rel)},{label},30")
        (out / "train_truth.csv").write_text(
            "\n".join(lines) + "\n" + downloaded.split("\n", 1)[1])
    print(f"bandai_folds: {style}, k = {k}: {len(reviewed)} reviewed clips, {len(test)} test "
          f"documents -> {out}", file=sys.stderr)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("unpack")
    f = sub.add_parser("folds")
    f.add_argument("feats", type=Path)
    f.add_argument("out", type=Path)
    f.add_argument("--per", type=int, default=12)
    f.add_argument("--seed", type=int, default=0)
    r = sub.add_parser("review")
    r.add_argument("fold", type=Path)
    r.add_argument("out", type=Path)
    r.add_argument("--k", type=int, required=True)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--features", type=Path, default=None)
    p = sub.add_parser("pooled")
    p.add_argument("feats", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--per", type=int, default=12)
    p.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    if a.cmd == "pooled":
        pooled(a.feats, a.out, a.per, a.seed)
        return 0
    if a.cmd == "review":
        review(a.fold, a.out, a.k, a.seed, a.features)
        return 0
    if a.cmd == "unpack":
        for p in unpack():
            print(p)
        return 0
    folds(a.feats, a.out, a.per, a.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
