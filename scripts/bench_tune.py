"""Benchmark of ``mtanno tune`` and of annotation with a tuned configuration (issue 10
targets: tune for the 11 HDM05 classes < 60 s on 2 cores; annotation with a tuned
configuration no slower than 1.2× the untuned one).

* ``tune --jobs 2`` on the train split (actors bd, bk, dg; 188 clips, 11 classes), whole
  command, median of ``--repeats``.
* Annotation of the 60-minute document of ``bench_annotate.py`` (all 44 actor-mm clips
  composed in order, tiled; 108 000 frames) with the templates alone and with
  ``--classes tuned.toml``: in one process (:func:`mtanno.annotate.annotate_document` on the
  document already read), median of 7, and as whole commands, median of ``--repeats``.
  The same with the tuned configuration that `tune --keyframes` writes, with keyframes;
  and the peak memory of annotating 10 hours with and without the tuned configuration.
  Last, the in-process runs once more, interleaved, in process CPU time (median of 15):
  the ratio with less of the noise of other jobs on a 2-core machine.

    .venv/bin/python scripts/bench_tune.py [--repeats 3] [--out .cache/bench/annotate]

With ``--growth`` (issue 34) it measures instead how ``tune`` grows with the training set:
the pooled Bandai set-2 training sets of ``bandai_folds.py pooled`` (all five styles; 3, 6,
12 and 24 clips per content and style: 150, 300, 600 and 1 200 clips, 10 classes, five
folds; 1 200 repeats clips where a style has fewer than 24 of a content), feature files with
poses, templates learned from each set; the issue's command ``mtanno tune --mt MT --manifest
train.csv --features-dir FEATS --seed 5 --jobs 2``, whole command, median of ``--repeats``
(wall, CPU of the command and its workers, peak RSS of the largest process, the load
before each run); then the exponents of wall and CPU time fitted on log–log (least
squares over the sizes) and the cross-validated F1/F2 of each size.

    .venv/bin/python scripts/bench_tune.py --growth [--repeats 3] [--sizes 3 6 12 24]
        [--bandai-out .cache/bench/bandai] [--max-examples N]
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402
from bench_annotate import (  # noqa: E402
    REPO,
    bench_setup,
    interleaved_cpu,
    learned_keyframes,
    median_wall,
    run,
    tiled,
    timed,
)


def _run_timed(args: list[str]) -> tuple[float, float, float, float]:
    """(wall s, CPU s of the command and its workers, peak RSS MB, load before)."""
    import os
    import resource

    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    proc = subprocess.run(["/usr/bin/time", "-f", "%M", str(REPO / ".venv" / "bin" / "mtanno"),
                           *args], check=True, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return wall, cpu, int(proc.stderr.strip().splitlines()[-1]) / 1024, load


def _exponent(sizes: list[int], values: list[float]) -> float:
    """Slope of log(value) against log(size), least squares."""
    import numpy as np

    return float(np.polyfit(np.log(sizes), np.log(values), 1)[0])


def growth(argv: list[str]) -> int:
    """The growth curve of ``tune`` on the pooled Bandai training sets (module docstring)."""
    import argparse
    import re

    from _bandai_bench import available, training, tune_args

    ap = argparse.ArgumentParser(description="tune's growth curve (bench_tune.py --growth)")
    ap.add_argument("--growth", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[3, 6, 12, 24])
    ap.add_argument("--bandai-out", default=str(REPO / ".cache" / "bench" / "bandai"))
    ap.add_argument("--max-examples", type=int, default=None)
    args = ap.parse_args(argv)
    if not available():
        print("bench_tune: the Bandai set-2 archives are missing; --growth needs them")
        return 2
    out = Path(args.bandai_out)
    for per in args.sizes:
        training(out, per)  # features, manifest and templates made before any timing
    print(f"machine: {machine()}")
    extra = [] if args.max_examples is None else ["--max-examples", str(args.max_examples)]
    print(f"tune --seed 5 --jobs 2{' ' + ' '.join(extra) if extra else ''}, whole command, "
          f"median of {args.repeats}; CPU = user + system of the command and its workers; "
          "peak RSS of the largest process")
    rows = []
    for per in args.sizes:
        cfg = out / f"growth{per}.toml"
        runs = [_run_timed([*tune_args(out, per), *extra, "-o", str(cfg), "-q"])
                for _ in range(args.repeats)]
        wall = statistics.median(r[0] for r in runs)
        cpu = statistics.median(r[1] for r in runs)
        peak = max(r[2] for r in runs)
        text = cfg.read_text()
        f1 = re.search(r"cross-validated, tuned: .*?F1 ([0-9.]+), .*?F2 ([0-9.]+)", text)
        clips = 50 * per
        rows.append((clips, wall, cpu, peak))
        print(f"  {clips:5d} clips: {wall:7.1f} s wall ({', '.join(f'{r[0]:.1f}' for r in runs)}), "
              f"{cpu:7.1f} s CPU, peak RSS {peak:6.0f} MB, load before "
              f"{', '.join(f'{r[3]:.2f}' for r in runs)}; cross-validated F1 {f1[1]} F2 "
              f"{f1[2]}", flush=True)
    if len(rows) > 1:
        n = [r[0] for r in rows]
        print(f"fitted exponents over {', '.join(map(str, n))} clips: wall "
              f"{_exponent(n, [r[1] for r in rows]):.2f}, CPU "
              f"{_exponent(n, [r[2] for r in rows]):.2f}, peak RSS "
              f"{_exponent(n, [r[3] for r in rows]):.2f} (target: time ≤ 1.2)")
    return 0


def main() -> int:
    if "--growth" in sys.argv[1:]:
        return growth(sys.argv[1:])
    got = bench_setup("bench_tune", __doc__)
    if got is None:
        return 2
    args, out, clips, src = got
    kf_dir = learned_keyframes(out, clips)
    print(f"machine: {machine()}")
    train = ["--manifest", str(clips), "--features-dir", str(out / "features"), "--split",
             "train", "--jobs", "2"]
    walls = []
    for _ in range(args.repeats):
        t = time.perf_counter()
        run(["tune", "--mt", str(out / "mt"), *train, "-o", str(out / "tuned.toml")])
        walls.append(time.perf_counter() - t)
    print(f"tune, 11 HDM05 classes, 188 clips, --jobs 2: {statistics.median(walls):.1f} s wall "
          f"(median of {args.repeats}: {', '.join(f'{w:.1f}' for w in walls)}; target < 60 s)")
    run(["tune", "--mt", str(out / "mt"), "--keyframes", str(kf_dir), *train, "-o",
         str(out / "tuned_kf.toml")])

    from mtanno.annotate import AnnotateOptions, annotate_document, load_annotation_setup
    from mtanno.features.store import read_features
    from mtanno.keyframes import KeyframeSet, class_spans, load_keyframe_folder
    from mtanno.templates.match import pack_document

    doc = tiled(src, out / "doc_60min.parquet", 60 * 60 * 30)
    ff = read_features(doc)
    queries = KeyframeSet(load_keyframe_folder(kf_dir), ff.names)  # once, as annotate
    rows, runners = [], []
    for name, cfg_path, kf in (("untuned", None, False), ("tuned", out / "tuned.toml", False),
                               ("untuned, keyframes", None, True),
                               ("tuned with keyframes, keyframes", out / "tuned_kf.toml", True)):
        # as annotate reads it
        setup = load_annotation_setup(out / "mt", AnnotateOptions(config_path=cfg_path))
        models, cfg = setup.models, setup.config
        annotate_document("w", ff.X[:, :3000], models, config=cfg)  # kernels loaded

        def once(models=models, cfg=cfg, kf=kf):  # packed once, as `mtanno annotate` does
            packed = pack_document(ff.X, ff.X.shape[0])
            w = class_spans(ff.X, ff.names, queries, packed=packed) if kf else None
            annotate_document(ff.document, ff.X, models, config=cfg, windows=w, packed=packed,
                              matrix=False)

        inproc = median_wall(once)
        runners.append(once)
        extra = (["--classes", str(cfg_path)] if cfg_path else []) + \
            (["--keyframes", str(kf_dir)] if kf else [])
        wall, _ = timed(["annotate", "--mt", str(out / "mt"), *extra, str(doc), "-o",
                         str(out / "ann_tune.csv"), "-q"], args.repeats)
        rows.append((name, inproc, wall, len({m.name for m in models}), len(models)))
    print("annotation of 60 min (108 000 frames): in one process (median of 7) | whole command "
          f"(median of {args.repeats})")
    for name, inproc, wall, n_classes, n_templates in rows:
        print(f"  {name:34s} {inproc * 1000:7.0f} ms | {wall:5.2f} s   ({n_classes} classes, "
              f"{n_templates} templates)")
    doc10 = tiled(src, out / "doc_600min.parquet", 600 * 60 * 30)
    for name, extra in (("untuned", []), ("tuned", ["--classes", str(out / "tuned.toml")])):
        t = time.perf_counter()
        proc = subprocess.run(["/usr/bin/time", "-f", "%M", str(REPO / ".venv" / "bin" / "mtanno"),
                               "annotate", "--mt", str(out / "mt"), *extra, str(doc10), "-o",
                               str(out / "ann_600_tune.csv"), "-q"],
                              check=True, capture_output=True, text=True)
        peak = int(proc.stderr.strip().splitlines()[-1]) / 1024
        print(f"annotate 10 h (1 080 000 frames), {name}: {time.perf_counter() - t:.1f} s wall, "
              f"peak RSS {peak:.0f} MB")
    base, tuned = rows[0], rows[1]
    kbase, ktuned = rows[2], rows[3]
    print(f"tuned / untuned: {tuned[1] / base[1]:.2f}x in one process, {tuned[2] / base[2]:.2f}x "
          f"whole command; with keyframes {ktuned[1] / kbase[1]:.2f}x and "
          f"{ktuned[2] / kbase[2]:.2f}x (target ≤ 1.2x)")
    med = interleaved_cpu(runners)
    print(f"tuned / untuned, CPU time interleaved (median of 15): {med[1] / med[0]:.2f}x "
          f"({med[0] * 1000:.0f} / {med[1] * 1000:.0f} ms); with keyframes "
          f"{med[3] / med[2]:.2f}x ({med[2] * 1000:.0f} / {med[3] * 1000:.0f} ms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
