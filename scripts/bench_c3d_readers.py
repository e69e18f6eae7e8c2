"""The choice of C3D reader (issue 36): ezc3d (C++ with Python bindings) against the pure-
Python ``c3d`` package, by speed on the five real takes of ``../shared/data/c3d`` and by
install weight, in the same run.

Each reader reads every file into a (frames × markers × 3) array of point coordinates, the
way mtanno needs them: ezc3d through its Python wrapper (``ezc3d.c3d(path)["data"]
["points"]``) and through its SWIG object directly (``ezc3d.ezc3d.c3d(path).get_points()``,
no parameter dictionaries); ``c3d`` through ``Reader.read_frames`` with and without its
per-frame NaN check (mtanno reads with ``check_nan=False`` and tests for missing markers
itself). Figures are the median of ``--repeats`` passes after a warm-up pass, in native
frames per second; install weight is the size of the installed files of each distribution
and of what it alone pulls in (both need only numpy). Run (both readers installed:
``pip install -e '.[bench]'``):

    .venv/bin/python scripts/bench_c3d_readers.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import io
import statistics
import sys
import time
import warnings
from importlib import metadata
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
C3D = REPO.parent / "shared" / "data" / "c3d"


def read_c3d_package(path: Path, check_nan: bool) -> int:
    import c3d

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = c3d.Reader(io.BytesIO(path.read_bytes()))
        n = r.last_frame - r.first_frame + 1
        out = np.empty((n, r.point_used, 3), np.float32)
        for k, (_, p, _) in enumerate(r.read_frames(copy=False, check_nan=check_nan)):
            out[k] = p[:, :3]
    return n


def read_ezc3d(path: Path) -> int:
    import ezc3d

    return ezc3d.c3d(str(path))["data"]["points"].shape[2]


def read_ezc3d_swig(path: Path) -> int:
    from ezc3d import ezc3d as swig

    return swig.c3d(str(path), swig.Options(False, False)).get_points().shape[2]


def rate(fn, files, repeats: int) -> float:
    fn(files[0])  # warm-up
    runs = []
    for _ in range(repeats):
        t = time.perf_counter()
        n = sum(fn(f) for f in files)
        runs.append(time.perf_counter() - t)
    return n / statistics.median(runs)


def installed_size(dist: str) -> float:
    """MB of the files a distribution installed (its RECORD)."""
    total = 0
    for f in metadata.files(dist) or ():
        p = Path(f.locate())
        if p.is_file():
            total += p.stat().st_size
    return total / 1e6


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    files = sorted(C3D.glob("*.c3d"))
    if not files:
        print(f"no C3D files in {C3D}")
        return 2
    print(f"machine: {machine()}")
    print(f"{len(files)} files; repeats {args.repeats} (median) after a warm-up pass\n")
    for name, fn in [("c3d (check_nan=False, as mtanno reads)", lambda p: read_c3d_package(p, False)),
                     ("c3d (check_nan=True, its default)", lambda p: read_c3d_package(p, True)),
                     ("ezc3d (Python wrapper)", read_ezc3d),
                     ("ezc3d (SWIG object, points only)", read_ezc3d_swig)]:
        print(f"{name:<42} {rate(fn, files, args.repeats):>10,.0f} frames/s")
    print()
    for dist in ("c3d", "ezc3d"):
        requires = metadata.requires(dist) or []
        print(f"{dist:<6} {metadata.version(dist):<8} installed {installed_size(dist):6.2f} MB; "
              f"requires: {', '.join(requires) or 'nothing'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
