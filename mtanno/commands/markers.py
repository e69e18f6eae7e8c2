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
    from mtanno._version import __version__
    from mtanno.errors import MtannoError
    from mtanno.io.c3d import read_c3d
    from mtanno.io.formats import format_of
    from mtanno.io.markerset import guess_toml
    from mtanno.util.output import write_text
    from mtanno.util.preflight import check_outputs

    if format_of(file).suffix != ".c3d":
        raise MtannoError("markers guess reads a C3D file (.c3d)", path=file)
    check_outputs([output], [file])
    data = read_c3d(file)
    text, base, missing = guess_toml(data.labels, source=file, version=__version__)
    write_text(output, text)
    note = (f"; not found: {', '.join(missing)} (fill them in)" if missing else "")
    click.echo(f"markers guess: base {base.name}, {len(base.markers) - len(missing)} of "
               f"{len(base.markers)} markers found{note}"
               + (f" -> {output}" if output != "-" else ""), err=True)


COMMANDS = [markers_group]
