"""A keyframe query as text (``mtanno keyframes show``): a header (class, feature set,
template, windows, how it was learned), one row per keyframe, then one row per feature a
keyframe fixes and one column per keyframe.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator

from mtanno.keyframes.model import KeyframeQuery

__all__ = ["format_query", "format_query_files"]


def format_query(q: KeyframeQuery, *, path: str | None = None) -> str:
    """A readable description of a query: header, one row per keyframe (position, group,
    gap to the previous one, vector), then a table with one row per feature fixed by some
    keyframe and one column per keyframe (``1``, ``0`` or ``·`` for a wildcard)."""
    left, right = q.widths()
    head = [f"keyframes      {path}" if path else None,
            f"class          {q.class_name}",
            f"feature set    {q.feature_set}, {q.fps:g} Hz",
            f"template       {q.template_length} columns",
            f"keyframes      {q.n}",
            f"windows        hits widened by {left} frames left, {right} right "
            f"({_ext_text(q)})"]
    prov = q.provenance
    if prov.get("method"):
        fit = prov.get("fitness") or {}
        extra = ""
        if fit:
            extra = (f"; training P {fit.get('P', float('nan')):.3f} R "
                     f"{fit.get('R', float('nan')):.3f} F{fit.get('beta', 2):g} "
                     f"{fit.get('F', float('nan')):.3f}")
        seed = f", seed {prov['seed']}" if "seed" in prov else ""
        head.append(f"learned by     {prov['method']}{seed}{extra}")
    out = [h for h in head if h is not None]
    out.append("")
    out.append("  #  pos  group    gap to previous    vector")
    for j, kf in enumerate(q.keyframes):
        gap = q.gaps[j - 1].text() if j else ""
        tol = f"  (≤{kf.mismatches} mismatch{'es' if kf.mismatches > 1 else ''})" \
            if kf.mismatches else ""
        out.append(f"{j + 1:3d}  {kf.position:3d}  {kf.group:<7s}  {gap:<17s}  {kf.vector}{tol}")
    rows = []
    for g, feats in q.groups.items():
        for k, name in enumerate(feats):
            cells = []
            for kf in q.keyframes:
                c = kf.vector[k] if kf.group == g else " "
                cells.append("·" if c == "*" else c)
            if any(c in "01" for c in cells):
                rows.append((f"{g}:{name}", cells))
    if rows:
        width = max(len(r[0]) for r in rows)
        out.append("")
        out.append(" " * (width + 2) + " ".join(f"{j + 1:>2d}" for j in range(q.n)))
        for name, cells in rows:
            out.append(f"{name:<{width}s}  " + " ".join(f"{c:>2s}" for c in cells))
    return "\n".join(out)


def _ext_text(q: KeyframeQuery) -> str:
    e = q.extension
    if e.left is not None:
        return "explicit widths"
    off = f" + {e.offset}" if e.offset else ""
    return f"{e.factor}·(q1−1){off} and {e.factor}·(K−qn){off}"


def format_query_files(paths: Iterable[str | os.PathLike]) -> Iterator[str]:
    """The text of ``mtanno keyframes show``: :func:`format_query` of every keyframe file
    of ``paths`` (files, or folders: every ``*.json`` in them), one at a time as each is
    read; a folder without keyframe files is an error."""
    from mtanno.errors import MtannoError
    from mtanno.keyframes.folders import keyframe_files
    from mtanno.keyframes.store import load_keyframes

    for f in paths:
        files = keyframe_files(f)
        if not files:
            raise MtannoError("no keyframe files (*.json) in this folder", path=str(f))
        for path in files:
            yield format_query(load_keyframes(path), path=str(path))
