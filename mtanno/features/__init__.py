"""Relational features: joint positions → boolean features per frame (docs/method.md §2).

:func:`compute_features` evaluates every row of a feature table at the native frame rate
(velocities and hysteresis included) and reduces the result to the 30 Hz analysis rate.
Three named feature sets (:data:`FEATURE_SETS`, selected by :func:`get_feature_set`):
``mr06-ak40`` (alias ``ak40``, the default: the 40 annotation features of
:mod:`~mtanno.features.table`), ``mrc05`` and ``mrc05-reference`` (the 31 features of [MRC05],
:mod:`~mtanno.features.table31`).

Modules: :mod:`~mtanno.features.table` and :mod:`~mtanno.features.table31` (the feature
definitions as data: joints, measure, thresholds, window), :mod:`~mtanno.features.measures`
(planes, angles, velocities, body units), :mod:`~mtanno.features.hysteresis` (two-threshold
quantisation, 30 Hz reduction), :mod:`~mtanno.features.compute` (feature sets and
:func:`compute_features`), :mod:`~mtanno.features.extract` (a motion file → its feature
file), :mod:`~mtanno.features.batch` (files and folders in batches: ``mtanno features``),
:mod:`~mtanno.features.poses` (poses normalised for root,
heading and leg length, which feature files may carry), ``_kernels`` (the numba kernels,
private). The feature file — the format this stage writes and every later stage reads —
is :mod:`~mtanno.features.store` (the one validating reader, the writer, layouts and
their check; ``_parquet``, the fast writer of short files, and ``_poseblock``, the optional
pose columns, are private to it); :mod:`~mtanno.features.inputs` finds the feature files
an input names.
"""

from mtanno.util.lazy import lazy_exports

# The names are attached on first use, so that reading a feature file
# (mtanno.features.store) does not load the numba kernels.
__getattr__, __all__ = lazy_exports(__name__, {
    "compute": ("FEATURE_SETS", "FeatureSet", "compute_features", "compute_features_native",
                "get_feature_set"),
    # (the function hysteresis is mtanno.features.hysteresis.hysteresis: a package name
    # that is also a submodule's would be the module once the module is imported)
    "hysteresis": ("ANALYSIS_FPS", "analysis_frames"),
    "table": ("FEATURE_NAMES", "FEATURE_SET", "FEATURE_SET_VERSION", "FEATURES", "GROUPS",
              "MIRROR_PAIRS", "Feature", "feature_index", "mirror_permutation"),
})


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
