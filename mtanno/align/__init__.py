"""Time alignment of two motions (MRC05 §7): a coarse segment-wise alignment from the
adaptive segmentations, refined by DTW inside the area it spans.

* :mod:`~mtanno.align.poses` — :class:`Performance` (a motion's features, native frames and
  joint positions at the analysis rate), :func:`load_performance`, and the pose
  normalisation of the pose distance (:func:`normalize_poses`).
* :mod:`~mtanno.align.coarse` — stage 1: :class:`Segments`, segment matching with merges,
  the widened area of the matched pairs (:func:`coarse_alignment`).
* :mod:`~mtanno.align.dtw` — stage 2: DTW inside an :class:`Area` with the pose or the
  feature cost (:func:`warp_poses`, :func:`warp_codes`), :func:`path_agreement`.
* :mod:`~mtanno.align.core` — :func:`align`, :func:`align_files`, :class:`Alignment` and
  its table (:func:`write_alignment`).
* :mod:`~mtanno.align.plot` — the alignment drawn like MRC05 Fig. 11 (needs matplotlib).
* ``_kernels`` — numba kernels (private).
"""

from mtanno.align.coarse import (
    ALL,
    POSE,
    CoarseAlignment,
    Segments,
    coarse_alignment,
    pose_features,
    select_features,
)
from mtanno.align.core import (
    COSTS,
    DEFAULT_BAND,
    DEFAULT_COST,
    Alignment,
    align,
    align_files,
    alignment_table,
    write_alignment,
)
from mtanno.align.dtw import Area, WarpingPath, local_costs, path_agreement, warp_codes, warp_poses
from mtanno.align.poses import (
    Performance,
    body_scale,
    load_performance,
    normalize_poses,
    performance_from_positions,
)

__all__ = [
    "ALL", "COSTS", "DEFAULT_BAND", "DEFAULT_COST", "POSE", "Alignment", "Area",
    "CoarseAlignment", "Performance", "Segments", "WarpingPath", "align", "align_files",
    "alignment_table", "body_scale", "coarse_alignment", "load_performance", "local_costs",
    "normalize_poses", "path_agreement", "performance_from_positions", "pose_features",
    "select_features", "warp_codes", "warp_poses", "write_alignment",
]
