"""The evidence of an annotation segment (issue 26, part 1): a few numbers that tell whether
its label is right, each kind one function registered by name (:data:`EVIDENCE`), and the
one place where their inputs are built — for the segments ``mtanno tune`` fits the
calibrator on and for those ``mtanno annotate`` scores, so that the two never differ.

Evidence of a segment of label ℓ (natural logarithms; d are verification costs,
:mod:`mtanno.confidence.verify`):

* ``cost`` — its cost over τ_ℓ (Δ/τ at the segment's end with the segment decoder; the
  least Δ̄ over τ in the reference annotation): how well the template fits;
* ``length`` — log(segment frames / template frames of ℓ): a class's motions have typical
  lengths. The template frames of a label are the median length of the base template of
  each of its classes (the template folder's; the extra templates a configuration adds
  are left out, in tune and annotate alike);
* ``verify`` — log(d_ℓ / s_ℓ): its cost inside ℓ's training examples over the class's
  leave-one-performer-out scale s_ℓ (how unusual it would be as a new performance);
* ``margin`` — log(d_ℓ / d_other): against the examples of the nearest other class;
* ``background`` — log(d_ℓ / d_none): against background motions (``tune --background``);
  0 without them.

To add a kind: a function ``(segment: SegmentFacts) -> float`` decorated with
:func:`register_evidence`, and a test on hand-made inputs; configurations name it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.errors import MtannoError
from mtanno.labels.segments import Annotation

__all__ = ["BANK_EVIDENCE", "EVIDENCE", "LabelFacts", "SegmentFacts", "document_evidence",
           "label_facts", "register_evidence", "segment_evidence", "verification_query"]

#: Cost ratio given to a segment whose cost is infinite (no match inside it).
FAR = 10.0
_EPS = 1e-6


@dataclass(frozen=True)
class LabelFacts:
    """What the evidence needs to know of every label: its τ, its template length (frames
    at 30 Hz) and its member classes (a class is its own member; a superclass has several).
    Made by :func:`label_facts` only."""

    taus: Mapping[str, float]
    lengths: Mapping[str, float]
    members: Mapping[str, tuple[str, ...]]


def label_facts(template_frames: Mapping[str, int], *, tau_for: Callable[[str], float],
                superclasses: Mapping[str, Sequence[str]] | None = None) -> LabelFacts:
    """The :class:`LabelFacts` of the classes whose base templates have
    ``template_frames`` (class → frames at 30 Hz), labelled as ``superclasses`` say (label
    → member classes; other classes are their own label), with τ of a label from
    ``tau_for``. The one function tune and annotate build the evidence inputs with."""
    member_of = {m: s for s, ms in (superclasses or {}).items() for m in ms}
    lens: dict[str, list[int]] = {}
    members: dict[str, list[str]] = {}
    for cls, frames in template_frames.items():
        lab = member_of.get(cls, cls)
        lens.setdefault(lab, []).append(int(frames))
        members.setdefault(lab, []).append(cls)
    return LabelFacts(taus={lab: float(tau_for(lab)) for lab in lens},
                      lengths={lab: float(np.median(v)) for lab, v in lens.items()},
                      members={lab: tuple(v) for lab, v in members.items()})


@dataclass
class SegmentFacts:
    """One segment as the evidence functions see it: the row, its label's facts, and the
    verification costs of its motion to the bank's classes (class → least cost; ``""``:
    the background), empty without a bank."""

    row: Annotation
    tau: float
    template_frames: float
    members: tuple[str, ...]
    near: Mapping[str, float] = field(default_factory=dict)
    scale: float = 1.0

    @property
    def own(self) -> float:
        """The least verification cost to the examples of the segment's own classes."""
        return min((self.near[c] for c in self.members if c in self.near), default=math.inf)


#: Evidence kind → function, in the order of the columns of :func:`segment_evidence`; the
#: kinds that need the verification bank.
_KINDS: dict[str, Callable[[SegmentFacts], float]] = {}
_BANK: set[str] = set()


def register_evidence(name: str, *, bank: bool = False):
    """Register an evidence function under ``name`` (``bank``: it needs the verification
    bank, :data:`BANK_EVIDENCE`)."""

    def register(fn: Callable[[SegmentFacts], float]) -> Callable[[SegmentFacts], float]:
        _KINDS[name] = fn
        if bank:
            _BANK.add(name)
        return fn

    return register


@register_evidence("cost")
def _cost(s: SegmentFacts) -> float:
    r = s.row
    ratio = r.cost / s.tau if s.tau > 0 and math.isfinite(r.cost) else FAR
    return min(ratio, FAR)


@register_evidence("length")
def _length(s: SegmentFacts) -> float:
    r = s.row
    return math.log((r.end - r.start + 1) / max(s.template_frames, 1.0))


@register_evidence("verify", bank=True)
def _verify(s: SegmentFacts) -> float:
    return math.log((s.own + _EPS) / s.scale)


@register_evidence("margin", bank=True)
def _margin(s: SegmentFacts) -> float:
    other = min((v for c, v in s.near.items() if c and c not in s.members), default=math.inf)
    return math.log((s.own + _EPS) / (other + _EPS)) if math.isfinite(other) else 0.0


@register_evidence("background", bank=True)
def _background(s: SegmentFacts) -> float:
    bg = s.near.get("", math.inf)
    return math.log((s.own + _EPS) / (bg + _EPS)) if math.isfinite(bg) else 0.0


#: The evidence of a segment, in the order of the columns of :func:`segment_evidence`.
EVIDENCE = tuple(_KINDS)
#: The evidence that needs a verification bank.
BANK_EVIDENCE = tuple(n for n in EVIDENCE if n in _BANK)


def verification_query(X: np.ndarray, poses: np.ndarray | None,
                       representation: str) -> Callable[[Annotation], np.ndarray]:
    """The verification sequence of a row's frames of a document (features ``X``, poses or
    None), in the bank's ``representation``: the one closure tune and annotate use."""
    from mtanno.confidence.verify import sequence

    def query(r: Annotation) -> np.ndarray:
        return sequence(X=X[:, r.start:r.end + 1] if representation == "features" else None,
                        poses=poses[r.start:r.end + 1] if representation == "poses" else None,
                        representation=representation)

    return query


def segment_evidence(rows: Sequence[Annotation], facts: LabelFacts, *, bank=None,
                     query: Callable[[Annotation], np.ndarray] | None = None,
                     names: Sequence[str] = EVIDENCE) -> np.ndarray:
    """(rows × names) evidence of the segments ``rows`` (module docstring). ``bank``
    (:class:`mtanno.confidence.verify.Bank`) and ``query`` (the verification sequence of a
    row) are needed for the evidence of :data:`BANK_EVIDENCE`."""
    unknown = [n for n in names if n not in _KINDS]
    if unknown:
        raise MtannoError(f"unknown evidence {', '.join(unknown)} (known: "
                          f"{', '.join(EVIDENCE)})")
    needs_bank = any(n in _BANK for n in names)
    if needs_bank and (bank is None or query is None):
        raise MtannoError("the verification evidence needs a bank and the segments' motion")
    fns = [_KINDS[n] for n in names]
    out = np.zeros((len(rows), len(names)))
    for i, r in enumerate(rows):
        s = SegmentFacts(r, facts.taus.get(r.label, math.nan),
                         facts.lengths.get(r.label, 1.0), facts.members.get(r.label, (r.label,)))
        if needs_bank:
            s.near = bank.nearest(query(r))
            own = [c for c in s.members if c in s.near]
            if not math.isfinite(s.own):
                raise MtannoError(f"the verification bank has no example of {r.label!r}",
                                  path=bank.path)
            s.scale = float(np.median([bank.scale.get(c, 1.0) for c in own]))
        out[i] = [fn(s) for fn in fns]
    return out


def document_evidence(rows: Sequence[Annotation], facts: LabelFacts, *, X: np.ndarray,
                      poses: np.ndarray | None, bank=None,
                      names: Sequence[str] = EVIDENCE) -> np.ndarray:
    """:func:`segment_evidence` of rows of one document (features ``X``, poses or None;
    rows' frames index them), verified against ``bank`` (None: no bank evidence)."""
    query = verification_query(X, poses, bank.representation) if bank is not None else None
    return segment_evidence(rows, facts, bank=bank, query=query, names=names)
