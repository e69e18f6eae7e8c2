"""``mtanno markers guess``: write a marker set for a C3D file's labels
(:func:`mtanno.io.markerset.guess_toml`), to check, complete and pass with ``--markers``.

Exit codes: 0 written (markers it could not find are listed), 2 usage error or a file that
cannot be read.
"""

from __future__ import annotations

import click

from mtanno.commands._common import EXIT_BAD_INPUT, user_errors


@click.group("markers")
def markers_group() -> None:
    """Marker sets: which markers of a C3D file make which canonical joint."""


@markers_group.command("guess", epilog=EXIT_BAD_INPUT)
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default="-", show_default=True, metavar="MAP.toml",
              help="Where to write the marker set ('-': standard output).")
@user_errors(2)
def guess_cmd(file: str, output: str) -> None:
    """Write a marker set for the markers of a C3D FILE: the built-in set whose markers
    the file's labels name best (by name or a known synonym such as LASI for LFWT, any
    case, subject prefix dropped), as `base = "SET"` with a [markers] table giving, for
    each marker of the set, the file's label. Markers it cannot find are left as comments
    to fill in; `--markers MAP.toml` then reads the file with it (docs/formats.md)."""
    from mtanno.io.c3d import guess_markers_file

    base, missing = guess_markers_file(file, output)
    note = (f"; not found: {', '.join(missing)} (fill them in)" if missing else "")
    click.echo(f"markers guess: base {base.name}, {len(base.markers) - len(missing)} of "
               f"{len(base.markers)} markers found{note}"
               + (f" -> {output}" if output != "-" else ""), err=True)


COMMANDS = [markers_group]
