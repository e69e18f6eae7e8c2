"""The tuned configuration as files (``mtanno tune -o``): the TOML configuration with the
cross-validated scores as comments, its extra templates and its verification bank.

Two layouts (issue 34):

* a **configuration folder** — ``tune -o DIR/`` (any output not ending in ``.toml``):
  ``DIR/classes.toml``, ``DIR/templates/CLASS.K.json`` and ``DIR/verify.parquet``, named
  relative to the configuration, so that the folder is moved, copied and renamed as one;
  ``annotate --classes DIR`` reads it;
* the configuration file ``CONFIG.toml`` with ``CONFIG.templates/`` and
  ``CONFIG.verify.parquet`` beside it (the layout before; still written for a ``.toml``
  output, and read wherever it lies).

Either way the configuration records what the documents' feature files need
(``[inputs]``: poses, feature set), which ``features --classes`` and the cron recipe follow.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mtanno._version import __version__
from mtanno.annotate import ClassConfig, class_config_text
from mtanno.annotate.config import CONFIG_FILE
from mtanno.errors import MtannoError
from mtanno.templates.params import ANNOTATION_TAU
from mtanno.tuning.search import Evaluation

__all__ = ["BANK_FILE", "FRAMES_FILE", "TEMPLATES_FOLDER", "bank_path_of", "check_tuned_output",
           "frame_bank_path_of", "is_config_folder", "template_folder_of", "tuned_paths",
           "write_tuned"]

#: The extra templates' folder and the verification bank of a configuration folder.
TEMPLATES_FOLDER = "templates"
BANK_FILE = "verify.parquet"
#: The frame classifier's bank of a configuration folder (issue 35; only with evidence
#: ``classifier``).
FRAMES_FILE = "frames.parquet"


def is_config_folder(output: str | os.PathLike) -> bool:
    """Whether ``tune -o output`` writes a configuration folder: a name ending in ``/``, an
    existing folder, or any name not ending in ``.toml``."""
    s = str(output)
    return s.endswith(("/", os.sep)) or Path(output).is_dir() or \
        Path(output).suffix.lower() != ".toml"


def tuned_paths(output: str | os.PathLike) -> tuple[Path, Path, Path]:
    """(configuration file, extra templates' folder, verification bank) of ``tune -o
    output`` (module docstring)."""
    p = Path(output)
    if is_config_folder(output):
        return p / CONFIG_FILE, p / TEMPLATES_FOLDER, p / BANK_FILE
    return p, p.with_name(p.stem + ".templates"), p.with_name(p.stem + ".verify.parquet")


def check_tuned_output(output: str | os.PathLike) -> None:
    """Refuse, before any work, a configuration folder that is an existing folder of
    other things (tune replaces what it wrote there, never a folder it did not write)."""
    p = Path(output)
    if is_config_folder(output) and p.is_dir() and not (p / CONFIG_FILE).is_file() \
            and any(p.iterdir()):
        raise MtannoError(f"is a folder of other files, not a class configuration folder (no "
                          f"{CONFIG_FILE}); name a new folder for tune's output",
                          path=str(output))
    if p.exists() and not p.is_dir() and is_config_folder(output):
        raise MtannoError("is a file: a configuration folder goes there (or name "
                          "CONFIG.toml for a configuration file)", path=str(output))


def template_folder_of(output: str | os.PathLike) -> Path:
    """Where :func:`write_tuned` puts a configuration's extra templates:
    ``DIR/templates/``, or ``CONFIG.templates/`` beside ``CONFIG.toml``."""
    return tuned_paths(output)[1]


def bank_path_of(output: str | os.PathLike) -> Path:
    """Where :func:`write_tuned` puts a configuration's verification bank:
    ``DIR/verify.parquet``, or ``CONFIG.verify.parquet`` beside ``CONFIG.toml``."""
    return tuned_paths(output)[2]


def frame_bank_path_of(output: str | os.PathLike) -> Path:
    """Where :func:`write_tuned` puts a configuration's frame classifier bank (when its
    confidence uses it): ``DIR/frames.parquet``, or ``CONFIG.frames.parquet`` beside
    ``CONFIG.toml``."""
    p = Path(output)
    if is_config_folder(output):
        return p / FRAMES_FILE
    return p.with_name(p.stem + ".frames.parquet")


def _confidence_section(cfg: ClassConfig, result, path: Path, bpath: Path,
                        fpath_of: str | os.PathLike) -> list[str]:
    """``[confidence]`` and ``[background]`` of the configuration ``path`` (the bank written
    to ``bpath``, beside it; the frame classifier's bank to :func:`frame_bank_path_of`
    ``(fpath_of)``) and header lines on how well the confidence did out of fold."""
    from mtanno.confidence.model import ConfidenceModel
    from mtanno.confidence.verify import write_bank
    from mtanno.evaluation.calibration import auroc, expected_calibration_error
    from mtanno.util.provenance import sha256_file

    fit = result.confidence
    cfg.background = {r["path"]: r["sha256"] for r in result.background}
    if fit is None:
        return []
    bank_file = sha = frames_file = frames_sha = None
    if result.bank is not None:
        write_bank(bpath, result.bank)
        bank_file, sha = bpath.name, sha256_file(bpath)
    if result.frame_bank is not None:
        from mtanno.confidence.frames import write_frame_bank

        fpath = frame_bank_path_of(fpath_of)
        write_frame_bank(fpath, result.frame_bank)
        frames_file, frames_sha = fpath.name, sha256_file(fpath)
    cfg.confidence = ConfidenceModel(tuple(fit.evidence), fit.calibrator, fit.min_confidence,
                                     bank_file, sha, str(path.parent),
                                     tuple(fit.invariance) if bank_file else (),
                                     frames_file=frames_file, frames_sha256=frames_sha)
    kinds = np.array(fit.kinds)
    blind = f" blind to {', '.join(fit.invariance)}" if fit.invariance else ""
    lines = [f"confidence ({', '.join(fit.evidence)}; verified by "
             f"{fit.representation or 'nothing'}{blind}), out of fold on {len(fit.right)} held-out "
             f"segments ({int((kinds == 'known').sum())} of known classes, "
             f"{int((kinds == 'unknown').sum())} over a class left out, "
             f"{int((kinds == 'background').sum())} on background): AUROC "
             f"{auroc(fit.oof, fit.right):.3f}, ECE {expected_calibration_error(fit.oof, fit.right):.3f}"]
    lines += [f"  min confidence {t['min_confidence']:g}: F1 {t['F1']:.3f} F2 {t['F2']:.3f} "
              f"unknown-class rate {t['U']:.3f} background labelled {t['background']:.3f}"
              for t in fit.table]
    return lines


def _write_templates(folder: Path, extra: dict, *, whole: bool) -> dict[str, list[str]]:
    """The extra templates as ``folder/CLASS.K.json``; returns ``[templates]`` (the files
    relative to the configuration's folder). With ``whole`` (a configuration folder's
    ``templates/``) the folder is replaced as one: written beside, then swapped in, so
    that no template of an earlier run is left behind."""
    from mtanno.templates.store import save_template
    from mtanno.util.output import make_folder

    target = folder.with_name(f".{folder.name}.new-{os.getpid()}") if whole else folder
    if whole:
        shutil.rmtree(target, ignore_errors=True)
    out: dict[str, list[str]] = {}
    if extra or not whole:
        make_folder(target)
    for c, mts in sorted(extra.items()):
        out[c] = []
        for i, mt in enumerate(mts, 1):
            save_template(target / f"{c}.{i}.json", mt)
            out[c].append(f"{folder.name}/{c}.{i}.json")
    if whole:
        old = folder.with_name(f".{folder.name}.old-{os.getpid()}")
        if folder.exists():
            os.replace(folder, old)
        if extra:
            os.replace(target, folder)
        shutil.rmtree(old, ignore_errors=True)
    return out


def _fmt(ev: Evaluation) -> str:
    p1, r1, f1 = ev.counts.frame()
    p2, r2, f2 = ev.counts.segment()
    return (f"P1 {p1:.3f} R1 {r1:.3f} F1 {f1:.3f}, P2 {p2:.3f} R2 {r2:.3f} F2 {f2:.3f}, "
            f"unknown-class rate {ev.unknown:.3f}")


def write_tuned(output: str | os.PathLike, result, *,
                command: Sequence[str] = ()) -> ClassConfig:
    """Write the tuned class configuration (TOML, cross-validated scores as comments), its
    extra templates and its verification bank as :func:`tuned_paths` ``(output)`` names
    them: a configuration folder, or ``CONFIG.toml`` with its side files (module
    docstring); returns the configuration as written. ``result``: a
    :class:`mtanno.tuning.run.TuneResult`."""
    from mtanno.util.output import atomic_path, make_folder

    check_tuned_output(output)
    path, folder, bpath = tuned_paths(output)
    if is_config_folder(output):
        make_folder(output)
    cfg = result.params.config()
    cfg.path = str(path)
    cfg.tuned_with = dict(result.template_sha256)
    cfg.poses = result.bank is not None and result.bank.representation == "poses"
    cfg.feature_set = result.feature_set
    if result.extra_templates or (is_config_folder(output) and folder.exists()):
        cfg.templates = _write_templates(folder, result.extra_templates,
                                         whole=is_config_folder(output))
    ev = result.evaluation
    header = [
        f"class configuration written by mtanno {__version__} tune "
        f"({' '.join(command) if command else 'API'})",
        f"seed {result.seed}; methods: {', '.join(result.methods) or 'none'}; held-out "
        f"documents: {result.documents}; unknown-class weight {result.unknown_weight:g}; "
        + (f"templates learned from at most {result.max_examples} examples each"
           if result.max_examples else "templates learned from all examples"),
        "folds (held-out performer: examples): "
        + ", ".join(f"{k}: {v}" for k, v in result.folds.items()),
        f"cross-validated, tuned:    {_fmt(ev)}",
        f"cross-validated, reference (tau {ANNOTATION_TAU}, no methods): {_fmt(result.reference)}",
        "search:",
        *(f"  {s}" for s in result.steps),
        *_confidence_section(cfg, result, path, bpath, output),
        "the training inputs this file was tuned on are listed at its end",
    ]
    comments = {}
    unscored = set(result.not_validated)
    for c in result.classes:
        pc = ev.per_class.get(c)
        hit, n = ev.per_class_unknown.get(c, (0, 0))
        if c in unscored:
            note = "not cross-validated (no fold has both its template and held-out examples)"
        else:
            note = (f"CV F1 {pc.frame()[2]:.3f} ({pc.frame_support} frames), F2 "
                    f"{pc.segment()[2]:.3f} ({pc.seg_support} segments)")
        if n:
            note += f", unknown-class rate {hit / n:.3f}"
        if c in cfg.tau:
            comments[("tau", c)] = note
        elif c in cfg.reject:
            comments[("reject", c)] = note
        else:
            comments[("classes", c)] = note
    text = class_config_text(cfg, header=header, comments=comments)
    plain = [c for c in result.classes if ("classes", c) in comments and comments[("classes", c)]]
    if plain:
        text += "\n# cross-validated scores of the classes at the default tau:\n" + "".join(
            f"#   {c}: {comments[('classes', c)]}\n" for c in plain)
    text += f"\n# training inputs ({len(result.inputs)} files; SHA-256, path):\n" + "".join(
        f"#   {i['sha256']}  {i['path']}\n" for i in result.inputs)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return cfg
