#!/usr/bin/env python
"""The cross-rig open-world protocol (issue 35; ``scripts/experiment_crossrig.sh``).

HDM05 templates and tuning; every other archive is *another rig* and holds both motions of
no HDM05 class (foreign) and motions of HDM05 classes (known), so that a rejection that
keys on the rig instead of the motion shows as lost recall:

* ``sets FEAT OUT``: the test sets and backgrounds as folders of links to the feature files
  of ``FEAT`` (``FEAT/cmu02``, ``FEAT/bandai1``, ``FEAT/bandai2/<style>``) and
  ``OUT/sets.json`` (set → rig, kind, the HDM05 label its motions have, files). Known sets:
  CMU 02 trial 03 (run/jog ≈ jog), trial 04 (jump, balance ≈ hop); Bandai set-1 and set-2
  "run" clips (≈ jog), the set-1 kick (≈ kick). Foreign sets: the other CMU 02 trials
  except 06 (bend over, scoop up, rise, lift arm: near grabHighR/depositFloorR, so neither
  foreign nor cleanly known; left out), Bandai set 1 without kick, run and dash (a sprint:
  neither), Bandai set 2 without run. Backgrounds: ``cmu_bg`` (the CMU foreign trials: no
  motion of a known class), ``cmu_all`` (all ten trials, the background of issue 26, for
  the record), ``b1_bg`` (the Bandai set-1 foreign clips). A background is never from the
  archive it is tested on.
* ``measure RUN --sets OUT/sets.json [--mm-truth SEED=TRUTH ...]``: the figures of one tuned
  configuration ``RUN/tuned.toml`` from its annotations ``RUN/<set>.csv`` and
  ``RUN/mm<SEED>.csv`` made with ``--min-confidence 0`` (every row; the configuration's
  minimum is applied here): per set the share of frames labelled and of frames labelled
  with the set's class; on actor mm's documents F1, F2, Acc, Edit, F1@50 (means over the
  seeds); confidence AUROC and ECE (10 bins) on the mm rows alone and with the rows of the
  other rig's sets (foreign rows all wrong, known rows right when they overlap the clip
  with IoU ≥ 0.5 under the set's class). Writes ``RUN/figures.json``, prints one line.
  ``--min M`` applies minimum M instead (``RUN/figures_minM.json``: e.g. 0, every row).
* ``table OUT/runs [--rows NAME...]``: Markdown tables per rig, a row per configuration
  (``NAME, min M`` for the figures at another minimum).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from pathlib import Path

import numpy as np

JOG, HOP, KICK = "jogLeftCircle4StepsRstart", "hopBothLegs1hops", "kickLFront1Reps"
STYLES = ("active", "elderly", "feminine", "masculine", "normal")
_B = re.compile(r"dataset-(?P<set>[12])_(?P<content>[a-z-]+)_(?P<style>[a-z-]+)_(?P<take>\d+)$")


def _define(feat: Path) -> dict[str, dict]:
    """set → {rig, kind, label, files} (module docstring)."""
    sets: dict[str, dict] = {}

    def add(name, rig, kind, label, path):
        sets.setdefault(name, {"rig": rig, "kind": kind, "label": label, "files": []})
        sets[name]["files"].append(str(path))

    for p in sorted((feat / "cmu02").glob("*.parquet")):
        trial = p.stem.split("_")[-1]
        add("cmu_all", "cmu", "background", None, p)
        if trial == "03":
            add("cmu_jog", "cmu", "known", JOG, p)
        elif trial == "04":
            add("cmu_hop", "cmu", "known", HOP, p)
        elif trial != "06":
            add("cmu_foreign", "cmu", "foreign", None, p)
            add("cmu_bg", "cmu", "background", None, p)
    parts = [(p, "1") for p in sorted((feat / "bandai1").glob("*.parquet"))]
    parts += [(p, "2") for s in STYLES for p in sorted((feat / "bandai2" / s).glob("*.parquet"))]
    for p, n in parts:
        m = _B.match(p.stem)
        if m is None:
            raise SystemExit(f"crossrig_tables: unexpected Bandai file {p}")
        c = m["content"]
        if c == "run":
            add(f"b{n}_run", "bandai", "known", JOG, p)
        elif c == "kick":
            add(f"b{n}_kick", "bandai", "known", KICK, p)
        elif c != "dash":
            add(f"b{n}_foreign", "bandai", "foreign", None, p)
            if n == "1":
                add("b1_bg", "bandai", "background", None, p)
    return sets


def make_sets(feat: Path, out: Path) -> int:
    sets = _define(feat)
    out.mkdir(parents=True, exist_ok=True)
    for name, s in sets.items():
        d = out / name
        d.mkdir(exist_ok=True)
        for f in s["files"]:
            link = d / Path(f).name
            if not link.exists():
                os.symlink(os.path.abspath(f), link)
        s["folder"] = str(d)
    (out / "sets.json").write_text(json.dumps(sets, indent=1))
    for name, s in sets.items():
        print(f"{name}: {s['rig']} {s['kind']}{' ' + s['label'] if s['label'] else ''}, "
              f"{len(s['files'])} files")
    return 0


def _min_confidence(toml: Path) -> float:
    from mtanno.annotate import load_class_config

    cfg = load_class_config(str(toml))
    return float(cfg.confidence.min_confidence) if cfg.confidence is not None else 0.0


def _share(rows, frames: dict[str, int], label: str | None) -> tuple[float, float]:
    """(share of frames labelled, share labelled ``label``) of the documents ``frames``."""
    total = sum(frames.values())
    anyc = {d: np.zeros(n, bool) for d, n in frames.items()}
    good = {d: np.zeros(n, bool) for d, n in frames.items()}
    for r in rows:
        anyc[r.doc][r.start:r.end + 1] = True
        if label is not None and r.label == label:
            good[r.doc][r.start:r.end + 1] = True
    hit = sum(int(v.sum()) for v in anyc.values())
    right = sum(int(v.sum()) for v in good.values())
    return (hit / total if total else math.nan), (right / total if total else math.nan)


def measure(run: Path, sets_file: Path, mm: list[str], least: float | None = None) -> int:
    from mtanno.annotate import read_annotation_tables
    from mtanno.evaluation import (
        auroc,
        evaluate_annotations,
        expected_calibration_error,
        rows_right,
    )
    from mtanno.labels.segments import Segment, to_segments
    from mtanno.labels.truth import read_truth

    least_given = least
    sets = json.loads(sets_file.read_text())
    config = run / "tuned.toml"  # none: a peer without confidence, every row kept
    if least is None:
        least = _min_confidence(config) if config.is_file() else 0.0
    out: dict = {"min_confidence": least, "sets": {}, "mm": {}}
    conf_rows: dict[str, tuple[list, list]] = {}  # set → (probabilities, right)
    for name, s in sets.items():
        path = run / f"{name}.csv"
        if not path.is_file():
            continue
        rows, frames, _ = read_annotation_tables([str(path)])
        kept = [r for r in rows if not r.confidence < least]
        labelled, right = _share(kept, frames, s["label"])
        out["sets"][name] = {"rig": s["rig"], "kind": s["kind"], "label": s["label"],
                             "documents": len(frames), "frames": sum(frames.values()),
                             "labelled": labelled, "right": right if s["label"] else None,
                             "rows": len(kept)}
        if s["label"]:
            truth = [Segment(d, 1, n, s["label"]) for d, n in frames.items()]
            ok = rows_right(rows, truth)
        else:
            ok = np.zeros(len(rows), bool)
        conf_rows[name] = ([r.confidence for r in rows], list(map(bool, ok)))
    reports, mm_p, mm_y = [], [], []
    for item in mm:
        seed, truth_path = item.split("=", 1)
        rows, frames, _ = read_annotation_tables([str(run / f"mm{seed}.csv")])
        truth = read_truth(truth_path)
        kept = [r for r in rows if not r.confidence < least]
        rep = evaluate_annotations(truth, to_segments(kept), documents=set(frames),
                                   frames=frames).as_dict()
        reports.append({"F1": rep["frame"]["F"], "F2": rep["segment"]["F"],
                        "Acc": rep["accuracy"], "Edit": rep["edit"], "F1@50": rep["f1_50"]})
        mm_p += [r.confidence for r in rows]
        mm_y += list(map(bool, rows_right(rows, truth)))
    if reports:
        out["mm"] = {k: float(np.mean([r[k] for r in reports])) for k in reports[0]}
        out["mm"]["per_seed"] = reports
        p, y = np.array(mm_p, float), np.array(mm_y, float)
    if reports and config.is_file():
        out["mm"]["auroc"] = auroc(p, y)
        out["mm"]["ece"] = expected_calibration_error(p, y)
        for scope in ("foreign", "all"):
            P, Y = [p], [y]
            for name, (cp, cy) in conf_rows.items():
                if scope == "all" or sets[name]["kind"] == "foreign":
                    P.append(np.array(cp, float))
                    Y.append(np.array(cy, float))
            P, Y = np.concatenate(P), np.concatenate(Y)
            out["mm"][f"auroc_{scope}"] = auroc(P, Y)
            out["mm"][f"ece_{scope}"] = expected_calibration_error(P, Y)
            out["mm"][f"rows_{scope}"] = int(len(P))
    (run / ("figures.json" if least_given is None else f"figures_min{least:g}.json")
     ).write_text(json.dumps(out, indent=1))
    parts = [f"{n} {v['labelled']:.3f}" + (f" ({v['right']:.3f} {v['label'][:4]})"
                                            if v["label"] else "")
             for n, v in out["sets"].items()]
    if out["mm"]:
        m = out["mm"]
        parts.append(f"mm F1 {m['F1']:.3f} F2 {m['F2']:.3f} Acc {m['Acc']:.3f} Edit "
                     f"{m['Edit']:.3f} F1@50 {m['F1@50']:.3f}" + (
                         f"; ECE mm {m['ece']:.3f}, +foreign {m['ece_foreign']:.3f}, +all "
                         f"{m['ece_all']:.3f}" if "ece" in m else ""))
    print(f"min {least:g}: " + ", ".join(parts))
    return 0


def _f(v, digits=3) -> str:
    return "–" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def _pooled(sets: dict, names: list[str]) -> tuple[float, float]:
    """(share labelled, share labelled with the sets' class) over the sets' frames."""
    n = sum(sets[k]["frames"] for k in names)
    lab = sum(sets[k]["labelled"] * sets[k]["frames"] for k in names)
    right = sum((sets[k]["right"] or 0.0) * sets[k]["frames"] for k in names)
    return (lab / n, right / n) if n else (math.nan, math.nan)


def table(runs: Path, names: list[str] | None) -> int:
    """Markdown tables per rig (module docstring): per configuration the share of the
    foreign sets' frames labelled (pooled, then per set), of each known class's frames
    labelled (pooled; in brackets: labelled with that class) and the mm figures."""
    found = {}
    for p in sorted(runs.glob("*/*/figures*.json")):
        name = p.parent.parent.name + p.stem[len("figures"):].replace("_min", ", min ")
        found.setdefault(name, {})[p.parent.name] = json.loads(p.read_text())
    order = names or sorted(found)
    for side, rig, title in (("bg_cmu", "bandai", "Bandai (background: CMU 02)"),
                             ("bg_bandai", "cmu", "CMU 02 (background: Bandai set 1)")):
        lines, cols = [], None
        for name in order:
            fig = found.get(name, {}).get(side)
            if fig is None:
                continue
            sets = {k: v for k, v in fig["sets"].items() if v["rig"] == rig}
            foreign = [k for k, v in sets.items() if v["kind"] == "foreign"]
            labels = sorted({v["label"] for v in sets.values() if v["label"]})
            if cols is None:
                cols = (foreign, labels)
                head = (["configuration", "min", "foreign, all"]
                        + [f"{k}" for k in foreign] * (len(foreign) > 1)
                        + [f"≈ {lab[:4]} (as {lab[:4]})" for lab in labels]
                        + ["mm F1", "mm F2", "mm Acc", "mm Edit", "mm F1@50", "ECE mm",
                           "ECE mm+foreign"])
                lines.append("| " + " | ".join(head) + " |")
                lines.append("|" + "---|" * len(head))
            cells = [name, f"{fig['min_confidence']:g}" if fig["min_confidence"] else "–",
                     _f(_pooled(sets, cols[0])[0])]
            if len(cols[0]) > 1:
                cells += [_f(sets[k]["labelled"]) for k in cols[0]]
            for lab in cols[1]:
                a, b = _pooled(sets, [k for k, v in sets.items() if v["label"] == lab])
                cells.append(f"{_f(a)} ({_f(b)})")
            m = fig.get("mm") or {}
            cells += [_f(m.get(k)) for k in ("F1", "F2", "Acc", "Edit", "F1@50", "ece",
                                              "ece_foreign")]
            lines.append("| " + " | ".join(cells) + " |")
        if lines:
            print(f"\n{title}\n")
            print("\n".join(lines))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    a = sub.add_parser("sets")
    a.add_argument("feat", type=Path)
    a.add_argument("out", type=Path)
    b = sub.add_parser("measure")
    b.add_argument("run", type=Path)
    b.add_argument("--sets", type=Path, required=True)
    b.add_argument("--mm", action="append", default=[], metavar="SEED=TRUTH")
    b.add_argument("--min", type=float, default=None,
                   help="this minimum confidence instead of the configuration's (writes "
                        "RUN/figures_minM.json)")
    c = sub.add_parser("table")
    c.add_argument("runs", type=Path)
    c.add_argument("--rows", nargs="*")
    args = ap.parse_args(argv)
    if args.what == "sets":
        return make_sets(args.feat, args.out)
    if args.what == "measure":
        return measure(args.run, args.sets, args.mm, args.min)
    return table(args.runs, args.rows)


if __name__ == "__main__":
    sys.exit(main())
