"""``mtanno features`` (mocap files to Parquet feature files) and ``mtanno info`` (what a
motion file or a feature file holds).

Exit codes: 0 success, 1 some files failed (the others were written), 2 usage error or bad
input, 3 output folder locked by another run, 130 interrupted.
"""

from __future__ import annotations

import sys

import click

from mtanno.commands._common import (
    inside_input_option,
    scheduler_option,
    show_progress,
    user_errors,
    wait_option,
    waiting_note,
)


@click.command("features")
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT...")
@click.option("-o", "--output", "outdir", required=True, type=click.Path(file_okay=False),
              help="Output directory; outputs mirror the input tree.")
@click.option("-j", "--jobs", default=1, show_default=True, type=click.IntRange(min=1),
              help="Number of worker processes.")
@click.option("--skeleton", "skeleton", default=None, metavar="MAP",
              help="Skeleton map (TOML file or map name) instead of the detected one.")
@click.option("--markers", default=None, metavar="SET",
              help="Marker set of the C3D inputs (TOML file or built-in name) instead of "
                   "the recognised one; `mtanno markers guess FILE.c3d` writes a starting "
                   "point (docs/formats.md).")
@click.option("--asf", type=click.Path(exists=True, dir_okay=False), default=None,
              help="ASF skeleton for every AMC input (default: found beside or above it).")
@click.option("-f", "--force", is_flag=True, help="Rewrite outputs that are up to date.")
@click.option("--feature-set", "feature_set", default="ak40", show_default=True,
              type=click.Choice(["ak40", "mrc05", "mrc05-reference"]),
              help="ak40: the 40 annotation features ([MR06] + F40); mrc05: the 31 features "
                   "of [MRC05] (reference bugs fixed, docs/index.md); mrc05-reference: as the "
                   "reference implementation computes them.")
@click.option("--up", type=click.Choice(["y", "z"]), default=None,
              help="The motion files' up axis: y (ASF/AMC, BVH of most tools) or z (e.g. "
                   "Blender, 3ds Max exports); Z-up data is turned so that Y is up. Default: "
                   "y for ASF/AMC and BVH; for C3D the file's POINT:Y_SCREEN, else z.")
@click.option("--poses", is_flag=True,
              help="Also store the normalised poses of the same 30 Hz frames: 66 float32 "
                   "columns pose.<joint>.<x|y|z> of the 22 canonical joints, root at x=z=0, "
                   "facing +x, in leg lengths (docs/formats.md), for pose evidence without "
                   "rereading the motion files.")
@click.option("--classes", "config_path", type=click.Path(), default=None, metavar="CONFIG",
              help="The class configuration the features are for (`annotate --classes "
                   "CONFIG`; a file or a folder from `mtanno tune`): compute what its "
                   "[inputs] say the feature files need — poses (as --poses) and its "
                   "feature set.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@inside_input_option
@wait_option
@scheduler_option
@user_errors(2, flags={"outdir": "-o"})
def features_cmd(inputs, outdir, jobs, skeleton, markers, asf, force, feature_set, up, poses,
                 config_path, quiet, inside_input, wait, scheduler):
    """Compute the relational features of mocap files (ASF/AMC, BVH, C3D): by default the
    40 annotation features, or the 31 [MRC05] features with --feature-set mrc05.

    INPUT is a motion file (.amc, .bvh, .c3d), a directory (searched recursively) or `-` to read
    file names from standard input, one per line. A file FILE.amc gives OUTDIR/FILE.parquet;
    a file found in directory DIR gives OUTDIR/<its path below DIR>.parquet. The document
    is named by the file's stem everywhere.

    An AMC file's ASF is taken from --asf, else from its folder or the nearest folder above
    it: the ASF whose name begins the AMC's name (HDM_bd.asf for HDM_bd_squat1Reps_001_120.amc,
    02.asf for 02_05.amc), else the only ASF there.

    A C3D file holds markers, not joints: its joints come from a marker set (the built-in
    41-marker Vicon set is recognised whatever the subject prefix; --markers for another).
    Units, up axis and frame rate come from the file. Markers lost for at most 0.25 s are
    filled from their segment; frames whose joints still cannot be computed are recorded
    as invalid in the feature file (a note names their share) and are never labelled.

    With --poses every output also holds the poses of its rows, normalised as the pose
    distance of `mtanno align` does (root at x = z = 0, turned to face +x, scaled by the leg
    length), so that later stages can compare poses from the feature files alone.
    --classes CONFIG computes what a class configuration of `mtanno tune` needs (its
    [inputs]: poses when it verifies segments by them, its feature set).

    An output is up to date, and skipped unless --force, when the provenance it records
    matches the inputs now: the motion file, its ASF, the skeleton map, the feature set, the
    up axis, the extractor version, whether it has poses (--poses), for C3D the marker
    set. Files that fail, and inputs that yield no motion file (an empty folder), are
    reported as `path:line: what is wrong` and the others are still written. OUTDIR may not
    be, or lie inside, an input folder unless --inside-input says so. Exit code: 0 all
    written or up to date, 1 some files failed, 2 usage error, 3 OUTDIR locked by another
    run (see --wait), 130 interrupted (finished outputs stay, no partial file).

    Example: mtanno features ../shared/data/hdm05_cut -o feats/ --jobs 2
    """
    from tqdm import tqdm

    from mtanno.features.batch import ExtractOptions, extract_to

    if config_path is not None:  # what the configuration's [inputs] need
        from mtanno.annotate.config import feature_inputs

        source = click.get_current_context().get_parameter_source("feature_set")
        feature_set, poses = feature_inputs(config_path, feature_set=feature_set, poses=poses,
                                            given=source is not None
                                            and source.name != "DEFAULT")

    items: list[str] = []
    listed: list[str] = []  # names read from standard input: one that fails is reported
    for item in inputs:
        if item == "-":
            listed.extend(line.strip() for line in sys.stdin if line.strip())
        else:
            items.append(item)
    bar = None

    def start(n: int) -> None:
        nonlocal bar
        bar = tqdm(total=n, unit="file", disable=not show_progress(quiet), desc="features")

    def progress(outcome):
        bar.update(1)
        if outcome.status == "failed":
            why = outcome.error.for_command() if outcome.error else outcome.message
            bar.write(f"mtanno: {why}", file=sys.stderr)
        elif outcome.message and not quiet:  # a note: the invalid share of a written file
            bar.write(f"mtanno: {outcome.message}", file=sys.stderr)

    try:
        summary = extract_to(items, outdir, ExtractOptions(
                                 feature_set=feature_set, poses=poses, skeleton=skeleton,
                                 markers=markers, up=up, force=force, n_jobs=jobs,
                                 scheduler=scheduler),
                             listed=listed, asf=asf, wait=wait, inside_input=inside_input,
                             on_wait=waiting_note(outdir), on_start=start, progress=progress)
    finally:
        if bar is not None:
            bar.close()
    if not quiet:
        click.echo(f"features: {summary.line()} -> {outdir}", err=True)
    sys.exit(1 if summary.failed else 0)


@click.command("info")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--asf", type=click.Path(exists=True, dir_okay=False), default=None,
              help="ASF skeleton of an AMC file (default: found beside or above it).")
@click.option("--skeleton", default=None, metavar="MAP",
              help="Skeleton map (TOML file or name) instead of the detected one.")
@click.option("--markers", default=None, metavar="SET",
              help="Marker set of a C3D file (TOML file or built-in name) instead of the "
                   "recognised one.")
@click.option("--up", type=click.Choice(["y", "z"]), default=None,
              help="The file's up axis (default: y for ASF/AMC and BVH; the file's for C3D).")
@click.option("--features", "list_features", is_flag=True,
              help="Feature file: list its features (id, name, index group) instead.")
@user_errors(2)
def info_cmd(file, asf, skeleton, markers, up, list_features):
    """Describe a motion file (rig, frame rate, length, joints, skeleton map coverage;
    for C3D the marker set, which joints each marker feeds, gaps filled and the share of
    invalid frames) or a feature file (.parquet: its metadata, with its invalid frames;
    --features lists its features with ids and groups, the names `mtanno show` and `mtanno
    query --features` take). Exit code 2 for a file that cannot be read."""
    from mtanno.info import describe_file

    for line in describe_file(file, asf=asf, skeleton=skeleton, markers=markers, up=up,
                              features=list_features):
        click.echo(line)


COMMANDS = [features_cmd, info_cmd]
