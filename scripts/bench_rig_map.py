"""Skeleton maps for BVH rigs no map file fits: how long making one takes, from the names
and from the hierarchy (issue 31, finding 5), and how often the hierarchy gets a renamed
rig right on whole archives.

    .venv/bin/python scripts/bench_rig_map.py [--runs 20] [--archives set1.tar.xz ...]

* Speed, on one Bandai clip (dataset-1_walk_normal_001): ``choose_map`` (what
  ``read_motion`` calls) for the rig with its Bandai names (the built-in map fits), with
  Mixamo names (made from the names), and renamed ``Bone01``… (names fail, then made from
  the hierarchy); and ``read_motion`` of the whole clip beside them. Median of --runs
  after a warm-up.
* Agreement: every clip of each archive renamed by each scheme of
  tests/test_rig_topology.py (and reflected in X, renamed ``Bone01``…): the share of
  feature values equal to the named rig's (reflected: to the named reflected rig read
  with the Bandai map's sides exchanged), and the clips whose map differs.

Figures go to docs/benchmarks.md by hand; nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "scripts"))

from _machine import machine  # noqa: E402
from data_cache import bandai_clips  # noqa: E402
from test_rig_guess import _mixamo, parse_bvh  # noqa: E402
from test_rig_topology import _reflect_bvh, _scheme, shuffle_children, swap_lr  # noqa: E402

from mtanno.features.extract import features_from_motion  # noqa: E402
from mtanno.io import read_motion  # noqa: E402
from mtanno.io.bvh import read_bvh  # noqa: E402
from mtanno.io.guess import choose_map, map_toml  # noqa: E402

SCHEMES = ("bone", "j00", "random", "japanese", "cyrillic", "shuffled", "wrong-sides")


def median_time(fn, runs: int) -> float:
    fn()
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def speed(tmp: Path, runs: int) -> None:
    clip = next(p for p in bandai_clips("set1.tar.xz")
                if p.name == "dataset-1_walk_normal_001.bvh")
    text = clip.read_text(encoding="utf-8")
    mix = _mixamo(parse_bvh(text)).write(tmp / "mixamo.bvh")
    b = parse_bvh(text)
    bones = b.rename(_scheme("bone", [n.name for n in b.nodes() if not n.end])) \
        .write(tmp / "bones.bvh")
    print(f"choose_map and read_motion on {clip.name}, median of {runs} runs:")
    for label, path in (("built-in map (Bandai names)", clip), ("from the names (Mixamo)", mix),
                        ("from the hierarchy (Bone01…)", bones)):
        rig, ch = read_bvh(path)
        t_map = median_time(lambda r=rig, c=ch: choose_map(r, None, c), runs)
        t_read = median_time(lambda p=path: read_motion(p), max(3, runs // 4))
        print(f"  {label:30s} choose_map {t_map * 1e3:7.2f} ms   read_motion "
              f"{t_read * 1e3:7.1f} ms   map {choose_map(rig, None, ch).name}")


def agreement(tmp: Path, archives: list[str]) -> None:
    for archive in archives:
        clips = bandai_clips(archive)
        print(f"{archive}: {len(clips)} clips")
        for scheme in (*SCHEMES, "reflected"):
            equal = total = 0
            wrong: list[str] = []
            t0 = time.perf_counter()
            for clip in clips:
                text = clip.read_text(encoding="utf-8")
                m0 = read_motion(clip)
                X0 = features_from_motion(m0)[0]
                b = parse_bvh(text)
                if scheme == "reflected":
                    _reflect_bvh(b)
                    swapped = tmp / "swapped.toml"
                    swapped.write_text(map_toml(replace(
                        m0.smap, name="bandai-swapped", joints=swap_lr(m0.smap.joints),
                        heading_axis=(0.0, 1.0, 0.0))), encoding="utf-8")
                    X0 = features_from_motion(read_motion(
                        b.write(tmp / "named.bvh"), skeleton=str(swapped)))[0]
                    expected = swap_lr(m0.smap.joints)
                else:
                    expected = m0.smap.joints
                ren = _scheme("bone" if scheme == "reflected" else scheme,
                              [n.name for n in b.nodes() if not n.end])
                b.rename(ren)
                if scheme == "shuffled":
                    shuffle_children(b.root, 7)
                try:
                    m = read_motion(b.write(tmp / "r.bvh"))
                    X = features_from_motion(m)[0]
                except Exception as exc:  # counted as wrong, every value unequal
                    wrong.append(f"{clip.name} ({exc})")
                    total += X0.size
                    continue
                back = {v + e: k + e for k, v in ren.items() for e in ("", "_End")}
                if {k: back[v] for k, v in m.smap.joints.items()} != expected:
                    wrong.append(clip.name)
                equal += int((X == X0).sum()) if X.shape == X0.shape else 0
                total += X0.size
            print(f"  {scheme:12s} equal values {equal / total:.6%} ({total - equal} of "
                  f"{total} differ); other map on {len(wrong)} clips; "
                  f"{time.perf_counter() - t0:.1f} s")
            for w in wrong[:5]:
                print(f"    {w}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--archives", nargs="*", default=["set1.tar.xz"],
                    help="Bandai archives to sweep (none: speed only)")
    args = ap.parse_args()
    print(machine())
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        speed(Path(d), args.runs)
        agreement(Path(d), args.archives)


if __name__ == "__main__":
    main()
