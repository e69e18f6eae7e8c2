#!/usr/bin/env python3
"""Frame-classifier baseline of the annotation experiments (issue 10): k-nearest-neighbour
classification of every frame, then a one-second majority filter; segments are the
maximal runs of one label. Not part of the package: it is the peer that `mtanno annotate`
has to beat, trained on the same clips or segments and scored by the same `mtanno
evaluate`.

* A frame is described by the 40 features of the frames within ±0.5 s (±15 frames at
  30 Hz: 31 frames × 40 bits), the frames beyond a clip's or document's ends repeating its
  first or last frame. Distance: the number of differing bits (Hamming).
* Training frames: every frame of every training example (a manifest's clips, or the
  labelled segments of a truth table), its window taken inside the example.
* Label of a frame: the majority among the k = 5 nearest training frames (ties: the label
  whose tied neighbours are nearer in sum, then the nearest one's); every frame gets one.
* Majority filter: each frame takes the most frequent label among the frames within
  ±0.5 s (31 frames; ties: the frame's own label if tied, else the smallest class index).

* Open world (issue 35): ``--none FEATS...`` adds every frame of these background feature
  files (motions of no class) as training frames of the class "none"; frames labelled
  "none" are left unlabelled (no row). Without it every frame gets a class.

    scripts/baseline_knn.py (--manifest CSV --features-dir DIR [--split S] |
                             --truth TRUTH.csv --train FEATS...) [--none FEATS ...]
                            DOCS... -o OUT.csv
"""

from __future__ import annotations

import argparse
import sys
import time

import numba
import numpy as np

#: Neighbours that vote (issue 10).
K = 5
#: The label of background frames (``--none``): never output.
NONE = "none"
#: Half window of the frame description and of the majority filter, frames at 30 Hz.
HALF = 15


@numba.njit(cache=True)
def _pack_windows(X, half, out):
    """Bit-pack, per frame, the features of frames t−half … t+half (edges repeated)."""
    f, L = X.shape
    for t in range(L):
        bit = 0
        for o in range(-half, half + 1):
            s = min(max(t + o, 0), L - 1)
            for i in range(f):
                if X[i, s]:
                    out[t, bit >> 6] |= np.uint64(1) << np.uint64(bit & 63)
                bit += 1


def pack_windows(X: np.ndarray, half: int = HALF) -> np.ndarray:
    """(frames × words) uint64: every frame's ±``half`` window of the (features × frames)
    0/1 matrix ``X``, bit-packed."""
    f, L = X.shape
    words = (f * (2 * half + 1) + 63) // 64
    out = np.zeros((L, words), dtype=np.uint64)
    _pack_windows(np.ascontiguousarray(X, dtype=np.uint8), half, out)
    return out


@numba.njit(cache=True)
def _popcount(x):
    x = x - ((x >> np.uint64(1)) & np.uint64(0x5555555555555555))
    x = (x & np.uint64(0x3333333333333333)) + ((x >> np.uint64(2)) & np.uint64(0x3333333333333333))
    x = (x + (x >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return (x * np.uint64(0x0101010101010101)) >> np.uint64(56)


@numba.njit(cache=True, parallel=True)
def _knn(test, train, train_labels, k, n_classes, out):
    """Label of every test window: majority of its k nearest training windows (Hamming;
    ties: smaller distance sum, then the nearest neighbour's label). Early abandon once a
    partial distance exceeds the current k-th best."""
    n, words = test.shape
    m = train.shape[0]
    for t in numba.prange(n):
        best_d = np.full(k, 1 << 30, np.int64)
        best_i = np.full(k, -1, np.int64)
        for j in range(m):
            d = 0
            limit = best_d[k - 1]
            for w in range(words):
                d += _popcount(test[t, w] ^ train[j, w])
                if d > limit:
                    break
            if d < limit:  # strictly nearer: insert, keeping earlier equals first
                p = k - 1
                while p > 0 and best_d[p - 1] > d:
                    best_d[p] = best_d[p - 1]
                    best_i[p] = best_i[p - 1]
                    p -= 1
                best_d[p] = d
                best_i[p] = j
        votes = np.zeros(n_classes, np.int64)
        dsum = np.zeros(n_classes, np.int64)
        for q in range(k):
            if best_i[q] >= 0:
                c = train_labels[best_i[q]]
                votes[c] += 1
                dsum[c] += best_d[q]
        lab = train_labels[best_i[0]]
        for c in range(n_classes):
            if votes[c] > votes[lab] or (votes[c] == votes[lab] and dsum[c] < dsum[lab]):
                lab = c
        out[t] = lab


def majority_filter(labels: np.ndarray, half: int = HALF) -> np.ndarray:
    """Each frame's most frequent label within ±``half`` frames (ties: its own label if
    tied, else the smallest label)."""
    L = labels.shape[0]
    n = int(labels.max()) + 1 if L else 0
    onehot = np.zeros((L + 1, n), dtype=np.int64)
    onehot[np.arange(1, L + 1), labels] = 1
    csum = np.cumsum(onehot, axis=0)
    lo = np.clip(np.arange(L) - half, 0, L)
    hi = np.clip(np.arange(L) + half + 1, 0, L)
    counts = csum[hi] - csum[lo]
    best = counts.max(axis=1)
    own = counts[np.arange(L), labels] == best
    return np.where(own, labels, np.argmax(counts, axis=1))


def runs(labels: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs (first, last, label), 0-based inclusive."""
    edges = np.flatnonzero(np.diff(labels)) + 1
    starts = np.concatenate(([0], edges))
    ends = np.concatenate((edges - 1, [labels.shape[0] - 1]))
    return [(int(a), int(b), int(labels[a])) for a, b in zip(starts, ends)]


def main(argv=None) -> int:
    from mtanno.annotate import Annotation, write_annotations
    from mtanno.errors import MtannoError
    from mtanno.features.inputs import document_files
    from mtanno.features.store import read_features
    from mtanno.templates.training import collect_sources, load_examples
    from mtanno.util.provenance import provenance

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("docs", nargs="+", help="feature files or folders of the documents")
    ap.add_argument("-o", "--output", required=True, help="annotation table to write")
    ap.add_argument("--manifest")
    ap.add_argument("--features-dir")
    ap.add_argument("--split")
    ap.add_argument("--truth")
    ap.add_argument("--train", action="append", default=[],
                    help="with --truth: the training documents' feature files or folders")
    ap.add_argument("--none", action="append", default=[], metavar="FEATS",
                    help="background feature file or folder (repeatable): training frames "
                         "of 'none'")
    ap.add_argument("-k", type=int, default=K)
    a = ap.parse_args(argv)
    try:
        sources = collect_sources(a.train, manifest=a.manifest, features_dir=a.features_dir,
                                  split=a.split, truth=a.truth)
        examples = load_examples(sources)
        classes = sorted({e.class_name for e in examples})
        none = [read_features(p).X for p in document_files(a.none)] if a.none else []
        if none:
            classes.append(NONE)
        train = np.concatenate([pack_windows(e.X) for e in examples]
                               + [pack_windows(X) for X in none])
        labels = np.concatenate([np.full(e.X.shape[1], classes.index(e.class_name))
                                 for e in examples]
                                + [np.full(X.shape[1], classes.index(NONE)) for X in none]
                                ).astype(np.int64)
        t0 = time.perf_counter()
        rows, files, frames = [], [], {}
        for path in document_files(a.docs):
            ff = read_features(path, sha256=True)
            out = np.empty(ff.X.shape[1], dtype=np.int64)
            _knn(pack_windows(ff.X), train, labels, a.k, len(classes), out)
            for s, e, lab in runs(majority_filter(out)):
                if classes[lab] == NONE:
                    continue
                rows.append(Annotation(ff.document, s, e, classes[lab], float("nan")))
            files.append({"path": str(path), "sha256": ff.sha256})
            frames[ff.document] = int(ff.X.shape[1])
        seconds = time.perf_counter() - t0
        write_annotations(a.output, rows, provenance=provenance(
            inputs=files, method=f"k-NN baseline (k={a.k}, ±{HALF} frames, 1 s majority)"
            + (f", none class from {len(none)} background files" if none else ""),
            training=[s.path for s in sources], documents=frames))
    except MtannoError as exc:
        print(f"baseline_knn: {exc}", file=sys.stderr)
        return 2
    print(f"baseline_knn: {len(frames)} documents, {len(rows)} segments, {len(train)} "
          f"training frames, {seconds:.2f} s -> {a.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
