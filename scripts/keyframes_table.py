#!/usr/bin/env python3
"""Per-class table of keyframe queries on HDM05 clips (issue 7): for each query folder
(learned by the GA, the hard and heuristic methods, or the reference implementation's
hand-made queries), the training fitness — P, R, F2 on the train-split clips (actors bd,
bk, dg; the learner's own measure, fitness.md) — and how many of the dev actor mm's clips
of the class it finds, and how many clips of other classes it fires in.

    scripts/keyframes_table.py --features FEATS --manifest clips.csv NAME=KF_DIR ...
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def clip_set(manifest: Path, features: Path, split: str):
    """(training set of the split's clips, their examples)."""
    from mtanno.keyframes.learn import keyframe_training_set
    from mtanno.templates import group_by_class, load_examples, sources_from_manifest

    srcs = sources_from_manifest(manifest, features_dir=features, split=split)
    groups = group_by_class(srcs)
    examples = [e for c in groups for e in load_examples(groups[c])]
    return keyframe_training_set(examples, jitter=0), examples


def clips_found(examples, query) -> tuple[int, int, int]:
    """(clips of the query's class with a hit, clips of the class, other clips with a hit),
    each clip searched on its own."""
    from mtanno.keyframes import search_documents

    found = total = neg = 0
    for ex in examples:
        hit = len(search_documents([("c", ex.X)], ex.feature_names, query)) > 0
        if ex.class_name == query.class_name:
            total += 1
            found += hit
        else:
            neg += hit
    return found, total, neg


def main(argv=None) -> int:
    from mtanno.keyframes import load_keyframe_folder

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--features", type=Path, required=True)
    ap.add_argument("--manifest", type=Path, required=True)
    ap.add_argument("folders", nargs="+", metavar="NAME=KF_DIR")
    a = ap.parse_args(argv)
    train, _ = clip_set(a.manifest, a.features, "train")
    _, dev = clip_set(a.manifest, a.features, "dev")
    sets = [(n, load_keyframe_folder(p)) for n, p in (f.split("=", 1) for f in a.folders)]
    classes = sorted({c for _, qs in sets for c in qs if c in train.classes()})
    head = "| class | " + " | ".join(
        f"{n}: n | P | R | F2 | mm found | other fires" for n, _ in sets) + " |"
    print(head)
    print("|" + "---|" * (1 + 6 * len(sets)))
    totals = {n: [0, 0, 0] for n, _ in sets}
    for c in classes:
        cells = [c]
        for n, qs in sets:
            q = qs.get(c)
            if q is None:
                cells += ["–"] * 6
                continue
            s = train.score_query(q, 2.0)
            f, p, neg = clips_found(dev, q)
            totals[n][0] += f
            totals[n][1] += p
            totals[n][2] += neg
            cells += [str(q.n), f"{s.P:.2f}", f"{s.R:.2f}", f"{s.F:.2f}", f"{f}/{p}", str(neg)]
        print("| " + " | ".join(cells) + " |")
    print("| all | " + " | ".join(
        f"| | | | {t[0]}/{t[1]} | {t[2]}" for n, t in totals.items()) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
