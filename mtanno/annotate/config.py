"""Class configurations: per-class τ, superclasses and the tuned annotation methods
([MBS09] §4 thresholds; the issue-10 methods of ``docs/annotation.md``), read from and
written to TOML (``mtanno annotate --classes``, ``mtanno tune``).

:data:`~mtanno.templates.params.ANNOTATION_TAU` is the τ of every class a configuration
does not name; :func:`~mtanno.templates.params.check_tau` checks every τ it holds.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from mtanno.confidence.model import ConfidenceModel, is_sha256
from mtanno.errors import MtannoError, read_toml
from mtanno.templates.params import ANNOTATION_TAU, check_tau

if TYPE_CHECKING:
    from mtanno.annotate.label import ClassModel

__all__ = ["CONFIG_FILE", "DECODER_KEYS", "INPUT_KEYS", "ClassConfig", "class_config_text",
           "config_file", "feature_inputs", "load_class_config", "write_class_config"]

#: The configuration's file in a configuration folder (``tune -o DIR/``, issue 34): the
#: folder holds it, its extra templates (``templates/``) and its verification bank, named
#: relative to it, so it moves and is renamed as one.
CONFIG_FILE = "classes.toml"




@dataclass
class ClassConfig:
    """Per-class thresholds, superclasses and the annotation methods of issue 10 (a TOML
    file, see ``docs/annotation.md``; ``mtanno tune`` writes one).

    ``tau`` maps class (or superclass) names to τ; ``superclasses`` maps a superclass
    name to the classes it joins (its Δ̄ is the frame-wise minimum over them). The methods,
    all off by default ([MBS09] as the reference implementation runs it):

    * ``resolve`` — overlap resolution: the segment decoder (:mod:`mtanno.annotate.decode`) picks
      one least-cost partition into matches instead of Δ̄ labels and extension;
    * ``refine`` — boundary refinement: with ``resolve`` a segment may start up to
      ``slack`` frames from its match's start; without, the extension of docs/method.md
      §7 step 4 walks only over frames no other class labels;
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
    to ``annotate`` are other ones. ``background``: the background motions tune saw
    (``tune --background``; file → SHA-256), for the record.

    ``confidence`` (issue 26; written by ``mtanno tune``): the ``[confidence]`` table as a
    :class:`mtanno.confidence.model.ConfidenceModel` (evidence, calibrator, minimum
    confidence, verification bank); None: the uncalibrated confidence.
    """

    default_tau: float = ANNOTATION_TAU
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
    background: dict[str, str] = field(default_factory=dict)
    confidence: ConfidenceModel | None = None
    #: ``[inputs]`` (issue 34; written by tune): what the documents' feature files need —
    #: ``poses`` (a pose block: ``mtanno features --poses``) and ``feature_set``; None:
    #: not said
    poses: bool | None = None
    feature_set: str | None = None
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

    @property
    def needs_poses(self) -> bool:
        """Whether the documents' feature files need poses: ``[inputs] poses``, or a
        verification bank of poses (a configuration written before ``[inputs]``)."""
        bank = getattr(self.confidence, "bank", None)
        return bool(self.poses) or getattr(bank, "representation", None) == "poses"

    def template_paths(self) -> dict[str, list[Path]]:
        """``[templates]`` as paths (relative ones taken from the configuration's folder)."""
        base = Path(self.path).parent if self.path else Path(".")
        return {c: [base / f for f in files] for c, files in self.templates.items()}


#: Keys of the ``[decoder]`` section of a class configuration and their types.
DECODER_KEYS = {"resolve": bool, "refine": bool, "slack": int, "frame_weight": float,
                "segment_cost": float, "delta": float}


#: Keys of the ``[inputs]`` section and their types.
INPUT_KEYS = {"poses": bool, "feature_set": str}

_SECTIONS = ("tau", "superclasses", "decoder", "reject", "templates", "tuned_with",
             "background", "confidence", "inputs")


def config_file(path: str | os.PathLike) -> Path:
    """The file of a class configuration given as ``path``: the file itself, or the
    :data:`CONFIG_FILE` of a configuration folder (``tune -o DIR/``)."""
    p = Path(path)
    if p.is_dir():
        p = p / CONFIG_FILE
        if not p.is_file():
            raise MtannoError(f"not a class configuration folder: no {CONFIG_FILE} in it "
                              "(mtanno tune -o DIR/ writes one)", path=str(path))
    return p


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


def feature_inputs(path: str | os.PathLike, *, feature_set: str, poses: bool,
                   given: bool = False) -> tuple[str, bool]:
    """(feature set, poses) that ``mtanno features --classes CONFIG`` computes: what the
    configuration's ``[inputs]`` need (issue 34), else ``feature_set`` and ``poses`` as
    given. ``given``: ``feature_set`` was chosen by the user, so one that differs from the
    configuration's is an error rather than replaced."""
    cfg = load_class_config(path)
    wanted = {"mr06-ak40": "ak40"}.get(cfg.feature_set, cfg.feature_set)  # the option's name
    if wanted is not None and wanted != feature_set:
        if given:
            raise MtannoError(f"{{feature_set}} {feature_set} is not the feature set of the "
                              f"class configuration ({wanted}; its [inputs])",
                              path=cfg.path, options=("feature_set",))
        feature_set = wanted
    return feature_set, poses or cfg.needs_poses


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
    path = config_file(path)
    spath = str(path)
    data, text = read_toml(path, what="class configuration")
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
    cfg.default_tau = number("tau", "default", taus.pop("default", ANNOTATION_TAU),
                             what="[tau] default")
    cfg.tau = {str(k): number("tau", k, v, what=f"[tau] {k}") for k, v in taus.items()}
    for k, v in data.get("superclasses", {}).items():
        if not isinstance(v, list) or not v or not all(isinstance(c, str) for c in v):
            raise bad("superclasses", k, "[superclasses] must map names to non-empty lists "
                                         "of classes")
    cfg.superclasses = {str(k): [str(c) for c in v]
                        for k, v in data.get("superclasses", {}).items()}
    _read_decoder(cfg, data.get("decoder", {}), bad)
    rej = dict(data.get("reject", {}))
    cfg.default_reject = number("reject", "default", rej.pop("default", math.inf),
                                what="[reject] default")
    cfg.reject = {str(k): number("reject", k, v, what=f"[reject] {k}") for k, v in rej.items()}
    _read_templates(cfg, data, bad)
    _read_confidence(cfg, data, bad)
    _read_inputs(cfg, data.get("inputs", {}), bad)
    return cfg


def _read_inputs(cfg: ClassConfig, section: dict, bad) -> None:
    """``[inputs]`` (:data:`INPUT_KEYS`) into ``cfg``."""
    for k, v in section.items():
        kind = INPUT_KEYS.get(k)
        if kind is None:
            raise bad("inputs", k, f"unknown key {k!r} in [inputs] (known: "
                                   f"{', '.join(INPUT_KEYS)})")
        if not isinstance(v, kind) or (kind is str and not v):
            want = "true or false" if kind is bool else "a feature set name"
            raise bad("inputs", k, f"[inputs] {k} must be {want}, got {v!r}")
        setattr(cfg, k, v)


def _read_confidence(cfg: ClassConfig, data: dict, bad) -> None:
    """``[background]`` (file → SHA-256) and ``[confidence]``
    (:meth:`ConfidenceModel.from_table`) into ``cfg``."""
    for k, v in data.get("background", {}).items():
        if not is_sha256(v):
            raise bad("background", k, f"[background] {k} must be the SHA-256 (64 lower-case "
                                       f"hex digits) of the background file, got {v!r}")
    cfg.background = {str(k): str(v) for k, v in data.get("background", {}).items()}
    if data.get("confidence"):
        cfg.confidence = ConfidenceModel.from_table(data["confidence"], path=cfg.path,
                                                    line_of=cfg.line_of)


def _read_decoder(cfg: ClassConfig, section: dict, bad) -> None:
    """The ``[decoder]`` keys into ``cfg``, each of its :data:`DECODER_KEYS` type and range
    (``bad(section, key, message)`` makes the error naming the line)."""
    for k, v in section.items():
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


def _read_templates(cfg: ClassConfig, data: dict, bad) -> None:
    """``[templates]`` (class → further template files) and ``[tuned_with]`` (class →
    SHA-256) into ``cfg``."""
    for k, v in data.get("templates", {}).items():
        if not isinstance(v, list) or not v or not all(isinstance(f, str) and f for f in v):
            raise bad("templates", k, "[templates] must map classes to non-empty lists of "
                                      "template files")
    cfg.templates = {str(k): list(v) for k, v in data.get("templates", {}).items()}
    for k, v in data.get("tuned_with", {}).items():
        if not is_sha256(v):
            raise bad("tuned_with", k, f"[tuned_with] {k} must be the SHA-256 (64 lower-case "
                                       f"hex digits) of the template file tune used, got {v!r}")
    cfg.tuned_with = {str(k): str(v) for k, v in data.get("tuned_with", {}).items()}


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
    section("background", sorted(cfg.background.items()))
    section("inputs", [(k, getattr(cfg, k)) for k in INPUT_KEYS if getattr(cfg, k) is not None])

    def tables(name: str, table: dict) -> None:  # nested tables as [a.b] sections
        section(name, [(k, v) for k, v in table.items() if not isinstance(v, dict)])
        for k, v in table.items():
            if isinstance(v, dict):
                tables(f"{name}.{_toml_key(k)}", v)

    if cfg.confidence is not None:
        tables("confidence", cfg.confidence.to_table())
    return "\n".join(out) + "\n"


def write_class_config(path: str | os.PathLike, cfg: ClassConfig, *,
                       header: Sequence[str] = (),
                       comments: dict[tuple[str, str], str] | None = None) -> None:
    """Write :func:`class_config_text` atomically (:func:`mtanno.util.output.atomic_path`)."""
    from mtanno.util.output import atomic_path

    with atomic_path(path) as tmp:
        Path(tmp).write_text(class_config_text(cfg, header=header, comments=comments),
                             encoding="utf-8")
