"""A tuned confidence as one object (issue 26): the ``[confidence]`` table of a class
configuration read into a typed :class:`ConfidenceModel` and written back from it — the
evidence used (:mod:`mtanno.confidence.evidence`), the calibrator that maps it to
probabilities (:mod:`mtanno.confidence.calibration`), the minimum confidence of an output
row and the verification bank file (:mod:`mtanno.confidence.verify`), relative to the
configuration and pinned by its SHA-256.

The table, as ``mtanno tune`` writes it::

    [confidence]
    evidence = ["cost", "length", "verify", "margin"]
    min_confidence = 0.3
    bank = "tuned.verify.parquet"
    bank_sha256 = "…"
    invariance = ["retarget"]     # what the verification is blind to (when any)
    frames = "tuned.frames.parquet"   # the frame classifier's bank (evidence "classifier")
    frames_sha256 = "…"

    [confidence.calibrator]
    …
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mtanno.confidence.calibration import Calibrator
from mtanno.confidence.evidence import BANK_EVIDENCE, EVIDENCE, FRAME_EVIDENCE
from mtanno.errors import MtannoError

__all__ = ["CONFIDENCE_KEYS", "ConfidenceModel", "check_min_confidence", "confidence_record",
           "is_sha256"]

#: Keys of the ``[confidence]`` table and their types.
CONFIDENCE_KEYS = {"evidence": list, "min_confidence": float, "bank": str, "bank_sha256": str,
                   "invariance": list, "frames": str, "frames_sha256": str, "calibrator": dict}


def check_min_confidence(value, *, what: str = "min confidence") -> float:
    """A minimum confidence: a number in [0, 1]."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise MtannoError(f"{what} must be a number in [0, 1], got {value!r}") from None
    if not 0.0 <= v <= 1.0:
        raise MtannoError(f"{what} must be a number in [0, 1], got {value!r}")
    return v


def is_sha256(v) -> bool:
    """Whether ``v`` is a SHA-256 as files record it (64 lower-case hex digits)."""
    return isinstance(v, str) and len(v) == 64 and all(ch in "0123456789abcdef" for ch in v)


@dataclass
class ConfidenceModel:
    """A tuned confidence: the evidence used, the calibrator mapping it to probabilities,
    the minimum confidence of an output row, and the verification bank (``bank_file`` as
    the configuration names it, relative to ``base``, the configuration's folder; None
    when no bank evidence is used). The bank is read on first use (:attr:`bank`), checked
    against ``bank_sha256``."""

    evidence: tuple[str, ...]
    calibrator: Calibrator
    min_confidence: float = 0.0
    bank_file: str | None = None
    bank_sha256: str | None = None
    base: str | None = None
    #: what the bank's verification is blind to (:data:`mtanno.confidence.verify.
    #: INVARIANCES`), as the bank records it
    invariance: tuple[str, ...] = ()
    #: the frame classifier's bank file (relative to ``base``) and its SHA-256 (None
    #: unless the evidence holds :data:`mtanno.confidence.evidence.FRAME_EVIDENCE`)
    frames_file: str | None = None
    frames_sha256: str | None = None
    config_path: str | None = field(default=None, repr=False)
    bank_line: int | None = field(default=None, repr=False)
    frames_line: int | None = field(default=None, repr=False)
    _bank: object = field(default=None, repr=False, compare=False)
    _frames: object = field(default=None, repr=False, compare=False)

    @classmethod
    def from_table(cls, table: dict, *, path: str | None = None,
                   line_of: Callable[[str, str], int | None] = lambda s, k: None
                   ) -> ConfidenceModel:
        """The model of a ``[confidence]`` table read from the configuration ``path``
        (``line_of(section, key)``: the line a key is on, for the messages). Every problem
        is one :class:`MtannoError` naming the file and line."""

        def bad(key: str, msg: str, section: str = "confidence") -> MtannoError:
            return MtannoError(msg, path=path, line=line_of(section, key))

        for k, v in table.items():
            kind = CONFIDENCE_KEYS.get(k)
            if kind is None:
                raise bad(k, f"unknown key {k!r} in [confidence] (known: "
                             f"{', '.join(CONFIDENCE_KEYS)})")
            ok = (isinstance(v, (int, float)) and not isinstance(v, bool)) if kind is float \
                else isinstance(v, kind)
            if not ok:
                raise bad(k, f"[confidence] {k} has the wrong type: {v!r}")
        names = table.get("evidence", [])
        if not names or not all(isinstance(e, str) and e in EVIDENCE for e in names):
            raise bad("evidence", f"[confidence] evidence must list names of "
                                  f"{', '.join(EVIDENCE)}, got {names!r}")
        least = table.get("min_confidence", 0.0)
        if not 0.0 <= least <= 1.0:
            raise bad("min_confidence", f"[confidence] min_confidence must be in [0, 1], "
                                        f"got {least!r}")
        if "calibrator" not in table:
            raise bad("confidence", "[confidence] needs a [confidence.calibrator] table", "")
        if ("bank" in table) != ("bank_sha256" in table) or (
                "bank_sha256" in table and not is_sha256(table["bank_sha256"])):
            raise bad("bank", "[confidence] bank and bank_sha256 (64 lower-case hex digits) "
                              "go together")
        names = tuple(names)
        invariance = table.get("invariance", [])
        from mtanno.confidence.verify import INVARIANCES

        if not all(isinstance(v, str) and v in INVARIANCES for v in invariance) \
                or len(set(invariance)) != len(invariance):
            raise bad("invariance", f"[confidence] invariance must list distinct names of "
                                    f"{', '.join(INVARIANCES)}, got {invariance!r}")
        if invariance and "bank" not in table:
            raise bad("invariance", "[confidence] invariance needs a verification bank")
        if ("frames" in table) != ("frames_sha256" in table) or (
                "frames_sha256" in table and not is_sha256(table["frames_sha256"])):
            raise bad("frames", "[confidence] frames and frames_sha256 (64 lower-case hex "
                                "digits) go together")
        if "frames" not in table and any(n in FRAME_EVIDENCE for n in names):
            raise bad("evidence", f"[confidence] evidence "
                                  f"{', '.join(n for n in names if n in FRAME_EVIDENCE)} needs "
                                  "the frame classifier's bank (frames = ...)")
        if "bank" not in table and any(n in BANK_EVIDENCE for n in names):
            raise bad("evidence", f"[confidence] evidence "
                                  f"{', '.join(n for n in names if n in BANK_EVIDENCE)} needs "
                                  "a verification bank (bank = ...)")
        line = line_of("", "confidence.calibrator")
        try:
            calibrator = Calibrator.from_dict(table["calibrator"], path=path)
        except MtannoError as exc:
            raise MtannoError(exc.message, path=path, line=line) from None
        have = tuple(getattr(calibrator, "names", names) or names)
        if have != names:
            raise MtannoError(f"[confidence] evidence {list(names)} is not what its "
                              f"calibrator was fitted on ({list(have)})", path=path, line=line)
        return cls(names, calibrator, float(least), table.get("bank"),
                   table.get("bank_sha256"),
                   str(Path(path).parent) if path else None,
                   tuple(v for v in INVARIANCES if v in invariance), table.get("frames"),
                   table.get("frames_sha256"), path, line_of("confidence", "bank"),
                   line_of("confidence", "frames"))

    def to_table(self) -> dict:
        """The ``[confidence]`` table (what :meth:`from_table` reads)."""
        out: dict = {"evidence": list(self.evidence), "min_confidence": self.min_confidence}
        if self.bank_file is not None:
            out["bank"] = self.bank_file
            out["bank_sha256"] = self.bank_sha256
        if self.invariance:
            out["invariance"] = list(self.invariance)
        if self.frames_file is not None:
            out["frames"] = self.frames_file
            out["frames_sha256"] = self.frames_sha256
        out["calibrator"] = self.calibrator.to_dict()
        return out

    @property
    def bank_path(self) -> str | None:
        """The bank file (None: no bank)."""
        if self.bank_file is None:
            return None
        return str(Path(self.base or ".") / self.bank_file)

    @property
    def bank(self):
        """The verification bank (:class:`mtanno.confidence.verify.Bank`; None without
        one), read once; it must be the file tune wrote (its SHA-256)."""
        if self._bank is None and self.bank_file is not None:
            from mtanno.confidence.verify import read_bank
            from mtanno.util.provenance import sha256_file

            where = {"path": self.config_path, "line": self.bank_line}
            path = self.bank_path
            if not Path(path).is_file():
                raise MtannoError(f"[confidence] bank {path} not found", **where)
            if sha256_file(path) != self.bank_sha256:
                raise MtannoError(f"[confidence] bank {path} is not the file tune wrote (its "
                                  "SHA-256 differs from bank_sha256); run mtanno tune again",
                                  **where)
            bank = read_bank(path)
            if tuple(bank.invariance) != tuple(self.invariance):
                raise MtannoError(f"[confidence] invariance {list(self.invariance)} is not "
                                  f"the bank's ({list(bank.invariance)}); run mtanno tune "
                                  "again", **where)
            self._bank = bank
        return self._bank

    @property
    def frame_bank(self):
        """The frame classifier's bank (:class:`mtanno.confidence.frames.FrameBank`; None
        without one), read once; it must be the file tune wrote (its SHA-256)."""
        if self._frames is None and self.frames_file is not None:
            from mtanno.confidence.frames import read_frame_bank
            from mtanno.util.provenance import sha256_file

            where = {"path": self.config_path, "line": self.frames_line}
            path = str(Path(self.base or ".") / self.frames_file)
            if not Path(path).is_file():
                raise MtannoError(f"[confidence] frames {path} not found", **where)
            if sha256_file(path) != self.frames_sha256:
                raise MtannoError(f"[confidence] frames {path} is not the file tune wrote (its "
                                  "SHA-256 differs from frames_sha256); run mtanno tune again",
                                  **where)
            self._frames = read_frame_bank(path)
        return self._frames

    def probabilities(self, E: np.ndarray) -> np.ndarray:
        """The calibrated probability of every row of evidence ``E``."""
        return np.clip(np.asarray(self.calibrator.predict(E), dtype=np.float64), 0.0, 1.0)


def confidence_record(model: ConfidenceModel | None, min_confidence: float | None) -> dict:
    """The provenance record of the confidence column: calibrated or not, the evidence,
    the minimum applied and the bank file."""
    if model is None:
        out: dict = {"calibrated": False, "score": "1 - cost/tau, clipped to [0, 1]"}
        least = min_confidence or 0.0
    else:
        out = {"calibrated": True, "evidence": list(model.evidence)}
        least = model.min_confidence if min_confidence is None else min_confidence
        if model.bank_file is not None:
            out["bank"] = {"path": model.bank_path, "sha256": model.bank_sha256,
                           "representation": model.bank.representation,
                           "invariance": list(model.invariance)}
        if model.frames_file is not None:
            out["frames"] = {"path": str(Path(model.base or ".") / model.frames_file),
                             "sha256": model.frames_sha256}
    out["min_confidence"] = least
    return out
