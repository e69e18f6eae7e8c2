#!/usr/bin/env python3
"""Helpers of the annotation experiments (issue 10; scripts/experiment_*.sh).

    annotation_tables.py drop TABLE.csv CLASS -o OUT.csv
        TABLE without the rows of CLASS (a manifest's ``class`` column or a truth table's
        ``label`` column): the training data of the unknown-class protocol.
    annotation_tables.py unknown ANNOTATION... --truth TRUTH.csv --class CLASS -o OUT.json
        The unknown-class rate of CLASS: the fraction of its truth frames that the
        annotations (made without a template of CLASS) label with any class; writes
        {"class", "frames", "labelled"}.
    annotation_tables.py quality NAME=REPORT.json[,REPORT.json...] ...
        A Markdown table: per row the mean over the reports (seeds, styles) of P1 R1 F1
        P2 R2 F2, frame accuracy, Edit and F1@{10,25,50} ("–" for reports without them),
        and each report's F1/F2 (``mtanno evaluate --json`` reports).
    annotation_tables.py unknown-table NAME=RATE.json[,RATE.json...] ...
        A Markdown table of unknown-class rates: per class and overall (frames pooled)
        for each named group of rate files.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections import defaultdict
from pathlib import Path


def drop(table: Path, cls: str, out: Path) -> int:
    with open(table, newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    col = head.index("class") if "class" in head else head.index("label")
    kept = [r for r in rows[1:] if r[col] != cls]
    if len(kept) == len(rows) - 1:
        print(f"annotation_tables: no rows of class {cls} in {table}", file=sys.stderr)
        return 2
    with open(out, "w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows([head, *kept])
    return 0


def unknown(annotations: list[str], truth: str, cls: str, out: Path) -> int:
    import numpy as np

    from mtanno.annotate import read_annotations
    from mtanno.labels.truth import read_truth

    rows = [a for p in annotations for a in read_annotations(p)]
    frames = labelled = 0
    by_doc: dict[str, list] = defaultdict(list)
    for a in rows:
        if a.label == cls:
            print(f"annotation_tables: {cls} is annotated, but it should have no template",
                  file=sys.stderr)
            return 2
        by_doc[a.doc].append(a)
    docs = {a.doc for a in rows}
    for t in read_truth(truth):
        if t.label != cls or (docs and t.doc not in docs):
            continue
        mask = np.zeros(t.end - t.start + 1, dtype=bool)
        for a in by_doc.get(t.doc, []):
            lo, hi = max(a.start + 1, t.start), min(a.end + 1, t.end)
            if lo <= hi:
                mask[lo - t.start:hi - t.start + 1] = True
        frames += mask.size
        labelled += int(mask.sum())
    out.write_text(json.dumps({"class": cls, "frames": frames, "labelled": labelled}) + "\n")
    return 0


def _groups(specs: list[str]) -> list[tuple[str, list[str]]]:
    out = []
    for spec in specs:
        name, files = spec.split("=", 1)
        out.append((name, [f for f in files.split(",") if f]))
    return out


#: The action-segmentation measures of ``mtanno evaluate --json`` (issue 24) and their columns.
FIELD_MEASURES = {"accuracy": "Acc", "edit": "Edit", "f1_10": "F1@10", "f1_25": "F1@25",
                  "f1_50": "F1@50"}


def _mean(values: list) -> str:
    """The mean to 3 decimals, "–" when a report lacks the value (older reports) or it is
    undefined (null)."""
    if not values or any(v is None for v in values):
        return "–"
    return f"{sum(values) / len(values):.3f}"


def quality(specs: list[str]) -> int:
    cols = " | ".join(FIELD_MEASURES.values())
    print(f"| annotation | P1 | R1 | F1 | P2 | R2 | F2 | {cols} | F1 each | F2 each |")
    print("|---|" + "---|" * (8 + len(FIELD_MEASURES)))
    for name, files in _groups(specs):
        reps = [json.loads(Path(f).read_text()) for f in files]
        mean = {(lvl, k): sum(r[lvl][k] for r in reps) / len(reps)
                for lvl in ("frame", "segment") for k in "PRF"}
        field = [_mean([r.get(key) for r in reps]) for key in FIELD_MEASURES]
        each1 = ", ".join(f"{r['frame']['F']:.3f}" for r in reps)
        each2 = ", ".join(f"{r['segment']['F']:.3f}" for r in reps)
        print(f"| {name} | " + " | ".join(f"{mean[(lvl, k)]:.3f}" for lvl in ("frame", "segment")
                                        for k in "PRF")
              + " | " + " | ".join(field) + f" | {each1} | {each2} |")
    return 0


def unknown_table(specs: list[str]) -> int:
    groups = _groups(specs)
    data = []
    classes: list[str] = []
    for name, files in groups:
        per: dict[str, list[int]] = defaultdict(lambda: [0, 0])
        for f in files:
            r = json.loads(Path(f).read_text())
            per[r["class"]][0] += r["labelled"]
            per[r["class"]][1] += r["frames"]
            if r["class"] not in classes:
                classes.append(r["class"])
        data.append((name, per))
    print("| class | frames | " + " | ".join(n for n, _ in data) + " |")
    print("|---|---|" + "---|" * len(data))
    for c in sorted(classes):
        n = next((per[c][1] for _, per in data if c in per), 0)
        cells = [f"{per[c][0] / per[c][1]:.3f}" if per.get(c) and per[c][1] else "–"
                 for _, per in data]
        print(f"| {c} | {n} | " + " | ".join(cells) + " |")
    tot = []
    for _, per in data:
        a = sum(v[0] for v in per.values())
        b = sum(v[1] for v in per.values())
        tot.append(f"**{a / b:.3f}**" if b else "–")
    total_frames = max((sum(v[1] for v in per.values()) for _, per in data), default=0)
    print(f"| all classes (frames pooled) | {total_frames} | " + " | ".join(tot) + " |")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("drop")
    d.add_argument("table", type=Path)
    d.add_argument("cls")
    d.add_argument("-o", "--output", type=Path, required=True)
    u = sub.add_parser("unknown")
    u.add_argument("annotations", nargs="+")
    u.add_argument("--truth", required=True)
    u.add_argument("--class", dest="cls", required=True)
    u.add_argument("-o", "--output", type=Path, required=True)
    q = sub.add_parser("quality")
    q.add_argument("groups", nargs="+", metavar="NAME=REPORT.json[,...]")
    t = sub.add_parser("unknown-table")
    t.add_argument("groups", nargs="+", metavar="NAME=RATE.json[,...]")
    a = ap.parse_args(argv)
    if a.cmd == "drop":
        return drop(a.table, a.cls, a.output)
    if a.cmd == "unknown":
        return unknown(a.annotations, a.truth, a.cls, a.output)
    if a.cmd == "quality":
        return quality(a.groups)
    return unknown_table(a.groups)


if __name__ == "__main__":
    sys.exit(main())
