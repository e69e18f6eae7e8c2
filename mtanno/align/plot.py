"""An alignment drawn like [MRC05] Fig. 11: the area of the cost matrix that was computed
(gray), the matched segment pairs' rectangles, and the warping path.

Needs matplotlib (``pip install 'mtanno[plot]'``); it is imported inside the functions, so
the rest of :mod:`mtanno.align` works without it. :func:`plot_alignment` draws on a given
Axes (or a new figure) and returns it; :func:`save_alignment_plot` writes a PNG, PDF or SVG
file atomically. Frames on the axes are 1-based analysis frames (30 Hz): motion B
horizontally, motion A vertically, as the paper draws its two walks.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mtanno.errors import MtannoError

if TYPE_CHECKING:  # type hints only: align.core calls this module (align_to)
    from mtanno.align.core import Alignment
    from mtanno.align.dtw import WarpingPath

__all__ = ["PLOT_SUFFIXES", "check_plot_path", "plot_alignment", "require_matplotlib",
           "save_alignment_plot"]

#: File types :func:`save_alignment_plot` writes, by suffix.
PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def require_matplotlib() -> Any:
    """The ``matplotlib`` module, or one :class:`MtannoError` saying how to install it."""
    try:
        import matplotlib
    except ImportError:
        raise MtannoError("plots need matplotlib, which is not installed: pip install "
                          "'mtanno[plot]' (or pip install matplotlib)") from None
    return matplotlib


def check_plot_path(path: str | os.PathLike) -> str:
    """The file type (``png``, ``pdf``, ``svg``) of a plot output, checked before any work:
    an unknown suffix or a missing matplotlib is one :class:`MtannoError`."""
    suffix = Path(path).suffix.lower()
    if suffix not in PLOT_SUFFIXES:
        raise MtannoError(f"unknown plot file type {suffix or '(no suffix)'!r}: name it "
                          f"{', '.join(PLOT_SUFFIXES)}", path=str(path))
    require_matplotlib()
    return suffix[1:]


def plot_alignment(al: Alignment, *, ax: Any = None, compare: WarpingPath | None = None,
                   compare_label: str = "full DTW") -> Any:
    """Draw ``al`` on ``ax`` (a new figure when None) and return the Axes.

    Artists, for who wants to inspect them: the computed area is a gray ``fill_betweenx``
    (label ``"computed area"``; rows in y, the columns lo − 0.5 … hi + 0.5 in x), each
    matched segment pair a rectangle patch (label ``"segment pairs"`` on the first), the
    path a black line (label ``"path"``: x = frames of B, y = frames of A, 1-based), and
    ``compare`` (e.g. the full-DTW path) a dashed line labelled ``compare_label``.
    """
    require_matplotlib()
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6 * max(0.4, min(2.5, al.a.frames / al.b.frames))))
    area = al.coarse.area if not al.full else None
    if area is not None:
        y = np.arange(area.n) + 1.0
        ax.fill_betweenx(np.repeat(y, 2) + np.tile([-0.5, 0.5], area.n),
                         np.repeat(area.lo + 0.5, 2), np.repeat(area.hi + 1.5, 2),
                         color="0.82", linewidth=0, label="computed area")
    sa, sb = al.coarse.segments_a, al.coarse.segments_b
    for k, (i, j) in enumerate(zip(al.coarse.pairs.a, al.coarse.pairs.b)):
        ax.add_patch(Rectangle((sb.start[j] + 0.5, sa.start[i] + 0.5), sb.length[j],
                               sa.length[i], fill=False, edgecolor="0.35", linewidth=0.6,
                               label="segment pairs" if k == 0 else None))
    if compare is not None:
        ax.plot(compare.b + 1, compare.a + 1, color="tab:red", linestyle="--", linewidth=1.0,
                label=compare_label)
    ax.plot(al.path.b + 1, al.path.a + 1, color="black", linewidth=1.2, label="path")
    ax.set_xlim(0.5, al.b.frames + 0.5)
    ax.set_ylim(0.5, al.a.frames + 0.5)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{al.b.name}: frame (30 Hz)")
    ax.set_ylabel(f"{al.a.name}: frame (30 Hz)")
    how = "full matrix" if al.full else f"{al.fraction:.1%} of the matrix, band {al.band}"
    ax.set_title(f"{al.cost} cost, {how}; mean cost {al.mean_cost:.3g}", fontsize=9)
    ax.legend(loc="lower right", fontsize=7)
    return ax


def save_alignment_plot(path: str | os.PathLike, al: Alignment, *,
                        compare: WarpingPath | None = None, dpi: int = 120) -> None:
    """Draw ``al`` (:func:`plot_alignment`) into the file ``path`` (.png, .pdf or .svg),
    atomically, without a display (Agg backend)."""
    kind = check_plot_path(path)
    from matplotlib.figure import Figure

    from mtanno.util.output import atomic_path

    fig = Figure(figsize=(6, 6 * max(0.4, min(2.5, al.a.frames / al.b.frames))))
    ax = fig.add_subplot()
    plot_alignment(al, ax=ax, compare=compare)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=kind)
