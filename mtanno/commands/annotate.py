"""Commands: annotate, evaluate, compose, truth (algorithms.md §7–8)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from mtanno.commands._common import show_progress, user_errors
from mtanno.errors import MtannoError


def feature_paths(inputs) -> list[Path]:
    """Feature files of the inputs (:func:`mtanno.store.feature_files`); two files may not
    name the same document."""
    from mtanno.store import feature_files

    out = feature_files(inputs)
    names: dict[str, Path] = {}
    for p in out:
        if p.stem in names:
            raise MtannoError(f"two feature files name the same document '{p.stem}': "
                              f"{names[p.stem]} and {p}")
        names[p.stem] = p
    return out


def load_class_models(mt_dir: str, *, delta: float, classes: tuple[str, ...] = ()):
    """Templates of a directory (``*.json``), quantized with ``delta``, as ClassModels,
    plus the feature names, feature set and frame rate they all share."""
    from mtanno.annotate import ClassModel
    from mtanno.templates.model import load_template, quantize

    paths = sorted(Path(mt_dir).glob("*.json")) if Path(mt_dir).is_dir() else [Path(mt_dir)]
    if not paths or not paths[0].exists():
        raise MtannoError("no templates (*.json) found", path=mt_dir)
    models, ref = [], None
    for p in paths:
        mt = load_template(p)
        if classes and mt.class_name not in classes:
            continue
        key = (list(mt.feature_names), mt.feature_set, float(mt.fps))
        if ref is None:
            ref = (key, p)
        elif key != ref[0]:
            raise MtannoError(f"template uses other features or frame rate than {ref[1]}",
                              path=str(p))
        q = quantize(mt, delta)
        models.append(ClassModel(mt.class_name, q.values, q.weights))
    if not models:
        raise MtannoError(f"none of the classes {', '.join(classes)} has a template", path=mt_dir)
    return models, ref[0]


def check_features(ff, key) -> None:
    """A feature file must have the templates' features (same names, order, set, rate)."""
    names, feature_set, fps = key
    if list(ff.names) != names or ff.meta.get("feature_set") != feature_set:
        raise MtannoError(f"feature file has feature set '{ff.meta.get('feature_set')}' "
                          f"({len(ff.names)} features) but the templates use "
                          f"'{feature_set}' ({len(names)} features)", path=ff.path)
    if float(ff.meta.get("analysis_fps", 0)) != fps:
        raise MtannoError(f"feature file is at {ff.meta.get('analysis_fps')} Hz but the "
                          f"templates at {fps} Hz", path=ff.path)


def _annotate_one(args):
    path, models, key, config, variant, match_variant, keyframes = args
    from mtanno.annotate import annotate_document
    from mtanno.keyframes import class_windows
    from mtanno.store import read_features

    ff = read_features(path)
    check_features(ff, key)
    windows = None
    if keyframes:
        try:
            windows = class_windows(ff.X, ff.names, keyframes,
                                    feature_set=ff.meta.get("feature_set"))
        except MtannoError as exc:
            raise MtannoError(exc.message, path=ff.path) from None
    rows, _, _ = annotate_document(ff.document, ff.X, models, config=config, windows=windows,
                                   dbar_variant=variant, match_variant=match_variant)
    return ff.document, rows, ff.native_frames


@click.command("annotate")
@click.argument("features", nargs=-1, required=True, metavar="FEATURES...")
@click.option("--mt", "mt_dir", required=True, type=click.Path(exists=True),
              help="Directory of class templates (CLASS.json) from learn-mt.")
@click.option("-o", "--output", "outputs", multiple=True, required=True,
              help="Annotation table, .csv or .parquet (repeat for both).")
@click.option("--keyframes", "kf_dir", type=click.Path(), default=None,
              help="Folder of keyframe queries (CLASS.json from learn-keyframes): a class's "
                   "template is matched only inside its candidate windows (MBS09 §5).")
@click.option("--classes", "config_path", type=click.Path(dir_okay=False), default=None,
              help="Class configuration (TOML): per-class tau, superclasses.")
@click.option("--tau", type=float, default=None,
              help="Threshold tau for every class without its own [default: 0.13].")
@click.option("--delta", type=float, default=0.05, show_default=True,
              help="Quantization delta of the templates.")
@click.option("--variant", type=click.Choice(["reference", "paper"]), default="reference",
              show_default=True, help="Modified-distance variant (algorithms.md §7).")
@click.option("--match", "match_variant", type=click.Choice(["reference", "paper"]),
              default="reference", show_default=True, help="Matching cost variant (§3.4).")
@click.option("-j", "--jobs", default=1, show_default=True, type=click.IntRange(min=1),
              help="Worker processes (documents in parallel).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@user_errors(2)
def annotate_cmd(features, mt_dir, outputs, kf_dir, config_path, tau, delta, variant,
                 match_variant, jobs, quiet):
    """Label every frame of documents with motion classes (MBS09 §4).

    FEATURES are feature files or directories of them. Every template is matched against
    every document; frames get the class whose modified distance is smallest (below tau),
    and the labelled runs are extended. Output rows: doc, start, end (1-based inclusive
    frames at 30 Hz), label, cost, start_native, end_native; rows may overlap.

    With --keyframes, each class that has a keyframe query is first searched for its key
    poses (a fast scan of the features), and its template is matched only inside the
    windows found (widened by the query's extension); classes without a query are matched
    everywhere, with a note.
    """
    from concurrent.futures import ProcessPoolExecutor

    from tqdm import tqdm

    from mtanno.annotate import ClassConfig, load_class_config, write_annotations

    for out in outputs:
        if Path(out).suffix.lower() not in (".csv", ".parquet"):
            raise MtannoError(f"output must end in .csv or .parquet: {out}")
    config = load_class_config(config_path) if config_path else ClassConfig()
    if tau is not None:
        config.default_tau = tau
    models, key = load_class_models(mt_dir, delta=delta)
    keyframes = _load_keyframes(kf_dir, models, key, quiet) if kf_dir else None
    paths = feature_paths(features)
    work = [(p, models, key, config, variant, match_variant, keyframes) for p in paths]
    rows, native, failed = [], {}, 0
    bar = tqdm(total=len(paths), unit="doc", disable=not show_progress(quiet), desc="annotate")

    def collect(result):
        doc, r, nf = result
        rows.extend(r)
        native[doc] = nf
        bar.update(1)

    if jobs > 1 and len(paths) > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(_annotate_one, w) for w in work]
            for fut in futures:
                try:
                    collect(fut.result())
                except MtannoError as exc:
                    failed += 1
                    bar.write(f"mtanno: {exc}", file=sys.stderr)
    else:
        for w in work:
            try:
                collect(_annotate_one(w))
            except MtannoError as exc:
                failed += 1
                bar.write(f"mtanno: {exc}", file=sys.stderr)
    bar.close()
    rows.sort(key=lambda a: (a.doc, a.start, a.end, a.label))
    for out in outputs:
        write_annotations(out, rows, native)
    if not quiet:
        click.echo(f"annotate: {len(paths) - failed} documents, {len(rows)} segments, "
                   f"{len(models)} classes, {failed} failed -> {', '.join(outputs)}", err=True)
    sys.exit(1 if failed else 0)


def _load_keyframes(kf_dir, models, key, quiet):
    """Keyframe queries of the template classes; notes (stderr) for classes without one
    and queries without a template."""
    from mtanno.keyframes import load_keyframe_folder

    queries = load_keyframe_folder(kf_dir)
    names = [m.name for m in models]
    for cls, q in queries.items():
        if q.feature_set != key[1]:
            raise MtannoError(f"keyframes of class '{cls}' are for feature set "
                              f"'{q.feature_set}' but the templates use '{key[1]}'", path=kf_dir)
    missing = [n for n in names if n not in queries]
    extra = sorted(set(queries) - set(names))
    if not quiet and missing:
        click.echo(f"annotate: note: no keyframe query for {', '.join(missing)}; matched "
                   "everywhere", err=True)
    if not quiet and extra:
        click.echo(f"annotate: note: keyframe queries without a template ignored: "
                   f"{', '.join(extra)}", err=True)
    return {n: queries[n] for n in names if n in queries}


@click.command("evaluate")
@click.argument("annotations", type=click.Path(exists=True, dir_okay=False))
@click.option("--truth", "truth_path", required=True, type=click.Path(dir_okay=False),
              help="Ground truth table (doc,start,end,label[,fps]).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), default=None,
              help="Also write the report as JSON.")
@click.option("--all-docs", is_flag=True,
              help="Count truth documents that have no annotation rows (default: only "
                   "documents present in ANNOTATIONS or listed with --doc).")
@click.option("--doc", "docs", multiple=True, help="Evaluate only these documents.")
@user_errors(2)
def evaluate_cmd(annotations, truth_path, json_path, all_docs, docs):
    """Frame- and segment-level precision, recall and F-measure of an annotation table
    against ground truth, overall and per class (MBS09 §7)."""
    from mtanno.annotate import read_annotations
    from mtanno.evaluate import evaluate_annotations
    from mtanno.store import atomic_path
    from mtanno.truth import Segment, read_truth

    truth = read_truth(truth_path)
    out = [Segment(a.doc, a.start + 1, a.end + 1, a.label) for a in read_annotations(annotations)]
    if docs:
        documents = set(docs)
    elif all_docs:
        documents = None
    else:
        documents = {s.doc for s in out} or {s.doc for s in truth}
    report = evaluate_annotations(truth, out, documents=documents)
    click.echo(report.table())
    if json_path:
        with atomic_path(json_path) as tmp:
            tmp.write_text(json.dumps(report.as_dict(), indent=1))


@click.command("evaluate-retrieval")
@click.argument("features", nargs=-1, required=True, metavar="FEATURES...")
@click.option("--mt", "mt_dir", required=True, type=click.Path(exists=True),
              help="Directory of class templates (CLASS.json) or one template.")
@click.option("--truth", "truth_path", required=True, type=click.Path(dir_okay=False),
              help="Ground truth of the documents (doc,start,end,label[,fps]).")
@click.option("--delta", type=float, default=0.1, show_default=True,
              help="Quantization delta of the templates (MR06 retrieval: 0.1).")
@click.option("--max-hits", default=2000, show_default=True, type=click.IntRange(min=1),
              help="Hit cap per class and document.")
@click.option("--class", "classes", multiple=True, help="Only these classes.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), default=None,
              help="Also write the results as JSON.")
@user_errors(2)
def evaluate_retrieval_cmd(features, mt_dir, truth_path, delta, max_hits, classes, json_path):
    """Retrieval quality per class (MR06 Tables 2 and 4): hits |H|, relevant hits |H+|,
    precision and recall for tau = 0.01 … 0.1, top-5/10/20 recall and the separation
    quotient, each template retrieved in all FEATURES documents."""
    from mtanno.evaluate import retrieval_evaluation, retrieval_report
    from mtanno.store import atomic_path, read_features
    from mtanno.truth import read_truth

    models, key = load_class_models(mt_dir, delta=delta, classes=tuple(classes))
    documents = []
    for p in feature_paths(features):
        ff = read_features(p)
        check_features(ff, key)
        documents.append((ff.document, ff.X))
    truth = read_truth(truth_path)
    results = [retrieval_evaluation(m.name, m.values, m.weights, documents, truth,
                                    max_hits=max_hits) for m in models]
    click.echo(retrieval_report(results))
    if json_path:
        with atomic_path(json_path) as tmp:
            tmp.write_text(json.dumps([r.as_dict() for r in results], indent=1))


@click.command("compose")
@click.argument("manifest", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Output directory for the documents, their ASF and truth.csv.")
@click.option("--actor", default=None, help="Use the clips of this actor only.")
@click.option("--split", default=None, help="Use the clips of this split only.")
@click.option("--root", type=click.Path(file_okay=False), default=None,
              help="Folder the manifest's file column is relative to [default: its folder].")
@click.option("--docs", "n_docs", default=10, show_default=True, type=click.IntRange(min=1),
              help="Number of documents.")
@click.option("--clips-per-doc", type=click.IntRange(min=1), default=None,
              help="Clips per document [default: all clips, each once].")
@click.option("--seed", default=0, show_default=True, type=int, help="Random seed.")
@click.option("--pause", default=0, show_default=True, type=click.IntRange(min=0),
              help="Native frames of stillness between clips (unlabelled).")
@click.option("--asf", type=click.Path(exists=True, dir_okay=False), default=None,
              help="ASF skeleton of the clips [default: found beside them].")
@click.option("--in-order", is_flag=True,
              help="Keep the manifest order instead of shuffling (e.g. one document of all "
                   "clips, for retrieval tables).")
@user_errors(2)
def compose_cmd(manifest, out_dir, actor, split, root, n_docs, clips_per_doc, seed, pause, asf,
                in_order):
    """Build long evaluation documents from labelled clips, with their exact ground truth.

    MANIFEST is a CSV with columns file,class[,actor,split] (e.g. the HDM05 clips.csv).
    Clips are drawn in a seeded random order; at every seam the root is turned and moved
    so the next clip starts where and facing how the previous one ended. Writes
    OUT/<ASF stem>_docNN.amc, the ASF, OUT/truth.csv (30 Hz) and OUT/compose.json.
    """
    from mtanno.compose import compose_documents, read_manifest

    clips = read_manifest(manifest, root=root, actor=actor, split=split)
    docs, truth = compose_documents(clips, out_dir, n_docs=n_docs, clips_per_doc=clips_per_doc,
                                    seed=seed, pause=pause, asf=asf, shuffle=not in_order)
    click.echo(f"compose: {len(docs)} documents, {len(truth)} labelled segments -> {out_dir}",
               err=True)


@click.group("truth")
def truth_group():
    """Convert ground-truth labels into mtanno's truth table (doc,start,end,label,fps)."""


@truth_group.command("mocap6")
@click.argument("labels", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False))
@user_errors(2)
def truth_mocap6(labels, output):
    """CMU mocap6 labels.json → truth table at 30 Hz."""
    from mtanno.truth import truth_from_mocap6, write_truth

    segs = truth_from_mocap6(labels)
    write_truth(output, segs)
    click.echo(f"truth: {len(segs)} segments -> {output}", err=True)


COMMANDS = [annotate_cmd, evaluate_cmd, evaluate_retrieval_cmd, compose_cmd, truth_group]
