"""Time alignment on real motions (issue 11 acceptance): a clip against a re-timed copy of
itself, and performances of one class by different actors (restricted vs full DTW).
Skipped, saying why, when ../shared/data is absent."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from align_support import composed_performance, retimed_pair, warp_recovery
from conftest import HDM05, require_data

from mtanno.align import align, load_performance, path_agreement
from mtanno.io import canonical_positions, read_motion

pytestmark = pytest.mark.realdata

RECOVERY_CLIPS = ["squat1Reps/HDM_bd_squat1Reps_001_120.amc",
                  "kickLFront1Reps/HDM_bd_kickLFront1Reps_001_120.amc",
                  "jogLeftCircle4StepsRstart/HDM_bd_jogLeftCircle4StepsRstart_001_120.amc"]


@pytest.mark.parametrize("clip", RECOVERY_CLIPS)
def test_a_known_non_linear_warp_is_recovered_with_both_costs(clip):
    require_data()
    motion = read_motion(HDM05 / clip)
    a, b, warp = retimed_pair(canonical_positions(motion), motion.heading, motion.fps)
    # the pose distance on the default features; the feature cost on the pose features
    # (velocity features change with the tempo the warp changes, docs/align.md)
    for options in ({"cost": "positions"}, {"cost": "features", "group": "pose"}):
        al = align(a, b, **options)
        assert warp_recovery(al, warp) >= 0.95, options
        assert al.fraction < 0.6


def test_a_bandai_walk_and_its_retimed_copy():
    require_data()
    from data_cache import bandai_clips

    clip = next(p for p in bandai_clips("set2-normal.tar.xz") if "_walk_normal_001" in p.name)
    motion = read_motion(clip)
    a, b, warp = retimed_pair(canonical_positions(motion), motion.heading, motion.fps)
    al = align(a, b)
    assert warp_recovery(al, warp) >= 0.95 and al.fraction <= 0.1


def restricted_vs_full(pairs, band=None):
    """(agreement over all frames of all pairs, largest fraction computed) with the default
    options, and per pair (agreement, fraction)."""
    same = frames = 0
    per_pair = []
    for pa, pb in pairs:
        opts = {} if band is None else {"band": band}
        full, part = align(pa, pb, full=True, **opts), align(pa, pb, **opts)
        agree = path_agreement(part.path, full.path)
        assert part.total_cost >= full.total_cost - 1e-9  # full DTW is the optimum
        per_pair.append((agree, part.fraction))
        same += agree * (pa.frames + pb.frames)
        frames += pa.frames + pb.frames
    return same / frames, max(f for _, f in per_pair), per_pair


@pytest.mark.parametrize("label, actors", [("squat1Reps", ("bd", "bk", "dg", "mm")),
                                           ("jogLeftCircle4StepsRstart", ("bk", "dg", "mm"))])
def test_hdm05_actors_restricted_path_equals_full_dtw(label, actors, tmp_path):
    require_data()
    # three repetitions of the class by each actor (the first three clips by file name)
    perfs = {x: load_performance(composed_performance(HDM05, label, x, 3, tmp_path))
             for x in actors}
    pairs = [(perfs[x], perfs[y]) for x, y in itertools.combinations(actors, 2)]
    agreement, largest, per_pair = restricted_vs_full(pairs)
    assert agreement >= 0.95 and largest <= 0.20, per_pair


def test_bandai_walks_of_two_styles_restricted_path_equals_full_dtw():
    require_data()
    from data_cache import bandai_clips

    def walks(style, k):
        clips = [p for p in bandai_clips(f"set2-{style}.tar.xz") if f"_walk_{style}_" in p.name]
        return [load_performance(p) for p in sorted(clips)[:k]]

    pairs = list(itertools.product(walks("normal", 2), walks("feminine", 3)))
    agreement, largest, per_pair = restricted_vs_full(pairs)
    assert agreement >= 0.95 and largest <= 0.20, per_pair


def test_motions_of_two_rigs_are_compared_by_their_canonical_joints():
    require_data()
    from data_cache import bandai_clips

    walk = next(p for p in bandai_clips("set2-normal.tar.xz") if "_walk_normal_001" in p.name)
    jog = HDM05 / RECOVERY_CLIPS[2]
    al = align(load_performance(jog), load_performance(Path(walk)))
    assert al.path.a[-1] + 1 == al.a.frames and np.isfinite(al.mean_cost)
