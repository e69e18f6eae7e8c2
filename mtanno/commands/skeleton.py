"""``mtanno skeleton guess``: write the skeleton map mtanno makes for a BVH rig from its
joint names and tree, or from its hierarchy and pose where the names say nothing
(:mod:`mtanno.io.guess`, :mod:`mtanno.io.topology`), so a user can check it, edit it and keep it
(``--skeleton MAP.toml``, or a file in ``~/.config/mtanno/skeletons/``).

Exit codes: 0 success, 2 usage error or bad input (a rig that cannot be mapped).
"""

from __future__ import annotations

import click

from mtanno.commands._common import EXIT_BAD_INPUT, user_errors


@click.group("skeleton")
def skeleton_group() -> None:
    """Skeleton maps: which rig joint is which canonical joint."""


@skeleton_group.command("guess", epilog=EXIT_BAD_INPUT)
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default="-", show_default=True, metavar="MAP.toml",
              help="Where to write the map ('-': standard output).")
@click.option("--name", default=None, metavar="NAME",
              help="The map's name (default guessed-<convention>, or guessed-hierarchy); "
                   "--skeleton NAME finds it once it is on the map search path.")
@click.option("--method", type=click.Choice(["auto", "names", "hierarchy"]), default="auto",
              show_default=True,
              help="How to place the joints: from the joint names and the tree (sides the "
                   "pose contradicts refused), from the hierarchy and pose alone, or auto: "
                   "the names with the sides from the pose, else the hierarchy (the map "
                   "`mtanno features` uses).")
@click.option("--swap-sides", is_flag=True,
              help="Map the joints named left to the right canonical joints and vice "
                   "versa, for a rig whose left/right names are mirrored (names only).")
@user_errors(2)
def guess_cmd(file: str, output: str, name: str | None, method: str,
              swap_sides: bool) -> None:
    """Write the skeleton map generated for the rig of a BVH FILE (the one `mtanno
    features` uses when no map file fits): each canonical joint placed from the joint
    names (Mixamo, MotionBuilder/HumanIK, Unreal, SMPL/SMPL-X, CMU, Xsens, Rokoko and
    similar conventions) and the tree, the sides checked against the pose; where the
    names say nothing (Bone01…, names in another script), from the hierarchy and pose
    alone: two legs and the spine meet at the pelvis, two arms and the neck branch off
    above it, left and right from the way the toes point. The heading axis comes from
    the hips. `--skeleton MAP.toml` reads the map back to the same map, so the features
    are the same. A rig that is not a humanoid's is refused, saying why."""
    from dataclasses import replace
    from pathlib import Path

    from mtanno._version import __version__
    from mtanno.errors import MtannoError
    from mtanno.io.bvh import read_bvh
    from mtanno.io.guess import guess_map, map_toml
    from mtanno.io.rigs import available_maps
    from mtanno.util.output import write_text
    from mtanno.util.preflight import check_outputs

    if Path(file).suffix.lower() != ".bvh":
        raise MtannoError("skeleton guess reads a BVH file (.bvh)", path=file)
    check_outputs([output], [file])
    rig, channels = read_bvh(file)
    smap = guess_map(rig, channels, swap_sides=swap_sides, method=method)
    fitting = next((m.name for m in available_maps() if m.fits(rig)), None)
    if fitting is not None:
        click.echo(f"skeleton guess: note: the map '{fitting}' fits this rig and is used "
                   "instead of a generated one unless --skeleton says otherwise", err=True)
    if name:
        smap = replace(smap, name=name)
    write_text(output, map_toml(smap, source=file, version=__version__))
    if output != "-":
        click.echo(f"skeleton guess: {smap.name} ({smap.description}) -> {output}", err=True)


COMMANDS = [skeleton_group]
