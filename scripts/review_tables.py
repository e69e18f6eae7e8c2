#!/usr/bin/env python3
"""The tables of scripts/experiment_review.sh (issue 24, the review loop on Bandai set 2):
for each number K of reviewed clips per content of the held-out style, the mean over the
held-out styles of F1 and F2 (frames and segments, [MBS09] §7), F1@50, Edit and frame
accuracy (all 0–1, from ``mtanno evaluate --json``), for the reference annotation and the
tuned one; then the tuned figures per style. ``test docs`` is the number of test documents
(summed over the styles in the first table): K·10 clips of each style are reviewed and so
leave its test. When every ``report_tuned_common.json`` is there (the tuned annotation of
each K evaluated on the test documents of the last K), a third table gives the means on
those same documents, so that the K compare on one test.

Usage: ``review_tables.py OUT [--styles S...] [--ks K...]`` (reads
OUT/<style>/k<K>/report_{reference,tuned}.json). Prints Markdown.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

STYLES = ("active", "elderly", "feminine", "masculine", "normal")
COLUMNS: tuple[tuple[str, Callable[[dict], float | None]], ...] = (
    ("F1", lambda r: r["frame"]["F"]), ("F2", lambda r: r["segment"]["F"]),
    ("F1@50", lambda r: r["f1_50"]), ("Edit", lambda r: r["edit"]),
    ("Acc", lambda r: r["accuracy"]))


def _report(path: Path) -> dict:
    if not path.exists():
        raise SystemExit(f"review_tables: {path} is missing")
    return json.loads(path.read_text(encoding="utf-8"))


def _figures(report: dict) -> list[float]:
    return [math.nan if f(report) is None else float(f(report)) for _, f in COLUMNS]


def _cells(values: Sequence[float]) -> str:
    return " | ".join("–" if math.isnan(v) else f"{v:.3f}" for v in values)


def tables(out: Path, styles: Sequence[str], ks: Sequence[str]) -> str:
    """The Markdown of both tables (means over ``styles`` per K and annotation; tuned per
    style); a missing report is a SystemExit naming it."""
    head = " | ".join(c for c, _ in COLUMNS)
    rule = "|---" * (len(COLUMNS) + 3) + "|"
    lines = [f"| K | annotation | {head} | test docs |", rule]
    per_style: dict[tuple[str, str], tuple[list[float], int]] = {}
    for k in ks:
        for run in ("reference", "tuned"):
            rows, docs = [], 0
            for s in styles:
                report = _report(out / s / f"k{k}" / f"report_{run}.json")
                rows.append(_figures(report))
                docs += len(report["documents"])
                if run == "tuned":
                    per_style[(s, k)] = (rows[-1], len(report["documents"]))
            mean = [sum(col) / len(col) for col in zip(*rows)]
            name = f"**{run}**" if run == "tuned" else run
            lines.append(f"| {k} | {name} | {_cells(mean)} | {docs} |")
    lines += ["", f"| style | K | {head} | test docs |", rule]
    for s in styles:
        for k in ks:
            figures, docs = per_style[(s, k)]
            lines.append(f"| {s} | {k} | {_cells(figures)} | {docs} |")
    common = {(s, k): out / s / f"k{k}" / "report_tuned_common.json" for s in styles
              for k in ks}
    if all(p.exists() for p in common.values()):
        lines += ["", f"Tuned, every K on the same test documents (those of K = {ks[-1]}):",
                  "", f"| K | {head} | test docs |", "|---" * (len(COLUMNS) + 2) + "|"]
        for k in ks:
            reports = [_report(common[(s, k)]) for s in styles]
            mean = [sum(col) / len(col) for col in zip(*map(_figures, reports))]
            docs = sum(len(r["documents"]) for r in reports)
            lines.append(f"| {k} | {_cells(mean)} | {docs} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the tables of the run folder given on the command line."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="the folder experiment_review.sh wrote")
    ap.add_argument("--styles", nargs="+", default=list(STYLES))
    ap.add_argument("--ks", nargs="+", default=["0", "1", "2"])
    a = ap.parse_args(argv)
    print(tables(a.out, a.styles, a.ks))
    return 0


if __name__ == "__main__":
    sys.exit(main())
