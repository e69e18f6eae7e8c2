"""A labelled interval of a document, in the two forms mtanno uses, and the one conversion
between them.

:class:`Segment` is what a user reads and writes (truth tables, the evaluation): 1-based
inclusive frames at 30 Hz. :class:`Annotation` is a segment as the code makes it: 0-based
inclusive frames at 30 Hz with the match's cost and the label's confidence (a named tuple:
documents of hours give thousands, made in a few microseconds each).
:meth:`Annotation.segment` is the one 0-based → 1-based step, and :meth:`Segment.frames0`
its inverse; frames are 1-based in every file and 0-based inside the code.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

__all__ = ["Annotation", "Segment", "by_document", "to_segments"]


@dataclass(frozen=True, order=True)
class Segment:
    """A labelled frame range of one document: 1-based inclusive frames at 30 Hz."""

    doc: str
    start: int
    end: int
    label: str

    @property
    def length(self) -> int:
        """Frames (at 30 Hz) the segment covers."""
        return self.end - self.start + 1

    def frames0(self) -> tuple[int, int]:
        """(start, end) as 0-based inclusive frames, as the code indexes arrays."""
        return self.start - 1, self.end - 1


class Annotation(NamedTuple):
    """One segment of an annotation: 0-based inclusive frames at 30 Hz. ``cost``: the
    match's distance Δ at the segment's end; ``confidence``: the probability that the
    label is right (:mod:`mtanno.confidence`), NaN until the annotation gives it."""

    doc: str
    start: int
    end: int
    label: str
    cost: float
    confidence: float = math.nan

    def segment(self) -> Segment:
        """The row as a :class:`Segment` (1-based inclusive frames)."""
        return Segment(self.doc, self.start + 1, self.end + 1, self.label)


def to_segments(rows: Sequence[Annotation]) -> list[Segment]:
    """The rows as :class:`Segment` (what the evaluation compares)."""
    return [a.segment() for a in rows]


def by_document(segments: Iterable[Segment]) -> dict[str, list[Segment]]:
    """Segments grouped by document, each group in order."""
    out: dict[str, list[Segment]] = {}
    for s in segments:
        out.setdefault(s.doc, []).append(s)
    for v in out.values():
        v.sort()
    return out
