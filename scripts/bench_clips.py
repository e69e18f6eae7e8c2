"""Benchmark of annotating many short files against one long document of the same motion
(issue 34 targets, 500 Bandai clips with a tuned configuration: ``--jobs 2`` ≤ 0.7× the time
of ``--jobs 1``, ≤ 1.5× the reference annotation (no ``--classes``), and per hour of motion
within 2× of one long document).

The clips: a seeded draw (``random.Random(0)``) of 500 and of 2 000 of the 2 148 Bandai
set-2 clips (all five styles; feature files with poses), each set a folder of links to the
feature files; the long document: the same clips' features and poses concatenated in the
same order into one feature file. The configuration: ``mtanno tune`` of the pooled
600-clip training set (``bandai_folds.py pooled``, 12 clips per content and style; the
templates learned from it; seed 5), which verifies by poses against its bank of 600
clips. Every run is the whole command ``mtanno annotate … -o OUT.csv -q``, wall time median
of ``--repeats``, with the CPU time of the command (user + system, its workers included)
and its peak RSS beside it; the outputs of ``--jobs 1`` and ``--jobs 2`` are compared byte
for byte.

    .venv/bin/python scripts/bench_clips.py [--repeats 3] [--sizes 500 2000]
        [--out .cache/bench/bandai]
"""

from __future__ import annotations

import argparse
import os
import random
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bandai_bench import MTANNO, REPO, available, features, tuned  # noqa: E402
from _machine import machine  # noqa: E402


def clip_set(out: Path, feats: Path, n: int) -> tuple[Path, Path, int]:
    """(folder of links to ``n`` drawn clips, the long document of the same clips, frames)."""
    from mtanno.features.store import read_features, write_features

    every = sorted(feats.glob("*/*.parquet"))
    chosen = random.Random(0).sample(every, n)
    folder = out / f"clips{n}"
    long = out / f"long{n}.parquet"
    if not folder.is_dir():
        tmp = out / f".clips{n}.tmp"
        tmp.mkdir(parents=True, exist_ok=True)
        for p in chosen:
            os.symlink(p.resolve(), tmp / p.name)
        tmp.rename(folder)
    frames = 0
    if not long.is_file():
        Xs, Ps = [], []
        for p in chosen:
            ff = read_features(p, poses=True)
            Xs.append(ff.X)
            Ps.append(ff.poses)
        X = np.concatenate(Xs, axis=1)
        meta = dict(ff.meta, document=long.stem, analysis_frames=X.shape[1],
                    native_frames=X.shape[1], native_fps=ff.meta["analysis_fps"])
        meta.pop("schema", None)
        write_features(long, X, ff.names, np.arange(1, X.shape[1] + 1), meta,
                       poses=np.concatenate(Ps))
    from mtanno.features.store import read_features as rf

    frames = rf(long).X.shape[1]
    return folder, long, frames


def timed(args: list[str], repeats: int) -> tuple[float, float, float]:
    """(median wall s, median CPU s of the command and its workers, peak RSS MB)."""
    walls, cpus, peak = [], [], 0.0
    for _ in range(repeats):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        proc = subprocess.run(["/usr/bin/time", "-f", "%M", *MTANNO, *args], check=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        walls.append(time.perf_counter() - t)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
        peak = max(peak, int(proc.stderr.strip().splitlines()[-1]) / 1024)
    return statistics.median(walls), statistics.median(cpus), peak


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[500, 2000])
    ap.add_argument("--out", default=str(REPO / ".cache" / "bench" / "bandai"))
    args = ap.parse_args()
    if not available():
        print("bench_clips: the Bandai set-2 archives are missing; the benchmark needs them")
        return 2
    out = Path(args.out)
    feats = features(out)
    mt, cfg = tuned(out)
    print(f"machine: {machine()}")
    print(f"configuration: {cfg} (templates {mt}); timings: whole command, median of "
          f"{args.repeats}; CPU: user + system of the command and its workers")
    for n in args.sizes:
        folder, long, frames = clip_set(out, feats, n)
        hours = frames / 30 / 3600
        print(f"\n{n} clips, {frames} frames ({hours * 60:.1f} min of motion):")
        res, outputs = {}, {}
        for name, target, classes in (("clips, tuned", folder, True),
                                      ("clips, reference", folder, False),
                                      ("long document, tuned", long, True),
                                      ("long document, reference", long, False)):
            for jobs in (1, 2):
                dst = out / f"ann_{n}_{'long' if target == long else 'clips'}_" \
                            f"{'tuned' if classes else 'ref'}_j{jobs}.csv"
                extra = ["--classes", str(cfg)] if classes else []
                wall, cpu, peak = timed(["annotate", "--mt", str(mt), *extra, str(target),
                                         "-o", str(dst), "-q", "--jobs", str(jobs)],
                                        args.repeats)
                res[(name, jobs)] = wall
                outputs.setdefault(name, []).append(dst.read_bytes())
                print(f"  {name:26s} --jobs {jobs}: {wall:6.2f} s wall, {cpu:6.2f} s CPU, "
                      f"peak RSS {peak:5.0f} MB; {wall / hours:6.2f} s per hour of motion")
        for name, got in outputs.items():
            print(f"  {name}: --jobs 1 and --jobs 2 outputs "
                  f"{'identical' if got[0] == got[1] else 'DIFFER'}")
        t1, t2 = res[("clips, tuned", 1)], res[("clips, tuned", 2)]
        r1, r2 = res[("clips, reference", 1)], res[("clips, reference", 2)]
        long1 = min(res[("long document, tuned", 1)], res[("long document, tuned", 2)])
        print(f"  tuned clips: --jobs 2 / --jobs 1 = {t2 / t1:.2f} (target ≤ 0.7); "
              f"reference clips {r2 / r1:.2f}")
        print(f"  tuned / reference: {t1 / r1:.2f} with --jobs 1, {t2 / r2:.2f} with --jobs 2 "
              f"(target ≤ 1.5)")
        print(f"  per hour of motion, tuned clips / one long document: {t1 / long1:.2f} with "
              f"--jobs 1, {t2 / long1:.2f} with --jobs 2 (target ≤ 2)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
