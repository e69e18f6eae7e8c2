"""Per-file CPU-time breakdown of ``mtanno features`` (issue 12): where a batch of short clips
spends its time, stage by stage, in CPU time (``time.process_time``) so that other jobs on
the machine do not change the figures.

Two measurements:

* **worker side**: the batch run in this process (``run_batch`` with one job, the code a
  pool worker runs for each file), with timers wrapped around each stage; each timer
  counts its own time only (the time of the timed stages it calls is subtracted);
* **parent side** (``--whole``): the whole command with ``--jobs 2`` in a subprocess, CPU
  time of the parent and of its workers (``getrusage``), once for all files and once for one
  file, so the marginal CPU per file is known.

Run:  .venv/bin/python scripts/profile_features.py [FOLDER] [--whole] [--repeats 3]
(FOLDER defaults to the tripled HDM05 tree of ``bench_features.py``).
"""

from __future__ import annotations

import argparse
import functools
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(REPO / "tests"))

from _machine import machine  # noqa: E402

_STACK: list[list] = []
TOTALS: dict[str, float] = {}
CALLS: dict[str, int] = {}


def _timed(name: str, fn):
    """``fn`` counting its exclusive CPU time under ``name``."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        frame = [0.0]  # time of timed callees
        _STACK.append(frame)
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            dt = time.process_time() - t0
            _STACK.pop()
            TOTALS[name] = TOTALS.get(name, 0.0) + dt - frame[0]
            CALLS[name] = CALLS.get(name, 0) + 1
            if _STACK:
                _STACK[-1][0] += dt

    return wrapper


def _timed_cm(name: str, cm_fn):
    """A context-manager function whose entering and leaving count under ``name``."""

    @functools.wraps(cm_fn)
    def wrapper(*args, **kwargs):
        cm = cm_fn(*args, **kwargs)

        class Timed:
            def __enter__(self):
                return _timed(name, cm.__enter__)()

            def __exit__(self, *exc):
                return _timed(name, cm.__exit__)(*exc)

        return Timed()

    return wrapper


def _patch(module, attr: str, name: str) -> None:
    if module is not None and hasattr(module, attr):
        setattr(module, attr, _timed(name, getattr(module, attr)))


def instrument() -> None:
    """Wrap the stages of one file (and of the batch around it) in timers."""
    import hashlib
    import json as json_mod

    import pyarrow as pa
    import pyarrow.parquet as pq

    import mtanno.features as features
    import mtanno.features.batch as batch
    import mtanno.features.extract as extract
    import mtanno.features.store as store
    import mtanno.io as io
    import mtanno.io.amc as amc
    import mtanno.util.output as output

    _patch(batch, "plan_batch", "parent: plan (listing, check_outputs)")
    _patch(batch, "up_to_date", "parent: up-to-date checks")
    _patch(batch, "_run_one", "other (task wrapper, metadata dict)")
    _patch(batch, "extract_file", "other (task wrapper, metadata dict)")
    _patch(extract, "read_motion", "other (task wrapper, metadata dict)")
    _patch(io, "find_asf", "find ASF (listing, resolve)")
    _patch(extract, "find_asf", "find ASF (listing, resolve)")
    _patch(batch, "find_asf", "find ASF (listing, resolve)")
    _patch(io, "_cached_asf", "ASF lookup (stat, resolve, cache)")
    _patch(amc, "read_amc", "parse AMC (read + numba kernel)")
    _patch(io, "read_channels", "parse AMC (read + numba kernel)")
    _patch(io, "find_map", "skeleton map lookup")
    _patch(io, "forward_kinematics", "kinematics")
    _patch(extract, "features_from_motion", "features")
    _patch(extract, "_motion_features", "features")
    _patch(features, "compute_features", "features")
    _patch(extract, "compute_features", "features")
    _patch(extract, "sha256_file", "SHA-256 of inputs")
    _patch(hashlib, "sha256", "SHA-256 of inputs")
    _patch(extract, "skeleton_digest", "SHA-256 of inputs")
    _patch(batch, "skeleton_digest", "SHA-256 of inputs")
    _patch(batch, "sha256_file", "SHA-256 of inputs")
    _patch(extract, "write_features", "write: Arrow table build")
    _patch(store, "_check_meta", "write: metadata JSON")
    for mod in (json_mod,):
        _patch(mod, "dumps", "write: metadata JSON")
    _patch(pq, "write_table", "write: Parquet encode")
    try:
        import mtanno.features._parquet as direct
    except ImportError:  # a checkout before the direct encoder
        direct = None
    _patch(direct, "encode", "write: Parquet encode")
    _patch(direct, "arrow_schema", "write: Parquet encode")
    _patch(pa, "table", "write: Arrow table build")
    fs_name = "write: file system (create, write, rename)"
    for mod in (store, output):
        if hasattr(mod, "atomic_path"):
            mod.atomic_path = _timed_cm(fs_name, mod.atomic_path)
        _patch(mod, "write_bytes", fs_name)
    import pathlib

    _patch(pathlib.Path, "write_bytes", fs_name)


def worker_side(folder: Path, repeats: int, where: Path | None = None) -> None:
    """The batch in this process, one job, every stage timed; best total of ``repeats``.
    Each pass writes into a new folder (all removed at the end: see bench_features.py on
    files deleted just before)."""
    from mtanno.features.batch import plan_batch, run_batch

    out = Path(tempfile.mkdtemp(prefix="mtanno-profile-", dir=where))
    try:
        jobs = plan_batch([folder], out / "warm")
        run_batch(jobs[:20], force=True)  # load kernels, caches of the ASF files
        instrument()
        import mtanno.features.batch as batch

        runs = []
        for k in range(repeats):
            TOTALS.clear()
            CALLS.clear()
            t0 = time.process_time()
            jobs = batch.plan_batch([folder], out / f"pass{k}")
            s = batch.run_batch(jobs, force=True)
            total = time.process_time() - t0
            runs.append((total, dict(TOTALS), s))
        total, totals, s = min(runs, key=lambda r: r[0])
    finally:
        if where is None:  # a folder given is left as it is (deleting many files just
            shutil.rmtree(out, ignore_errors=True)  # before slows the next ones' creation)
    n = len(jobs)
    frames = sum(o.frames for o in s.outcomes)
    known = sum(totals.values())
    totals["other (task wrapper, metadata dict)"] = \
        totals.get("other (task wrapper, metadata dict)", 0.0) + total - known
    print(f"worker side, one process, {n} files ({frames} analysis frames), best of "
          f"{repeats}: {total:.3f} s CPU = {1000 * total / n:.2f} ms per file")
    for name, t in sorted(totals.items(), key=lambda kv: -kv[1]):
        print(f"  {name:<45} {1000 * t / n:6.2f} ms/file  {100 * t / total:5.1f} %")


def _report_at_exit(folder: str) -> None:
    """In a pool worker: write this worker's timers and CPU time to ``folder`` at exit."""
    import os
    from multiprocessing import util

    def report():
        with open(os.path.join(folder, f"{os.getpid()}.json"), "w") as fh:
            json.dump({"totals": TOTALS, "cpu": time.process_time()}, fh)

    util.Finalize(None, report, exitpriority=10)


def pool_side(folder: Path, jobs: int, where: Path | None = None) -> None:
    """The batch in a pool of ``jobs`` workers started here (the timers inherited through
    fork); each worker reports its timers and its whole CPU time at exit, so the time
    outside the timed stages (task passing, result pickling, the pool's threads) shows."""
    import mtanno.util.workers as workers
    from mtanno.features.batch import plan_batch, run_batch

    out = Path(tempfile.mkdtemp(prefix="mtanno-profile-", dir=where))
    reports = Path(tempfile.mkdtemp(prefix="mtanno-profile-reports-"))
    init = workers._init_worker

    def init_and_report(*args):
        init(*args)
        TOTALS.clear()
        _report_at_exit(str(reports))

    try:
        run_batch(plan_batch([folder], out / "warm")[:20], force=True)  # kernels loaded
        jobs_list = plan_batch([folder], out / "run")
        instrument()
        workers._init_worker = init_and_report
        TOTALS.clear()
        t0 = time.process_time()
        w0 = time.perf_counter()
        s = run_batch(jobs_list, force=True, n_jobs=jobs)
        parent = time.process_time() - t0
        wall = time.perf_counter() - w0
        parent_totals = dict(TOTALS)
        got = [json.loads(p.read_text()) for p in reports.glob("*.json")]
    finally:
        workers._init_worker = init
        if where is None:  # a folder given is left as it is (deleting many files just
            shutil.rmtree(out, ignore_errors=True)  # before slows the next ones' creation)
        shutil.rmtree(reports, ignore_errors=True)
    n = len(jobs_list)
    assert not s.failed
    totals: dict[str, float] = {}
    cpu = 0.0
    for g in got:
        cpu += g["cpu"]
        for k, v in g["totals"].items():
            totals[k] = totals.get(k, 0.0) + v
    totals["worker: outside the stages (tasks, results, pool threads)"] = \
        cpu - sum(totals.values())
    print(f"pool of {jobs} workers (forked after the kernels were loaded), {n} files: "
          f"wall {wall:.2f} s; parent CPU {parent:.3f} s = {1000 * parent / n:.2f} ms per "
          f"file; workers CPU {cpu:.3f} s = {1000 * cpu / n:.2f} ms per file")
    for name, t in sorted(totals.items(), key=lambda kv: -kv[1]):
        print(f"  {name:<58} {1000 * t / n:6.2f} ms/file")
    for name, t in sorted(parent_totals.items(), key=lambda kv: -kv[1]):
        if t >= 0.0005 * n:
            print(f"  parent: {name:<50} {1000 * t / n:6.2f} ms/file")


_RUSAGE = r"""
import atexit, resource, sys
def _report():
    s = resource.getrusage(resource.RUSAGE_SELF); c = resource.getrusage(resource.RUSAGE_CHILDREN)
    sys.stderr.write("RUSAGE %r %r\n" % (s.ru_utime + s.ru_stime, c.ru_utime + c.ru_stime))
atexit.register(_report)
from mtanno.cli import main
sys.argv = ["mtanno", *sys.argv[1:]]
main()
"""


def _whole(inputs: list[str], out: Path, jobs: int) -> tuple[float, float, float]:
    """(wall s, parent CPU s, workers CPU s) of one whole command."""
    import os

    env = {**os.environ, "PYTHONPATH": str(REPO)}
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", _RUSAGE, "features", "-q", "--force",
                        "--jobs", str(jobs), *inputs, "-o", str(out)],
                       check=True, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    line = next(ln for ln in r.stderr.splitlines() if ln.startswith("RUSAGE"))
    parent, children = map(float, line.split()[1:])
    return wall, parent, children


def whole_side(folder: Path, repeats: int, jobs: int, where: Path | None = None) -> None:
    files = sorted(folder.rglob("*.amc"))
    out = Path(tempfile.mkdtemp(prefix="mtanno-profile-", dir=where))
    try:
        _whole([str(files[0])], out / "warm", jobs)
        alls = [_whole([str(folder)], out / f"all{k}", jobs) for k in range(repeats)]
        ones = [_whole([str(files[0])], out / f"one{k}", jobs) for k in range(repeats)]
    finally:
        if where is None:  # a folder given is left as it is (deleting many files just
            shutil.rmtree(out, ignore_errors=True)  # before slows the next ones' creation)
    med = [statistics.median(r[i] for r in alls) for i in range(3)]
    one = [statistics.median(r[i] for r in ones) for i in range(3)]
    n = len(files) - 1
    print(f"whole command --jobs {jobs}, {len(files)} files, median of {repeats}: "
          f"wall {med[0]:.2f} s (one file {one[0]:.2f} s)")
    print(f"  parent CPU  {med[1]:.2f} s (one file {one[1]:.2f} s): marginal "
          f"{1000 * (med[1] - one[1]) / n:.2f} ms per file")
    print(f"  workers CPU {med[2]:.2f} s (one file {one[2]:.2f} s): marginal "
          f"{1000 * (med[2] - one[2]) / n:.2f} ms per file")
    print(f"  all CPU marginal {1000 * (med[1] + med[2] - one[1] - one[2]) / n:.2f} ms per "
          f"file; wall marginal {1000 * (med[0] - one[0]) / n:.2f} ms per file")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", nargs="?", type=Path,
                    default=REPO / ".cache" / "bench" / "hdm05x3")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--whole", action="store_true", help="also the whole command (parent side)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path,
                    help="folder for the outputs, kept (default: a temporary one, removed)")
    args = ap.parse_args()
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    if not args.folder.is_dir():
        from bench_features import tripled_tree

        tripled_tree(args.folder)
    print(f"machine: {machine()}")
    worker_side(args.folder, args.repeats, args.out)
    pool_side(args.folder, args.jobs, args.out)
    if args.whole:
        whole_side(args.folder, args.repeats, args.jobs, args.out)
    print(json.dumps({"load_after": __import__("os").getloadavg()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
