#!/usr/bin/env python3
"""The tables of scripts/experiment_review.sh (issue 24, the review loop): for each number K
of reviewed clips per content of the held-out style, the mean over the held-out styles of
F1, F2 (frames, segments; [MBS09] §7), F1@50, Edit and frame accuracy, for the reference
annotation and the tuned one; then the tuned figures per style.

Usage: ``review_tables.py OUT [--styles S...] [--ks K...]`` (OUT/<style>/k<K>/report_*.json
from ``mtanno evaluate --json``). Prints Markdown.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

COLUMNS = (("F1", lambda r: r["frame"]["F"]), ("F2", lambda r: r["segment"]["F"]),
           ("F1@50", lambda r: r["f1_50"]), ("Edit", lambda r: r["edit"]),
           ("Acc", lambda r: r["accuracy"]))


def _figures(path: Path) -> list[float]:
    report = json.loads(path.read_text(encoding="utf-8"))
    return [float("nan") if f(report) is None else float(f(report)) for _, f in COLUMNS]


def _cells(values: list[float]) -> str:
    return " | ".join(f"{v:.3f}" for v in values)


def tables(out: Path, styles: list[str], ks: list[str]) -> str:
    """The Markdown of both tables; a missing report is a SystemExit naming it."""
    head = " | ".join(c for c, _ in COLUMNS)
    lines = [f"| K | annotation | {head} |", "|---|---|" + "---|" * len(COLUMNS)]
    per_style = {}
    for k in ks:
        for run in ("reference", "tuned"):
            rows = []
            for s in styles:
                path = out / s / f"k{k}" / f"report_{run}.json"
                if not path.exists():
                    raise SystemExit(f"review_tables: {path} is missing")
                rows.append(_figures(path))
                if run == "tuned":
                    per_style[(s, k)] = rows[-1]
            mean = [sum(col) / len(col) for col in zip(*rows)]
            lines.append(f"| {k} | {run} | {_cells(mean)} |")
    lines += ["", f"| style | K | {head} |", "|---|---|" + "---|" * len(COLUMNS)]
    for s in styles:
        for k in ks:
            lines.append(f"| {s} | {k} | {_cells(per_style[(s, k)])} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--styles", nargs="+",
                    default=["active", "elderly", "feminine", "masculine", "normal"])
    ap.add_argument("--ks", nargs="+", default=["0", "1", "2"])
    a = ap.parse_args(argv)
    print(tables(a.out, a.styles, a.ks))
    return 0


if __name__ == "__main__":
    sys.exit(main())
