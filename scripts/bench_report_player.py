"""Benchmark of ``mtanno report --motions`` (issue 24 targets: 10 documents of 60 s each
with their motions in < 10 s as a whole command, the page < 20 MB).

Ten documents are composed from the HDM05 clips of actor mm (``mtanno compose``, seeded, 60
s and more each); their annotation is their truth as an annotation table (one row per
clip, a cost and a confidence each), so the page has a review list as long as a real run's.
Timed: the whole ``mtanno report ANNOTATION -o DIR --motions DOCS/`` command (reading the
10 AMC files, the poses, the timeline figures, the page), median of ``--repeats``, and the
same without ``--motions`` in the same run (the players' share); the page's size.

    .venv/bin/python scripts/bench_report_player.py [--repeats 3] [--out .cache/bench/report]
"""

from __future__ import annotations

import argparse
import csv
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
MTANNO = REPO / ".venv" / "bin" / "mtanno"
HDM05 = REPO.parent / "shared" / "data" / "hdm05_cut"


def run(*args) -> float:
    t0 = time.perf_counter()
    subprocess.run([str(MTANNO), *map(str, args)], check=True)
    return time.perf_counter() - t0


def setup(out: Path) -> tuple[Path, Path]:
    """The ten composed documents and their annotation table."""
    docs = out / "docs"
    if not (docs / "truth.csv").exists():
        run("compose", HDM05 / "clips.csv", "--actor", "mm", "--docs", 10, "--clips-per-doc",
            28, "--seed", 0, "-o", docs, "-q")
    ann = out / "annotation.csv"
    with open(docs / "truth.csv", newline="") as fh:
        truth = list(csv.DictReader(fh))
    with open(ann, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["doc", "start", "end", "label", "cost", "confidence"])
        for i, r in enumerate(truth):
            w.writerow([r["doc"], r["start"], r["end"], r["label"], f"{0.01 * (i % 20):.2f}",
                        f"{1 - 0.04 * (i % 20):.2f}"])
    return docs, ann


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=REPO / ".cache" / "bench" / "report")
    a = ap.parse_args(argv)
    print(machine())
    docs, ann = setup(a.out)
    frames = {}
    with open(docs / "truth.csv", newline="") as fh:
        for r in csv.DictReader(fh):
            frames[r["doc"]] = max(frames.get(r["doc"], 0), int(r["end"]))
    print(f"{len(frames)} documents, {min(frames.values()) / 30:.0f}–"
          f"{max(frames.values()) / 30:.0f} s each, {sum(frames.values()) / 30 / 60:.1f} min")
    run("report", ann, "-o", a.out / "warm", "--motions", docs, "-q")  # compile, cache
    with_m, without = [], []
    for _ in range(a.repeats):  # interleaved: both see the same machine load
        with_m.append(run("report", ann, "-o", a.out / "with", "--motions", docs, "-q"))
        without.append(run("report", ann, "-o", a.out / "without", "-q"))
    page = (a.out / "with" / "index.html").stat().st_size
    plain = (a.out / "without" / "index.html").stat().st_size
    print(f"report --motions, whole command: {statistics.median(with_m):.2f} s (median of "
          f"{a.repeats}; target < 10 s)")
    print(f"report without --motions:        {statistics.median(without):.2f} s")
    print(f"page: {page / 1e6:.2f} MB with the players, {plain / 1e6:.2f} MB without "
          "(target < 20 MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
