"""Benchmark of motion-template learning: seconds per class for the 11 HDM05 classes.

Training set per class = every clip of actors bd, bk, dg (``clips.csv`` split ``train``),
in file-name order — the golden templates' setting (``../shared/data/reference/mt/``).
Input: the reference implementation's 30 Hz features (``reference/features/<class>/*.csv``,
default) or mtanno feature files (``--features-dir DIR`` as written by
``mtanno features ../shared/data/hdm05_cut -o DIR``). Only the learning is timed (the
call of :func:`mtanno.templates.learn.learn` on the in-memory matrices), not file reading.
Every figure is the median of ``--repeats`` runs after one warm-up run (which loads or
compiles the numba kernels); each result is also checked against the golden template.

Original system (docs/method.md §9): 3 s per class (MBS09), 3.8–25.6 s, mean 7.5 s (MR06); the
reference implementation under Octave needed the times in ``reference/mt/*_info.txt``,
listed beside ours. Target: < 0.5 s per class. Run:

    .venv/bin/python scripts/bench_learn.py [--repeats 3] [--features-dir DIR]
"""

from __future__ import annotations

import argparse
import csv
import re
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"
REFERENCE = SHARED / "reference"
sys.path.insert(0, str(REPO))

from mtanno.templates.learn import learn  # noqa: E402


def training_sets(features_dir: Path | None) -> dict[str, list[np.ndarray]]:
    rows = list(csv.DictReader((SHARED / "hdm05_cut" / "clips.csv").open()))
    by_class: dict[str, list[str]] = {}
    for r in rows:
        if r["split"] == "train":
            by_class.setdefault(r["class"], []).append(r["file"])
    out = {}
    for cls in sorted(by_class):
        files = sorted(by_class[cls], key=lambda f: Path(f).name)
        if features_dir is None:
            out[cls] = [np.loadtxt(REFERENCE / "features" / cls / (Path(f).stem + ".csv"),
                                   delimiter=",", skiprows=1)[:, 1:].T.copy() for f in files]
        else:
            from mtanno.features.store import read_feature_matrix

            out[cls] = [read_feature_matrix(features_dir / Path(f).with_suffix(".parquet"))
                        for f in files]
    return out


def original_seconds(cls: str) -> float | None:
    info = REFERENCE / "mt" / f"{cls}_info.txt"
    if not info.is_file():
        return None
    m = re.search(r"^learning_wall_s=(\S+)", info.read_text(), re.M)
    return float(m.group(1)) if m else None


def matches_golden(cls: str, res) -> str:
    gold_file = REFERENCE / "mt" / f"{cls}.csv"
    if not gold_file.is_file():
        return "n/a"
    gold = np.loadtxt(gold_file, delimiter=",", skiprows=1)
    if res.values.shape != (gold.shape[1] - 2, gold.shape[0]):
        return "DIFFERENT LENGTH"
    dv = max(np.abs(res.values - gold[:, 2:].T).max(), np.abs(res.weights - gold[:, 1]).max())
    return "exact" if dv == 0 else f"max diff {dv:.2g}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--features-dir", type=Path, default=None,
                    help="mtanno feature files (mirroring clips.csv) instead of the golden "
                         "30 Hz CSVs")
    args = ap.parse_args()
    if not (SHARED / "hdm05_cut" / "clips.csv").is_file():
        print(f"bench_learn: {SHARED} not found; nothing to measure", file=sys.stderr)
        return 2
    sets = training_sets(args.features_dir)
    print(f"machine: {machine()}")
    src = args.features_dir or "golden 30 Hz features (reference/features)"
    print(f"input: {src}; median of {args.repeats} runs after one warm-up run\n")
    print(f"{'class':<30} {'N':>3} {'mean len':>8} {'K':>4} {'iter':>4} {'seconds':>8} "
          f"{'original':>9}  result")
    times = []
    for cls, ex in sets.items():
        learn(ex)  # warm-up
        runs = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            res = learn(ex)
            runs.append(time.perf_counter() - t0)
        med = statistics.median(runs)
        times.append(med)
        orig = original_seconds(cls)
        print(f"{cls:<30} {len(ex):>3} {np.mean([X.shape[1] for X in ex]):>8.1f} "
              f"{res.values.shape[1]:>4} {res.iterations:>4} {med:>8.3f} "
              f"{'' if orig is None else f'{orig:.2f}':>9}  {matches_golden(cls, res)}")
    print(f"\nper class: median {statistics.median(times):.3f} s, max {max(times):.3f} s, "
          f"total {sum(times):.2f} s (target < 0.5 s per class; original 3-25.6 s, MR06/MBS09)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
