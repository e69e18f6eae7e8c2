"""``scripts/ceiling_tune.py`` (issue 10 diagnosis): tune's search run on the annotated
documents themselves scores those documents, and scores them at least as well as the
reference annotation (the search starts from its grid)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from mtanno.features.store import read_features
from mtanno.templates.training import collect_sources, group_by_class, load_examples
from mtanno.tuning.cv import _documents
from mtanno.tuning.search import Params

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "ceiling_tune.py"


def _script():
    spec = importlib.util.spec_from_file_location("ceiling_tune", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_ceiling_scores_the_annotated_documents(world):
    mod = _script()
    train = mod._examples(collect_sources(manifest=world.manifest, features_dir=world.feats,
                                          split="train"))
    held = [e for g in group_by_class(collect_sources(truth=world.truth,
                                                      training=world.doc_files)).values()
            for e in load_examples(g)]
    docs = _documents(held, lambda p: read_features(p).X)
    params, ev, tuner = mod.ceiling("docs", train, held, docs, world.mt, 0.02)
    truth_frames = sum(e.X.shape[1] for e in held)
    assert ev.counts.frame_support == truth_frames
    assert ev.counts.seg_support == len(held)
    reference = tuner.evaluate(tuner.with_tau(Params(), 0.13))
    assert ev.J >= reference.J
    assert ev.J == tuner.evaluate(params).J
