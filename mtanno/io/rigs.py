"""Skeleton maps: which node of a rig is which canonical joint.

Spec: ``docs/method.md`` §1 (canonical joints) and ``docs/method/features.md`` §1.5. A
skeleton map is a TOML file (see ``mtanno/skeletons/*.toml`` and ``docs/formats.md``)::

    name = "cmu-asf"
    description = "..."
    format = "asf"                      # which reader's rigs it applies to
    detect = ["lfemur", "rhumerus"]     # the map fits a rig that has all these nodes
    heading = { node = "root", axis = [1.0, 0.0, 0.0] }   # F40: root-local axis

    [joints]
    root = "root"
    lhip = "lhipjoint"
    ...

Maps are searched in the directories of ``$MTANNO_SKELETON_PATH`` (``os.pathsep``
separated), then the user folder ``$XDG_CONFIG_HOME/mtanno/skeletons`` (``~/.config`` when
``XDG_CONFIG_HOME`` is unset or empty), then the maps shipped inside the package
(``mtanno/skeletons``, package data found through :mod:`importlib.resources`), so a user
adds a rig by dropping a file there, or passes one with ``--skeleton``.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError, read_toml
from mtanno.io.skeleton import Rig

#: The canonical joints features use, in this order (docs/method.md §1).
CANONICAL_JOINTS: tuple[str, ...] = (
    "root", "lhip", "rhip", "lknee", "rknee", "lankle", "rankle", "ltoes", "rtoes", "belly",
    "chest", "neck", "head", "headtop", "lshoulder", "rshoulder", "lelbow", "relbow", "lwrist",
    "rwrist", "lfingers", "rfingers",
)



@functools.lru_cache(maxsize=1)
def builtin_dir() -> Path:
    """Folder of the skeleton maps shipped with the package (package data)."""
    return Path(str(resources.files("mtanno") / "skeletons"))


def user_dir() -> Path:
    """The user's skeleton-map folder: ``$XDG_CONFIG_HOME/mtanno/skeletons``, by default
    ``~/.config/mtanno/skeletons`` (XDG Base Directory specification)."""
    base = os.environ.get("XDG_CONFIG_HOME", "")
    return (Path(base) if base and Path(base).is_absolute() else Path.home() / ".config") \
        / "mtanno" / "skeletons"


@dataclass(frozen=True)
class SkeletonMap:
    """A parsed skeleton map (see module docstring)."""

    name: str
    format: str
    joints: dict[str, str]
    detect: tuple[str, ...]
    heading_node: str
    heading_axis: tuple[float, float, float]
    path: str
    description: str = ""
    #: How the map was chosen or made, for ``mtanno info`` (not part of :attr:`digest`).
    how: str = ""

    def fits(self, rig: Rig) -> bool:
        """True if the map is for this file format and the rig has every detect node."""
        return self.fits_nodes(rig.kind, rig.names)

    def fits_nodes(self, kind: str, names) -> bool:
        """:meth:`fits` for a rig given by its kind and node names."""
        names = set(names)
        return self.format == kind and all(n in names for n in self.detect)

    @functools.cached_property
    def digest(self) -> str:
        """SHA-256 of what the map says (not where it is): feature files record it, so
        their features are recomputed when the map that made them changes (computed once
        per map: a map does not change once read)."""
        import hashlib
        import json

        body = {"name": self.name, "format": self.format, "joints": self.joints,
                "detect": list(self.detect), "heading": [self.heading_node,
                                                         list(self.heading_axis)]}
        return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()

    def coverage(self, rig: Rig) -> dict[str, str | None]:
        """Canonical joint → rig node name, or None where the map or the rig lacks it."""
        names = set(rig.names)
        return {j: (self.joints[j] if self.joints.get(j) in names else None)
                for j in CANONICAL_JOINTS}

    def indices(self, rig: Rig, joints: tuple[str, ...] = CANONICAL_JOINTS) -> np.ndarray:
        """Rig node index of each canonical joint in ``joints``.

        Raises :class:`MtannoError` naming the first joint the map does not give or the rig
        does not have.
        """
        out = np.empty(len(joints), dtype=np.int64)
        for k, j in enumerate(joints):
            node = self.joints.get(j)
            if node is None:
                raise MtannoError(f"skeleton map '{self.name}' ({self.path}) has no entry for "
                                  f"joint '{j}', which the features need", path=rig.source)
            if node not in rig.names:
                raise MtannoError(f"skeleton map '{self.name}' maps joint '{j}' to '{node}', "
                                  f"which the rig does not have", path=rig.source)
            out[k] = rig.names.index(node)
        return out

    def heading_index(self, rig: Rig) -> int:
        if self.heading_node not in rig.names:
            raise MtannoError(f"skeleton map '{self.name}' takes the heading from node "
                              f"'{self.heading_node}', which the rig does not have",
                              path=rig.source)
        return rig.names.index(self.heading_node)


def load_map(path: str | os.PathLike) -> SkeletonMap:
    """Read one skeleton map file, checking its fields."""
    path = Path(path)
    data, _ = read_toml(path, what="skeleton map")
    try:
        joints = data["joints"]
        fmt = data["format"]
        name = data.get("name", path.stem)
    except KeyError as exc:
        raise MtannoError(f"skeleton map lacks the key {exc}", path=str(path)) from None
    if not isinstance(joints, dict) or not all(isinstance(v, str) for v in joints.values()):
        raise MtannoError("[joints] must map canonical joint names to node names",
                          path=str(path))
    unknown = sorted(set(joints) - set(CANONICAL_JOINTS))
    if unknown:
        raise MtannoError(f"unknown canonical joint(s) {', '.join(unknown)}; known: "
                          f"{', '.join(CANONICAL_JOINTS)}", path=str(path))
    shared: dict[str, str] = {}
    for joint, node in joints.items():
        if node in shared:  # two joints at one point: the features between them are void
            raise MtannoError(f"joints '{shared[node]}' and '{joint}' are both mapped to node "
                              f"'{node}'; every canonical joint needs its own node",
                              path=str(path))
        shared[node] = joint
    heading, axis = _heading(data.get("heading", {}), str(path))
    detect = data.get("detect", list(joints.values()))
    if not isinstance(detect, list) or not all(isinstance(v, str) for v in detect):
        raise MtannoError("detect must be a list of node names", path=str(path))
    return SkeletonMap(
        name=str(name), format=str(fmt), joints=dict(joints),
        detect=tuple(detect),
        heading_node=str(heading.get("node", joints.get("root", ""))),
        heading_axis=axis,  # type: ignore[arg-type]
        path=str(path), description=str(data.get("description", "")))


def _heading(heading, path: str) -> tuple[dict, tuple[float, float, float]]:
    """The ``heading`` table of a map and its axis: three finite numbers, not all zero."""
    try:
        axis = tuple(float(v) for v in heading.get("axis", (1.0, 0.0, 0.0)))
        ok = isinstance(heading.get("node", ""), str) and len(axis) == 3 \
            and all(np.isfinite(axis)) and any(axis)
    except (TypeError, ValueError, AttributeError):
        ok = False
    if not ok:
        raise MtannoError('heading must be { node = "NODE", axis = [x, y, z] } with three '
                          'finite numbers, not all zero', path=path)
    return heading, axis  # type: ignore[return-value]


def search_dirs() -> list[Path]:
    """Directories searched for skeleton maps, first match wins."""
    env = os.environ
    return list(_search_dirs(env.get("MTANNO_SKELETON_PATH", ""), env.get("XDG_CONFIG_HOME", ""),
                             env.get("HOME")))


@functools.lru_cache(maxsize=8)
def _search_dirs(extra: str, xdg: str, home: str | None) -> tuple[Path, ...]:
    """:func:`search_dirs` for these values of the variables it depends on (a batch asks
    once per file)."""
    dirs = [Path(p) for p in extra.split(os.pathsep) if p]
    dirs.append(user_dir())
    dirs.append(builtin_dir())
    return tuple(dirs)


_MAP_CACHE: dict[tuple, list[SkeletonMap]] = {}
_DIR_CACHE: dict[tuple[str, int], list[Path]] = {}


def available_maps() -> list[SkeletonMap]:
    """All maps on the search path (a name found earlier hides later ones).

    Folder listings are cached per folder modification time and parsed maps per (file,
    modification time), so a batch reads each map once.
    """
    files = []
    for d in search_dirs():
        try:
            dkey = (str(d), os.stat(d).st_mtime_ns)
        except OSError:
            continue
        if dkey not in _DIR_CACHE:
            _DIR_CACHE[dkey] = sorted(d.glob("*.toml"))
        files.extend(_DIR_CACHE[dkey])
    stamps = []
    for f in files:
        try:
            stamps.append((str(f), os.stat(f).st_mtime_ns))
        except OSError:  # gone since the folder was listed
            continue
    key = tuple(stamps)
    if key not in _MAP_CACHE:
        seen: dict[str, SkeletonMap] = {}
        for f in files:
            m = load_map(f)
            seen.setdefault(m.name, m)
        _MAP_CACHE.clear()
        _MAP_CACHE[key] = list(seen.values())
    return _MAP_CACHE[key]


def find_map(rig: Rig, override: str | os.PathLike | None = None) -> SkeletonMap:
    """The skeleton map for ``rig``: ``override`` (a file or a map name) or the first fit."""
    return select_map(rig.kind, rig.names, override, source=rig.source)


def select_map(kind: str, names, override: str | os.PathLike | None = None, *,
               source: str | None = None) -> SkeletonMap:
    """:func:`find_map` for a rig given by its kind (``asf``/``bvh``) and node names."""
    if override is not None:
        p = Path(override)
        if p.suffix == ".toml" or p.exists():
            return load_map(p)
        for m in available_maps():
            if m.name == str(override):
                return m
        raise MtannoError(f"no skeleton map named '{override}' (known: "
                          f"{', '.join(m.name for m in available_maps())})")
    for m in available_maps():
        if m.fits_nodes(kind, names):
            return m
    raise MtannoError(f"no skeleton map fits this {kind.upper()} rig (nodes: "
                      f"{', '.join(list(names)[:8])}, ...); add one to {user_dir()} or "
                      "pass {skeleton} MAP.toml", path=source, options=("skeleton",))
