"""Benchmark of the feature stage: parsing, forward kinematics and features, separately.

Data: the 232 HDM05 clips (ASF/AMC, 120 Hz) and the 174 Bandai set-1 clips (BVH, 30 Hz) in
``../shared/data``; C3D: the same 232 HDM05 clips as virtual-marker C3D files (the 41 Vicon
markers placed on their bones, ``tests/virtual_markers.py``, written once into the cache) and
the five real C3D takes of ``../shared/data/c3d`` (read + markers → joints + features).
Peer: pybvh 0.9 (PyPI) reading the same BVH files and computing world
joint positions, measured in the same run. pybvh refuses position channels below the root,
which every Bandai joint has, so both readers are timed on an equivalent rewrite of each
file made once beforehand (``scripts/pybvh_peer.py``; positions agree to 1e-12); mtanno is
also timed on the original files.

Every figure is the median over ``--repeats`` passes after one warm-up pass (which loads
the numba kernels from their cache); the warm-up pass is reported as "cold". Run:

    .venv/bin/python scripts/bench_features.py [--repeats 5] [--quick] [--whole-only] [--c3d]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "scripts"))

from data_cache import CACHE_ROOT, SHARED_DATA, bandai_clips  # noqa: E402

from mtanno.features import compute_features  # noqa: E402
from mtanno.io import read_channels  # noqa: E402
from mtanno.io.rigs import find_map  # noqa: E402
from mtanno.io.skeleton import forward_kinematics  # noqa: E402


def one_pass(files) -> tuple[int, float, float, float]:
    """(native frames, parse s, kinematics s, features s) for one pass over the files."""
    frames = 0
    tp = tk = tf = 0.0
    for f in files:
        t0 = time.perf_counter()
        rig, ch = read_channels(f)
        t1 = time.perf_counter()
        smap = find_map(rig)
        pos, head = forward_kinematics(rig, ch.angles, ch.trans, ch.has_trans,
                                       heading_node=smap.heading_index(rig),
                                       heading_axis=smap.heading_axis)
        joints = pos[:, smap.indices(rig)]
        t2 = time.perf_counter()
        compute_features(joints, head, ch.fps)
        t3 = time.perf_counter()
        frames += ch.n_frames
        tp += t1 - t0
        tk += t2 - t1
        tf += t3 - t2
    return frames, tp, tk, tf


def one_pass_c3d(files) -> tuple[int, float, float, float]:
    """(native frames, read s, markers → joints s, features s) for one pass over C3D files
    (:func:`mtanno.io.c3d.read_c3d`, the marker set, :func:`marker_joints`)."""
    from mtanno.io.c3d import read_c3d
    from mtanno.io.markerjoints import marker_joints
    from mtanno.io.markerset import choose_set
    from mtanno.io.skeleton import to_y_up

    frames = 0
    tp = tk = tf = 0.0
    for f in files:
        t0 = time.perf_counter()
        md = read_c3d(f)
        t1 = time.perf_counter()
        mset = choose_set(md.labels)
        joints, heading, _, _ = marker_joints(mset, md.labels, md.points, md.fps)
        joints, heading = to_y_up(joints / 10.0, md.up), to_y_up(heading, md.up)
        t2 = time.perf_counter()
        compute_features(joints, heading, md.fps)
        t3 = time.perf_counter()
        frames += md.n_frames
        tp += t1 - t0
        tk += t2 - t1
        tf += t3 - t2
    return frames, tp, tk, tf


def virtual_c3d_files(clips) -> list[Path]:
    """The HDM05 clips as virtual-marker C3D files (Z up, mm), made once into the cache."""
    from c3d_support import write_c3d
    from virtual_markers import place_markers

    out_dir = CACHE_ROOT.parent / "bench" / "c3d-hdm05"
    out_dir.mkdir(parents=True, exist_ok=True)
    out = []
    for amc in clips:
        c3d = out_dir / (amc.stem + ".c3d")
        if not c3d.exists():
            labels, pts = place_markers(*read_channels(amc))
            tmp = c3d.with_suffix(".tmp")
            write_c3d(tmp, labels, np.stack([pts[..., 0], -pts[..., 2], pts[..., 1]], axis=-1))
            tmp.replace(c3d)
        out.append(c3d)
    return out


def bench_mtanno(name: str, files, repeats: int, one_pass=one_pass) -> dict:
    cold = one_pass(files)
    runs = [one_pass(files) for _ in range(repeats)]  # (C3D: parse = read, kinematics = joints)
    n = runs[0][0]
    med = [statistics.median(r[i] for r in runs) for i in (1, 2, 3)]
    total = statistics.median(r[1] + r[2] + r[3] for r in runs)
    res = {"name": name, "files": len(files), "frames": n,
           "parse": n / med[0], "fk": n / med[1], "features": n / med[2], "total": n / total,
           "parse_fk": n / statistics.median(r[1] + r[2] for r in runs),
           "cold_total": n / (cold[1] + cold[2] + cold[3])}
    print(f"{name:<34} {len(files):>4} files {n:>7} frames | parse {res['parse']:>9,.0f} | "
          f"kinematics {res['fk']:>9,.0f} | features {res['features']:>9,.0f} | "
          f"all three {res['total']:>9,.0f} frames/s (cold pass {res['cold_total']:,.0f})")
    return res


def bench_pybvh(files, repeats: int) -> float:
    import warnings

    import pybvh

    def one():
        frames = 0
        t0 = time.perf_counter()
        for f in files:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                b = pybvh.read_bvh_file(f, world_up="+y")
            frames += np.asarray(b.node_positions()).shape[0]
        return frames, time.perf_counter() - t0

    one()
    runs = [one() for _ in range(repeats)]
    n = runs[0][0]
    rate = n / statistics.median(t for _, t in runs)
    print(f"{'pybvh (read + positions)':<34} {len(files):>4} files {n:>7} frames | "
          f"read + positions {rate:>9,.0f} frames/s")
    return rate


def pybvh_files(originals) -> list[Path]:
    """The pybvh-readable rewrite of each Bandai file, made once into the cache."""
    from pybvh_peer import pybvh_compatible

    out_dir = CACHE_ROOT.parent / "bench" / "pybvh-set1"
    out_dir.mkdir(parents=True, exist_ok=True)
    out = []
    for f in originals:
        g = out_dir / f.name
        if not g.exists() or g.stat().st_mtime < f.stat().st_mtime:
            tmp = g.with_suffix(".tmp")
            pybvh_compatible(f, tmp)
            tmp.replace(g)
        out.append(g)
    return out


def tripled_tree(dst: Path) -> Path:
    """The 232 HDM05 clips three times (symbolic links, with their ASF files): 696 files."""
    if (dst / ".complete").is_file():
        return dst
    src = SHARED_DATA / "hdm05_cut"
    for k in range(3):
        for f in sorted(src.glob("*/*.amc")) + sorted(src.glob("*.asf")):
            link = dst / f"copy{k}" / f.relative_to(src)
            link.parent.mkdir(parents=True, exist_ok=True)
            if not link.exists():
                link.symlink_to(f)
    (dst / ".complete").write_text("ok\n")
    return dst


def _load() -> str:
    import os

    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def whole_command(repeats: int, jobs: int = 2, *, fresh: bool = True, tree: Path | None = None,
                  out: Path | None = None) -> dict:
    """`mtanno features` as a whole command (process start-up, planning, workers, reading,
    writing) over many short clips into a new output folder: the marginal rate = native
    frames / (time for all files − time for one file), so the start-up is not counted
    (issue 12). Each figure is the median of ``repeats`` runs (all-files and one-file runs
    alternate, so a change of load hits both); the load average before and after is
    printed, since other jobs on the machine change wall-clock figures, and so is the CPU
    time (user + system, the command and its workers), which they change much less.

    ``fresh``: every run writes into a folder of its own, all removed at the end. Otherwise
    the one output folder is emptied before each run, as this benchmark did first; on an
    ext4 file system without a journal (this machine's) that makes each new file's inode
    allocation step over the inodes deleted in the last five minutes (``recently_deleted``
    in the kernel's profile), a cost of the benchmark rather than of the command. (Rewriting
    existing outputs costs more still: replacing a file frees the old one's blocks.)

    ``tree`` (the clips) and ``out`` (the folder that receives the output folders) default
    to ``.cache/bench`` of this checkout; give both to compare two checkouts on the same
    files and folders. Outputs written into a given ``out`` are left there, so that a run
    that follows is not slowed by their deletion."""
    import os
    import resource
    import shutil
    import subprocess

    tree = tripled_tree(tree or REPO / ".cache" / "bench" / "hdm05x3")
    files = sorted(tree.rglob("*.amc"))
    one = files[0]
    from mtanno.io import read_motion

    frames = sum(read_motion(f).n_frames for f in files)
    # the command of this checkout (the venv's entry point, this tree first on the path)
    exe = Path(sys.executable).with_name("mtanno")
    cmd = [str(exe), "features", "-q", "--force", "--jobs", str(jobs)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])}
    root = out or REPO / ".cache" / "bench" / "hdm05x3-out"
    if out is None:
        shutil.rmtree(root, ignore_errors=True)
    runs = iter(range(1_000_000))

    def wall(inputs) -> tuple[float, float]:
        """(wall s, CPU s) of one run."""
        out = root / f"run{next(runs)}" if fresh else root / "emptied"
        if not fresh:
            shutil.rmtree(out, ignore_errors=True)  # (not timed)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        subprocess.run([*cmd, *map(str, inputs), "-o", str(out)], check=True, env=env)
        t = time.perf_counter() - t
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        return t, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)

    load_before = _load()
    try:
        wall([one])  # warm the file cache and the kernels' on-disk cache
        wall([tree])
        alls, ones = [], []
        for _ in range(max(3, repeats)):
            alls.append(wall([tree]))
            ones.append(wall([one]))
    finally:
        if out is None:
            shutil.rmtree(root, ignore_errors=True)
    t_all, t_one = (statistics.median(t for t, _ in x) for x in (alls, ones))
    c_all, c_one = (statistics.median(c for _, c in x) for x in (alls, ones))
    rate = frames / (t_all - t_one)
    per_file = 1000 * (c_all - c_one) / (len(files) - 1)
    how = "a new folder per run" if fresh else "one folder emptied before each run"
    print(f"whole command, {len(files)} files ({frames:,} native frames), --jobs {jobs}, "
          f"{how}, median of {len(alls)}: {t_all:.2f} s (runs "
          f"{' '.join(f'{t:.2f}' for t, _ in alls)}); one file {t_one:.2f} s; marginal "
          f"{rate:,.0f} native frames/s (target >= 100,000); CPU {c_all:.2f} s, one file "
          f"{c_one:.2f} s: {per_file:.2f} ms per file; load average before {load_before}, "
          f"after {_load()}")
    return {"files": len(files), "frames": frames, "all": t_all, "one": t_one, "rate": rate,
            "cpu_all": c_all, "cpu_one": c_one, "cpu_per_file_ms": per_file}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="a few files only (smoke run)")
    ap.add_argument("--c3d", action="store_true",
                    help="the AMC and C3D paths only (all HDM05 clips, the real takes)")
    ap.add_argument("--whole-only", action="store_true",
                    help="only the whole-command figure (issue 12)")
    ap.add_argument("--tree", type=Path, help="the tripled HDM05 tree (whole command)")
    ap.add_argument("--out", type=Path, help="where the whole command writes (removed after)")
    ap.add_argument("--fresh-only", action="store_true",
                    help="whole command into new folders only (not also into an emptied one)")
    args = ap.parse_args()
    if not SHARED_DATA.is_dir():
        print(f"bench_features: {SHARED_DATA} not found; the benchmark needs the real data")
        return 2
    print(f"machine: {machine()}")
    if args.whole_only:
        whole_command(args.repeats, tree=args.tree, out=args.out)
        if not args.fresh_only:
            whole_command(args.repeats, fresh=False, tree=args.tree, out=args.out)
        return 0
    print(f"repeats: {args.repeats} (median), one warm-up pass; single process (one core)\n")
    hdm = sorted((SHARED_DATA / "hdm05_cut").glob("*/*.amc"))
    set1 = bandai_clips("set1.tar.xz")
    if args.quick:
        hdm, set1 = hdm[:20], set1[:10]
    asf = bench_mtanno("mtanno HDM05 ASF/AMC 120 Hz", hdm, args.repeats)
    vc3d = bench_mtanno("mtanno HDM05 as C3D (virtual) 120 Hz", virtual_c3d_files(hdm),
                        args.repeats, one_pass_c3d)
    takes = sorted((SHARED_DATA / "c3d").glob("*.c3d"))
    real = bench_mtanno("mtanno real C3D takes 120 Hz", takes, args.repeats, one_pass_c3d)
    c3d_line = (f"C3D read + markers → joints + features: {vc3d['total']:,.0f} native frames/s "
                f"on the HDM05 clips as C3D = {vc3d['total'] / asf['total']:.0%} of the AMC path "
                f"(goal >= 50 %); real takes {real['total']:,.0f} frames/s = "
                f"{real['total'] / asf['total']:.0%}")
    if args.c3d:
        print(f"\n{c3d_line}")
        return 0
    bvh = bench_mtanno("mtanno Bandai set1 BVH 30 Hz", set1, args.repeats)
    rewritten = pybvh_files(set1)
    same = bench_mtanno("mtanno Bandai set1, pybvh rewrite", rewritten, args.repeats)
    peer = bench_pybvh(rewritten, args.repeats)
    print()
    print(f"ASF/AMC parse + kinematics + features: {asf['total']:,.0f} native frames/s per core "
          f"(target >= 100,000; the original system: ~2,000)")
    print(c3d_line)
    print(f"BVH read + positions, same files: mtanno {same['parse_fk']:,.0f} vs pybvh "
          f"{peer:,.0f} frames/s = {same['parse_fk'] / peer:.1f}x (target >= 2x); "
          f"mtanno on the original 6-channel files: {bvh['parse_fk']:,.0f} frames/s")
    if not args.quick:
        whole_command(args.repeats, tree=args.tree, out=args.out)
        if not args.fresh_only:
            whole_command(args.repeats, fresh=False, tree=args.tree, out=args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
