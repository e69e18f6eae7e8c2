"""Index and query benchmark (MRC05 §6.1–6.2, Tables 2 and 3; docs/method.md §4 and §9).

Data: the Bandai set-2 archives (5 styles, 30 fps BVH) and the 232 HDM05 clips. Features are
computed once per feature set into ``.cache/bench/<data>-<set>/`` (skipped when present;
not timed). Then, per data set and feature set:

* build: ``build_index`` of the feature directory into ``.cache/bench/index-…`` (median of
  ``--repeat`` runs; feature extraction excluded, reading the feature files included and
  also shown on its own as "read");
* size: index bytes, segments, non-empty lists and bytes per segment per group (Table 2);
* queries (Table 3): ``--queries`` random queries (default 10 000) per mode and query size
  (5, 10, 20 segments) on one group (default: the upper group, MRC05's I_u), each guaranteed
  at least one hit because it is cut out of an indexed document:

  - exact: L consecutive segment vectors of a document;
  - fuzzy: the same with 6 random features freed at every position (|V_i| = 2^6 = 64
    alternatives, as in Table 3), never a feature that tells the position from its
    neighbours, so neighbouring sets stay disjoint;
  - adaptive: 6 random features of the group fixed, the rest free (64 alternatives per
    set), the sets being L consecutive runs of the document's projected segmentation
    (a query by example of L segments);
  - adaptive-2: the same with only 2 features fixed (many hits).

  Latency is the wall time of :func:`mtanno.index.search` (normalisation, list scan,
  frames) per query, grouped by hit count (1–9, 10–99, ≥ 100): median and 95th percentile.

Run ``python scripts/bench_index.py --help``; figures in docs/index.md came from
``python scripts/bench_index.py``. ``--command-only FEATURES --repeat 5`` times only the
whole ``mtanno index`` command over a folder (``--mtanno EXE`` for another checkout's).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from data_cache import SHARED_DATA, unpack_archive  # noqa: E402

from mtanno.index import FuzzySet, GroupQuery, Query, build_index, search  # noqa: E402
from mtanno.index.core import collect_feature_files, read_feature_docs  # noqa: E402
from mtanno.index.storage import read_index_manifest  # noqa: E402

BENCH = REPO / ".cache" / "bench"
SET2 = ["set2-active", "set2-elderly", "set2-feminine", "set2-masculine", "set2-normal"]
SIZES = (5, 10, 20)
BUCKETS = ((1, 9, "1–9"), (10, 99, "10–99"), (100, None, "≥100"))
FREE_BITS = 6


def features_dir(name: str, sources: list[Path], feature_set: str) -> Path:
    """Compute features once into .cache/bench/<name>-<set> (not timed)."""
    out = BENCH / f"{name}-{feature_set}"
    marker = out / ".complete"
    if marker.is_file():
        return out
    print(f"computing {feature_set} features for {name} into {out} (once) …", flush=True)
    cmd = [sys.executable, "-m", "mtanno.cli", "features", *map(str, sources), "-o", str(out),
           "--feature-set", feature_set, "--jobs", str(os.cpu_count() or 1), "-q"]
    subprocess.run(cmd, check=True)
    marker.write_text("ok\n")
    return out


def sources(name: str) -> list[Path]:
    if name == "bandai-set2":
        return [unpack_archive(SHARED_DATA / "bandai" / f"{a}.tar.xz") for a in SET2]
    return [SHARED_DATA / "hdm05_cut"]


def bench_build(feats: Path, out: Path, repeat: int) -> dict:
    """Median times of the build phases (read feature files, segment + inverted lists,
    write) and of a whole :func:`build_index` call."""
    from mtanno.index.build import _default_groups, _entries
    from mtanno.index.core import assemble, check_compatible, resolve_groups
    from mtanno.index.storage import write_index

    paths = collect_feature_files([feats])
    read_feature_docs(paths)  # warm the page cache: every timing below reads from memory
    phases: dict[str, list[float]] = {"read": [], "segment": [], "write": [], "build": []}
    index = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        docs = read_feature_docs(paths)
        t1 = time.perf_counter()
        check_compatible(docs)
        gs = resolve_groups(docs[0].names, _default_groups(docs[0]), None)
        idx = assemble(docs[0].meta["feature_set"], 1, docs[0].names, 30.0, gs,
                       _entries(docs, gs))
        t2 = time.perf_counter()
        tmp = out.with_name(out.name + "-phases")
        if tmp.exists():
            shutil.rmtree(tmp)
        write_index(idx, tmp)
        t3 = time.perf_counter()
        shutil.rmtree(tmp)
        if out.exists():
            shutil.rmtree(out)
        t4 = time.perf_counter()
        index = build_index([feats], out)
        t5 = time.perf_counter()
        for k, v in zip(phases, (t1 - t0, t2 - t1, t3 - t2, t5 - t4)):
            phases[k].append(v)
    manifest = read_index_manifest(out)
    # the whole command, process start-up included (issue 12: < 5 s for Bandai set 2)
    whole = []
    for _ in range(repeat):
        shutil.rmtree(out, ignore_errors=True)
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "mtanno.cli", "index", str(feats), "-o",
                        str(out), "-q"], check=True)
        whole.append(time.perf_counter() - t)
    return {"index": index, "files": len(paths), "manifest": manifest,
            "command": statistics.median(whole),
            **{k: statistics.median(v) for k, v in phases.items()}}


def print_sizes(name: str, fs: str, b: dict) -> None:
    index, files = b["index"], b["manifest"]["files"]
    total = sum(e["bytes"] for e in files.values())
    minutes = index.frames / index.fps / 60
    print(f"\n## {name}, feature set {fs}: {len(index.documents)} documents, {index.frames} "
          f"frames at {index.fps:g} Hz ({minutes:.1f} min)")
    print(f"build_index: {b['build']:.2f} s for {b['files']} feature files (phases: read "
          f"{b['read']:.2f} s, segment + inverted lists {b['segment']:.2f} s, write "
          f"{b['write']:.2f} s); index {total / 1e6:.2f} MB on disk; the whole command "
          f"`mtanno index` {b['command']:.2f} s (start-up included; target < 5 s for Bandai "
          f"set 2)")
    print("| group | f | segments | seg/frame | lists (of 2^f) | bytes | bytes/segment |")
    print("|---|---|---|---|---|---|---|")
    for g in index.groups.values():
        size = files[f"segments-{g.name}.parquet"]["bytes"] + files[f"lists-{g.name}.parquet"]["bytes"]
        print(f"| {g.name} | {len(g.features)} | {g.n_segments} | "
              f"{g.n_segments / index.frames:.3f} | {g.n_lists} ({2 ** len(g.features)}) | "
              f"{size} | {size / max(1, g.n_segments):.2f} |")


# --- random queries guaranteed to hit --------------------------------------------------------

def _docs_with(g, min_segments):
    counts = np.diff(g.doc_offsets)
    return np.flatnonzero(counts >= min_segments)


def exact_query(rng, g, L):
    docs = _docs_with(g, L)
    d = int(rng.choice(docs))
    lo, hi = int(g.doc_offsets[d]), int(g.doc_offsets[d + 1])
    k = int(rng.integers(lo, hi - L + 1))
    n = len(g.features)
    return GroupQuery(g.name, tuple(FuzzySet.exact(int(c), n) for c in g.code[k:k + L]))


def fuzzy_query(rng, g, L, tries=50):
    """L consecutive segment vectors, each with 6 random features freed (64 alternatives);
    features that tell a position from a neighbour stay fixed, so neighbouring sets are
    disjoint (no merging) and the document segment range is a fuzzy hit."""
    n = len(g.features)
    full = (1 << n) - 1
    docs = _docs_with(g, L)
    for _ in range(tries):
        d = int(rng.choice(docs))
        lo, hi = int(g.doc_offsets[d]), int(g.doc_offsets[d + 1])
        k = int(rng.integers(lo, hi - L + 1))
        codes = [int(c) for c in g.code[k:k + L]]
        sets = []
        for i, c in enumerate(codes):
            keep = 0
            if i > 0:
                keep |= c ^ codes[i - 1]
            if i + 1 < L:
                keep |= c ^ codes[i + 1]
            free_ok = [b for b in range(n) if not keep >> b & 1]
            if len(free_ok) < FREE_BITS:
                break
            free = sum(1 << int(b) for b in rng.choice(free_ok, FREE_BITS, replace=False))
            sets.append(FuzzySet(((full & ~free, c & ~free),)))
        if len(sets) == L:
            return GroupQuery(g.name, tuple(sets))
    return None


def adaptive_query(rng, g, L, tries=200, fixed=None):
    """A query by example of L segments: ``fixed`` random features of the group (default
    all but 6) fixed to a document's projected segmentation, the others free."""
    n = len(g.features)
    fixed = n - FREE_BITS if fixed is None else fixed
    for _ in range(tries):
        bits = rng.choice(n, fixed, replace=False)
        mask = sum(1 << int(b) for b in bits)
        d = int(rng.integers(len(g.doc_offsets) - 1))
        lo, hi = int(g.doc_offsets[d]), int(g.doc_offsets[d + 1])
        proj = g.code[lo:hi] & mask
        if len(proj) == 0:
            continue
        starts = np.flatnonzero(np.r_[True, proj[1:] != proj[:-1]])
        if len(starts) < L:
            continue
        j = int(rng.integers(0, len(starts) - L + 1))
        vals = proj[starts[j:j + L]]
        return GroupQuery(g.name, tuple(FuzzySet(((mask, int(v)),)) for v in vals))
    return None


def broad_query(rng, g, L):
    """Adaptive query with only 2 features fixed (2^(f−2) alternatives per set): the
    general queries that give many hits."""
    return adaptive_query(rng, g, L, fixed=2)


#: label → (query maker, mode)
MAKERS = {"exact": (exact_query, "exact"), "fuzzy": (fuzzy_query, "fuzzy"),
          "adaptive": (adaptive_query, "adaptive"), "adaptive-2": (broad_query, "adaptive")}


def bench_queries(index, group: str, n_queries: int, seed: int) -> list[dict]:
    g = index.groups[group]
    rng = np.random.default_rng(seed)
    search(index, Query((exact_query(rng, g, 2),), "exact"))  # JIT warm-up (cache load)
    search(index, Query((adaptive_query(rng, g, 2),), "adaptive"))
    rows = []
    for label, (make, mode) in MAKERS.items():
        for L in SIZES:
            times, hits = [], []
            made = 0
            while made < n_queries:
                gq = make(rng, g, L)
                if gq is None:
                    break
                q = Query((gq,), mode)
                t = time.perf_counter_ns()
                h = search(index, q)
                times.append((time.perf_counter_ns() - t) / 1e6)
                hits.append(len(h))
                made += 1
            times_a, hits_a = np.array(times), np.array(hits)
            if made < n_queries:
                print(f"warning: {label} L={L}: only {made} queries could be sampled")
            if made == 0:
                continue
            assert (hits_a >= 1).all(), f"{label} L={L}: a query without hits"
            for lo, hi, blabel in BUCKETS:
                sel = (hits_a >= lo) & ((hits_a <= hi) if hi is not None else True)
                if not sel.any():
                    continue
                rows.append({"mode": label, "L": L, "bucket": blabel, "n": int(sel.sum()),
                             "hits_mean": float(hits_a[sel].mean()),
                             "hits_sd": float(hits_a[sel].std()),
                             "median_ms": float(np.median(times_a[sel])),
                             "p95_ms": float(np.percentile(times_a[sel], 95))})
            rows.append({"mode": label, "L": L, "bucket": "all", "n": len(times_a),
                         "hits_mean": float(hits_a.mean()), "hits_sd": float(hits_a.std()),
                         "median_ms": float(np.median(times_a)),
                         "p95_ms": float(np.percentile(times_a, 95))})
    return rows


def print_queries(name, fs, group, rows, index) -> None:
    g = index.groups[group]
    print(f"\n### {name} {fs}: queries on group '{group}' ({len(g.features)} features, "
          f"{g.n_segments} segments); fuzzy/adaptive sets have {2 ** FREE_BITS} alternatives, "
          f"adaptive-2 sets {2 ** (len(g.features) - 2)}")
    print("| mode | segments | hits | queries | mean hits (sd) | median ms | p95 ms |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['mode']} | {r['L']} | {r['bucket']} | {r['n']} | {r['hits_mean']:.1f} "
              f"({r['hits_sd']:.1f}) | {r['median_ms']:.3f} | {r['p95_ms']:.3f} |")


def bench_command(feats: Path, repeat: int, *, mtanno: str | None = None) -> None:
    """Time ``mtanno index FEATS -o OUT -q`` as a user runs it (a new process each time,
    imports included; the feature files in the page cache after a first untimed run):
    the median of ``repeat`` runs, with the phases of one run in-process beside it (the
    package import, collecting the paths and checking the outputs, reading the files,
    the rest). ``mtanno`` is the executable (default this interpreter's ``-m mtanno``), so
    two checkouts can be compared on the same files."""
    import tempfile

    cmd = [mtanno] if mtanno else [sys.executable, "-m", "mtanno"]
    with tempfile.TemporaryDirectory(prefix="bench-index-") as tmp:
        out = Path(tmp) / "idx"
        subprocess.run([*cmd, "index", str(feats), "-o", str(out), "-q"], check=True)
        walls, cpus = [], []
        for _ in range(repeat):
            shutil.rmtree(out, ignore_errors=True)
            r0 = os.times()
            t = time.perf_counter()
            subprocess.run([*cmd, "index", str(feats), "-o", str(out), "-q"], check=True)
            walls.append(time.perf_counter() - t)
            r1 = os.times()
            cpus.append(r1.children_user - r0.children_user + r1.children_system
                        - r0.children_system)
        probe = subprocess.run([*cmd[:1], "-c", "import sys, time; t = time.perf_counter(); "
                                "import mtanno.cli; print(time.perf_counter() - t)"]
                               if not mtanno else ["true"], capture_output=True, text=True)
    n = len(collect_feature_files([feats]))
    t = time.perf_counter()
    paths = collect_feature_files([feats])
    t_collect = time.perf_counter() - t
    t = time.perf_counter()
    read_feature_docs(paths)
    t_read = time.perf_counter() - t
    imp = f"{float(probe.stdout):.2f} s" if probe.stdout.strip() else "n/a"
    print(f"`mtanno index` over {n} feature files ({' '.join(cmd)}): median "
          f"{statistics.median(walls):.2f} s wall of {repeat} runs (min {min(walls):.2f}, max "
          f"{max(walls):.2f}), {statistics.median(cpus):.2f} s CPU; in-process phases: import "
          f"of mtanno.cli {imp}, collect paths {t_collect:.2f} s, read the files "
          f"{t_read:.2f} s ({t_read / max(1, n) * 1000:.2f} ms each); target < 5 s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--command-only", metavar="FEATURES", type=Path, default=None,
                    help="only time the whole `mtanno index` command over this folder of "
                         "feature files (median of --repeat runs; e.g. 5)")
    ap.add_argument("--mtanno", default=None, help="with --command-only: the mtanno "
                    "executable to time (e.g. another checkout's .venv/bin/mtanno)")
    ap.add_argument("--queries", type=int, default=10_000, help="queries per mode and size")
    ap.add_argument("--repeat", type=int, default=3, help="build repetitions (median)")
    ap.add_argument("--data", nargs="+", default=["bandai-set2", "hdm05"],
                    choices=["bandai-set2", "hdm05"])
    ap.add_argument("--feature-sets", nargs="+", default=["mrc05", "ak40"],
                    choices=["mrc05", "ak40", "mrc05-reference"])
    ap.add_argument("--group", default="upper", help="group the queries run on")
    ap.add_argument("--seed", type=int, default=2005)
    args = ap.parse_args()
    if args.command_only is not None:
        print(f"machine: {machine()}")
        bench_command(args.command_only, args.repeat, mtanno=args.mtanno)
        return
    if not SHARED_DATA.is_dir():
        sys.exit(f"bench_index: {SHARED_DATA} not found (the shared data folder)")
    print(f"# mtanno index benchmark\nmachine: {machine()}")
    for name in args.data:
        src = sources(name)
        for fs in args.feature_sets:
            feats = features_dir(name, src, fs)
            b = bench_build(feats, BENCH / f"index-{name}-{fs}", args.repeat)
            print_sizes(name, fs, b)
            if args.queries > 0:
                rows = bench_queries(b["index"], args.group, args.queries, args.seed)
                print_queries(name, fs, args.group, rows, b["index"])
            sys.stdout.flush()


if __name__ == "__main__":
    main()
