"""The pose block of feature files (private to :mod:`mtanno.features.store`): column names and
the checks of the metadata's ``poses`` entry and of the pose columns against it, from the
schema alone (``docs/formats.md``; ``mtanno features --poses``, issue 26 part 3).

The block is one float32 column ``pose.<joint>.<x|y|z>`` per canonical joint and axis, the
joint positions normalised by :func:`mtanno.features.poses.normalize_poses` (leg lengths).
"""

from __future__ import annotations

from collections.abc import Sequence

import pyarrow as pa

from mtanno.errors import MtannoError

__all__ = ["POSE_AXES", "POSE_PREFIX", "check_pose_columns", "check_pose_meta", "pose_columns",
           "text_field"]

#: Columns whose names begin so are the pose block (``pose.<joint>.<x|y|z>``, float32); no
#: feature column may be named so.
POSE_PREFIX = "pose."
POSE_AXES = ("x", "y", "z")


def text_field(value, message: str, spath: str) -> str:
    """``value`` if it is a non-empty string, else the error ``message, got value``."""
    if not isinstance(value, str) or not value:
        raise MtannoError(f"{message}, got {value!r}", path=spath)
    return value


def pose_columns(joints: Sequence[str]) -> list[str]:
    """Names of the pose columns for ``joints``, in file order: joint by joint, x, y, z."""
    return [f"{POSE_PREFIX}{j}.{a}" for j in joints for a in POSE_AXES]


def check_pose_meta(block, spath: str) -> list[str]:
    """Validate the ``poses`` entry of the metadata: the canonical joints in order, the unit
    ``leg lengths`` and a normalisation in words (:func:`mtanno.features.poses.pose_metadata`).
    Returns its joints."""
    from mtanno.features.poses import pose_metadata

    want = pose_metadata()
    if not isinstance(block, dict):
        raise MtannoError(f"poses in the mtanno metadata must be a JSON object, got "
                          f"{type(block).__name__}", path=spath)
    if block.get("joints") != want["joints"]:
        raise MtannoError(f"poses in the mtanno metadata must list the "
                          f"{len(want['joints'])} canonical joints in order "
                          f"({', '.join(want['joints'][:3])}, …), got {block.get('joints')!r}",
                          path=spath)
    if block.get("unit") != want["unit"]:
        raise MtannoError(f"poses in the mtanno metadata must be in {want['unit']!r}, got unit "
                          f"{block.get('unit')!r}", path=spath)
    text_field(block.get("normalisation"), "poses in the mtanno metadata must say their "
               "normalisation (a non-empty string)", spath)
    return list(want["joints"])


def check_pose_columns(meta: dict, schema: pa.Schema, spath: str) -> list[str] | None:
    """The pose columns of a file (in :func:`pose_columns` order; None without a pose
    block), checked against its metadata from the schema alone: a ``poses`` entry and
    ``pose.*`` columns go together, every joint has its three columns, no other column
    begins with ``pose.``, and each is float32."""
    present = [c for c in schema.names if c.startswith(POSE_PREFIX)]
    block = meta.get("poses")
    if block is None:
        if present:
            raise MtannoError(f"pose column(s) {', '.join(present[:3])}"
                              f"{' …' if len(present) > 3 else ''} without a poses entry in "
                              "the mtanno metadata", path=spath)
        return None
    want = pose_columns(block["joints"])  # the entry itself was checked by check_pose_meta
    if not present:
        raise MtannoError(f"the mtanno metadata describes poses but the file has none of "
                          f"the {len(want)} pose columns ({want[0]}, …)", path=spath)
    have = set(present)
    missing = [c for c in want if c not in have]
    if missing:
        raise MtannoError(f"the pose block lacks {len(missing)} of its {len(want)} columns: "
                          f"{', '.join(missing[:3])}{' …' if len(missing) > 3 else ''}",
                          path=spath)
    stray = sorted(have - set(want))
    if stray:
        raise MtannoError(f"column '{stray[0]}' is not a pose column of the joints the "
                          "metadata lists (pose.<joint>.<x|y|z>)", path=spath)
    for c in want:
        kind = schema.field(c).type
        if kind != pa.float32():
            raise MtannoError(f"pose column '{c}' is {kind}, not float32", path=spath)
    return want
