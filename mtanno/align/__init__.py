"""Time alignment of two motions ([MRC05] §7): a coarse segment-wise alignment from the
adaptive segmentations, refined by DTW inside the area it spans (docs/align.md).

* :mod:`~mtanno.align.poses` — :class:`Performance` (a motion's features, native frames and
  joint positions at the analysis rate), :func:`load_performance`, and the pose
  normalisation of the pose distance (:func:`normalize_poses`).
* :mod:`~mtanno.align.coarse` — stage 1: :class:`Segments`, segment matching with merges,
  the widened area of the matched pairs (:func:`coarse_alignment`), feature selection.
* :mod:`~mtanno.align.dtw` — stage 2: DTW inside an :class:`Area` with the pose or the
  feature cost (:func:`warp_poses`, :func:`warp_codes`), :func:`path_agreement`.
* :mod:`~mtanno.align.core` — :func:`align`, :func:`align_files`, :class:`Alignment` and
  its table (:func:`write_alignment`).
* :mod:`~mtanno.align.options` — the cost names and defaults (imports nothing heavy).
* :mod:`~mtanno.align.plot` — the alignment drawn like [MRC05] Fig. 11 (needs matplotlib).
* ``_kernels`` — numba kernels (private).

The names below are attached lazily (PEP 562): ``import mtanno.align`` is cheap, and the
kernels load with the first name used.
"""

from __future__ import annotations

from mtanno.util.lazy import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "coarse": ("ALL", "POSE", "CoarseAlignment", "Segments", "coarse_alignment",
               "pose_features", "select_features"),
    "core": ("Alignment", "align", "align_files", "alignment_table", "write_alignment"),
    "dtw": ("Area", "WarpingPath", "local_costs", "path_agreement", "warp_codes",
            "warp_poses"),
    "options": ("COSTS", "DEFAULT_BAND", "DEFAULT_COST"),
    "poses": ("Performance", "body_scale", "load_performance", "normalize_poses",
              "performance_from_positions"),
})


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
