#!/usr/bin/env python3
"""Diagnosis, not a result: how far could ``mtanno tune`` get if it could see the
documents it is judged on? (issue 10, ``docs/benchmarks.md``, "ceiling").

For each annotated document set of an experiment run (mocap6: each recording, with the
templates of the other two; Bandai: each held-out style, with the templates of the other
four), tune's own search (:class:`mtanno.tuning.search.Tuner`, every method, the same grids)
is run with the *annotated documents themselves* as its only fold: the templates are
learned from all training examples, exactly like the experiment's, and every parameter is
chosen by its score on the test documents. The figures are therefore an optimistic
ceiling of the method family (per-class τ, rejection, segment decoder, refinement, groups,
time-scaled copies, frame evidence, δ) with these templates and features; they must never
be reported as annotation quality. The search is tune's coordinate search, not an
exhaustive one, so the ceiling is indicative.

It reads the outputs of a finished experiment run (features, truth, fold manifests,
templates) and writes nothing.

    scripts/ceiling_tune.py mocap6 OUT [--unknown-weight W]      (OUT of experiment_mocap6.sh)
    scripts/ceiling_tune.py bandai OUT [--unknown-weight W] [--style S]...
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mtanno.features.store import read_features
from mtanno.templates.store import load_template_folder
from mtanno.templates.tempo import TEMPO_SCALES
from mtanno.templates.training import collect_sources, group_by_class, load_examples
from mtanno.tuning.cv import Fold, _documents, _separate  # the held-out documents tune builds
from mtanno.tuning.run import _learn_params
from mtanno.tuning.score import Counts
from mtanno.tuning.search import DELTA_GRID, GROUPS, Tuner, prepare_fold_class

MOCAP6_DOCS = ("13_29", "13_30", "13_31")
BANDAI_STYLES = ("active", "elderly", "feminine", "masculine", "normal")


def _examples(sources):
    return [e for g in group_by_class(sources).values() for e in load_examples(g)]


def ceiling(name: str, train, held, held_out, mt_dir: Path, unknown_weight: float):
    """Tune's search with the test documents ``held_out`` as the one fold; returns the
    parameters, their evaluation and the tuner (to score other parameters alike)."""
    templates = load_template_folder(mt_dir)
    prepared = {}
    for c, mt in templates.items():
        prepared[(name, c)] = prepare_fold_class(
            c, [e for e in train if e.class_name == c], held_out.X, held_out.offsets,
            deltas=DELTA_GRID, groups=GROUPS, learn=_learn_params(mt), spans=None,
            evidence=True, scales=TEMPO_SCALES)
    tuner = Tuner([Fold(name, train, held_out, held)], prepared, classes=list(templates),
                  unknown_weight=unknown_weight)
    params, ev, _ = tuner.search()
    return params, ev, tuner


def runs(kind: str, out: Path, styles):
    """(name, training examples, test examples, test documents, templates folder)."""
    if kind == "mocap6":
        for test in MOCAP6_DOCS:
            feats = {d: out / "features" / f"{d}.parquet" for d in MOCAP6_DOCS}
            train = _examples(collect_sources(
                truth=out / "truth.csv", training=[feats[d] for d in MOCAP6_DOCS if d != test]))
            held = _examples(collect_sources(truth=out / "truth.csv", training=[feats[test]]))
            yield test, train, held, _documents(held, lambda p: read_features(p).X), \
                out / f"test_{test}" / "mt"
    else:
        for s in styles:
            f = out / "folds" / s
            train = _examples(collect_sources(manifest=f / "train.csv",
                                              features_dir=out / "features"))
            held = _examples(collect_sources(
                truth=f / "truth.csv", training=sorted((out / "features" / s).glob("*.parquet"))))
            yield s, train, held, _separate(held, name=s), f / "mt"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("kind", choices=("mocap6", "bandai"))
    ap.add_argument("out", type=Path, help="output folder of the experiment script")
    ap.add_argument("--unknown-weight", type=float, default=0.02)
    ap.add_argument("--style", action="append", choices=BANDAI_STYLES)
    a = ap.parse_args(argv)
    print(f"ceiling of tune's search on the annotated documents themselves ({a.kind}, "
          f"unknown-class weight {a.unknown_weight:g}) — a diagnosis, not a result")
    print("| test | P1 | R1 | F1 | P2 | R2 | F2 | U (one-fold) | δ | decoder | copies |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    pooled, unk, f1s, f2s = Counts.zero(), [0, 0], [], []
    for name, train, held, ho, mt_dir in runs(a.kind, a.out, a.style or BANDAI_STYLES):
        p, ev, _ = ceiling(name, train, held, ho, mt_dir, a.unknown_weight)
        (p1, r1, f1), (p2, r2, f2) = ev.counts.frame(), ev.counts.segment()
        copies = {c: s for c, s in p.scales.items() if s}
        print(f"| {name} | {p1:.3f} | {r1:.3f} | {f1:.3f} | {p2:.3f} | {r2:.3f} | {f2:.3f} | "
              f"{ev.unknown:.3f} | {p.delta:g} | {'segment' if p.resolve else 'reference'} | "
              f"{copies or '-'} |", flush=True)
        pooled += ev.counts
        unk[0] += ev.unknown_frames[0]
        unk[1] += ev.unknown_frames[1]
        f1s.append(f1)
        f2s.append(f2)
    if a.kind == "mocap6":  # the experiment pools the three recordings
        print(f"pooled: F1 {pooled.frame()[2]:.3f} F2 {pooled.segment()[2]:.3f} "
              f"U {unk[0] / max(unk[1], 1):.3f}")
    else:  # and averages over the styles
        print(f"means over the styles: F1 {sum(f1s) / len(f1s):.3f} F2 {sum(f2s) / len(f2s):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
