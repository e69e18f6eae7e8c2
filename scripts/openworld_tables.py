#!/usr/bin/env python
"""Figures of the open-world protocol (issue 26; ``scripts/experiment_openworld.sh``).

* ``labelled ANNOTATION...``: the fraction of the documents' frames that some row labels
  (frames per document from each table's provenance) — on a foreign archive, every
  labelled frame is wrong;
* ``confidence ANNOTATION --truth T``: how well the confidence column tells right rows
  (a truth segment of the row's label overlaps it with IoU ≥ 0.5) from wrong ones: AUROC,
  expected calibration error (10 bins), the reliability table; ``--plot PNG`` draws it.

Prints one line (or a small table) per call; ``--json`` writes the figures.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def labelled(paths: list[str]) -> dict:
    from mtanno.annotate import read_annotation_tables

    rows, frames, _ = read_annotation_tables(paths)
    total = sum(frames.values())
    cover = {d: np.zeros(n, dtype=bool) for d, n in frames.items()}
    for r in rows:
        cover[r.doc][r.start:r.end + 1] = True
    hit = int(sum(c.sum() for c in cover.values()))
    per_label: dict[str, int] = {}
    for r in rows:
        per_label[r.label] = per_label.get(r.label, 0) + r.end - r.start + 1
    return {"documents": len(frames), "frames": total, "labelled": hit,
            "fraction": hit / total if total else 0.0, "rows": len(rows),
            "frames_per_label": dict(sorted(per_label.items(), key=lambda kv: -kv[1]))}


def confidence(paths: list[str], truth: str, bins: int = 10) -> dict:
    from mtanno.annotate import read_annotation_tables
    from mtanno.evaluation.calibration import (
        auroc,
        expected_calibration_error,
        reliability_table,
        rows_right,
    )
    from mtanno.labels.truth import read_truth

    rows, _, _ = read_annotation_tables(paths)
    right = rows_right(rows, read_truth(truth))
    prob = [r.confidence for r in rows]
    p, y = np.array(prob, dtype=float), np.array(right, dtype=float)
    keep = ~np.isnan(p)
    table = reliability_table(p[keep], y[keep], bins=bins)
    return {"rows": int(keep.sum()), "right": int(y[keep].sum()),
            "auroc": auroc(p[keep], y[keep]),
            "ece": expected_calibration_error(p[keep], y[keep], bins=bins),
            "reliability": table.rows(), "_table": table}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    a = sub.add_parser("labelled")
    a.add_argument("annotations", nargs="+")
    a.add_argument("--json")
    c = sub.add_parser("confidence")
    c.add_argument("annotations", nargs="+")
    c.add_argument("--truth", required=True)
    c.add_argument("--json")
    c.add_argument("--plot")
    args = ap.parse_args(argv)
    if args.what == "labelled":
        out = labelled(args.annotations)
        print(f"labelled {out['fraction']:.3f} of {out['frames']} frames "
              f"({out['documents']} documents, {out['rows']} rows)")
    else:
        out = confidence(args.annotations, args.truth)
        print(f"confidence: {out['rows']} rows ({out['right']} right), AUROC "
              f"{out['auroc']:.3f}, ECE {out['ece']:.3f}")
        table = out.pop("_table")
        if args.plot:
            from mtanno.plot import reliability_figure

            reliability_figure(table, title="confidence").savefig(args.plot, dpi=100)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({k: v for k, v in out.items() if not k.startswith("_")}, fh, indent=1,
                      default=str)
    return 0


if __name__ == "__main__":
    sys.exit(main())
