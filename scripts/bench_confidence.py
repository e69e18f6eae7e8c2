"""Benchmark of open-world annotation (issue 26 targets): ``tune`` with background for the
11 HDM05 classes and about 200 background clips (< 120 s on 2 cores), and annotation with
verification (the tuned confidence) against annotation without it (≤ 2×) on a 60-minute
document.

Inputs, all with poses (``features --poses``): the HDM05 train split (templates, tuning);
background: the Bandai set 1 clips without kicks, runs and dashes, the ten CMU subject 02
trials and the first clips of Bandai set 2 (style normal) up to 200; the 60-minute document
is one composed document of all 44 actor-mm clips tiled to 108 000 frames (as
``bench_annotate.py`` makes it, with its poses). Tune is timed as a whole command
(``--jobs 2``); annotation as a whole command (median of ``--repeats``, the two
configurations interleaved) and in one process (matching and labels, then the
confidence, median of 7).

    .venv/bin/python scripts/bench_confidence.py [--repeats 5] [--out .cache/bench/confidence]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from _machine import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"
MTANNO = str(REPO / ".venv" / "bin" / "mtanno")


def run(*args) -> float:
    t = time.perf_counter()
    subprocess.run([MTANNO, *map(str, args)], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - t


def background(out: Path) -> Path:
    """A folder of links to about 200 background motion files."""
    import data_cache

    src = out / "background_src"
    if src.exists():
        return src
    src.mkdir(parents=True)
    set1 = [p for p in data_cache.bandai_clips("set1.tar.xz")
            if not any(k in p.name for k in ("_kick_", "_run_", "_dash_"))]
    cmu = sorted((SHARED / "cmu_02").glob("*.amc"))
    normal = data_cache.bandai_clips("set2-normal.tar.xz")[:200 - len(set1) - len(cmu)]
    for p in [*set1, *normal]:
        (src / p.name).symlink_to(p.resolve())
    (src / "cmu02").mkdir()
    for p in [*cmu, SHARED / "cmu_02" / "02.asf"]:
        (src / "cmu02" / p.name).symlink_to(p.resolve())
    return src


def tiled_with_poses(src: Path, dst: Path, frames: int) -> Path:
    from mtanno.features.store import read_features, write_features

    ff = read_features(src, poses=True)
    reps = -(-frames // ff.X.shape[1])
    X = np.tile(ff.X, (1, reps))[:, :frames]
    P = np.tile(ff.poses, (reps, 1, 1))[:frames]
    native = np.arange(1, frames + 1) * 4 - 3
    meta = dict(ff.meta, document=dst.stem, analysis_frames=frames,
                native_frames=int(native[-1]))
    meta.pop("schema", None)
    meta.pop("poses", None)
    write_features(dst, X, ff.names, native, meta, poses=P)
    return dst


def prepare(out: Path):
    clips = SHARED / "hdm05_cut" / "clips.csv"
    if not (out / "mt").exists():
        run("features", SHARED / "hdm05_cut", "-o", out / "features", "--poses", "--jobs", "2",
            "-q")
        run("learn-mt", "--manifest", clips, "--features-dir", out / "features", "--split",
            "train", "-o", out / "mt", "-q")
    if not (out / "background").exists():
        run("features", background(out), "-o", out / "background", "--poses", "--jobs", "2",
            "-q")
    doc = out / "doc_60min.parquet"
    if not doc.exists():
        run("compose", clips, "--actor", "mm", "--docs", "1", "--in-order", "-o", out / "docs")
        run("features", out / "docs", "-o", out / "docfeats", "--poses", "-q")
        tiled_with_poses(next((out / "docfeats").glob("*.parquet")), doc, 60 * 60 * 30)
    return clips, doc


def in_process(out: Path, doc: Path, config: Path) -> tuple[float, float]:
    """(median seconds of matching and labels, of the confidence) of the document."""
    from mtanno.annotate import AnnotateOptions, annotate_document, load_annotation_setup
    from mtanno.confidence.score import score_document
    from mtanno.features.store import read_features

    ff = read_features(doc, poses=True)
    setup = load_annotation_setup(out / "mt", AnnotateOptions(config_path=config))
    label, score = [], []
    for _ in range(7):
        t0 = time.perf_counter()
        rows, _, _ = annotate_document(ff.document, ff.X, setup.models, config=setup.config,
                                       matrix=False)
        t1 = time.perf_counter()
        score_document(rows, X=ff.X, poses=ff.poses, models=setup.models,
                       config=setup.config, confidence=setup.confidence)
        label.append(t1 - t0)
        score.append(time.perf_counter() - t1)
    return statistics.median(label), statistics.median(score)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=REPO / ".cache" / "bench" / "confidence")
    args = ap.parse_args()
    if not (SHARED / "hdm05_cut" / "clips.csv").exists():
        print(f"bench_confidence: {SHARED} not found", file=sys.stderr)
        return 2
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    clips, doc = prepare(out)
    n_bg = len(list((out / "background").rglob("*.parquet")))
    print(machine())
    train = ["--mt", out / "mt", "--manifest", clips, "--features-dir", out / "features",
             "--split", "train", "--jobs", "2", "-q"]
    plain, tuned = out / "plain.toml", out / "tuned.toml"
    run("tune", *train, "--no-confidence", "-o", plain)  # warm the JIT cache
    t_tune = run("tune", *train, "--background", out / "background", "-o", tuned)
    print(f"tune, 11 classes, {n_bg} background files, --jobs 2: {t_tune:.1f} s "
          "(target < 120 s)")
    walls: dict[str, list[float]] = {"without": [], "with": []}
    for cfg in (plain, tuned):  # warm-up
        run("annotate", "--mt", out / "mt", "--classes", cfg, doc, "-o", out / "a.csv", "-q")
    for _ in range(args.repeats):
        for name, cfg in (("without", plain), ("with", tuned)):
            walls[name].append(run("annotate", "--mt", out / "mt", "--classes", cfg, doc, "-o",
                                   out / f"a_{name}.csv", "-q"))
    w0, w1 = (statistics.median(walls[k]) for k in ("without", "with"))
    print(f"annotate 60 min (108 000 frames), whole command, median of {args.repeats}: "
          f"without confidence {w0:.2f} s, with verification and confidence {w1:.2f} s "
          f"= {w1 / w0:.2f}× (target ≤ 2×)")
    label, score = in_process(out, doc, tuned)
    rows = sum(1 for _ in open(out / "a_with.csv")) - 1
    print(f"in one process, median of 7: matching and labels {label * 1000:.0f} ms, "
          f"confidence of the segments {score * 1000:.0f} ms ({label and (label + score) / label:.2f}×"
          f"; {rows} rows kept)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
