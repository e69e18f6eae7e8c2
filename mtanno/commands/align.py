"""``mtanno align``: time alignment of two motions ([MRC05] §7).

Exit codes: 0 success, 2 usage error or bad input (nothing written), 130 interrupted.
"""

from __future__ import annotations

import click

from mtanno.align.options import COSTS, DEFAULT_BAND, DEFAULT_COST
from mtanno.commands._common import NAMES, user_errors


@click.command("align", epilog="Exit codes: 0 success, 2 usage error or bad input (nothing "
               "written), 130 interrupted.")
@click.argument("motion_a", metavar="A", type=click.Path(dir_okay=False))
@click.argument("motion_b", metavar="B", type=click.Path(dir_okay=False))
@click.option("--features", "features", default=None, metavar="NAME,...", type=NAMES,
              help="Features to segment by (and to compare with --cost features), "
                   "comma-separated names.")
@click.option("--group", default=None, metavar="GROUP",
              help="Feature group instead of --features: lower, upper, mix, all (default) or "
                   "pose (the features that measure no velocity; recommended with --cost "
                   "features).")
@click.option("--band", default=DEFAULT_BAND, show_default=True, type=click.IntRange(min=0),
              metavar="FRAMES",
              help="Widen every matched segment rectangle by this many 30 Hz frames on each "
                   "side.")
@click.option("--cost", default=DEFAULT_COST, show_default=True, type=click.Choice(COSTS),
              help="Local cost of the DTW: positions (mean joint distance of poses normalised "
                   "for root translation, heading and leg length; motion files only) or "
                   "features (fraction of differing features).")
@click.option("--full", is_flag=True,
              help="Classical DTW over the whole cost matrix, for comparison.")
@click.option("-o", "--output", default="-", show_default=True,
              type=click.Path(dir_okay=False, allow_dash=True),
              help="Warping path table: .csv, .parquet or .jsonl (with provenance, "
                   "docs/formats.md), or - for CSV on standard output.")
@click.option("--plot", "plot_path", default=None, type=click.Path(dir_okay=False),
              help="Also draw the alignment like [MRC05] Fig. 11 into this .png, .pdf or .svg "
                   "file (needs matplotlib: pip install 'mtanno[plot]').")
@click.option("--asf", type=click.Path(exists=True, dir_okay=False), default=None,
              help="ASF skeleton of AMC inputs (default: found beside or above each).")
@click.option("--skeleton", default=None, metavar="MAP",
              help="Skeleton map (TOML file or name) instead of the detected one.")
@click.option("--feature-set", "feature_set", default="ak40", show_default=True,
              type=click.Choice(["ak40", "mrc05", "mrc05-reference"]),
              help="Features computed for motion files (feature files keep their own).")
@click.option("-q", "--quiet", is_flag=True, help="No summary line.")
@user_errors(2)
def align_cmd(motion_a, motion_b, features, group, band, cost, full, output, plot_path, asf,
              skeleton, feature_set, quiet):
    """Align motion B to motion A in time ([MRC05] §7): a coarse alignment of their
    segments, refined by DTW inside the area it spans.

    A and B are motion files (.amc, .bvh, .c3d) or feature files (.parquet, from `mtanno
    features`; --cost features only). Stage 1 cuts both into adaptive segments (maximal runs
    of equal feature vectors over the chosen features) and matches the two segment
    sequences by DTW, where a segment one motion lacks is merged into a neighbouring match;
    stage 2 runs classical DTW on the frames (30 Hz) only inside the matched segment pairs'
    rectangles widened by --band frames (docs/align.md).

    Output columns, one row per path cell: frame_a, frame_b (1-based 30 Hz frames),
    native_a, native_b (frames of the source files), cost (local cost). Total and mean cost
    and the fraction of the matrix computed are in the table's provenance and the summary
    line.

    Example: mtanno align walk1.bvh walk2.bvh -o path.csv --plot path.png
    """
    from mtanno.align.core import align_files, summary, write_alignment
    from mtanno.util.preflight import check_outputs
    from mtanno.util.tables import file_record, output_files, provenance, table_format

    table_format(output)
    if plot_path is not None:
        from mtanno.align.plot import check_plot_path

        check_plot_path(plot_path)
    inputs = [motion_a, motion_b] + ([asf] if asf else [])
    check_outputs(output_files(output) + ([plot_path] if plot_path else []), inputs)
    names = None if features is None else [f.strip() for f in features.split(",") if f.strip()]
    al = align_files(motion_a, motion_b, asf=asf, skeleton=skeleton, feature_set=feature_set,
                     features=names, group=group, band=band, cost=cost, full=full)
    facts = summary(al)
    write_alignment(output, al, provenance=provenance(
        inputs=[file_record(p) for p in inputs], group=group, **facts))
    if plot_path is not None:
        from mtanno.align.plot import save_alignment_plot

        save_alignment_plot(plot_path, al)
    if not quiet:
        area = "the full matrix" if full else f"{al.fraction:.1%} of the matrix (band {band})"
        click.echo(f"align: {al.a.name} ({al.a.frames} frames) ~ {al.b.name} ({al.b.frames} "
                   f"frames): {len(al.path.a)} path cells, {cost} cost total "
                   f"{al.total_cost:.4g}, mean {al.mean_cost:.4g}; computed {area} in "
                   f"{al.seconds['total']:.3f} s"
                   + (f" -> {output}" if output != "-" else ""), err=True)


COMMANDS = [align_cmd]
