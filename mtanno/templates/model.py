"""The motion template (MT) object, its checks, quantization and mirroring (its JSON file
and folders of them: :mod:`mtanno.templates.store`).

An MT of a motion class ([MR06] §4) is a (features × K) matrix with entries in [0, 1] and one
weight per column; columns are time steps at the 30 Hz analysis rate, and the weights sum
to about the mean length of the training examples in frames. A *quantized* MT
(docs/method.md §3.3) has entries 0, 1 or the wildcard 0.5; the matching stage (§3.4)
ignores wildcard entries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from mtanno.errors import MtannoError

if TYPE_CHECKING:
    from mtanno.features.store import FeatureLayout

__all__ = [
    "SCHEMA", "KINDS", "MIRROR_SUFFIX", "FeatureRank", "MotionTemplate", "check_feature_names",
    "check_template", "is_number", "mirror", "quantize", "rank_features",
]

#: Schema identifier written into (and required from) every template file.
SCHEMA = "mtanno.template/1"
#: Template kinds: soft ([MR06] §4.1) and hard (thesis §3.3.1).
KINDS = ("soft", "hard")
#: Appended to (or removed from) the class name by :func:`mirror`.
MIRROR_SUFFIX = "_mirrored"
#: Value of a wildcard entry in a quantized or hard template.
WILDCARD = 0.5


@dataclass(eq=False)
class MotionTemplate:
    """A motion template of one class.

    Attributes
    ----------
    class_name:
        Name of the motion class (the JSON file is usually ``<class_name>.json``).
    feature_names:
        Row names, e.g. ``mtanno.features.FEATURE_NAMES``.
    values:
        (features × K) float64 matrix, entries in [0, 1]; after quantization exactly 0, 1
        or 0.5 (wildcard). Column k is time step k at ``fps``.
    weights:
        (K,) positive column weights (how many frames at ``fps`` a column stands for).
    feature_set:
        Name of the feature set the rows come from (``"mr06-ak40"``).
    fps:
        Frame rate of the columns (30.0).
    kind:
        ``"soft"`` or ``"hard"``.
    quantized:
        Whether ``values`` are quantized (0, 1, 0.5 only).
    delta:
        The quantization δ the template was quantized with (matching uses the template as
        it is); None when not quantized.
    training:
        One dict per training example: ``file`` (feature file), ``document`` (its stem),
        ``sha256`` (of the file), ``frames`` ([start, end], 1-based inclusive at ``fps``).
    params:
        Learning parameters (method, iter_max, iter_thresh, …).
    iterations:
        Learning iterations run.
    final_cost:
        Final maximum normalised alignment cost of learning (the "spread").
    history:
        Per-iteration costs: ``{"max": [...], "mean": [...]}``.
    path:
        The file it was read from (:func:`load_template`), not stored in it.
    """

    class_name: str
    feature_names: list[str]
    values: np.ndarray
    weights: np.ndarray
    feature_set: str = "mr06-ak40"
    fps: float = 30.0
    kind: str = "soft"
    quantized: bool = False
    delta: float | None = None
    training: list[dict] = field(default_factory=list)
    params: dict = field(default_factory=dict)
    iterations: int = 0
    final_cost: float = 0.0
    history: dict = field(default_factory=dict)
    path: str | None = field(default=None, compare=False)

    schema = SCHEMA

    def __post_init__(self) -> None:
        self.values = np.asarray(self.values, dtype=np.float64)
        self.weights = np.asarray(self.weights, dtype=np.float64)
        self.feature_names = list(self.feature_names)
        check_template(self)

    @property
    def length(self) -> int:
        """Number of columns K (time steps at ``fps``)."""
        return int(self.values.shape[1])

    @property
    def n_features(self) -> int:
        return int(self.values.shape[0])

    def layout(self, source: str | None = None) -> FeatureLayout:
        """The template's :class:`~mtanno.features.store.FeatureLayout` (feature set, feature
        names, frame rate), what :func:`~mtanno.features.store.check_layout` compares;
        ``source`` names it in messages (default: ``template CLASS``)."""
        from mtanno.features.store import FeatureLayout

        return FeatureLayout(self.feature_set, tuple(self.feature_names), float(self.fps),
                             source if source is not None else f"template {self.class_name}")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, MotionTemplate):
            return NotImplemented
        a, b = self.to_dict(), other.to_dict()
        return a == b

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of the template (see module docstring)."""
        return {
            "schema": SCHEMA,
            "class": self.class_name,
            "kind": self.kind,
            "feature_set": self.feature_set,
            "fps": float(self.fps),
            "length": self.length,
            "quantized": bool(self.quantized),
            "delta": None if self.delta is None else float(self.delta),
            "iterations": int(self.iterations),
            "final_cost": float(self.final_cost),
            "history": {k: [float(x) for x in v] for k, v in self.history.items()},
            "params": self.params,
            "training": self.training,
            "feature_names": list(self.feature_names),
            "weights": [float(x) for x in self.weights],
            "values": [[float(x) for x in row] for row in self.values],
        }


#: Largest template weight accepted: a weight counts the frames aligned to a column, so a
#: larger one is no learned template (and would blow up matching's column expansion).
MAX_WEIGHT = 1e6


def check_template(mt: MotionTemplate, path: str | None = None, *, line_of=None) -> None:
    """Check every field of a template; an error names ``path`` and, when ``line_of``
    (key, values row or None → line number or None; from :func:`load_template`) is given,
    the line of the offending field or values row."""

    def bad(msg: str, key: str | None = None, row: int | None = None) -> MtannoError:
        line = line_of(key, row) if line_of is not None and key is not None else None
        return MtannoError(msg, path=path, line=line)

    if not isinstance(mt.class_name, str) or not mt.class_name.strip():
        raise bad("class name must be a non-empty string", "class")
    if not mt.feature_names or not all(isinstance(n, str) and n for n in mt.feature_names):
        raise bad("feature_names must be a non-empty list of names", "feature_names")
    if len(set(mt.feature_names)) != len(mt.feature_names):
        dup = sorted({n for n in mt.feature_names if mt.feature_names.count(n) > 1})
        raise bad(f"duplicate feature names: {', '.join(dup)}", "feature_names")
    V, w = mt.values, mt.weights
    if V.ndim != 2 or V.shape[0] != len(mt.feature_names):
        raise bad(f"values must be ({len(mt.feature_names)} features × columns), got shape "
                  f"{V.shape}", "values")
    if V.shape[1] == 0:
        raise bad("template has no columns", "values")
    if w.shape != (V.shape[1],):
        raise bad(f"weights must have one entry per column ({V.shape[1]}), got {w.size}",
                  "weights")
    if not np.isfinite(V).all():
        r, c = np.argwhere(~np.isfinite(V))[0]
        raise bad(f"values row {r + 1} ({mt.feature_names[r]}) column {c + 1} is not a "
                  f"finite number", "values", int(r))
    if (V < 0).any() or (V > 1).any():
        r, c = np.argwhere((V < 0) | (V > 1))[0]
        raise bad(f"values row {r + 1} ({mt.feature_names[r]}) column {c + 1} is "
                  f"{float(V[r, c])!r}, outside [0, 1]", "values", int(r))
    if not np.isfinite(w).all() or (w <= 0).any() or (w > MAX_WEIGHT).any():
        c = int(np.argwhere(~np.isfinite(w) | (w <= 0) | (w > MAX_WEIGHT))[0][0])
        raise bad(f"weight {c + 1} is {float(w[c])!r}; weights must be positive, finite and at "
                  f"most {MAX_WEIGHT:g}", "weights")
    if mt.kind not in KINDS:
        raise bad(f"kind must be one of {', '.join(KINDS)}, got {mt.kind!r}", "kind")
    if not isinstance(mt.feature_set, str) or not mt.feature_set:
        raise bad("feature_set must be a non-empty string", "feature_set")
    if not is_number(mt.fps) or not math.isfinite(mt.fps) or mt.fps <= 0:
        raise bad(f"fps must be a positive number, got {mt.fps!r}", "fps")
    if not isinstance(mt.quantized, bool):
        raise bad("quantized must be true or false", "quantized")
    if mt.delta is not None and (not is_number(mt.delta) or not 0 <= mt.delta <= 0.5):
        raise bad(f"delta must be null or a number in [0, 0.5], got {mt.delta!r}", "delta")
    if mt.quantized:
        if mt.delta is None:
            raise bad("a quantized template needs the delta it was quantized with", "delta")
        off = ~np.isin(V, (0.0, WILDCARD, 1.0))
        if off.any():
            r, c = np.argwhere(off)[0]
            raise bad(f"quantized template has value {float(V[r, c])!r} at row {r + 1} column "
                      f"{c + 1} (only 0, 0.5, 1 allowed)", "values", int(r))
    if not isinstance(mt.iterations, int) or isinstance(mt.iterations, bool) \
            or mt.iterations < 0:
        raise bad(f"iterations must be an integer ≥ 0, got {mt.iterations!r}", "iterations")
    if not is_number(mt.final_cost) or not math.isfinite(mt.final_cost) \
            or mt.final_cost < 0:
        raise bad(f"final_cost must be a finite number ≥ 0, got {mt.final_cost!r}",
                  "final_cost")
    if not isinstance(mt.params, dict):
        raise bad("params must be an object", "params")
    if not isinstance(mt.history, dict) or not all(
            isinstance(v, list) and all(is_number(x) for x in v) for v in mt.history.values()):
        raise bad("history must be an object of number lists", "history")
    if not isinstance(mt.training, list):
        raise bad("training must be a list", "training")
    for n, t in enumerate(mt.training, 1):
        if not isinstance(t, dict):
            raise bad(f"training entry {n} must be an object")
        missing = [k for k in ("file", "document", "sha256", "frames") if k not in t]
        if missing:
            raise bad(f"training entry {n} lacks {', '.join(missing)}")
        fr = t["frames"]
        if not (isinstance(fr, list) and len(fr) == 2 and all(
                isinstance(x, int) and not isinstance(x, bool) for x in fr)
                and 1 <= fr[0] <= fr[1]):
            raise bad(f"training entry {n}: frames must be [start, end], 1-based, "
                      f"start ≤ end")


def is_number(x: Any) -> bool:
    """Whether a JSON value is a number (an int or float, not a bool)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def check_feature_names(mt: MotionTemplate, path: str | None = None,
                        line: int | None = None, *, set_line: int | None = None) -> None:
    """A template of a built-in feature set names only features of that set (its table
    says which names it has; matching, mirroring and keyframes rely on them): checked when
    a template file is read or written, so ``mt quantize`` refuses what ``mt mirror``
    refuses. A feature set of the caller's own (API) has no table here to check against,
    nor have templates made in memory for a test or a plot; but a set named as none of
    mtanno's whose features all belong to one of them is a wrong name (``feature_set =
    "bogus"`` over the 40 annotation features), refused (``set_line``: the line that
    names it), since no feature file of those features would ever match it."""
    from mtanno.features import get_feature_set
    from mtanno.features.compute import feature_set_mismatch

    wrong = feature_set_mismatch(mt.feature_set, mt.feature_names)
    if wrong is not None:
        try:  # a set of mtanno's: a feature is wrong; else the set's name is
            get_feature_set(mt.feature_set)
        except MtannoError:
            line = set_line
        raise MtannoError(wrong, path=path, line=line)


# --------------------------------------------------------------------------- operations


def quantize(mt: MotionTemplate, delta: float) -> MotionTemplate:
    """Quantized copy of ``mt`` (docs/method.md §3.3; [MR06] §5.2): entries ≤ δ become 0,
    entries ≥ 1 − δ become 1, the rest the wildcard 0.5.

    Both comparisons are inclusive and tested in that order, so δ = 0 keeps exactly the
    unanimous entries (0 and 1) and δ = 0.5 leaves no wildcard (0.5 itself becomes 0).
    δ = 0.1 is [MR06]'s retrieval setting, 0.05 [MBS09]'s annotation setting.
    """
    if not is_number(delta) or not 0.0 <= float(delta) <= 0.5:
        raise MtannoError(f"quantization delta must be a number in [0, 0.5], got {delta!r}")
    delta = float(delta)
    V = mt.values
    Q = np.full(V.shape, WILDCARD)
    Q[V >= 1.0 - delta] = 1.0
    Q[V <= delta] = 0.0
    return replace(mt, values=Q, weights=mt.weights.copy(), quantized=True, delta=delta,
                   training=[dict(t) for t in mt.training], params=dict(mt.params),
                   history={k: list(v) for k, v in mt.history.items()})


@dataclass(frozen=True)
class FeatureRank:
    """How much a quantized template relies on one feature: its entries that are not
    wildcards (``fixed``), of which ``ones`` are 1."""

    name: str
    fixed: int
    ones: int


def rank_features(q: MotionTemplate) -> list[FeatureRank]:
    """The features of a quantized template, those with the most non-wildcard entries
    first (the ones the matching relies on; ties: more 1 entries, then feature order) —
    what ``mtanno mt show`` lists."""
    if not q.quantized:
        raise MtannoError("rank_features needs a quantized template (quantize it first)")
    fixed = (q.values != WILDCARD).sum(axis=1)
    ones = (q.values == 1.0).sum(axis=1)
    order = sorted(range(q.n_features), key=lambda r: (-fixed[r], -ones[r], r))
    return [FeatureRank(q.feature_names[r], int(fixed[r]), int(ones[r])) for r in order]


def mirror_names(feature_set: str, *, path: str | None = None) -> dict[str, str]:
    """Feature name → name of its left/right partner (itself when unpaired) for a known
    feature set ([MR06] Table 6 / [MRC05] Table 1; :attr:`mtanno.features.FeatureSet.mirror_pairs`);
    an unknown set is an error naming ``path`` (the template's file)."""
    from mtanno.features import FEATURE_SETS, get_feature_set

    try:
        fs = get_feature_set(feature_set)
    except MtannoError:
        raise MtannoError(f"no mirror table for feature set {feature_set!r} (known: "
                          f"{', '.join(FEATURE_SETS)})", path=path) from None
    names = fs.names
    table = {n: n for n in names}
    for a, b in fs.mirror_pairs:
        table[names[a]] = names[b]
        table[names[b]] = names[a]
    return table


def mirror(mt: MotionTemplate, *, name: str | None = None) -> MotionTemplate:
    """Left/right mirrored copy of ``mt`` ([MR06] §5.4): the rows of every left/right feature
    pair are swapped (by feature name, using the feature set's mirror table), so a
    template of 'CartwheelLeft' finds right cartwheels.

    The class name is ``name`` if given; otherwise :data:`MIRROR_SUFFIX` is appended, or
    removed when already present, so mirroring twice gives back the original template.
    """
    table = mirror_names(mt.feature_set, path=mt.path)
    unknown = [n for n in mt.feature_names if n not in table]
    if unknown:
        raise MtannoError(f"features not in the {mt.feature_set} mirror table: "
                          f"{', '.join(unknown)}", path=mt.path)
    index = {n: i for i, n in enumerate(mt.feature_names)}
    lonely = [n for n in mt.feature_names if table[n] not in index]
    if lonely:
        raise MtannoError("cannot mirror: the template lacks the partner of "
                          + ", ".join(f"{n} ({table[n]})" for n in lonely), path=mt.path)
    perm = [index[table[n]] for n in mt.feature_names]
    if name is None:
        cn = mt.class_name
        name = cn[: -len(MIRROR_SUFFIX)] if cn.endswith(MIRROR_SUFFIX) and \
            len(cn) > len(MIRROR_SUFFIX) else cn + MIRROR_SUFFIX
    params = dict(mt.params)
    if params.pop("mirrored", False) is False:
        params["mirrored"] = True
    return replace(mt, class_name=name, values=mt.values[perm].copy(),
                   weights=mt.weights.copy(), training=[dict(t) for t in mt.training],
                   params=params, history={k: list(v) for k, v in mt.history.items()})
