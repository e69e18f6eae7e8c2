"""Looking into feature files: which features a file holds, and when they are on.

This is the API behind ``mtanno info FILE.parquet --features`` and ``mtanno show``: read
a document's features as a compact text timeline (one row per feature, one character per
frame or per block of frames) to pick the frames and features of a query by example
([MRC05] §6.2, ``mtanno query --example``). Frames are 1-based and inclusive at 30 Hz, as in
every file.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.features.store import FeatureFile
from mtanno.io.skeleton import Motion

#: Characters of a timeline cell: the feature is off in every frame of the cell, on in
#: every frame, or on in some.
OFF, ON, MIXED = ".", "#", "+"
#: Default number of timeline columns (frames per column grow to fit).
DEFAULT_WIDTH = 100


def describe_feature_file(ff: FeatureFile) -> list[str]:
    """The lines ``mtanno info FILE.parquet`` prints: document, source motion file (with
    the start of its SHA-256), feature set and count, frames at the analysis and the native
    rate, the pose block if the file has one (``features --poses``: joints and unit),
    skeleton map and the mtanno version that wrote it (the file's metadata)."""
    m = ff.meta
    poses = m.get("poses") if ff.has_poses else None
    n = ff.X.shape[1]
    invalid = n - int(ff.valid.sum())
    markers = m.get("markers") if isinstance(m.get("markers"), dict) else None
    return [
        f"feature file   {ff.path}",
        f"document       {ff.document}",
        f"source         {m.get('source')} (sha256 {str(m.get('source_sha256'))[:12]}…)",
        f"feature set    {m.get('feature_set')} v{m.get('feature_set_version')}, "
        f"{len(ff.names)} features",
        f"frames         {ff.X.shape[1]} at {m.get('analysis_fps')} Hz "
        f"({m.get('native_frames')} native at {m.get('native_fps')} Hz)",
        *([f"poses          {len(poses['joints'])} joints, {poses['unit']}"] if poses else []),
        *([f"invalid        {invalid} frames ({100 * invalid / max(n, 1):.1f} %) in "
           f"{len(m['invalid'])} stretch(es): no evidence, never labelled"]
          if "invalid" in m else []),
        *([f"marker set     {markers.get('set')} (subject prefix "
           f"{markers.get('subject') or 'none'!r}, units {markers.get('units')})"]
          if markers else [f"skeleton map   {m.get('skeleton_map')}"]),
        f"mtanno         {m.get('mtanno_version')}",
    ]


def describe_motion(motion: Motion) -> list[str]:
    """The lines ``mtanno info MOTION`` prints for a motion read by
    :func:`mtanno.io.read_motion`: rig, frame rate, length in frames and seconds, skeleton
    map and how it was chosen or made (a map file that fits, ``--skeleton``, or generated
    from the joint names and the tree, :mod:`mtanno.io.guess`, or from the hierarchy and
    rest pose, :mod:`mtanno.io.topology`), and which rig joint each
    canonical joint of the map comes from (MISSING where the map finds none)."""
    from mtanno.io.rigs import CANONICAL_JOINTS

    if motion.markers is not None:
        return describe_markers(motion)
    rig = motion.rig
    cov = motion.smap.coverage(rig)
    missing = [j for j in CANONICAL_JOINTS if cov[j] is None]
    lines = [
        f"file           {motion.source}",
        f"rig            {rig.kind.upper()} ({rig.source}), {rig.n_nodes} nodes",
        f"frame rate     {motion.fps:g} Hz",
        f"frames         {motion.n_frames}",
        f"duration       {motion.n_frames / motion.fps:.2f} s",
        f"skeleton map   {motion.smap.name} ({motion.smap.path})",
        *([f"map made by    {motion.smap.how}"] if getattr(motion.smap, "how", "") else []),
        f"map coverage   {len(CANONICAL_JOINTS) - len(missing)}/{len(CANONICAL_JOINTS)}"
        + (f" (missing: {', '.join(missing)})" if missing else ""),
    ]
    return lines + [f"  {j:<10} <- {cov[j] or 'MISSING'}" for j in CANONICAL_JOINTS]


def describe_markers(motion: Motion) -> list[str]:
    """The lines ``mtanno info FILE.c3d`` prints: frame rate, length, units and up axis,
    the marker set and how it was chosen, the subject prefix, gaps filled and frames
    invalid, the body sizes measured, which canonical joints each marker feeds and how
    each joint is made (:mod:`mtanno.io.markerset`)."""
    from mtanno.io.rigs import CANONICAL_JOINTS

    r = motion.markers
    mset = motion.smap
    n = motion.n_frames
    filled = sum(r.filled.values())
    lines = [
        f"file           {motion.source}",
        f"markers        {len(r.markers) + len(r.ignored)} in the file, {len(r.markers)} "
        f"read" + (f" (ignored: {', '.join(r.ignored[:8])}{' …' if len(r.ignored) > 8 else ''})"
                   if r.ignored else ""),
        f"frame rate     {motion.fps:g} Hz",
        f"frames         {n}",
        f"duration       {n / motion.fps:.2f} s",
        f"units, up      {r.units}, {r.up.upper()} up",
        f"marker set     {mset.name} ({mset.path})",
        f"set chosen     {mset.how}",
        f"subject        {r.subject or '(no prefix)'}",
        f"gaps filled    {filled} marker-frames" + (
            f" ({', '.join(f'{k} {v}' for k, v in sorted(r.filled.items())[:8])})"
            if filled else ""),
        f"invalid        {r.n_invalid} frames ({100 * r.n_invalid / max(n, 1):.1f} %)" + (
            f"; joints not computed: {', '.join(f'{k} {v}' for k, v in r.invalid.items())}"
            if r.invalid else ""),
        "sizes (mm)     " + ", ".join(f"{k} {v:.0f}" for k, v in r.sizes.items()),
        "marker feeds joints:",
    ]
    width = max((len(k) for k in r.feeds), default=4)
    for marker, joints in r.feeds.items():
        label = r.markers.get(marker, "MISSING")
        lines.append(f"  {marker:<{width}} ({label}) -> {', '.join(joints) or '(gap filling only)'}")
    lines.append("joints:")
    cov = mset.coverage(motion.rig)
    lines += [f"  {j:<10} <- {cov[j]}" for j in CANONICAL_JOINTS]
    return lines


def feature_rows(ff: FeatureFile) -> list[dict]:
    """One dict per feature of a feature file, in column order: ``id`` (F01…, from the
    file's ``feature_ids``), ``name`` and ``group`` (the index group holding it, from the
    file's ``groups``; empty when the file records none)."""
    ids = ff.meta.get("feature_ids")
    ids = ids if isinstance(ids, list) and len(ids) == len(ff.names) else \
        [f"F{i + 1:02d}" for i in range(len(ff.names))]
    groups = ff.meta.get("groups") if isinstance(ff.meta.get("groups"), dict) else {}
    group_of = {n: g for g, members in groups.items() if isinstance(members, list)
                for n in members}
    return [{"id": str(i), "name": n, "group": group_of.get(n, "")}
            for i, n in zip(ids, ff.names)]


def select_features(ff: FeatureFile, wanted: Sequence[str]) -> list[int]:
    """Rows of the features named in ``wanted`` (names or ids such as ``F20``), in the
    order given; an unknown one is an error listing how to see the known ones."""
    rows = feature_rows(ff)
    by_key = {r["name"]: k for k, r in enumerate(rows)}
    by_key.update({r["id"]: k for k, r in enumerate(rows)})
    out = []
    for w in wanted:
        w = w.strip()
        if not w:
            continue
        if w not in by_key:
            raise MtannoError(f"unknown feature '{w}' (see `mtanno info {ff.path} --features`)",
                              path=ff.path)
        out.append(by_key[w])
    if not out:
        raise MtannoError("no features chosen", path=ff.path)
    return out


def text_timeline(X: np.ndarray, labels: Sequence[str], *, first_frame: int = 1,
                  width: int = DEFAULT_WIDTH) -> list[str]:
    """A feature matrix (features × frames, 0/1) as text: a ruler line of frame numbers,
    then one line per feature: its label, then one character per column — ``#`` on, ``.``
    off, ``+`` on in part of the column's frames. A column is one frame when the frames fit
    in ``width`` columns, else a block of ⌈frames / width⌉ frames. ``first_frame`` is the
    1-based frame of column 0 of ``X``."""
    X = np.asarray(X, dtype=np.uint8)
    n = X.shape[1]
    if n == 0:
        raise MtannoError("no frames to show")
    if width < 1:
        raise MtannoError("width must be at least 1 column")
    block = max(1, math.ceil(n / width))
    cols = math.ceil(n / block)
    pad = np.zeros((X.shape[0], cols * block - n), np.uint8)
    on = np.concatenate([X, pad], axis=1).reshape(X.shape[0], cols, block).sum(axis=2)
    size = np.full(cols, block)
    size[-1] = n - (cols - 1) * block
    lw = max(len(x) for x in labels)
    ruler = [" "] * (cols + 8)
    for c in range(0, cols, 10):
        text = str(first_frame + c * block)
        ruler[c:c + len(text)] = text
    lines = [" " * (lw + 2) + "".join(ruler).rstrip()]
    for label, counts in zip(labels, on):
        cells = np.where(counts == 0, OFF, np.where(counts == size, ON, MIXED))
        lines.append(f"{label:<{lw}}  " + "".join(cells.tolist()))
    return lines


def describe_file(path: str | os.PathLike, *, asf: str | os.PathLike | None = None,
                  skeleton: str | None = None, markers: str | None = None,
                  up: str | None = None, features: bool = False) -> list[str]:
    """The lines ``mtanno info FILE`` prints: a feature file's metadata
    (:func:`describe_feature_file`) or, with ``features``, its features as a table (id,
    name, index group; :func:`feature_rows`); a motion file's rig, rate, length and joints
    (:func:`describe_motion`; ``asf``, ``skeleton``, ``markers``, ``up`` as
    :func:`mtanno.io.read_motion` takes them)."""
    from mtanno.features.store import read_features

    path = Path(path)
    parquet = path.suffix.lower() == ".parquet"
    if features and not parquet:
        raise MtannoError("{features} goes with a feature file (.parquet)", path=str(path),
                          options=("features",))
    if not parquet:
        from mtanno.io import read_motion

        return describe_motion(read_motion(path, asf=asf, skeleton=skeleton, markers=markers,
                                           up=up))
    ff = read_features(path)
    if not features:
        return describe_feature_file(ff)
    rows = feature_rows(ff)
    width = max(len(r["name"]) for r in rows)
    return [f"{'id':<4} {'name':<{width}}  group"] + [
        f"{r['id']:<4} {r['name']:<{width}}  {r['group']}" for r in rows]


@dataclass
class Timeline:
    """The text timeline ``mtanno show`` prints (:attr:`lines`: a header, then one row per
    feature) and what a picture of it needs: the rows drawn (features × frames), their
    labels, the first frame (1-based) and a title."""

    lines: list[str]
    X: np.ndarray
    labels: list[str]
    first_frame: int
    title: str


def feature_timeline(path: str | os.PathLike, *, frames: str | None = None,
                     features: Sequence[str] | None = None,
                     width: int = DEFAULT_WIDTH) -> Timeline:
    """The :class:`Timeline` of feature file ``path``: frames ``"A:B"`` (1-based inclusive,
    default all), only ``features`` (names, ids or aliases; default all), at most ``width``
    columns (:func:`text_timeline`)."""
    from mtanno.features.store import read_features
    from mtanno.util.clips import parse_frame_range

    ff = read_features(path)
    a, b = parse_frame_range(frames, ff.X.shape[1]) or (0, ff.X.shape[1] - 1)
    rows = select_features(ff, list(features)) if features else list(range(len(ff.names)))
    info = feature_rows(ff)
    labels = [f"{info[r]['id']} {info[r]['group']}:{info[r]['name']}" for r in rows]
    X = ff.X[rows, a:b + 1]
    block = -(-X.shape[1] // width)
    head = (f"{ff.document}: frames {a + 1}-{b + 1} of {ff.X.shape[1]} at {ff.fps:g} Hz, "
            f"{block} frame{'s' if block > 1 else ''} per column")
    lines = [head, *text_timeline(X, labels, first_frame=a + 1, width=width)]
    return Timeline(lines, X, labels, a + 1, f"{ff.document}, frames {a + 1}-{b + 1}")
