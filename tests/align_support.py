"""Test and benchmark material for time alignment: re-timed copies of a motion with a known
warp, how well a path recovers that warp, and performances of one class composed from the
HDM05 clips of one actor. Used by tests/test_align_data.py and scripts/bench_align.py."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from mtanno.align import Alignment, Performance, performance_from_positions
from mtanno.evaluation.compose import Clip, compose_documents


def warp_function(m: int, n: int, *, alpha: float = 0.3, beta: float = 0.15) -> np.ndarray:
    """A smooth non-linear time warp: for each of m frames of the copy, the (fractional)
    frame of the original it shows, from 0 to n − 1. Its slope varies between
    (1 − α − β) and (1 + α + β) times the mean (n − 1)/(m − 1)."""
    s = np.arange(m) / (m - 1)
    w = s + alpha * np.sin(2 * np.pi * s) / (2 * np.pi) + beta * np.sin(4 * np.pi * s) / (4 * np.pi)
    return w * (n - 1)


def _interpolate(P: np.ndarray, t: np.ndarray) -> np.ndarray:
    i = np.minimum(np.floor(t).astype(np.int64), len(P) - 2)
    f = (t - i).reshape((-1,) + (1,) * (P.ndim - 1))
    return P[i] * (1 - f) + P[i + 1] * f


def retimed_pair(joints: np.ndarray, heading: np.ndarray, fps: float, *, stretch: float = 1.2,
                 name: str = "clip") -> tuple[Performance, Performance, np.ndarray]:
    """(original, copy, warp): the copy has round(stretch · n) native frames, frame k
    showing the original's joint positions (and heading) at native time warp[k], linearly
    interpolated; both get their features computed from those positions."""
    n = len(joints)
    w = warp_function(int(round(stretch * n)), n)
    a = performance_from_positions(joints, heading, fps, name=name)
    b = performance_from_positions(_interpolate(joints, w), _interpolate(heading, w), fps,
                                   name=f"{name}-retimed")
    return a, b, w


def warp_recovery(al: Alignment, warp: np.ndarray, *, tolerance: float = 1.0) -> float:
    """Fraction of the frames of A and B (analysis rate) whose path cells all lie within
    ``tolerance`` frames of the known warp: for a frame of B, the frames of A it is matched
    with versus the analysis frame the warp maps it to; for a frame of A likewise with the
    inverse warp."""
    a, b = al.a, al.b
    ratio_a = a.native_fps / a.layout.fps
    true_a = warp[b.native_frames - 1] / ratio_a  # per frame of B
    native_b = np.interp(np.arange(a.frames) * ratio_a, warp, np.arange(len(warp)))
    true_b = np.interp(native_b, b.native_frames - 1, np.arange(b.frames))  # per frame of A
    pa, pb = al.path.a, al.path.b
    ok_b = np.ones(b.frames, dtype=bool)
    ok_b[pb[np.abs(pa - true_a[pb]) > tolerance]] = False
    ok_a = np.ones(a.frames, dtype=bool)
    ok_a[pa[np.abs(pb - true_b[pa]) > tolerance]] = False
    return float((ok_a.sum() + ok_b.sum()) / (a.frames + b.frames))


def composed_performance(hdm05: Path, label: str, actor: str, k: int, out: Path) -> Path:
    """An AMC document of the first k clips (by file name) of one class by one HDM05 actor,
    one after the other (``mtanno compose``, no shuffling): k repetitions of the motion."""
    with open(hdm05 / "clips.csv", encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if r["class"] == label and r["actor"] == actor]
    clips = [Clip(hdm05 / r["file"], label, actor) for r in sorted(rows, key=lambda r: r["file"])]
    docs, _ = compose_documents(clips[:k], out / f"{label}_{actor}", n_docs=1, shuffle=False,
                                prefix=f"{label}_{actor}")
    return docs[0]
