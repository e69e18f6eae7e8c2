"""Frame-wise annotation of documents with motion classes (MBS09 §4–5, algorithms.md §7).

For every class template the matching distance Δ_p (algorithms.md §3.4) is computed over
the document, optionally only inside candidate windows (from a keyframe stage), turned into
the *modified distance* Δ̄_p that spreads each match's cost over the frames it covers, and
the label of a frame is the class with the smallest Δ̄ there. Maximal runs of one label are
then extended while Δ̄ keeps falling towards them, which gives the output segments (they may
overlap segments of other labels).

Frames are 0-based inside this module and 1-based inclusive in the tables it writes.
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numba
import numpy as np

from mtanno._dbar import reference_dbar_kernel
from mtanno.errors import MtannoError, read_input

if TYPE_CHECKING:
    from mtanno.store import FeatureLayout

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: Annotation threshold τ of MBS09 (used for every class without its own τ).
DEFAULT_TAU = 0.13
#: Quantization δ of the templates for annotation (MBS09).
DEFAULT_DELTA = 0.05
#: Candidate windows per class (keyframe preselection): a list of (first, last) frames,
#: 0-based inclusive, or a (firsts, lasts) pair of sorted disjoint int64 arrays.
Windows = dict[str, "list[tuple[int, int]] | tuple[np.ndarray, np.ndarray]"]


@dataclass
class ClassConfig:
    """Per-class thresholds, superclasses and the annotation methods of issue 10 (a TOML
    file, see ``docs/annotation.md``; ``mtanno tune`` writes one).

    ``tau`` maps class (or superclass) names to τ; ``superclasses`` maps a superclass
    name to the classes it joins (its Δ̄ is the frame-wise minimum over them). The methods,
    all off by default (MBS09 as the reference implementation runs it):

    * ``resolve`` — overlap resolution: the segment decoder (:mod:`mtanno.decode`) picks
      one least-cost partition into matches instead of Δ̄ labels and extension;
    * ``refine`` — boundary refinement: with ``resolve`` a segment may start up to
      ``slack`` frames from its match's start; without, the extension of §7 step 4 walks
      only over frames no other class labels;
    * ``reject`` — rejection ceilings ρ per label (``default_reject`` for the others):
      matches with Δ above it are never taken (segment decoder) or picked (Δ̄);
    * ``frame_weight`` — tie-breaking by frame-wise evidence (segment decoder);
    * ``segment_cost`` — a fixed cost λ per segment (segment decoder; in frames): long
      motions are not cut into short matches of other classes, short spurious matches
      stay out;
    * ``templates`` — several templates per class: further template files of a class
      (paths relative to the configuration), matched like its own; its Δ is the
      frame-wise minimum over them;
    * ``delta`` — the templates' quantization δ (None: the command's ``--delta``).

    ``tuned_with`` (written by ``mtanno tune``): class → SHA-256 of the template file the
    parameters were tuned with; :meth:`template_warnings` says when the templates given
    to ``annotate`` are other ones.
    """

    default_tau: float = DEFAULT_TAU
    tau: dict[str, float] = field(default_factory=dict)
    superclasses: dict[str, list[str]] = field(default_factory=dict)
    path: str | None = None
    resolve: bool = False
    refine: bool = False
    slack: int = 3
    frame_weight: float = 0.0
    segment_cost: float = 0.0
    delta: float | None = None
    default_reject: float = math.inf
    reject: dict[str, float] = field(default_factory=dict)
    templates: dict[str, list[str]] = field(default_factory=dict)
    tuned_with: dict[str, str] = field(default_factory=dict)
    lines: dict[tuple[str, str], int] = field(default_factory=dict, repr=False, compare=False)

    def tau_for(self, name: str) -> float:
        return self.tau.get(name, self.default_tau)

    def reject_for(self, name: str) -> float:
        return self.reject.get(name, self.default_reject)

    def line_of(self, section: str, key: str) -> int | None:
        """1-based line of ``key`` in ``[section]`` of the file read (None if unknown)."""
        return self.lines.get((section, key))

    def check(self, classes: Sequence[str]) -> None:
        """Refuse what would be silently ignored or give nonsense: a τ that is not a
        number ≥ 0 (NaN labels nothing; with ``resolve`` τ must be > 0), and names in
        ``[tau]``, ``[reject]``, ``[superclasses]`` or ``[templates]`` that are none of
        ``classes`` (the templates' classes) or of the superclasses."""
        for name, value in [("default", self.default_tau), *self.tau.items()]:
            what = f"tau of {name}" if name != "default" else "tau"
            check_tau(value, what=what, path=self.path)
            if self.resolve and not value > 0:
                raise MtannoError(f"{what} must be > 0 with [decoder] resolve, got {value!r}",
                                  path=self.path, line=self.line_of("tau", name))
        known = set(classes)
        labels = known | set(self.superclasses)
        for sup, members in self.superclasses.items():
            unknown = [m for m in members if m not in known]
            if unknown:
                raise MtannoError(f"superclass {sup!r} names class(es) without a template: "
                                  f"{', '.join(unknown)} (classes: {', '.join(sorted(known))})",
                                  path=self.path, line=self.line_of("superclasses", sup))
        for section, table, allowed in (("tau", self.tau, labels),
                                        ("reject", self.reject, labels),
                                        ("templates", self.templates, known)):
            unknown = sorted(n for n in table if n not in allowed)
            if unknown:
                what = "classes and superclasses" if allowed is labels else "classes"
                raise MtannoError(f"[{section}] names unknown class(es) {', '.join(unknown)} "
                                  f"(no template; {what}: {', '.join(sorted(allowed))})",
                                  path=self.path, line=self.line_of(section, unknown[0]))

    def template_warnings(self, models: Sequence[ClassModel]) -> list[str]:
        """Warnings when ``models`` (the template folder's classes) are not the templates
        this configuration was tuned with (``[tuned_with]``; none for a configuration
        without it): per-class thresholds tuned for other templates may not suit these."""
        if not self.tuned_with:
            return []
        changed = sorted(m.name for m in models if m.name in self.tuned_with
                         and m.sha256 is not None and m.sha256 != self.tuned_with[m.name])
        untuned = sorted(m.name for m in models if m.name not in self.tuned_with)
        out = []
        if changed:
            out.append(f"the template(s) of {', '.join(changed)} are not those {self.path} was "
                       f"tuned with (SHA-256 in its [tuned_with]): its thresholds may not suit "
                       f"them; run mtanno tune again")
        if untuned:
            out.append(f"the class(es) {', '.join(untuned)} are not in the [tuned_with] of "
                       f"{self.path}: tune did not see their templates")
        return out

    def methods(self) -> dict:
        """The issue-10 methods in use, for an output's provenance (empty: none)."""
        out: dict = {}
        if self.resolve:
            out["resolve"] = True
        if self.refine:
            out["refine"] = {"slack": self.slack} if self.resolve else "unclaimed"
        if self.resolve and self.frame_weight > 0:
            out["frame_weight"] = self.frame_weight
        if self.resolve and self.segment_cost > 0:
            out["segment_cost"] = self.segment_cost
        if self.reject or self.default_reject != math.inf:
            out["reject"] = {**({"default": self.default_reject}
                                if self.default_reject != math.inf else {}), **self.reject}
        if self.templates:
            out["templates"] = {c: list(v) for c, v in self.templates.items()}
        if self.delta is not None:
            out["delta"] = self.delta
        return out

    def template_paths(self) -> dict[str, list[Path]]:
        """``[templates]`` as paths (relative ones taken from the configuration's folder)."""
        base = Path(self.path).parent if self.path else Path(".")
        return {c: [base / f for f in files] for c, files in self.templates.items()}


def check_tau(tau, *, what: str = "tau", path: str | None = None) -> float:
    """τ as a float; NaN, a negative value or a non-number is an :class:`MtannoError`
    (∞ is allowed: every match counts)."""
    try:
        value = float(tau)
    except (TypeError, ValueError):
        raise MtannoError(f"{what} must be a number ≥ 0, got {tau!r}", path=path) from None
    if not value >= 0:
        raise MtannoError(f"{what} must be a number ≥ 0, got {tau!r}", path=path)
    return value


#: Keys of the ``[decoder]`` section of a class configuration and their types.
DECODER_KEYS = {"resolve": bool, "refine": bool, "slack": int, "frame_weight": float,
                "segment_cost": float, "delta": float}
_SECTIONS = ("tau", "superclasses", "decoder", "reject", "templates", "tuned_with")


def _key_lines(text: str) -> dict[tuple[str, str], int]:
    """(section, key) → 1-based line of ``key =`` in a simple TOML file (for messages)."""
    out: dict[tuple[str, str], int] = {}
    section = ""
    for i, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if s.startswith("[") and not s.startswith("[["):
            section = s.strip("[] \t").split("#")[0].strip()
            out.setdefault(("", section), i)
        elif "=" in s and not s.startswith("#"):
            key = s.split("=", 1)[0].strip().strip('"\'')
            out.setdefault((section, key), i)
    return out


def load_class_config(path: str | os.PathLike) -> ClassConfig:
    """Read a class configuration (``docs/annotation.md``)::

        [tau]
        default = 0.13
        lieDownFloor = 0.06

        [superclasses]
        kick = ["kickLFront1Reps", "kickRFront1Reps"]

        [decoder]                 # issue 10's methods, all optional
        resolve = true
        refine = true
        slack = 3
        frame_weight = 0.3
        segment_cost = 6
        delta = 0.05

        [reject]
        default = 0.1
        squat1Reps = 0.08

        [templates]
        squat1Reps = ["tuned.templates/squat1Reps.2.json"]

    Every problem is one :class:`MtannoError` naming the file and, where it can be told,
    the line: unknown sections or keys, values of the wrong type, τ or ρ not a number
    ≥ 0, a slack that is not an integer ≥ 0, a frame weight or segment cost that is not a
    finite number ≥ 0, δ outside [0, 0.5).
    """
    spath = str(path)
    try:
        text = read_input(path, what="class configuration").decode("utf-8")
        data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MtannoError(f"not a valid TOML class configuration: {exc}", path=spath) from None
    except RecursionError:  # arrays or tables nested thousands deep (tomllib recurses)
        raise MtannoError("not a valid TOML class configuration: nested too deeply",
                          path=spath) from None
    cfg = ClassConfig(path=spath, lines=_key_lines(text))

    def bad(section: str, key: str | None, msg: str) -> MtannoError:
        line = cfg.line_of(section, key) if key is not None else cfg.line_of("", section)
        return MtannoError(msg, path=spath, line=line)

    unknown = sorted(set(data) - set(_SECTIONS))
    if unknown:
        raise bad(unknown[0], None, f"unknown section(s) {', '.join(unknown)} (known: "
                                    f"{', '.join(_SECTIONS)})")
    for name in _SECTIONS:
        if name in data and not isinstance(data[name], dict):
            raise bad(name, None, f"[{name}] must be a table of keys")

    def number(section: str, key: str, value, *, what: str) -> float:
        try:
            return check_tau(value, what=what)
        except MtannoError as exc:
            raise bad(section, key, exc.message) from None

    taus = dict(data.get("tau", {}))
    cfg.default_tau = number("tau", "default", taus.pop("default", DEFAULT_TAU),
                             what="[tau] default")
    cfg.tau = {str(k): number("tau", k, v, what=f"[tau] {k}") for k, v in taus.items()}
    for k, v in data.get("superclasses", {}).items():
        if not isinstance(v, list) or not v or not all(isinstance(c, str) for c in v):
            raise bad("superclasses", k, "[superclasses] must map names to non-empty lists "
                                         "of classes")
    cfg.superclasses = {str(k): [str(c) for c in v]
                        for k, v in data.get("superclasses", {}).items()}
    for k, v in data.get("decoder", {}).items():
        kind = DECODER_KEYS.get(k)
        if kind is None:
            raise bad("decoder", k, f"unknown key {k!r} in [decoder] (known: "
                                    f"{', '.join(DECODER_KEYS)})")
        ok = (isinstance(v, bool) if kind is bool else
              isinstance(v, int) and not isinstance(v, bool) if kind is int else
              isinstance(v, (int, float)) and not isinstance(v, bool))
        if not ok:
            want = {bool: "true or false", int: "an integer", float: "a number"}[kind]
            raise bad("decoder", k, f"[decoder] {k} must be {want}, got {v!r}")
        setattr(cfg, k, kind(v))
    if cfg.slack < 0:
        raise bad("decoder", "slack", f"[decoder] slack must be ≥ 0, got {cfg.slack}")
    if not (cfg.frame_weight >= 0 and math.isfinite(cfg.frame_weight)):
        raise bad("decoder", "frame_weight", "[decoder] frame_weight must be a finite number "
                                             f"≥ 0, got {cfg.frame_weight!r}")
    if not (cfg.segment_cost >= 0 and math.isfinite(cfg.segment_cost)):
        raise bad("decoder", "segment_cost", "[decoder] segment_cost must be a finite number "
                                             f"≥ 0, got {cfg.segment_cost!r}")
    if cfg.delta is not None and not 0 <= cfg.delta < 0.5:
        raise bad("decoder", "delta", f"[decoder] delta must be in [0, 0.5), got {cfg.delta!r}")
    rej = dict(data.get("reject", {}))
    cfg.default_reject = number("reject", "default", rej.pop("default", math.inf),
                                what="[reject] default")
    cfg.reject = {str(k): number("reject", k, v, what=f"[reject] {k}") for k, v in rej.items()}
    for k, v in data.get("templates", {}).items():
        if not isinstance(v, list) or not v or not all(isinstance(f, str) and f for f in v):
            raise bad("templates", k, "[templates] must map classes to non-empty lists of "
                                      "template files")
    cfg.templates = {str(k): list(v) for k, v in data.get("templates", {}).items()}
    for k, v in data.get("tuned_with", {}).items():
        if not (isinstance(v, str) and len(v) == 64
                and all(ch in "0123456789abcdef" for ch in v)):
            raise bad("tuned_with", k, f"[tuned_with] {k} must be the SHA-256 (64 lower-case "
                                       f"hex digits) of the template file tune used, got {v!r}")
    cfg.tuned_with = {str(k): str(v) for k, v in data.get("tuned_with", {}).items()}
    return cfg


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "inf" if v == math.inf else repr(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return json.dumps(v)
    return str(v)


def _toml_key(k: str) -> str:
    return k if k and all(c.isalnum() or c in "_-" for c in k) else json.dumps(k)


def class_config_text(cfg: ClassConfig, *, header: Sequence[str] = (),
                      comments: dict[tuple[str, str], str] | None = None) -> str:
    """The TOML text of a class configuration (what :func:`load_class_config` reads back
    to an equal :class:`ClassConfig`): ``header`` lines as comments on top, and
    ``comments[(section, key)]`` after the key's value."""
    comments = comments or {}
    out = [f"# {h}" if h else "#" for h in header]

    def section(name: str, items: list[tuple[str, object]]) -> None:
        if not items:
            return
        if out:
            out.append("")
        out.append(f"[{name}]")
        for k, v in items:
            note = comments.get((name, k))
            out.append(f"{_toml_key(k)} = {_toml_value(v)}" + (f"  # {note}" if note else ""))

    section("decoder", [("resolve", cfg.resolve), ("refine", cfg.refine), ("slack", cfg.slack),
                        ("frame_weight", cfg.frame_weight)]
            + ([("segment_cost", cfg.segment_cost)] if cfg.segment_cost else [])
            + ([("delta", cfg.delta)] if cfg.delta is not None else []))
    section("tau", [("default", cfg.default_tau), *sorted(cfg.tau.items())])
    if cfg.reject or cfg.default_reject != math.inf:
        section("reject", [("default", cfg.default_reject), *sorted(cfg.reject.items())])
    section("superclasses", sorted(cfg.superclasses.items()))
    section("templates", sorted(cfg.templates.items()))
    section("tuned_with", sorted(cfg.tuned_with.items()))
    return "\n".join(out) + "\n"


def write_class_config(path: str | os.PathLike, cfg: ClassConfig, *,
                       header: Sequence[str] = (),
                       comments: dict[tuple[str, str], str] | None = None) -> None:
    """Write :func:`class_config_text` atomically (:func:`mtanno.output.atomic_path`)."""
    from mtanno.output import atomic_path

    with atomic_path(path) as tmp:
        Path(tmp).write_text(class_config_text(cfg, header=header, comments=comments),
                             encoding="utf-8")


#: What the reference Δ̄ says of start frames that no matcher gives.
_START_OUTSIDE = "a match with Δ ≤ τ starts before its window or after its end frame"


def _reference_in_spans(delta, start, tau: float, max_hits: int | None, out: np.ndarray,
                        spans) -> tuple[np.ndarray, np.ndarray]:
    """The reference Δ̄ written into ``out`` inside ``spans`` only (``out`` elsewhere left
    as it was): for :func:`label_document` without its matrix. Returns the spans checked
    and with touching ones joined (where the row holds Δ̄, for :func:`_row_spans`)."""
    from mtanno.templates.match import check_spans

    first, last = check_spans(*spans, out.shape[0])
    cap = np.iinfo(np.int64).max if max_hits is None else int(max_hits)
    if reference_dbar_kernel(np.ascontiguousarray(delta, dtype=np.float64),
                             np.ascontiguousarray(start, dtype=np.int64), float(check_tau(tau)),
                             cap, out, first, last, True) < 0:
        raise MtannoError(_START_OUTSIDE)
    if len(first) > 1:
        keep = np.ones(len(first), bool)
        keep[1:] = first[1:] > last[:-1] + 1  # a span that touches the one before joins it
        first, last = first[keep], np.append(last[np.flatnonzero(keep)[1:] - 1], last[-1])
    return first, last


def _row_spans(per_row: Sequence[tuple[np.ndarray, np.ndarray] | None], L: int):
    """(firsts, lasts, offsets) of :func:`segments_from_labels`' ``row_spans``: each row's
    spans, or the whole document for a row given as None."""
    whole = (np.zeros(1, np.int64), np.full(1, L - 1, np.int64))
    parts = [whole if sp is None else sp for sp in per_row]
    offsets = np.zeros(len(parts) + 1, np.int64)
    np.cumsum([len(a) for a, _ in parts], out=offsets[1:])
    return (np.concatenate([a for a, _ in parts]), np.concatenate([b for _, b in parts]),
            offsets)


def modified_delta(delta: np.ndarray, start: np.ndarray, *, tau: float = DEFAULT_TAU,
                   variant: str = "reference", max_hits: int | None = None,
                   out: np.ndarray | None = None,
                   spans: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Δ̄ from a distance curve Δ and start frames (algorithms.md §7 step 2; MBS09 §4).

    ``variant="reference"`` (default, what the reference implementation does): repeatedly
    take the smallest remaining Δ(ℓ) ≤ τ (ties: earliest frame), fill the frames of
    [a_ℓ, ℓ] that are still ∞ with Δ(ℓ), and exclude that range from further picks;
    ``max_hits`` caps the picks (the reference used 2000). ``variant="paper"`` (MBS09 as
    written): for every local minimum ℓ of Δ below τ, Δ̄(k) = min(Δ̄(k), Δ(ℓ)) on [a_ℓ, ℓ].
    Frames are 0-based; Δ = ∞ where no match ends. ``out`` (float64, Δ's length) receives
    Δ̄ instead of a new array (a batch reuses one buffer). ``spans``: (firsts, lasts),
    the sorted disjoint frame ranges (0-based inclusive, :func:`merged_spans`) outside
    which Δ is ∞, such as keyframe windows; the reference variant then reads Δ only
    inside them, so a short window costs little in a long document.
    """
    delta = np.ascontiguousarray(delta, dtype=np.float64)
    start = np.ascontiguousarray(start, dtype=np.int64)
    if delta.shape != start.shape or delta.ndim != 1:
        raise MtannoError("delta and start must be 1-D arrays of the same length")
    tau = check_tau(tau)
    if out is None:
        dbar = np.full(delta.shape[0], np.inf)
    else:
        if out.shape != delta.shape or out.dtype != np.float64:
            raise MtannoError("out must be a float64 array of Δ's length")
        dbar = out
        dbar.fill(np.inf)
    if variant == "reference":
        cap = np.iinfo(np.int64).max if max_hits is None else int(max_hits)
        L = delta.shape[0]
        if spans is None:
            first, last = np.zeros(1, np.int64), np.full(1, L - 1, np.int64)
        else:
            from mtanno.templates.match import check_spans

            first, last = check_spans(*spans, L)
        if reference_dbar_kernel(delta, start, float(tau), cap, dbar, first, last) < 0:
            raise MtannoError(_START_OUTSIDE)
        return dbar
    if variant == "paper":
        d = np.where(np.isfinite(delta), delta, np.inf)
        left = np.concatenate(([np.inf], d[:-1]))
        right = np.concatenate((d[1:], [np.inf]))
        minima = np.flatnonzero((d <= tau) & (d < left) & (d <= right))
        for end in minima:
            s = start[end]
            np.minimum(dbar[s:end + 1], d[end], out=dbar[s:end + 1])
        return dbar
    raise MtannoError(f"unknown Δ̄ variant '{variant}' (reference or paper)")


@numba.njit(cache=True)
def _extend(dbar, s, t, lo, hi):
    """Walk outward from [s, t] while Δ̄ does not rise (algorithms.md §7 step 4), inside
    frames lo … hi (where the row holds Δ̄: outside, it would be ∞ and stop the walk)."""
    r = s
    while r > lo and dbar[r - 1] <= dbar[r]:
        r -= 1
    u = t
    while u < hi and dbar[u + 1] <= dbar[u]:
        u += 1
    return r, u


@numba.njit(cache=True)
def _extend_unclaimed(dbar, labels, p, s, t, lo, hi):
    """:func:`_extend` that walks only over frames whose label is none or ``p`` (boundary
    refinement, issue 10: the extension never runs into another class's frames)."""
    r = s
    while r > lo and dbar[r - 1] <= dbar[r] and (labels[r - 1] < 0 or labels[r - 1] == p):
        r -= 1
    u = t
    while u < hi and dbar[u + 1] <= dbar[u] and (labels[u + 1] < 0 or labels[u + 1] == p):
        u += 1
    return r, u


class Annotation(NamedTuple):
    """One output segment: 0-based inclusive frames at 30 Hz (a named tuple: documents of
    hours give thousands, made in a few microseconds each)."""

    doc: str
    start: int
    end: int
    label: str
    cost: float


def label_frames(dbars: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(label index per frame, −1 where every Δ̄ is ∞; Δ_min per frame). Ties → smallest
    class index (algorithms.md §7 step 3)."""
    dmin = dbars.min(axis=0)
    labels = np.argmin(dbars, axis=0).astype(np.int64)
    labels[~np.isfinite(dmin)] = -1
    return labels, dmin


@numba.njit(cache=True)
def _frame_labels(dbars, firsts, lasts, offsets, labels):
    """Each frame's label: the row with the smallest Δ̄ (ties → smaller row), −1 where
    every Δ̄ is ∞. Row p holds Δ̄ only in its spans [firsts[i], lasts[i]], i in
    offsets[p] … offsets[p + 1] − 1 (sorted, disjoint; elsewhere it counts as ∞ and is not
    read). Rows are read in order, a block of frames at a time (contiguous loads instead of
    one load per row and frame)."""
    P, L = dbars.shape
    block = 1024
    best = np.empty(block)
    at = offsets[:-1].copy()  # each row's first span not yet behind the block
    for j0 in range(0, L, block):
        j1 = min(L, j0 + block)
        best[:j1 - j0] = np.inf
        lab = labels[j0:j1]
        lab[:] = -1
        for p in range(P):
            i = at[p]
            while i < offsets[p + 1] and lasts[i] < j0:
                i += 1
            at[p] = i
            while i < offsets[p + 1] and firsts[i] < j1:
                a = max(firsts[i], j0) - j0
                row = dbars[p, j0:j1]
                for j in range(a, min(lasts[i] + 1, j1) - j0):  # selects: it vectorizes
                    v = row[j]
                    b = best[j]
                    t = v < b
                    best[j] = v if t else b
                    lab[j] = p if t else lab[j]
                i += 1


@numba.njit(cache=True, inline="always")
def _span_of(firsts, lo, hi, frame):
    """The index in lo … hi − 1 of the last span starting at or before ``frame``."""
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if firsts[mid] <= frame:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def _label_runs(dbars, firsts, lasts, offsets, extend, rank, out_p, out_s, out_t, out_cost):
    """Segments of a Δ̄ matrix (labels × frames; row p valid in its spans only, as for
    :func:`_frame_labels`): each frame's label is the smallest Δ̄ (ties → smaller label,
    none where all are ∞); maximal runs of one label, extended while Δ̄ of the label does
    not rise (``extend`` 1; 2: only over frames of no other label; 0: not extended),
    merged per label where they overlap, with the smallest Δ̄ inside. Writes (label,
    start, end, cost) sorted by start, end and ``rank`` of the label (the order of the
    label names); returns their number."""
    P, L = dbars.shape
    labels = np.empty(L, np.int64)
    _frame_labels(dbars, firsts, lasts, offsets, labels)
    n = 0
    prev = -2
    s0 = 0
    for j in range(L + 1):
        lab = labels[j] if j < L else -1
        if j == L or lab != prev:
            if j > 0 and prev >= 0:
                s, t = s0, j - 1
                if extend:  # the walk stays inside the row's spans around the run
                    lo = firsts[_span_of(firsts, offsets[prev], offsets[prev + 1], s)]
                    hi = lasts[_span_of(firsts, offsets[prev], offsets[prev + 1], t)]
                    if extend == 2:
                        s, t = _extend_unclaimed(dbars[prev], labels, prev, s, t, lo, hi)
                    else:
                        s, t = _extend(dbars[prev], s, t, lo, hi)
                out_p[n] = prev
                out_s[n] = s
                out_t[n] = t
                n += 1
            prev = lab
            s0 = j
    order = np.argsort(out_p[:n] * (L + 1) + out_s[:n])
    sp = out_p[:n][order]
    ss = out_s[:n][order]
    st = out_t[:n][order]
    m = 0
    for i in range(n):
        if m > 0 and out_p[m - 1] == sp[i] and ss[i] <= out_t[m - 1]:  # overlapping: merge
            if st[i] > out_t[m - 1]:
                out_t[m - 1] = st[i]
        else:
            out_p[m] = sp[i]
            out_s[m] = ss[i]
            out_t[m] = st[i]
            m += 1
    by_rank = np.argsort(rank[out_p[:m]], kind="mergesort")
    key = out_s[:m] * (L + 1) + out_t[:m]
    order = by_rank[np.argsort(key[by_rank], kind="mergesort")]
    sp = out_p[:m][order]
    ss = out_s[:m][order]
    st = out_t[:m][order]
    for i in range(m):
        out_p[i] = sp[i]
        out_s[i] = ss[i]
        out_t[i] = st[i]
        c = np.inf
        for j in range(ss[i], st[i] + 1):
            if dbars[sp[i], j] < c:
                c = dbars[sp[i], j]
        out_cost[i] = c
    return m


def segments_from_labels(doc: str, names: Sequence[str], dbars: np.ndarray, *,
                         extend: bool | str = True, row_spans=None) -> list[Annotation]:
    """Maximal runs of one label, extended (optional) and merged per label (§7 step 4).
    ``extend="unclaimed"`` walks only over frames that no other label has (boundary
    refinement, issue 10). ``row_spans`` (internal, :func:`_row_spans`): (firsts, lasts,
    offsets), the frames where each row holds Δ̄; elsewhere it counts as ∞ and is not read
    (keyframe windows: the rows need not be filled outside them)."""
    dbars = np.ascontiguousarray(dbars, dtype=np.float64)
    L = dbars.shape[1]
    out_p = np.empty(L + 1, np.int64)
    out_s = np.empty(L + 1, np.int64)
    out_t = np.empty(L + 1, np.int64)
    cost = np.empty(L + 1)
    if extend not in (True, False, "unclaimed"):
        raise MtannoError(f"extend must be True, False or 'unclaimed', got {extend!r}")
    rank = np.empty(len(names), np.int64)  # rows sorted by (start, end, label name)
    rank[sorted(range(len(names)), key=lambda i: names[i])] = np.arange(len(names))
    P = dbars.shape[0]
    if row_spans is None:  # every row valid everywhere
        firsts, lasts = np.zeros(P, np.int64), np.full(P, L - 1, np.int64)
        offsets = np.arange(P + 1, dtype=np.int64)
    else:
        firsts, lasts, offsets = row_spans
    m = _label_runs(dbars, firsts, lasts, offsets,
                    2 if extend == "unclaimed" else int(bool(extend)), rank, out_p, out_s,
                    out_t, cost)
    return [Annotation(doc, s, t, names[p], c) for p, s, t, c in
            zip(out_p[:m].tolist(), out_s[:m].tolist(), out_t[:m].tolist(), cost[:m].tolist())]


def single_label_segments(doc: str, names: Sequence[str], dbars: np.ndarray,
                          rows: Sequence[Annotation]) -> list[Annotation]:
    """Resolve overlapping segments into a partition (``annotate --single-label``).

    Every frame covered by one or more of ``rows`` (the segments of one document, possibly
    overlapping after the extension of algorithms.md §7 step 4) keeps the label, among the
    segments covering it, with the smallest Δ̄ there (ties → the smaller label index, as in
    step 3); frames no segment covers stay unlabelled. The result is the maximal runs of
    one label: no two segments share a frame. ``cost`` is the smallest Δ̄ of the label
    inside its run. Frames are 0-based at 30 Hz.
    """
    dbars = np.asarray(dbars, dtype=np.float64)
    P, L = dbars.shape
    index = {n: k for k, n in enumerate(names)}
    cover = np.zeros((P, L), dtype=bool)
    for r in rows:
        cover[index[r.label], r.start:r.end + 1] = True
    # covered frames rank by Δ̄ (∞ after every finite value), uncovered ones never win
    key = np.where(cover, np.nan_to_num(dbars, posinf=np.finfo(np.float64).max), np.inf)
    label = np.argmin(key, axis=0)
    label[~cover.any(axis=0)] = -1
    out: list[Annotation] = []
    change = np.flatnonzero(np.diff(label)) + 1
    for s, e in zip(np.r_[0, change], np.r_[change, L]):
        p = int(label[s])
        if p >= 0:
            out.append(Annotation(doc, int(s), int(e) - 1, names[p],
                                  float(dbars[p, s:e].min())))
    return out


@dataclass
class ClassModel:
    """A class as the annotator needs it: name, quantized template values and weights.

    :meth:`matcher` packs the template for the matching kernel once and keeps it, so a
    batch of documents does not repeat that work per document."""

    name: str
    values: np.ndarray
    weights: np.ndarray
    path: str | None = None
    sha256: str | None = None
    _prepared: dict = field(default_factory=dict, repr=False, compare=False)

    def record(self) -> dict:
        """The provenance record of the class's template: class, file, SHA-256."""
        return {"class": self.name, "path": self.path, "sha256": self.sha256}

    def matcher(self, variant: str = "reference"):
        from mtanno.templates.match import PreparedTemplate

        if variant not in self._prepared:
            self._prepared[variant] = PreparedTemplate(self.values, self.weights,
                                                       variant=variant)
        return self._prepared[variant]

    def column_keys(self) -> frozenset:
        """The template's distinct columns (as bytes), made once: what
        :func:`evidence_covered` compares."""
        if "columns" not in self._prepared:
            V = np.ascontiguousarray(self.values.T)
            self._prepared["columns"] = frozenset(row.tobytes() for row in V)
        return self._prepared["columns"]

    def evidence_columns(self):
        """The template's :class:`mtanno.decode.EvidenceColumns` (frame evidence), made
        once."""
        from mtanno.decode import evidence_columns

        if "evidence" not in self._prepared:
            self._prepared["evidence"] = evidence_columns(self.values)
        return self._prepared["evidence"]


def class_deltas(X: np.ndarray, classes: Sequence[ClassModel], *,
                 windows: Windows | None = None,
                 match_variant: str = "reference") -> list[tuple[np.ndarray, np.ndarray]]:
    """Δ_p and start frames of every class over one document (X: features × frames).

    ``windows`` (from a keyframe stage) restricts a class to candidate windows
    [first, last] (0-based inclusive; clipped to the document, overlapping ones merged; or
    a (firsts, lasts) pair of sorted disjoint arrays, :func:`mtanno.keyframes.class_spans`):
    Δ_p is computed inside each window (windows are matched as separate documents) and is
    ∞ elsewhere (MBS09 §5). Classes without an entry are matched everywhere. The document
    is bit-packed once for all classes.
    """
    from mtanno.templates.match import pack_document

    L = X.shape[1]
    out = []
    packed = pack_document(X, X.shape[0]) if classes else None
    spans = _class_spans(windows, L)
    for c in classes:
        delta, start = np.empty(L), np.empty(L, np.int64)
        _class_delta(X, packed, c, spans.get(c.name), match_variant, delta, start)
        out.append((delta, start))
    return out


def _class_spans(windows: Windows | None, L: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each class's windows merged once (:func:`merged_spans`), for all its templates; a
    (firsts, lasts) pair of arrays (:func:`mtanno.keyframes.class_spans`) is only checked."""
    from mtanno.templates.match import check_spans

    out = {}
    for name, w in (windows or {}).items():
        if isinstance(w, tuple) and len(w) == 2 and all(isinstance(a, np.ndarray) for a in w):
            out[name] = check_spans(w[0], w[1], L)
        else:
            out[name] = merged_spans(w, L)
    return out


def _class_delta(X, packed, c: ClassModel, spans, match_variant, delta, start, *,
                 clear: bool = True) -> None:
    """Δ and starts of one class into ``delta``/``start`` (inside ``spans``, merged
    windows, if not None; outside them ∞ and −1, or, without ``clear``, as they were)."""
    matcher = c.matcher(match_variant)
    if matcher.f != X.shape[0]:
        raise MtannoError(f"document has {X.shape[0]} features but template '{c.name}' "
                          f"{matcher.f}")
    if spans is not None:
        matcher.match_spans(packed, *spans, out=(delta, start), clear=clear)
    else:
        matcher.run(packed, np.array([0, X.shape[1]], dtype=np.int64), out=(delta, start))


def merged_spans(spans, L: int) -> tuple[np.ndarray, np.ndarray]:
    """Windows (first, last frame; 0-based inclusive) clipped to [0, L − 1], sorted,
    overlapping ones merged: (starts, ends), as the matchers take them."""
    arr = np.array(spans, dtype=np.int64).reshape(-1, 2)
    a, b = np.maximum(arr[:, 0], 0), np.minimum(arr[:, 1], L - 1)
    keep = b >= a
    a, b = a[keep], b[keep]
    if a.size == 0:
        return a, b
    order = np.lexsort((b, a))
    a, b = a[order], b[order]
    reach = np.maximum.accumulate(b)  # furthest end so far
    first = np.ones(a.shape[0], dtype=bool)
    first[1:] = a[1:] > reach[:-1]  # a window that starts after every earlier one ended
    last = np.append(first[1:], True)
    return a[first], reach[last]


def evidence_covered(classes: Sequence[ClassModel]) -> set[int]:
    """Indices of the templates whose frame evidence another template of the same class
    already gives: every column of theirs is a column of the other one (a time-scaled copy,
    :mod:`mtanno.tuning.tempo`, or a duplicate), so their evidence — the best column
    anywhere in the template — is never lower, and the class's minimum stays the other's.
    Of templates with the same columns the first is kept."""
    cols = [c.column_keys() for c in classes]
    out = set()
    for i, a in enumerate(classes):
        for j, b in enumerate(classes):
            if j != i and a.name == b.name and a.values.shape[0] == b.values.shape[0] \
                    and cols[i] <= cols[j] and (cols[i] != cols[j] or j < i):
                out.add(i)
                break
    return out


def annotate_document(doc: str, X: np.ndarray, classes: Sequence[ClassModel], *,
                      config: ClassConfig | None = None,
                      windows: Windows | None = None,
                      dbar_variant: str = "reference", match_variant: str = "reference",
                      max_hits: int | None = None, extend: bool = True,
                      single_label: bool = False, packed: np.ndarray | None = None,
                      matrix: bool = True,
                      ) -> tuple[list[Annotation], list[str], np.ndarray | None]:
    """Annotate one document (MBS09 §4–5): returns (segments, label names, Δ̄ matrix).

    Labels are the classes, or the superclasses of ``config`` joining them (classes not in
    a superclass keep their name); Δ̄ of a label is the frame-wise minimum of its classes'.
    Segments of different labels may overlap (the reference output); with
    ``single_label`` overlaps are resolved frame by frame to the label with the smallest
    Δ̄ (:func:`single_label_segments`), so the segments form a partition of the labelled
    frames. Several :class:`ClassModel` of one name (a class with several templates) make
    one label, like a superclass. With ``config.resolve`` the segments come from the
    segment decoder (:func:`label_document`; already a partition) and the matrix holds
    Δ/τ per label instead of Δ̄. ``windows``: candidate windows per class, as
    :func:`class_deltas` takes them (:func:`mtanno.keyframes.class_spans`). ``packed``: X
    already bit-packed (:func:`mtanno.templates.match.pack_document`, as for
    :func:`mtanno.keyframes.class_windows`), to pack it once. ``matrix=False``: no matrix
    (None; :func:`label_document`), which saves filling and reading it outside the windows.
    """
    config = config or ClassConfig()
    if not classes:
        raise MtannoError("no class templates to annotate with")
    from mtanno.templates.match import pack_document

    L = X.shape[1]
    if packed is None:
        packed = pack_document(X, X.shape[0])
    elif np.shape(packed) != (L, (X.shape[0] + 63) // 64) or packed.dtype != np.uint64:
        raise MtannoError(f"packed document must be uint64 ({L} frames × "
                          f"{(X.shape[0] + 63) // 64} words), got {np.shape(packed)}")
    # one Δ buffer for all classes: documents can be hours long
    delta, start = np.empty(L), np.empty(L, np.int64)
    evidence = config.resolve and config.frame_weight > 0

    if evidence:
        from mtanno.decode import EVIDENCE_MARGIN, distinct_frames, row_evidence

        distinct = distinct_frames(packed)  # once for all templates
        covered = evidence_covered(classes)

    spans = _class_spans(windows, L)
    # the reference Δ̄ and the decoder's rows read Δ inside the windows only: the buffer is
    # not cleared outside them
    clear = not config.resolve and dbar_variant != "reference"

    names = [c.name for c in classes]
    rows, own = None, {}
    if config.resolve:  # the only template of a label is matched into the decoder's row
        labels, member_of, count = _label_layout(names, config)
        rows = (np.empty((len(labels), L)), np.empty((len(labels), L), dtype=np.int64))
        for i, n in enumerate(names):
            lab = member_of.get(n, n)
            if count[lab] == 1:
                own[i] = labels.index(lab)

    def matches():
        for i, c in enumerate(classes):
            if i in own:
                k = own[i]
                _class_delta(X, packed, c, spans.get(c.name), match_variant, rows[0][k],
                             rows[1][k], clear=True)
                d, s = None, None
            else:
                _class_delta(X, packed, c, spans.get(c.name), match_variant, delta, start,
                             clear=clear)
                d, s = delta, start
            if not evidence or i in covered:  # covered: its columns are another template's
                yield c.name, d, s, None
                continue
            near = None
            if c.name in spans:  # only where c can be
                first, last = spans[c.name]
                near = merged_spans(np.column_stack((first - EVIDENCE_MARGIN,
                                                     last + EVIDENCE_MARGIN)), L)
            yield c.name, d, s, row_evidence(packed, c.evidence_columns(), spans=near,
                                             distinct=distinct)

    return label_document(doc, names, matches(), L, config=config,
                          dbar_variant=dbar_variant, max_hits=max_hits, extend=extend,
                          single_label=single_label, spans=spans, matrix=matrix, rows=rows)


def _label_layout(names: Sequence[str], config: ClassConfig) -> tuple[list[str], dict, dict]:
    """The labels of templates ``names`` (classes, or the superclasses of ``config``
    joining them) in order of first appearance, the superclass of each member, and the
    number of templates per label."""
    member_of = {m: s for s, ms in config.superclasses.items() for m in ms}
    labels: list[str] = []
    for n in names:
        lab = member_of.get(n, n)
        if lab not in labels:
            labels.append(lab)
    count = {lab: sum(member_of.get(n, n) == lab for n in names) for lab in labels}
    return labels, member_of, count


def label_document(doc: str, names: Sequence[str], matches, n_frames: int, *,
                   config: ClassConfig | None = None, dbar_variant: str = "reference",
                   max_hits: int | None = None, extend: bool = True,
                   single_label: bool = False,
                   spans: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
                   matrix: bool = True,
                   rows: tuple[np.ndarray, np.ndarray] | None = None,
                   ) -> tuple[list[Annotation], list[str], np.ndarray | None]:
    """Segments of one document from its templates' distance functions (algorithms.md
    §7 steps 2–4, or the methods of issue 10 that ``config`` switches on).

    ``names`` is the class of each template, in order; ``matches`` yields, for each
    template in that order, (class, Δ, start frames, frame evidence or None) — Δ and the
    starts as :func:`mtanno.templates.match.match_template` gives them (the arrays may be
    reused buffers: each is read before the next is asked for), the evidence of
    :func:`mtanno.decode.frame_evidence` where ``config.frame_weight`` is used (an
    array, or a :class:`mtanno.decode.RowEvidence`, written into the decoder's buffer
    without a temporary; None for a template whose evidence another of its class gives,
    :func:`evidence_covered`; at least one template per class must give it). ``spans``:
    per class, the merged windows outside which its Δ is ∞ (keyframe preselection), so
    that Δ̄ and the decoder's rows read Δ only inside them.

    * Default (MBS09, the reference implementation): Δ̄ per class with τ (at most the
      class's rejection ceiling ρ), labels, extension (``config.refine``: only over
      frames of no other label).
    * ``config.resolve``: the segment decoder (:func:`mtanno.decode.decode_segments`) on
      Δ/τ per label (templates with Δ > ρ dropped), with ``config.slack`` when
      ``config.refine``, the relative frame evidence weighted by ``config.frame_weight``
      and ``config.segment_cost`` per segment; a segment's cost is Δ at its end.
    * ``single_label`` (default path only; the decoder's segments are a partition
      already): overlaps resolved frame by frame (:func:`single_label_segments`).

    ``matrix=False``: the matrix is not returned (None), and in the default path the Δ̄
    row of a class with ``spans`` is neither filled nor read outside them (the same
    segments, less work where keyframe windows cover little of the document).

    ``rows`` (segment decoder only): the decoder's (labels × frames) Δ and start arrays,
    allocated by the caller (labels as :func:`_label_layout` orders them), so that the
    only template of a label can be matched straight into its row: ``matches`` then
    yields (class, None, None, evidence) for it, the row holding its raw Δ and starts
    (∞ and anything where no match ends), and the decoder applies its τ and ρ (the same
    segments as folding Δ/τ into the row, one pass over the frames less).

    Returns (segments sorted by start, end and label; label names; Δ̄ or Δ/τ matrix).
    """
    config = config or ClassConfig()
    labels, member_of, count = _label_layout(names, config)
    L = int(n_frames)
    P = len(labels)

    def limits(name: str, lab: str) -> tuple[float, float]:
        return (config.tau.get(name, config.tau_for(lab)),
                config.reject.get(name, config.reject_for(lab)))

    if not config.resolve:
        # without the matrix, a row with windows is written and read inside them only
        sparse = (not matrix and not single_label and dbar_variant == "reference"
                  and all(n == 1 for n in count.values()))
        row_spans: list[tuple[np.ndarray, np.ndarray] | None] = [None] * P
        mat = np.empty((P, L))  # rows written by modified_delta; folded rows start at ∞
        for k, lab in enumerate(labels):
            if count[lab] > 1:
                mat[k].fill(np.inf)
        tmp = np.empty(L)
        written = set()
        for name, delta, start, _ in matches:
            lab = member_of.get(name, name)
            tau, rho = limits(name, lab)
            k = labels.index(lab)
            sp = (spans or {}).get(name)
            if sparse and sp is not None:
                row_spans[k] = _reference_in_spans(delta, start, min(tau, rho), max_hits,
                                                   mat[k], sp)
                written.add(k)
                continue
            out = mat[k] if count[lab] == 1 else tmp
            modified_delta(delta, start, tau=min(tau, rho), variant=dbar_variant,
                           max_hits=max_hits, out=out, spans=sp)
            if count[lab] > 1:
                np.minimum(mat[k], tmp, out=mat[k])
            written.add(k)
        for k in set(range(P)) - written:  # a label whose templates gave no Δ
            mat[k].fill(np.inf)
        mode: bool | str = "unclaimed" if (extend and config.refine) else extend
        rows = segments_from_labels(doc, labels, mat, extend=mode,
                                    row_spans=_row_spans(row_spans, L) if sparse else None)
        if single_label:
            rows = single_label_segments(doc, labels, mat, rows)
        return rows, labels, (mat if matrix else None)

    from mtanno.decode import RowEvidence, decode_segments, evidence_sums, fold_label

    # written in full by each label's first template (fold_label(first=True)), so the
    # (labels × frames) arrays of long documents are not filled twice
    if rows is not None:
        mat, starts = rows
        if mat.shape != (P, L) or starts.shape != (P, L):
            raise MtannoError(f"decoder rows must be ({P} labels × {L} frames) arrays")
    else:
        mat = np.empty((P, L))
        starts = np.empty((P, L), dtype=np.int64)
    folded: set[int] = set()
    raw: dict[int, tuple[float, float]] = {}  # label → (τ, ρ) of a row holding raw Δ
    # τ of each label for the cost column; a label whose members have different τ (a
    # superclass) keeps, per frame, the τ of the template that gives the minimum
    member_taus: dict[int, set[float]] = {}
    for n in names:
        lab = member_of.get(n, n)
        member_taus.setdefault(labels.index(lab), set()).add(limits(n, lab)[0])
    label_tau = {k: next(iter(t)) for k, t in member_taus.items() if len(t) == 1}
    tau_rows = {k: np.ones(L) for k in member_taus if k not in label_tau}
    # each label's evidence in ev[:, 1:] (its first template's copied, further ones folded
    # by np.minimum), turned into the decoder's running sums in place
    ev = np.empty((P, L + 1)) if config.frame_weight > 0 else None
    has_evidence: set[int] = set()
    for name, delta, start, evidence in matches:
        lab = member_of.get(name, name)
        tau, rho = limits(name, lab)
        if not tau > 0:
            raise MtannoError(f"tau of {name} must be > 0 for the segment decoder, got {tau!r}",
                              path=config.path)
        k = labels.index(lab)
        span = (spans or {}).get(name)
        if delta is None:  # matched into its row: the decoder applies τ and ρ
            if rows is None or count[lab] != 1:
                raise MtannoError("a template matched into its row must be the only one "
                                  "of its label, in the decoder rows given")
            raw[k] = (float(tau), float(rho))
        elif k in label_tau:
            fold_label(mat[k], starts[k], delta, start, tau=tau, reject=rho,
                       first=k not in folded, spans=span)
        else:
            before = mat[k].copy() if k in folded else np.full(L, np.inf)
            fold_label(mat[k], starts[k], delta, start, tau=tau, reject=rho,
                       first=k not in folded, spans=span)
            tau_rows[k][mat[k] < before] = tau
        folded.add(k)
        if ev is not None and evidence is not None:
            if k in has_evidence:
                frames = evidence.frames() if isinstance(evidence, RowEvidence) else evidence
                np.minimum(ev[k, 1:], frames, out=ev[k, 1:])
            elif isinstance(evidence, RowEvidence):
                evidence.write(ev[k, 1:])
            else:
                ev[k, 1:] = evidence
            has_evidence.add(k)
    if ev is not None and len(has_evidence) < len(member_taus):
        raise MtannoError("frame_weight > 0 needs the frame evidence of a template of every "
                          "class")
    scale, ceiling = np.ones(P), np.full(P, np.inf)
    for k, (tau, rho) in raw.items():
        scale[k], ceiling[k] = tau, rho
    decoded = decode_segments(mat, starts, tau=scale, reject=ceiling,
                              slack=config.slack if config.refine else 0,
                              evidence=None if ev is None else evidence_sums(ev),
                              weight=config.frame_weight, segment_cost=config.segment_cost)
    # cost: Δ at the segment's end, back from Δ/τ where the row holds Δ/τ (to 12 digits:
    # the division's rounding)
    def tau_at(k: int, t: int) -> float:
        if k in raw:
            return 1.0
        return label_tau[k] if k in label_tau else float(tau_rows[k][t])

    out = [Annotation(doc, d.start, d.end, labels[d.label],
                      float(f"{d.cost * tau_at(d.label, d.end):.12g}")) for d in decoded]
    out.sort(key=lambda a: (a.start, a.end, a.label))
    if matrix:  # Δ/τ in every row, as folding gives it
        for k, (tau, rho) in raw.items():
            gone = ~(mat[k] <= rho)
            np.multiply(mat[k], 1.0 / tau, out=mat[k])
            mat[k][gone] = np.inf
    return out, labels, (mat if matrix else None)


ANNOTATION_COLUMNS = ("doc", "start", "end", "label", "cost", "start_native", "end_native")


def annotation_table(rows: Sequence[Annotation], native: dict[str, np.ndarray] | None = None):
    """The annotation table of ``rows`` as a :class:`pyarrow.Table`: doc, start, end
    (1-based inclusive 30 Hz frames), label, cost (null where infinite), and start_native,
    end_native (1-based native frames) when ``native`` maps each document to its feature
    file's native_frame column."""
    pairs = None
    if native is not None:
        pairs = [(int(native[r.doc][r.start]), int(native[r.doc][r.end])) for r in rows]
    return _annotation_arrow(rows, pairs)


def _annotation_arrow(rows: Sequence[Annotation], pairs: Sequence[tuple[int, int]] | None):
    """:func:`annotation_table` with each row's native start and end given (or None)."""
    import pyarrow as pa

    from mtanno.tables import arrow_table

    cols: dict[str, list] = {"doc": [r.doc for r in rows], "start": [r.start + 1 for r in rows],
                             "end": [r.end + 1 for r in rows], "label": [r.label for r in rows],
                             "cost": [r.cost if math.isfinite(r.cost) else None for r in rows]}
    if pairs is not None:
        cols["start_native"] = [a for a, _ in pairs]
        cols["end_native"] = [b for _, b in pairs]
    types = {"doc": pa.string(), "label": pa.string(), "cost": pa.float64()}
    return arrow_table(cols, types)  # (names of non-UTF-8 files written as text)


def write_annotations(path: str | os.PathLike, rows: Sequence[Annotation],
                      native: dict[str, np.ndarray] | None = None, *,
                      provenance: dict | None = None) -> None:
    """Write an annotation table (:func:`annotation_table`) atomically, in the format of
    its suffix (``.csv``, ``.parquet``, ``.jsonl``; ``-`` for standard output), with its
    provenance (:mod:`mtanno.tables`)."""
    from mtanno.tables import write_table

    write_table(path, annotation_table(rows, native), provenance=provenance)


def read_annotations(path: str | os.PathLike) -> list[Annotation]:
    """Read an annotation table written by :func:`write_annotations` (frames → 0-based).

    Every row is checked: a doc and a label, integer frames 1 ≤ start ≤ end, a cost that is
    a number or empty; a bad row is an error naming its line."""
    return read_annotation_table(path)[0]


def read_annotation_table(path: str | os.PathLike) -> tuple[list[Annotation], dict | None]:
    """:func:`read_annotations` and the table's provenance (None when it has none)."""
    from mtanno.tables import read_table

    table = read_table(path, what="annotation table")
    return _annotation_rows(table, native=False)[0], table.provenance


def _annotation_rows(table, *, native: bool = True
                     ) -> tuple[list[Annotation], list[tuple[int, int]] | None]:
    """The checked rows of an annotation table (:func:`read_annotations`) and, with
    ``native`` and when it has the columns start_native and end_native, each row's native
    start and end (checked too; else None)."""
    from mtanno.tables import parse_int, parse_text
    from mtanno.truth import MAX_FRAME

    table.require(["doc", "start", "end", "label"])
    native = native and "start_native" in table.columns and "end_native" in table.columns
    out, pairs = [], []
    for i, row in enumerate(table.rows):
        doc, label = parse_text(table, i, "doc"), parse_text(table, i, "label")
        start = parse_int(table, i, "start", minimum=1, maximum=MAX_FRAME)
        end = parse_int(table, i, "end", minimum=1, maximum=MAX_FRAME)
        if end < start:
            raise table.error(i, f"start {start} is after end {end}")
        cost = row.get("cost")
        if cost is None:
            cost = float("inf")
        else:
            try:
                cost = float(cost)
            except (TypeError, ValueError):
                raise table.error(i, f"cost must be a number, got {cost!r}") from None
            if math.isnan(cost):
                raise table.error(i, "cost is NaN")
        out.append(Annotation(doc, start - 1, end - 1, label, cost))
        if native:
            pairs.append((parse_int(table, i, "start_native", minimum=1),
                          parse_int(table, i, "end_native", minimum=1)))
    return out, (pairs if native else None)


#: Suffixes of the annotation tables a folder given to evaluate or report is searched for.
ANNOTATION_SUFFIXES = (".csv", ".parquet", ".jsonl")


def annotation_files(inputs: Sequence[str | os.PathLike]) -> list[str]:
    """Annotation tables named by ``inputs``: files (and ``-``) as given; a folder (the
    per-document tables of ``annotate --output-dir``) gives every table below it
    (``*.csv``, ``*.parquet``, ``*.jsonl``, sorted; hidden files and folders — locks,
    temporaries — skipped). A folder without tables is an error."""
    out: list[str] = []
    for item in inputs:
        p = Path(item)
        if str(item) != "-" and p.is_dir():
            found = sorted(q for q in p.rglob("*") if q.suffix.lower() in ANNOTATION_SUFFIXES
                           and not any(part.startswith(".") for part in q.relative_to(p).parts)
                           and q.is_file())
            if not found:
                raise MtannoError("no annotation tables (*.csv, *.parquet, *.jsonl) in this "
                                  "folder", path=str(p))
            out.extend(str(q) for q in found)
        else:
            out.append(str(item))
    return out


def merge_annotation_tables(paths: Sequence[str | os.PathLike]):
    """One annotation table (:class:`pyarrow.Table`) of the rows of several, each document
    in one of them only, sorted by document, start, end and label — what ``annotate -o``
    writes for the same documents — and the documents' frame counts their provenances
    record. The native columns are kept when every table has them."""
    from mtanno.tables import read_table

    rows: list[Annotation] = []
    pairs: list[tuple[int, int]] | None = []
    frames: dict[str, int] = {}
    where: dict[str, str] = {}
    for path in paths:
        table = read_table(path, what="annotation table")
        part, native = _annotation_rows(table)
        _claim_documents(where, part, path)
        rows.extend(part)
        pairs = None if pairs is None or native is None else pairs + native
        frames.update(_recorded_frames(table.provenance))
    order = sorted(range(len(rows)), key=lambda i: (rows[i].doc, rows[i].start, rows[i].end,
                                                    rows[i].label))
    return (_annotation_arrow([rows[i] for i in order],
                              None if pairs is None else [pairs[i] for i in order]), frames)


def _claim_documents(where: dict[str, str], rows: Sequence[Annotation], path) -> None:
    """Each document in one table only: else an error naming both files."""
    for d in sorted({a.doc for a in rows}):
        if d in where:
            raise MtannoError(f"document {d!r} is annotated in {where[d]} too; give each "
                              "document's annotation once", path=str(path))
        where[d] = str(path)


def _recorded_frames(prov: dict | None) -> dict[str, int]:
    from mtanno.tables import text

    recorded = (prov or {}).get("documents")
    if not isinstance(recorded, dict):
        return {}
    # named as the rows name them (a non-UTF-8 file name's bytes as \xNN: tables.text)
    return {text(str(k)): int(v) for k, v in recorded.items()
            if isinstance(v, int) and not isinstance(v, bool)}


def read_annotation_tables(paths: Sequence[str | os.PathLike]
                           ) -> tuple[list[Annotation], dict[str, int], list[dict]]:
    """The rows of several annotation tables (a run split over machines, or the
    per-document tables of ``annotate --output-dir``: :func:`annotation_files`), each
    document in one of them only (else an error naming both files); the documents' frame
    counts their provenance records (``annotate`` records them) and the provenances."""
    rows: list[Annotation] = []
    frames: dict[str, int] = {}
    provs: list[dict] = []
    where: dict[str, str] = {}
    for path in paths:
        part, prov = read_annotation_table(path)
        _claim_documents(where, part, path)
        rows.extend(part)
        provs.append(prov or {})
        frames.update(_recorded_frames(prov))
    return rows, frames, provs


# --------------------------------------------------------------------------- batches


def load_class_models(mt_dir: str | os.PathLike, *, delta: float = DEFAULT_DELTA,
                      classes: Sequence[str] = ()) -> tuple[list[ClassModel], FeatureLayout]:
    """The templates of a folder (``*.json``; or one template file;
    :func:`mtanno.templates.model.load_template_folder`), quantized with ``delta``, as
    :class:`ClassModel` records (with their file and SHA-256), and the feature layout
    (set, names, rate) they all share. ``classes`` keeps only those."""
    from mtanno.templates.model import load_template_folder

    return class_models(load_template_folder(mt_dir, classes=classes), delta=delta,
                        where=f"the templates in {mt_dir}")


def class_models(templates: dict, *, delta: float = DEFAULT_DELTA,
                 where: str = "the templates") -> tuple[list[ClassModel], FeatureLayout]:
    """:class:`ClassModel` records of loaded templates (class name →
    :class:`mtanno.templates.model.MotionTemplate`, e.g. from ``load_template_folder`` or
    learned in memory), quantized with ``delta``, and the feature layout they share
    (``where`` names them in messages)."""
    from mtanno.store import FeatureLayout, check_layout, sha256_file
    from mtanno.templates.model import quantize

    if not templates:
        raise MtannoError("no class templates to annotate with")
    models: list[ClassModel] = []
    for mt in templates.values():
        q = quantize(mt, delta)
        model = ClassModel(mt.class_name, q.values, q.weights, path=mt.path,
                           sha256=sha256_file(mt.path) if mt.path else None)
        try:
            model.matcher("reference")  # refuse a template the kernel cannot use, naming it
        except MtannoError as exc:
            raise MtannoError(exc.message, path=mt.path) from None
        models.append(model)
    first = next(iter(templates.values()))
    layout = FeatureLayout(first.feature_set, tuple(first.feature_names), float(first.fps), where)
    for mt in templates.values():  # templates made in memory were not checked by a reader
        check_layout(FeatureLayout(mt.feature_set, tuple(mt.feature_names), float(mt.fps),
                                   f"template {mt.class_name}"), layout, path=mt.path)
    return models, layout


def load_config_templates(config: ClassConfig, layout: FeatureLayout, *,
                          delta: float = DEFAULT_DELTA) -> list[ClassModel]:
    """The further templates of ``config.templates`` (several templates per class) as
    :class:`ClassModel` records, quantized with ``delta``: each file must hold a template
    of the class it is listed under, with the ``layout`` of the other templates."""
    from mtanno.store import FeatureLayout, check_layout, sha256_file
    from mtanno.templates.model import load_template, quantize

    out = []
    for cls, paths in config.template_paths().items():
        line = config.line_of("templates", cls)
        for path in paths:
            if not path.is_file():
                raise MtannoError(f"[templates] {cls}: template file {path} not found",
                                  path=config.path, line=line)
            mt = load_template(path)
            if mt.class_name != cls:
                raise MtannoError(f"[templates] {cls}: {path} holds a template of class "
                                  f"{mt.class_name!r}", path=config.path, line=line)
            check_layout(FeatureLayout(mt.feature_set, tuple(mt.feature_names), float(mt.fps),
                                       f"template {path}"), layout, path=str(path))
            q = quantize(mt, delta)
            model = ClassModel(cls, q.values, q.weights, path=str(path),
                               sha256=sha256_file(path))
            try:
                model.matcher("reference")
            except MtannoError as exc:
                raise MtannoError(exc.message, path=str(path)) from None
            out.append(model)
    return out


@dataclass
class AnnotationBatch:
    """What :func:`annotate_files` did: the segments of every document annotated, each
    document's native frames and frame count, the files read (path, SHA-256) and the
    failures (one message per file that could not be annotated); ``seconds`` is the time
    spent annotating (keyframe search, matching, labels; not reading), summed over the
    documents."""

    rows: list[Annotation] = field(default_factory=list)
    native: dict[str, np.ndarray] = field(default_factory=dict)
    frames: dict[str, int] = field(default_factory=dict)
    files: list[dict] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    seconds: float = 0.0


def _annotate_file(path, models, layout, config, dbar_variant, match_variant, keyframes,
                   single_label=False):
    """One document of a batch: (document, rows, native frames, sha256) or the message of
    its failure (a worker sends it back as text)."""
    import time

    from mtanno.store import check_layout, read_features
    from mtanno.templates.match import pack_document

    try:
        ff = read_features(path, sha256=True)
        check_layout(ff, layout)
        t0 = time.perf_counter()
        windows = None
        packed = pack_document(ff.X, ff.X.shape[0])  # once, for keyframes and templates
        if keyframes:
            from mtanno.keyframes import class_spans

            try:
                windows = class_spans(ff.X, ff.names, keyframes,
                                      feature_set=layout.feature_set, packed=packed)
            except MtannoError as exc:
                raise MtannoError(exc.message, path=ff.path) from None
        rows, _, _ = annotate_document(ff.document, ff.X, models, config=config,
                                       windows=windows, dbar_variant=dbar_variant,
                                       match_variant=match_variant, single_label=single_label,
                                       packed=packed, matrix=False)
    except MtannoError as exc:
        return str(exc)
    return ff.document, rows, ff.native_frames, ff.sha256, time.perf_counter() - t0


def _iter_annotate(paths: Sequence[str | os.PathLike], models: Sequence[ClassModel], *,
                   layout: FeatureLayout, config: ClassConfig, dbar_variant: str,
                   match_variant: str, keyframes, n_jobs: int,
                   single_label: bool, scheduler: str | None):
    """(path, result) for every document of a batch in input order, as the pool delivers
    them: result is ``(document, rows, native frames, sha256, seconds)`` or the message
    of the document's failure."""
    from mtanno.keyframes import KeyframeSet
    from mtanno.workers import make_pool

    if keyframes and not isinstance(keyframes, KeyframeSet):
        # prepared once for the batch; if that fails, each document says why
        try:
            keyframes = KeyframeSet(keyframes, layout.names, feature_set=layout.feature_set)
        except MtannoError:
            pass
    args = [(str(p), models, layout, config, dbar_variant, match_variant, keyframes,
             single_label) for p in paths]
    with make_pool(jobs=n_jobs, scheduler=scheduler, n_tasks=len(args)) as pool:
        for a, result in zip(args, pool.map(_annotate_file, args)):
            yield a[0], result


def annotate_files(paths: Sequence[str | os.PathLike], models: Sequence[ClassModel], *,
                   layout: FeatureLayout, config: ClassConfig | None = None,
                   dbar_variant: str = "reference", match_variant: str = "reference",
                   keyframes=None, n_jobs: int = 1,
                   progress=None, single_label: bool = False,
                   scheduler: str | None = None) -> AnnotationBatch:
    """Annotate feature files (:func:`annotate_document`), in ``n_jobs`` processes
    (:class:`mtanno.workers.WorkerPool`). ``keyframes`` maps class names to keyframe
    queries (:mod:`mtanno.keyframes`), or is a :class:`mtanno.keyframes.KeyframeSet` of
    them: those classes are matched only inside their
    candidate windows in each document (MBS09 §5), the others everywhere. A file that
    cannot be read or does not have the templates' ``layout`` is recorded in ``failed``
    and the batch goes on. ``progress`` is called once per file with its path and its
    failure message (None on success). ``single_label`` resolves overlapping segments
    (:func:`single_label_segments`). ``scheduler``: a dask.distributed cluster runs the
    documents instead of local processes (:class:`mtanno.workers.DaskPool`, same results).
    Rows are sorted by document, start, end and label."""
    batch = AnnotationBatch()
    for path, result in _iter_annotate(paths, models, layout=layout,
                                       config=config or ClassConfig(),
                                       dbar_variant=dbar_variant, match_variant=match_variant,
                                       keyframes=keyframes, n_jobs=n_jobs,
                                       single_label=single_label, scheduler=scheduler):
        if isinstance(result, str):
            batch.failed.append(result)
            if progress:
                progress(path, result)
            continue
        doc, rows, native, digest, seconds = result
        batch.seconds += seconds
        batch.rows.extend(rows)
        batch.native[doc] = native
        batch.frames[doc] = int(native.shape[0])
        batch.files.append({"path": str(path), "sha256": digest})
        if progress:
            progress(path, None)
    batch.rows.sort(key=lambda r: (r.doc, r.start, r.end, r.label))
    return batch


@dataclass
class AnnotationSetup:
    """Everything that shapes an annotation besides its documents, loaded once for a batch
    (:func:`load_annotation_setup`): the class models (the templates of the template folder
    and of the configuration's ``[templates]``, quantized with ``delta``), their feature
    layout, the class configuration, the keyframe queries with their files, and the
    options. :meth:`provenance` is what every annotation table of the batch records, and
    :meth:`annotate` runs :func:`annotate_files` with it."""

    models: list[ClassModel]
    layout: FeatureLayout
    config: ClassConfig = field(default_factory=ClassConfig)
    delta: float = DEFAULT_DELTA
    dbar_variant: str = "reference"
    match_variant: str = "reference"
    keyframes: dict = field(default_factory=dict)
    keyframe_files: list[dict] = field(default_factory=list)
    single_label: bool = False
    config_sha256: str | None = None
    #: classes without a keyframe query (matched everywhere), and queries without a template
    keyframes_missing: list[str] = field(default_factory=list)
    keyframes_extra: list[str] = field(default_factory=list)
    #: the configuration was tuned with other templates (:meth:`ClassConfig.template_warnings`)
    warnings: list[str] = field(default_factory=list)

    @property
    def classes(self) -> list[str]:
        return list(dict.fromkeys(m.name for m in self.models))

    def files(self) -> list[str]:
        """Every file the setup was read from: templates, class configuration, keyframe
        queries."""
        return [*(m.path for m in self.models if m.path), *([self.config.path]
                if self.config.path else []), *(f["path"] for f in self.keyframe_files)]

    def provenance(self, *, inputs=(), documents: dict[str, int] | None = None) -> dict:
        """The provenance of an annotation table of ``inputs`` (feature file records) with
        ``documents`` (frames per document): templates with SHA-256, τ (default and per
        class), superclasses, δ, the configuration's methods, the configuration file and its
        SHA-256, variants, feature set, keyframe files, single label."""
        from mtanno.tables import provenance

        cfg = self.config
        return provenance(inputs=inputs, templates=[m.record() for m in self.models],
                          tau=cfg.default_tau, tau_per_class=cfg.tau or None,
                          superclasses=cfg.superclasses or None, delta=self.delta,
                          methods=cfg.methods() or None,
                          classes=({"path": cfg.path, "sha256": self.config_sha256}
                                   if cfg.path else None),
                          variant=self.dbar_variant, match=self.match_variant,
                          feature_set=self.layout.feature_set,
                          keyframes=self.keyframe_files or None,
                          single_label=self.single_label or None, documents=documents)

    def annotate(self, paths: Sequence[str | os.PathLike], *, n_jobs: int = 1, progress=None,
                 scheduler: str | None = None) -> AnnotationBatch:
        """:func:`annotate_files` of ``paths`` with this setup."""
        return annotate_files(paths, self.models, layout=self.layout, config=self.config,
                              dbar_variant=self.dbar_variant, match_variant=self.match_variant,
                              keyframes=self.keyframes or None, n_jobs=n_jobs,
                              progress=progress, single_label=self.single_label,
                              scheduler=scheduler)

    def iter_annotate(self, paths: Sequence[str | os.PathLike], *, n_jobs: int = 1,
                      scheduler: str | None = None):
        """(path, result) per document in input order as they are done (result: document,
        rows, native frames, SHA-256, seconds; or the failure's message)."""
        return _iter_annotate(paths, self.models, layout=self.layout, config=self.config,
                              dbar_variant=self.dbar_variant, match_variant=self.match_variant,
                              keyframes=self.keyframes or None, n_jobs=n_jobs,
                              single_label=self.single_label, scheduler=scheduler)


def annotation_setup(templates: dict, *, config: ClassConfig | None = None,
                     config_sha256: str | None = None, tau: float | None = None,
                     delta: float | None = None, dbar_variant: str = "reference",
                     match_variant: str = "reference", single_label: bool = False,
                     where: str = "the templates") -> AnnotationSetup:
    """The :class:`AnnotationSetup` of loaded templates (class name →
    :class:`mtanno.templates.model.MotionTemplate`) and a class configuration, applied as
    ``mtanno annotate --classes`` applies it: checked against the templates' classes, its
    δ unless ``delta`` is given (else :data:`DEFAULT_DELTA`), its further templates, and
    :meth:`ClassConfig.template_warnings` in ``warnings``. ``tau`` replaces its default τ
    (on a copy: the object passed is not changed)."""
    from dataclasses import replace

    config = replace(config) if config is not None else ClassConfig()
    if tau is not None:
        config.default_tau = check_tau(tau)
    if delta is None:
        delta = config.delta if config.delta is not None else DEFAULT_DELTA
    models, layout = class_models(templates, delta=delta, where=where)
    config.check([m.name for m in models])
    warnings = config.template_warnings(models)
    models += load_config_templates(config, layout, delta=delta)
    return AnnotationSetup(models, layout, config, delta, dbar_variant, match_variant,
                           single_label=single_label, config_sha256=config_sha256,
                           warnings=warnings)


def load_annotation_setup(mt_dir: str | os.PathLike, *,
                          config_path: str | os.PathLike | None = None,
                          keyframes_dir: str | os.PathLike | None = None,
                          tau: float | None = None, delta: float | None = None,
                          dbar_variant: str = "reference", match_variant: str = "reference",
                          single_label: bool = False) -> AnnotationSetup:
    """Read what ``mtanno annotate`` annotates with: the templates of ``mt_dir``, the
    class configuration (``config_path``; :func:`annotation_setup`), the keyframe queries
    of ``keyframes_dir`` for those classes. ``tau`` replaces the configuration's default
    τ; ``delta`` defaults to the configuration's ``[decoder] delta``, else
    :data:`DEFAULT_DELTA`."""
    from mtanno.store import sha256_file
    from mtanno.templates.model import load_template_folder

    setup = annotation_setup(
        load_template_folder(mt_dir),
        config=load_class_config(config_path) if config_path else None,
        config_sha256=sha256_file(config_path) if config_path else None, tau=tau,
        delta=delta, dbar_variant=dbar_variant, match_variant=match_variant,
        single_label=single_label, where=f"the templates in {mt_dir}")
    if keyframes_dir:
        from mtanno.keyframes import load_class_keyframes

        (setup.keyframes, setup.keyframe_files, setup.keyframes_missing,
         setup.keyframes_extra) = load_class_keyframes(keyframes_dir, setup.classes,
                                                       feature_set=setup.layout.feature_set,
                                                       fps=setup.layout.fps)
    return setup
