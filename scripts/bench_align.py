"""Time-alignment benchmark (issue 11; MRC05 §7): restricted against full DTW on long motions.

A document of at least a minute is composed from the HDM05 clips of one actor (``mtanno
compose``: the clips in a seeded random order, roots re-anchored at the seams), read once
(joint positions and features), and aligned with a copy of itself re-timed by a known smooth
non-linear warp (20 % longer, local tempo between 0.55 and 1.45 times the mean; the copy's
features are computed from its interpolated positions, tests/align_support.py). For each
cost the script reports, as medians of ``--repeat`` runs after a warm-up:

* stage 1 (segments and their matching), stage 2 restricted (DTW inside the widened area,
  with the pose normalisation and the path's local costs) and the whole alignment
  (:func:`mtanno.align.align`, both stages), against stage 2 over the full matrix (``full``);
* the DTW kernel alone on the same inputs, restricted and full (:func:`warp_poses` /
  :func:`warp_codes`);
* the fraction of the matrix computed, the agreement of the restricted path with the full
  one, and how well each recovers the known warp (frames within one frame of it).

Reading the file (parse, kinematics, features) is reported separately.

``--quality`` prints instead how the restricted path compares with full DTW on performances
of one class by different actors: for every HDM05 class, three repetitions per actor (the
first three clips by file name, composed as in tests/test_align_data.py) aligned pairwise
across actors, and Bandai walks of the styles normal and feminine; and the known-warp
recovery of one clip per class.

    .venv/bin/python scripts/bench_align.py [--repeat 7] [--actors mm bd] [--quality]
"""

from __future__ import annotations

import argparse
import csv
import itertools
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(REPO / "tests"))
from _machine import machine  # noqa: E402
from align_support import composed_performance, retimed_pair, warp_recovery  # noqa: E402
from data_cache import bandai_clips  # noqa: E402

from mtanno.align import (  # noqa: E402
    align,
    load_performance,
    normalize_poses,
    path_agreement,
    warp_codes,
    warp_poses,
)
from mtanno.evaluation.compose import Clip, compose_documents  # noqa: E402
from mtanno.index.core import frame_codes  # noqa: E402
from mtanno.io import canonical_positions, read_motion  # noqa: E402

HDM05 = REPO.parent / "shared" / "data" / "hdm05_cut"
BENCH = REPO / ".cache" / "bench_align"


def median_time(fn, repeat: int) -> tuple[float, object]:
    out = fn()  # warm-up (and the result)
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def compose(actor: str) -> Path:
    with open(HDM05 / "clips.csv", encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if r["actor"] == actor]
    clips = [Clip(HDM05 / r["file"], r["class"], actor) for r in rows]
    docs, _ = compose_documents(clips, BENCH / actor, n_docs=1, seed=1, prefix=f"align_{actor}")
    return docs[0]


def bench_cost(a, b, warp, cost: str, group: str | None, repeat: int) -> None:
    """One row of the speed table (module docstring)."""
    opts = {"cost": cost, "group": group}
    t_part, part = median_time(lambda: align(a, b, **opts), repeat)
    full = align(a, b, full=True, **opts)
    stage1 = statistics.median(align(a, b, **opts).seconds["coarse"] for _ in range(repeat))
    stage2 = statistics.median(align(a, b, **opts).seconds["dtw"] for _ in range(repeat))
    stage2_full = statistics.median(align(a, b, full=True, **opts).seconds["dtw"]
                                    for _ in range(repeat))
    if cost == "positions":
        PA, PB = normalize_poses(a.joints), normalize_poses(b.joints)
        k_part, _ = median_time(lambda: warp_poses(PA, PB, area=part.coarse.area), repeat)
        k_full, _ = median_time(lambda: warp_poses(PA, PB), repeat)
    else:
        rows = [a.layout.names.index(f) for f in part.features]
        CA, CB = frame_codes(a.X, rows), frame_codes(b.X, rows)
        nf = len(rows)
        k_part, _ = median_time(lambda: warp_codes(CA, CB, n_features=nf,
                                                   area=part.coarse.area), repeat)
        k_full, _ = median_time(lambda: warp_codes(CA, CB, n_features=nf), repeat)
    print(f"| {cost}{' (pose features)' if group else ''} | {stage1 * 1e3:.1f} ms | "
          f"{stage2 * 1e3:.1f} ms | **{t_part:.3f} s** | {stage2_full * 1e3:.0f} ms | "
          f"**{stage2_full / stage2:.1f}×** | {k_part * 1e3:.1f} ms | {k_full * 1e3:.0f} ms "
          f"| {k_full / k_part:.1f}× | {part.fraction:.1%} | "
          f"{path_agreement(part.path, full.path):.3f} | {warp_recovery(part, warp):.3f} | "
          f"{warp_recovery(full, warp):.3f} |")


def bench(doc: Path, repeat: int) -> None:
    t_read, _ = median_time(lambda: load_performance(doc), max(1, repeat // 2))
    motion = read_motion(doc)
    a, b, warp = retimed_pair(canonical_positions(motion), motion.heading, motion.fps,
                              name=doc.stem)
    print(f"\n{doc.stem}: {motion.n_frames} native frames at {motion.fps:g} Hz "
          f"({motion.n_frames / motion.fps:.1f} s), {a.frames} × {b.frames} frames at 30 Hz "
          f"(the copy {b.frames / 30:.1f} s); reading + features {t_read:.3f} s")
    print("| cost | stage 1 | stage 2 restricted | whole alignment | stage 2 full | "
          "speed-up | kernel restricted | kernel full | kernel speed-up | fraction | "
          "agreement | recovery restricted | recovery full |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for cost, group in (("positions", None), ("features", "pose")):
        bench_cost(a, b, warp, cost, group, repeat)


def pair_rows(pairs, opts) -> tuple[str, ...]:
    agree, tol1, frac, ratio, worst = [], [], [], [], []
    for pa, pb in pairs:
        full, part = align(pa, pb, full=True, **opts), align(pa, pb, **opts)
        weight = pa.frames + pb.frames
        agree.append((path_agreement(part.path, full.path), weight))
        tol1.append((path_agreement(part.path, full.path, tolerance=1), weight))
        frac.append(part.fraction)
        ratio.append(part.total_cost / full.total_cost)
        worst.append(agree[-1][0])

    def pooled(v):
        return sum(x * w for x, w in v) / sum(w for _, w in v)

    return (f"{pooled(agree):.3f}", f"{min(worst):.3f}", f"{pooled(tol1):.3f}",
            f"{statistics.median(frac):.1%} ({max(frac):.1%})", f"{max(ratio):.3f}")


def quality() -> None:
    with open(HDM05 / "clips.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    classes = sorted({r["class"] for r in rows})
    tmp = Path(tempfile.mkdtemp(prefix="align-quality-"))
    print("| performances | pairs | cost | equal frames | worst pair | within 1 frame | "
          "fraction median (max) | cost ratio max |")
    print("|---|---|---|---|---|---|---|---|")
    for label in classes:
        actors = [x for x in ("bd", "bk", "dg", "mm")
                  if sum(r["class"] == label and r["actor"] == x for r in rows) >= 3]
        perfs = [load_performance(composed_performance(HDM05, label, x, 3, tmp))
                 for x in actors]
        pairs = list(itertools.combinations(perfs, 2))
        if not pairs:
            continue
        for cost, group in (("positions", None), ("features", "pose")):
            cells = pair_rows(pairs, {"cost": cost, "group": group})
            print(f"| {label} ×3, {'/'.join(actors)} | {len(pairs)} | {cost} | "
                  + " | ".join(cells) + " |")
    walks = {s: [load_performance(p) for p in sorted(
        q for q in bandai_clips(f"set2-{s}.tar.xz") if f"_walk_{s}_" in q.name)[:4]]
        for s in ("normal", "feminine")}
    pairs = list(itertools.product(walks["normal"], walks["feminine"]))
    for cost, group in (("positions", None), ("features", "pose")):
        print(f"| Bandai walk normal × feminine | {len(pairs)} | {cost} | "
              + " | ".join(pair_rows(pairs, {"cost": cost, "group": group})) + " |")
    print("\n| clip | frames | recovery positions | recovery features (pose) | "
          "recovery features (all) |")
    print("|---|---|---|---|---|")
    for label in classes:
        clip = HDM05 / sorted(r["file"] for r in rows if r["class"] == label)[0]
        motion = read_motion(clip)
        a, b, warp = retimed_pair(canonical_positions(motion), motion.heading, motion.fps)
        got = [warp_recovery(align(a, b, **o), warp) for o in (
            {"cost": "positions"}, {"cost": "features", "group": "pose"}, {"cost": "features"})]
        print(f"| {clip.stem} | {a.frames} × {b.frames} | "
              + " | ".join(f"{g:.3f}" for g in got) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--actors", nargs="+", default=["mm", "bd"])
    ap.add_argument("--quality", action="store_true",
                    help="the restricted-vs-full and recovery tables instead of speed")
    args = ap.parse_args()
    if not HDM05.is_dir():
        sys.exit(f"bench_align: {HDM05} not found (the HDM05 clips of ../shared/data)")
    random.seed(0)
    np.random.seed(0)
    print(f"machine: {machine()}")
    if args.quality:
        quality()
        return
    for actor in args.actors:
        bench(compose(actor), args.repeat)


if __name__ == "__main__":
    main()
