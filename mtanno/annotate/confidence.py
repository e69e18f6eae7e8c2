"""Confidence of every annotation segment (issue 26, part 1): the probability that its label
is right — that a truth segment of its label overlaps it with IoU ≥ 0.5 — from a few
numbers of evidence about the segment (:data:`EVIDENCE`), mapped to a probability by a
calibrator learned in ``mtanno tune``'s cross-validation
(:mod:`mtanno.annotate.calibration`; :mod:`mtanno.tuning.confidence`).

Evidence of a segment of label ℓ (natural logarithms; d are verification costs,
:mod:`mtanno.annotate.verify`):

* ``cost`` — its cost over τ_ℓ (Δ/τ at the segment's end with the segment decoder; the
  least Δ̄ over τ in the reference annotation): how well the template fits;
* ``length`` — log(segment frames / template frames of ℓ): a class's motions have typical
  lengths;
* ``verify`` — log(d_ℓ / s_ℓ): its cost inside ℓ's training examples over the class's
  leave-one-performer-out scale s_ℓ (how unusual it would be as a new performance);
* ``margin`` — log(d_ℓ / d_other): against the examples of the nearest other class;
* ``background`` — log(d_ℓ / d_none): against background motions (``tune --background``);
  0 without them.

Without a tuned confidence (no ``[confidence]`` in the class configuration) the
confidence is :func:`mtanno.annotate.calibration.uncalibrated_confidence` of the cost
ratio, a monotone score marked uncalibrated in the provenance.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mtanno.annotate.calibration import uncalibrated_confidence
from mtanno.errors import MtannoError
from mtanno.labels.segments import Annotation

__all__ = ["BANK_EVIDENCE", "EVIDENCE", "ConfidenceModel", "check_min_confidence",
           "confidence_record", "load_confidence", "score_document", "segment_evidence",
           "single_label_by_confidence",
           "with_confidence"]

#: The evidence of a segment, in the order of the columns of :func:`segment_evidence`.
EVIDENCE = ("cost", "length", "verify", "margin", "background")
#: The evidence that needs a verification bank.
BANK_EVIDENCE = ("verify", "margin", "background")
#: Cost ratio given to a segment whose cost is infinite (no match inside it).
_FAR = 10.0
_EPS = 1e-6


def check_min_confidence(value, *, what: str = "min confidence") -> float:
    """A minimum confidence: a number in [0, 1]."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise MtannoError(f"{what} must be a number in [0, 1], got {value!r}") from None
    if not 0.0 <= v <= 1.0:
        raise MtannoError(f"{what} must be a number in [0, 1], got {value!r}")
    return v


def segment_evidence(rows: Sequence[Annotation], *, taus: dict[str, float],
                     lengths: dict[str, float], members: dict[str, Sequence[str]] | None = None,
                     bank=None, query: Callable[[Annotation], np.ndarray] | None = None,
                     names: Sequence[str] = EVIDENCE) -> np.ndarray:
    """(rows × names) evidence of the segments ``rows`` (module docstring).

    ``taus`` and ``lengths``: τ and template length (frames at 30 Hz) per label;
    ``members``: the classes of a superclass label (a class is its own member); ``bank``
    (:class:`mtanno.annotate.verify.Bank`) and ``query`` (the verification sequence of a
    row) are needed for the evidence of :data:`BANK_EVIDENCE`."""
    unknown = [n for n in names if n not in EVIDENCE]
    if unknown:
        raise MtannoError(f"unknown evidence {', '.join(unknown)} (known: "
                          f"{', '.join(EVIDENCE)})")
    needs_bank = any(n in BANK_EVIDENCE for n in names)
    if needs_bank and (bank is None or query is None):
        raise MtannoError("the verification evidence needs a bank and the segments' motion")
    members = members or {}
    out = np.zeros((len(rows), len(names)))
    col = {n: k for k, n in enumerate(names)}
    for i, r in enumerate(rows):
        tau = taus.get(r.label, math.nan)
        ratio = r.cost / tau if tau > 0 and math.isfinite(r.cost) else _FAR
        if "cost" in col:
            out[i, col["cost"]] = min(ratio, _FAR)
        if "length" in col:
            out[i, col["length"]] = math.log((r.end - r.start + 1) / max(lengths.get(
                r.label, 1.0), 1.0))
        if not needs_bank:
            continue
        near = bank.nearest(query(r))
        own = [c for c in members.get(r.label, (r.label,)) if c in near]
        d = min((near[c] for c in own), default=math.inf)
        if not math.isfinite(d):
            raise MtannoError(f"the verification bank has no example of {r.label!r}",
                              path=bank.path)
        scale = float(np.median([bank.scale.get(c, 1.0) for c in own]))
        if "verify" in col:
            out[i, col["verify"]] = math.log((d + _EPS) / scale)
        if "margin" in col:
            other = min((v for c, v in near.items() if c and c not in own), default=math.inf)
            out[i, col["margin"]] = math.log((d + _EPS) / (other + _EPS)) \
                if math.isfinite(other) else 0.0
        if "background" in col:
            bg = near.get("", math.inf)
            out[i, col["background"]] = math.log((d + _EPS) / (bg + _EPS)) \
                if math.isfinite(bg) else 0.0
    return out


@dataclass
class ConfidenceModel:
    """A tuned confidence (``[confidence]`` of a class configuration): the evidence used,
    the calibrator mapping it to probabilities, the minimum confidence of an output row,
    and the verification bank (None when no bank evidence is used)."""

    evidence: tuple[str, ...]
    calibrator: object
    min_confidence: float = 0.0
    bank: object = None
    bank_path: str | None = None
    bank_sha256: str | None = None

    def probabilities(self, E: np.ndarray) -> np.ndarray:
        return np.clip(np.asarray(self.calibrator.predict(E), dtype=np.float64), 0.0, 1.0)


def with_confidence(rows: Sequence[Annotation], confidence: Sequence[float]) -> list[Annotation]:
    """The rows with their confidence (rounded to 6 digits: the tables hold what was
    computed, the same on every machine to that precision)."""
    return [r._replace(confidence=round(float(c), 6)) for r, c in zip(rows, confidence)]


def _label_facts(models, config) -> tuple[dict, dict, dict]:
    """τ, template length (median over its templates; frames at 30 Hz) and member classes
    of every label of ``models`` under ``config``."""
    member_of = {m: s for s, ms in config.superclasses.items() for m in ms}
    lens: dict[str, list[int]] = {}
    members: dict[str, list[str]] = {}
    for m in models:
        lab = member_of.get(m.name, m.name)
        lens.setdefault(lab, []).append(int(m.values.shape[1]))
        if m.name not in members.setdefault(lab, []):
            members[lab].append(m.name)
    taus = {lab: config.tau_for(lab) for lab in lens}
    return taus, {k: float(np.median(v)) for k, v in lens.items()}, members


def score_document(rows: Sequence[Annotation], *, X: np.ndarray, poses: np.ndarray | None,
                   models, config, confidence: ConfidenceModel | None) -> list[Annotation]:
    """The rows of one document (features ``X``, poses or None) with their confidence:
    the tuned ``confidence`` (evidence, calibrator), or :func:`uncalibrated_confidence`
    without one."""
    taus, lengths, members = _label_facts(models, config)
    if confidence is None:
        return with_confidence(rows, uncalibrated_confidence(np.array(
            [r.cost / taus[r.label] if taus.get(r.label, 0) > 0 else math.inf for r in rows])))
    if not rows:
        return []
    bank = confidence.bank
    query = None
    if bank is not None:
        from mtanno.annotate.verify import sequence

        rep = bank.representation

        def query(r: Annotation) -> np.ndarray:
            return sequence(X=X[:, r.start:r.end + 1] if rep == "features" else None,
                            poses=poses[r.start:r.end + 1] if rep == "poses" else None,
                            representation=rep)
    E = segment_evidence(rows, taus=taus, lengths=lengths, members=members, bank=bank,
                         query=query, names=confidence.evidence)
    return with_confidence(rows, confidence.probabilities(E))


def single_label_by_confidence(rows: Sequence[Annotation]) -> list[Annotation]:
    """Overlapping segments of one document resolved into a partition by confidence: each
    frame keeps the label of the most confident segment covering it (ties: the earlier
    row); adjacent pieces of one label join (their largest confidence, least cost)."""
    if not rows:
        return []
    L = max(r.end for r in rows) + 1
    owner = np.full(L, -1, dtype=np.int64)
    order = sorted(range(len(rows)), key=lambda i: (-np.nan_to_num(rows[i].confidence,
                                                                   nan=-1.0), i))
    for i in order:
        r = rows[i]
        span = owner[r.start:r.end + 1]
        span[span < 0] = i
    out: list[Annotation] = []
    change = np.flatnonzero(np.diff(owner)) + 1
    for s, e in zip(np.r_[0, change].tolist(), np.r_[change, L].tolist()):
        i = int(owner[s])
        if i < 0:
            continue
        r = rows[i]
        if out and out[-1].label == r.label and out[-1].end == s - 1:
            p = out[-1]
            out[-1] = p._replace(end=e - 1, cost=min(p.cost, r.cost),
                                 confidence=max(p.confidence, r.confidence))
        else:
            out.append(r._replace(start=s, end=e - 1))
    return out


def load_confidence(config) -> ConfidenceModel | None:
    """The tuned confidence of a class configuration (its ``[confidence]``; None without
    one): the calibrator, and the verification bank read from its file (relative to the
    configuration), which must be the one tune wrote (its SHA-256)."""
    conf = config.confidence
    if not conf:
        return None
    from pathlib import Path

    from mtanno.annotate.calibration import Calibrator

    line = config.line_of("", "confidence.calibrator")
    try:
        calibrator = Calibrator.from_dict(conf["calibrator"], path=config.path)
    except MtannoError as exc:
        raise MtannoError(exc.message, path=config.path, line=line) from None
    names = tuple(conf["evidence"])
    have = tuple(getattr(calibrator, "names", names) or names)
    if have != names:
        raise MtannoError(f"[confidence] evidence {list(names)} is not what its calibrator "
                          f"was fitted on ({list(have)})", path=config.path, line=line)
    bank = bank_path = sha = None
    if "bank" in conf:
        from mtanno.annotate.verify import read_bank
        from mtanno.util.tables import sha256_file

        base = Path(config.path).parent if config.path else Path(".")
        bank_path = str(base / conf["bank"])
        if not Path(bank_path).is_file():
            raise MtannoError(f"[confidence] bank {bank_path} not found", path=config.path,
                              line=config.line_of("confidence", "bank"))
        sha = sha256_file(bank_path)
        if sha != conf["bank_sha256"]:
            raise MtannoError(f"[confidence] bank {bank_path} is not the file tune wrote "
                              "(its SHA-256 differs from bank_sha256); run mtanno tune again",
                              path=config.path, line=config.line_of("confidence", "bank"))
        bank = read_bank(bank_path)
    if bank is None and any(n in BANK_EVIDENCE for n in names):
        raise MtannoError(f"[confidence] evidence {', '.join(n for n in names if n in BANK_EVIDENCE)}"
                          " needs a verification bank (bank = ...)", path=config.path,
                          line=config.line_of("confidence", "evidence"))
    return ConfidenceModel(names, calibrator, float(conf.get("min_confidence", 0.0)), bank,
                           bank_path, sha)


def confidence_record(model: ConfidenceModel | None, min_confidence: float | None) -> dict:
    """The provenance record of the confidence column: calibrated or not, the evidence,
    the minimum applied and the bank file."""
    if model is None:
        out: dict = {"calibrated": False, "score": "1 - cost/tau, clipped to [0, 1]"}
        least = min_confidence or 0.0
    else:
        out = {"calibrated": True, "evidence": list(model.evidence)}
        least = model.min_confidence if min_confidence is None else min_confidence
        if model.bank_path:
            out["bank"] = {"path": model.bank_path, "sha256": model.bank_sha256,
                           "representation": model.bank.representation}
    out["min_confidence"] = least
    return out
