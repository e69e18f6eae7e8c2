"""A motion template as a person reads it (``mtanno mt show``): class, kind, length, the
performance lengths a match can cover, weights, learning result, training files, the
features the matching relies on most, and optionally the quantized template drawn as text.
"""

from __future__ import annotations

from mtanno.templates.match import match_lengths
from mtanno.templates.model import MotionTemplate, quantize, rank_features
from mtanno.templates.params import RETRIEVAL_DELTA
from mtanno.templates.tempo import matched_columns

__all__ = ["format_template", "format_template_file"]

#: Characters of ``--picture``: 1, 0 and wildcard entries of the quantized template.
PICTURE = {0.0: ".", 1.0: "#", 0.5: "~"}
#: Features listed by default.
TOP_FEATURES = 10


def format_template(mt: MotionTemplate, *, path: str | None = None, delta: float | None = None,
                    top: int = TOP_FEATURES, picture: bool = False, files: bool = False) -> str:
    """The text of ``mtanno mt show`` for ``mt`` (read from ``path``): an unquantized
    template is quantized with ``delta`` (default: retrieval's δ, [MR06]) for the feature
    ranking (``top`` features) and the ``picture``; ``files`` lists every training file."""
    if mt.quantized:
        q, d = mt, mt.delta
        state = f"quantized, δ = {mt.delta:g}"
    else:
        d = RETRIEVAL_DELTA if delta is None else delta
        q = quantize(mt, d)
        state = "not quantized"
    w = mt.weights
    lines: list[str] = []
    echo = lines.append
    echo(f"template      {mt.class_name} ({mt.kind}, {state})")
    echo(f"file          {path if path is not None else mt.path}")
    echo(f"features      {mt.n_features} of feature set {mt.feature_set}, {mt.fps:g} Hz")
    echo(f"length        {mt.length} columns ({mt.length / mt.fps:.2f} s)")
    lo, hi = match_lengths(mt.weights)
    echo(f"matches       performances of {lo}-{hi} frames ({lo / mt.fps:.2f}-{hi / mt.fps:.2f} s;"
         f" the DTW steps allow half to twice its {matched_columns(mt.weights)} "
         f"matched columns)")
    echo(f"weights       sum {w.sum():.3f}, min {w.min():.3f}, mean {w.mean():.3f}, "
         f"max {w.max():.3f}")
    hist = mt.history.get("max", [])
    hist_txt = f" (per iteration: {' '.join(f'{x:.4g}' for x in hist)})" if hist else ""
    echo(f"learning      {mt.iterations} iteration(s), final cost {mt.final_cost:.6g}"
         f"{hist_txt}")
    n = len(mt.training)
    spans = [int(t["frames"][1]) - int(t["frames"][0]) + 1 for t in mt.training
             if isinstance(t.get("frames"), list) and len(t["frames"]) == 2]
    echo(f"training      {n} example(s)" + (f", {min(spans)}-{max(spans)} frames" if spans else ""))
    if spans and (min(spans) < 1.25 * lo or max(spans) > hi / 1.25):
        echo("  (examples near the matchable lengths: a faster or slower performer may be "
             "missed; `mtanno mt scale` makes a copy for them)")
    shown = mt.training if files else mt.training[:3]
    for t in shown:
        fr = t.get("frames", ["?", "?"])
        echo(f"  {t.get('document')}  frames {fr[0]}-{fr[1]}  {t.get('file')}  "
             f"sha256 {str(t.get('sha256'))[:12]}")
    if len(shown) < n:
        echo(f"  ... {n - len(shown)} more (--files lists them all)")
    if top:
        echo(f"features with most non-wildcard entries (δ = {d:g}; of {mt.length} columns):")
        width = max(len(x) for x in mt.feature_names)
        for f in rank_features(q)[:top]:
            echo(f"  {f.name:<{width}}  {f.fixed:>4}  (1: {f.ones}, 0: {f.fixed - f.ones})")
    V = q.values
    if picture:
        echo(f"quantized template (δ = {d:g}): '#' 1, '.' 0, '~' wildcard")
        width = max(len(x) for x in mt.feature_names)
        for r, name in enumerate(mt.feature_names):
            echo(f"  {name:<{width}} " + "".join(PICTURE[float(x)] for x in V[r]))
    return "\n".join(lines)


def format_template_file(path: str, *, delta: float | None = None, top: int = TOP_FEATURES,
                         picture: bool = False, files: bool = False) -> str:
    """:func:`format_template` of the template file ``path``."""
    from mtanno.templates.store import load_template

    return format_template(load_template(path), path=path, delta=delta, top=top,
                           picture=picture, files=files)
