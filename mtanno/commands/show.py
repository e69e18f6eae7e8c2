"""``mtanno show``: a feature file as a compact text timeline (or a picture), to pick the
frames and features of a query by example ([MRC05] §6.2)."""

from __future__ import annotations

import click

from mtanno.commands._common import EXIT_BAD_INPUT, NAMES, user_errors


@click.command("show", epilog=EXIT_BAD_INPUT)
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--frames", default=None, metavar="A:B",
              help="Frames to show, 1-based inclusive at 30 Hz (default: all).")
@click.option("--features", "feature_list", default=None, metavar="NAME,...", type=NAMES,
              help="Features to show, by name or id (F20); default: all. `mtanno info "
                   "FILE --features` lists them.")
@click.option("--width", default=100, show_default=True, type=click.IntRange(min=10),
              help="Columns of the timeline; longer ranges show blocks of frames per column.")
@click.option("--plot", "plot_path", default=None, type=click.Path(dir_okay=False),
              metavar="FILE.png", help="Draw the same as a picture (.png, .svg; needs the "
                                       "extra 'plot': pip install 'mtanno[plot]').")
@user_errors(2)
def show_cmd(file, frames, feature_list, width, plot_path):
    """Print when the features of a feature file are on: one row per feature (id, group,
    name), one column per frame — '#' on, '.' off — or, for long ranges, per block of
    frames ('+' on in part of the block).

    Read it to pick a query by example: the frames where the motion happens and the
    features that change there, then `mtanno query INDEX --example FILE --frames A:B
    --features NAME,...`.
    """
    from mtanno.features.store import read_features
    from mtanno.info import feature_rows, select_features, text_timeline
    from mtanno.util.preflight import check_outputs
    from mtanno.util.tables import parse_frame_range

    if plot_path is not None:
        from mtanno.plot import require_matplotlib

        require_matplotlib()
        check_outputs([plot_path], [file])
    ff = read_features(file)
    a, b = parse_frame_range(frames, ff.X.shape[1]) or (0, ff.X.shape[1] - 1)
    rows = select_features(ff, feature_list.split(",")) if feature_list else \
        list(range(len(ff.names)))
    info = feature_rows(ff)
    labels = [f"{info[r]['id']} {info[r]['group']}:{info[r]['name']}" for r in rows]
    X = ff.X[rows, a:b + 1]
    block = -(-X.shape[1] // width)
    click.echo(f"{ff.document}: frames {a + 1}-{b + 1} of {ff.X.shape[1]} at "
               f"{ff.fps:g} Hz, {block} frame{'s' if block > 1 else ''} per column")
    for line in text_timeline(X, labels, first_frame=a + 1, width=width):
        click.echo(line)
    if plot_path is not None:
        from mtanno.plot import plot_features, save_figure

        ax = plot_features(X, labels, first_frame=a + 1)
        ax.set_title(f"{ff.document}, frames {a + 1}-{b + 1}")
        save_figure(ax, plot_path)
        click.echo(f"show: plot -> {plot_path}", err=True)


COMMANDS = [show_cmd]
