"""Matching throughput of the bit-packed streaming kernel against libfmp and librosa.

    .venv/bin/python scripts/bench_match.py [--runs 5] [--length 200000] [--no-peers]

Sizes of issue 3: a quantized template of K = 100 columns (about 15 % wildcards, weights
≈ 1) against a random binary document of L = 200 000 frames and 40 features; throughput in
cells/s = K·L / seconds, median of --runs runs after a warm-up, one thread (the thread
variables below are set before numpy is imported; the kernels are serial anyway).

* mtanno: `match_template` end to end (input checks, bit packing, kernel; Δ and start frames
  for every frame) and the kernel alone, for both variants.
* libfmp (`libfmp.c7.compute_accumulated_cost_matrix_subsequence_dtw_21`, numba, steps
  (1,1),(2,1),(1,2), unweighted) and librosa (`librosa.sequence.dtw(C=…, subseq=True,
  backtrack=False)` with steps (1,1),(1,2),(2,1) and multiplicative weights 1,1,2): both
  need the full K×L local-cost matrix, built here with numpy (two matrix products give the
  masked disagreements, the reference cost formula scales them) and timed separately.
  Neither returns start frames (that would take a backtrack per end frame).
* Peak memory of one template against a 10-hour document (1 080 000 frames at 30 Hz),
  measured in a child process (VmHWM, and tracemalloc for numpy's allocations).

Figures go to docs/benchmarks.md by hand; nothing here is asserted by the tests.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_annotate import median_wall  # noqa: E402

F, K = 40, 100
TEN_HOURS = 10 * 3600 * 30


def make_inputs(L: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    X = np.empty((F, L), dtype=np.uint8)
    for i in range(F):  # row by row: no float temporaries of the whole document
        X[i] = rng.random(L) < rng.uniform(0.1, 0.6)
    V = (rng.random((F, K)) < 0.35).astype(float)
    V[rng.random((F, K)) < 0.15] = 0.5
    w = rng.uniform(0.8, 1.4, size=K)  # all round to one copy: K expanded columns
    return V, w, X


def median_time(fn, runs: int) -> float:
    fn()  # warm-up (JIT compilation, caches)
    return median_wall(fn, runs)


def cost_matrix(V, w, X):
    """Full K×L local cost of the reference variant, with numpy."""
    n = V.shape[1]
    V1 = (V == 1.0).T.astype(np.float64)
    V0 = (V == 0.0).T.astype(np.float64)
    Y = X.astype(np.float64)
    mism = V1 @ (1.0 - Y) + V0 @ Y
    nnz = (V != 0.5).sum(axis=0)
    return mism / n * ((w + 1.0) / (2.0 * np.maximum(1, nnz)))[:, None]


def bench(runs: int, L: int, peers: bool) -> dict:
    from mtanno.templates.match import PreparedTemplate, _pack_frames, match_template

    V, w, X = make_inputs(L)
    cells = K * L
    res: dict = {"K": K, "L": L, "features": F, "runs": runs}
    packed = np.empty((L, 1), dtype=np.uint64)
    _pack_frames(X, packed)
    offsets = np.array([0, L], dtype=np.int64)
    for variant in ("reference", "paper"):
        t = median_time(lambda v=variant: match_template(V, w, X, variant=v), runs)
        prep = PreparedTemplate(V, w, variant=variant, steps=((1, 1), (1, 2), (2, 1)),
                         step_weights=(1, 1, 2))
        tk = median_time(lambda p=prep: p.run(packed, offsets), runs)
        res[f"mtanno_{variant}"] = {"seconds": t, "cells_per_s": cells / t,
                                    "kernel_seconds": tk, "kernel_cells_per_s": cells / tk}
    if not peers:
        return res
    C = cost_matrix(V, w, X)
    tc = median_time(lambda: cost_matrix(V, w, X), runs)
    res["cost_matrix"] = {"seconds": tc, "cells_per_s": cells / tc}
    try:
        import libfmp.c7 as c7

        fn = c7.compute_accumulated_cost_matrix_subsequence_dtw_21
        fn(C[:, :500])
        td = median_time(lambda: fn(C), runs)
        res["libfmp"] = {"dtw_seconds": td, "dtw_cells_per_s": cells / td,
                         "total_cells_per_s": cells / (td + tc)}
    except ImportError as exc:
        res["libfmp"] = {"error": f"not installed ({exc})"}
    try:
        import librosa

        sigma = np.array([[1, 1], [1, 2], [2, 1]])
        mul = np.array([1.0, 1.0, 2.0])

        def run_librosa(Cm=C):
            return librosa.sequence.dtw(C=Cm, subseq=True, backtrack=False,
                                        step_sizes_sigma=sigma, weights_mul=mul)

        run_librosa(C[:, :500])
        td = median_time(run_librosa, max(3, runs // 2))
        res["librosa"] = {"dtw_seconds": td, "dtw_cells_per_s": cells / td,
                          "total_cells_per_s": cells / (td + tc)}
    except ImportError as exc:
        res["librosa"] = {"error": f"not installed ({exc})"}
    return res


def _proc_status(key: str) -> int:
    """A memory figure of this process from /proc/self/status, in bytes."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"{key} not in /proc/self/status")


def memory_child(L: int) -> None:
    """Run in a child: peak memory of one template matched against an L-frame document.

    Uses VmHWM (the resident high-water mark of this process image; ru_maxrss would carry the
    parent's peak across fork and exec), reset just before matching where the kernel allows
    it (/proc/self/clear_refs), and tracemalloc for numpy's allocations.
    """
    import tracemalloc

    from mtanno.templates.match import match_template

    V, w, X = make_inputs(2000)
    match_template(V, w, X)  # compile / load the kernels first
    _, _, X = make_inputs(L, seed=1)
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")  # reset VmHWM to the current resident size
        reset = True
    except OSError:
        reset = False
    before = _proc_status("VmRSS")
    tracemalloc.start()
    delta, start = match_template(V, w, X)
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(json.dumps({"frames": L, "document_bytes": X.nbytes, "rss_before": before,
                      "rss_peak": _proc_status("VmHWM"), "hwm_reset": reset,
                      "traced_peak": traced_peak, "output_bytes": delta.nbytes + start.nbytes}))


def mb(x: float) -> str:
    return f"{x / 2**20:.1f} MiB"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="timed runs per measurement (≥ 5)")
    ap.add_argument("--length", type=int, default=200_000, help="document frames")
    ap.add_argument("--no-peers", action="store_true", help="skip libfmp and librosa")
    ap.add_argument("--memory-child", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_child is not None:
        memory_child(args.memory_child)
        return

    print(f"# bench_match: K={K}, L={args.length}, {F} features, median of {args.runs} runs, "
          f"1 thread, {platform.processor() or platform.machine()}, python "
          f"{platform.python_version()}")
    r = bench(args.runs, args.length, not args.no_peers)
    for v in ("reference", "paper"):
        m = r[f"mtanno_{v}"]
        print(f"mtanno {v:<9}  end to end {m['cells_per_s'] / 1e6:8.1f} M cells/s "
              f"({m['seconds'] * 1e3:7.1f} ms)   kernel {m['kernel_cells_per_s'] / 1e6:8.1f} "
              f"M cells/s ({m['kernel_seconds'] * 1e3:7.1f} ms)")
    ours = r["mtanno_reference"]["cells_per_s"]
    if "cost_matrix" in r:
        c = r["cost_matrix"]
        print(f"cost matrix (numpy, for the peers)  {c['cells_per_s'] / 1e6:8.1f} M cells/s "
              f"({c['seconds'] * 1e3:7.1f} ms)")
        best = 0.0
        for name in ("libfmp", "librosa"):
            p = r[name]
            if "error" in p:
                print(f"{name:<8} {p['error']}")
                continue
            best = max(best, p["dtw_cells_per_s"])
            print(f"{name:<8}  DTW only {p['dtw_cells_per_s'] / 1e6:8.1f} M cells/s "
                  f"({p['dtw_seconds'] * 1e3:7.1f} ms)   with cost matrix "
                  f"{p['total_cells_per_s'] / 1e6:8.1f} M cells/s   mtanno/{name}: "
                  f"{ours / p['dtw_cells_per_s']:5.1f}x (DTW only), "
                  f"{ours / p['total_cells_per_s']:5.1f}x (with cost matrix)")
        if best:
            print(f"mtanno reference vs the faster peer's DTW alone: {ours / best:.1f}x "
                  f"(target ≥ 3x); absolute target ≥ 300 M cells/s: "
                  f"{'met' if ours >= 300e6 else 'NOT met'}")
    out = subprocess.run([sys.executable, __file__, "--memory-child", str(TEN_HOURS)],
                         capture_output=True, text=True, check=True)
    m = json.loads(out.stdout)
    print(f"10-hour document ({m['frames']} frames, features {mb(m['document_bytes'])}): "
          f"peak RSS {mb(m['rss_peak'])} (before matching {mb(m['rss_before'])}, "
          f"+{mb(m['rss_peak'] - m['rss_before'])}"
          f"{'' if m['hwm_reset'] else '; peak not reset, includes the setup'}); "
          f"numpy allocations during matching peak {mb(m['traced_peak'])} "
          f"(of which Δ and start {mb(m['output_bytes'])}); "
          f"a full K×L float64 matrix would be {mb(K * m['frames'] * 8)}")


if __name__ == "__main__":
    main()
