"""Two-stage time alignment of two motions ([MRC05] §7), and its table.

:func:`align` runs stage 1 (:func:`mtanno.align.coarse.coarse_alignment`: adaptive segments
matched with merges, their rectangles widened by a band) and stage 2 (DTW inside that area
with the pose distance or the feature Hamming distance, :mod:`mtanno.align.dtw`); with
``full=True`` stage 2 computes the whole matrix instead (classical DTW, for comparison).
:func:`align_files` reads the two files first; :func:`write_alignment` writes the warping
path as a table (``docs/formats.md`` convention).
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from mtanno.align.coarse import CoarseAlignment, coarse_alignment, select_features
from mtanno.align.dtw import FEATURE_TIE, Area, WarpingPath, local_costs, warp_codes, warp_poses
from mtanno.align.options import COST_UNITS, COSTS, DEFAULT_BAND, DEFAULT_COST
from mtanno.align.poses import Performance, load_performance, normalize_poses
from mtanno.errors import MtannoError
from mtanno.features import FEATURE_SET, FeatureSet
from mtanno.features.store import check_layout
from mtanno.index.core import frame_codes
from mtanno.io.formats import expected

__all__ = ["Alignment", "align", "align_files", "align_to", "alignment_table", "summary",
           "write_alignment"]



@dataclass(frozen=True)
class Alignment:
    """Two motions aligned.

    Attributes
    ----------
    a, b:
        The two motions (rows and columns of the cost matrix).
    features:
        The features stage 1 segmented by (and the feature cost compared).
    cost:
        ``"positions"`` or ``"features"``.
    coarse:
        Stage 1: segments, matched pairs, the widened area.
    path:
        The warping path of stage 2 (0-based analysis frames) with its total cost and the
        cells computed.
    local:
        Local cost of every cell of the path.
    full:
        True when stage 2 computed the whole matrix.
    seconds:
        Wall time of ``"coarse"`` (stage 1), ``"dtw"`` (stage 2, with the pose
        normalisation) and ``"total"``.
    """

    a: Performance
    b: Performance
    features: tuple[str, ...]
    cost: str
    coarse: CoarseAlignment
    path: WarpingPath
    local: np.ndarray
    full: bool
    seconds: dict[str, float] = field(default_factory=dict)

    # the parts' figures under the names the summary and the table use
    total_cost = property(lambda self: self.path.total,
                          doc="Sum of the local costs along the path.")
    mean_cost = property(lambda self: self.path.mean,
                         doc="Total cost / number of path cells: the mean local cost along "
                             "the path.")
    fraction = property(lambda self: self.path.fraction,
                        doc="Fraction of the n × m cost matrix that stage 2 computed.")
    band = property(lambda self: self.coarse.band, doc="The widening of stage 1's area, in frames.")


def _codes(p: Performance, features: Sequence[str]) -> np.ndarray:
    pos = {n: i for i, n in enumerate(p.layout.names)}
    return frame_codes(p.X, [pos[f] for f in features])


def align(a: Performance, b: Performance, *, features: Sequence[str] | None = None,
          group: str | None = None, band: int = DEFAULT_BAND, cost: str = DEFAULT_COST,
          full: bool = False) -> Alignment:
    """Align motion B to motion A in two stages ([MRC05] §7, module docstring).

    Parameters
    ----------
    a, b:
        The motions (:func:`mtanno.align.poses.load_performance`); their features must be
        of the same layout (feature set, names, analysis rate); the ``positions`` cost needs
        joint positions of both (motion files, not feature files).
    features, group:
        The features stage 1 segments by: names, or a group of the feature set
        (``lower``, ``upper``, ``mix``, or ``all``, the default).
    band:
        Frames (30 Hz) by which every matched segment rectangle is widened on each side.
    cost:
        Local cost of stage 2: ``"positions"`` (pose distance in leg lengths) or
        ``"features"`` (fraction of the chosen features that differ).
    full:
        Compute the whole cost matrix in stage 2 (classical DTW) instead of the area.
    """
    if cost not in COSTS:
        raise MtannoError(f"unknown cost '{cost}' (choose from {', '.join(COSTS)})")
    check_layout(b.layout, a.layout, path=b.where)
    if cost == "positions":
        for p in (a, b):
            if p.joints is None:
                raise MtannoError("a feature file has features but no joint positions: the "
                                  f"positions cost needs the motion file ({expected()}); use "
                                  "{cost} features for feature files", path=p.where,
                                  options=("cost",))
    for p in (a, b):
        if p.frames == 0:
            raise MtannoError("motion has no frames", path=p.where)
    chosen = select_features(a.layout.names, a.groups, features=features, group=group)
    t0 = time.perf_counter()
    ca, cb = _codes(a, chosen), _codes(b, chosen)
    coarse = coarse_alignment(ca, cb, n_features=len(chosen), band=band)
    t1 = time.perf_counter()
    area = Area.full(a.frames, b.frames) if full else coarse.area
    if cost == "positions":
        pa_, pb_ = normalize_poses(a.joints), normalize_poses(b.joints)
        path = warp_poses(pa_, pb_, area=area)
        local = local_costs(path, poses=(pa_, pb_))
    else:
        phases = (coarse.segments_a.phases(), coarse.segments_b.phases())
        tie = FEATURE_TIE / len(chosen)
        path = warp_codes(ca, cb, n_features=len(chosen), area=area, phases=phases, tie=tie)
        local = local_costs(path, codes=(ca, cb), n_features=len(chosen), phases=phases,
                            tie=tie)
    t2 = time.perf_counter()
    return Alignment(a, b, chosen, cost, coarse, path, local, bool(full),
                     {"coarse": t1 - t0, "dtw": t2 - t1, "total": t2 - t0})


def align_files(path_a: str | os.PathLike, path_b: str | os.PathLike, *,
                asf: str | os.PathLike | None = None, skeleton: str | os.PathLike | None = None,
                feature_set: str | FeatureSet = FEATURE_SET,
                features: Sequence[str] | None = None, group: str | None = None,
                band: int = DEFAULT_BAND, cost: str = DEFAULT_COST,
                full: bool = False) -> Alignment:
    """:func:`align` of two files: motion files (``.amc``, ``.bvh``, ``.c3d``; ``asf``,
    ``skeleton`` and ``feature_set`` as in :func:`mtanno.align.poses.load_performance`) or
    feature files (``.parquet``, feature cost only). ``features``, ``group``, ``band``, ``cost``,
    ``full``: those of :func:`align`."""
    if cost == "positions":
        for p in (path_a, path_b):
            if str(p).lower().endswith(".parquet"):
                raise MtannoError("a feature file has features but no joint positions: the "
                                  f"positions cost needs the motion file ({expected()}); use "
                                  "{cost} features for feature files", path=str(p),
                                  options=("cost",))
    a = load_performance(path_a, asf=asf, skeleton=skeleton, feature_set=feature_set)
    b = load_performance(path_b, asf=asf, skeleton=skeleton, feature_set=feature_set)
    return align(a, b, features=features, group=group, band=band, cost=cost, full=full)


def alignment_table(al: Alignment) -> pa.Table:
    """The warping path as a table: ``frame_a``, ``frame_b`` (1-based analysis frames,
    30 Hz), ``native_a``, ``native_b`` (1-based frames of the source motion files) and
    ``cost`` (local cost of the cell), one row per cell, in path order."""
    return pa.table({
        "frame_a": pa.array(al.path.a + 1, pa.int64()),
        "frame_b": pa.array(al.path.b + 1, pa.int64()),
        "native_a": pa.array(al.a.native_frames[al.path.a], pa.int64()),
        "native_b": pa.array(al.b.native_frames[al.path.b], pa.int64()),
        "cost": pa.array(al.local, pa.float64()),
    })


def summary(al: Alignment) -> dict:
    """What the table's provenance records about an alignment (besides its inputs)."""
    return {"cost": al.cost, "cost_unit": COST_UNITS[al.cost], "full": al.full,
            "band": al.band, "features": list(al.features),
            "feature_set": al.a.layout.feature_set, "analysis_fps": al.a.layout.fps,
            "frames_a": al.a.frames, "frames_b": al.b.frames,
            "segments_a": len(al.coarse.segments_a), "segments_b": len(al.coarse.segments_b),
            "segment_pairs": int(len(al.coarse.pairs.a)),
            "path_cells": int(len(al.path.a)), "total_cost": al.total_cost,
            "mean_cost": al.mean_cost, "cells_computed": al.path.cells,
            "fraction_computed": al.fraction}


def write_alignment(path: str | os.PathLike, al: Alignment, *,
                    provenance: dict | None = None) -> None:
    """Write the warping path (:func:`alignment_table`) to ``path`` (``.csv``,
    ``.parquet``, ``.jsonl`` or ``-``) with its provenance."""
    from mtanno.util.tables import write_table

    write_table(path, alignment_table(al), provenance=provenance)


def align_to(path_a: str | os.PathLike, path_b: str | os.PathLike,
             output: str | os.PathLike = "-", *, plot_path: str | os.PathLike | None = None,
             asf: str | os.PathLike | None = None, skeleton: str | os.PathLike | None = None,
             feature_set: str | FeatureSet = FEATURE_SET,
             features: Sequence[str] | None = None, group: str | None = None,
             band: int = DEFAULT_BAND, cost: str = DEFAULT_COST, full: bool = False,
             ) -> Alignment:
    """The whole ``mtanno align`` run: :func:`align_files` of ``path_a`` and ``path_b``
    (``asf``, ``skeleton``, ``feature_set``; the options of :func:`align`), its warping
    path written to ``output`` (suffix picks the format, ``-`` is CSV on standard output)
    with the inputs and :func:`summary` as provenance, and with ``plot_path`` drawn there
    (:func:`mtanno.align.plot.save_alignment_plot`). The outputs (and the plot's format and
    matplotlib) are checked before any work."""
    from mtanno.align.plot import check_plot_path, save_alignment_plot
    from mtanno.util.preflight import check_outputs
    from mtanno.util.provenance import file_record, provenance
    from mtanno.util.tables import output_files, table_format

    table_format(output)
    if plot_path is not None:
        check_plot_path(plot_path)
    inputs = [path_a, path_b] + ([asf] if asf else [])
    check_outputs(output_files(output) + ([plot_path] if plot_path else []), inputs)
    al = align_files(path_a, path_b, asf=asf, skeleton=skeleton, feature_set=feature_set,
                     features=features, group=group, band=band, cost=cost, full=full)
    write_alignment(output, al, provenance=provenance(
        inputs=[file_record(p) for p in inputs], group=group, **summary(al)))
    if plot_path is not None:
        save_alignment_plot(plot_path, al)
    return al
