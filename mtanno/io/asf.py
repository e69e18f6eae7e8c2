"""ASF skeleton reader (Acclaim skeleton file; CMU and HDM05 rigs).

Spec: ``docs/method.md`` §1, ``docs/method/features.md`` §1.1–1.3. Lengths are divided by
``:units length`` and multiplied by 2.54, so positions come out in centimetres; angles follow
``:units angle`` (deg by default). A bone's ``axis ax ay az ORDER`` gives the fixed
conjugation C (``C = R_{ORDER[2]}·R_{ORDER[1]}·R_{ORDER[0]}``, i.e. ``Rz·Ry·Rx`` for
``XYZ``); its motion rotation is ``M`` composed in the same order from the AMC dof values,
and the local rotation is ``L = C·M·C⁻¹``. The root's rotation is not conjugated; its
``orientation`` (zero in every file we know) left-multiplies it.

The file is read as Latin-1 (HDM05 headers hold a Latin-1 byte) with any line ending.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from mtanno.errors import MtannoError, read_text_input
from mtanno.io import _limits
from mtanno.io.skeleton import AXIS_CODES, Rig, euler_matrix

INCH_CM = 2.54


@dataclass
class AsfSkeleton:
    """A parsed ASF file.

    Attributes
    ----------
    rig:
        The node tree (node 0 = root, then bones in ``:bonedata`` order, reordered only if
        a parent would otherwise follow its child).
    dofs:
        Bone name → its ``dof`` tokens in file order (e.g. ``["rx", "ry", "rz"]``).
    root_order:
        The ``:root order`` tokens (e.g. ``TX TY TZ RX RY RZ``).
    length_scale:
        Factor from file length units to centimetres (``2.54 / length``).
    angle_scale:
        Factor from file angle units to radians.
    """

    rig: Rig
    dofs: dict[str, list[str]]
    root_order: list[str]
    length_scale: float
    angle_scale: float


def read_text_lines(path: str | os.PathLike) -> list[str]:
    """Lines of a text file read as Latin-1, any line ending; rejects empty and binary files."""
    raw = read_text_input(path)
    return raw.decode("latin-1").splitlines()


def _order_to_axes(order: str, path: str, line: int) -> list[int]:
    order = order.lower()
    if sorted(order) != ["x", "y", "z"]:
        raise MtannoError(f"bad axis order '{order.upper()}' (expected a permutation of XYZ)",
                          path=path, line=line)
    return [AXIS_CODES[c] for c in order]


def _compose(axes_applied_first: list[int], angles: list[float]) -> np.ndarray:
    """R_{a[2]}(θ2)·R_{a[1]}(θ1)·R_{a[0]}(θ0): rotation about a[0] applied first."""
    m = np.eye(3)
    for ax, th in zip(reversed(axes_applied_first), reversed(angles)):
        m = m @ euler_matrix(ax, th)
    return m


def _floats(tokens: list[str], n: int, what: str, path: str, line: int,
            limit: float = _limits.MAX_LENGTH) -> list[float]:
    """``n`` finite numbers of magnitude at most ``limit`` (beyond, their squares would
    overflow further on)."""
    if len(tokens) != n:
        raise MtannoError(f"'{what}' needs {n} numbers, found {len(tokens)}", path=path, line=line)
    try:
        vals = [float(t) for t in tokens]
    except ValueError:
        raise MtannoError(f"'{what}' has a value that is not a number", path=path,
                          line=line) from None
    if not all(np.isfinite(vals)):
        raise MtannoError(f"'{what}' has a NaN or infinite value", path=path, line=line)
    if any(abs(v) > limit for v in vals):
        raise MtannoError(f"'{what}' has an absurd value (beyond ±{limit:g})", path=path,
                          line=line)
    return vals


def _sections(lines: list[str], spath: str):
    """The ASF's sections: units (length divisor, angle unit), the root's fields (tokens
    and line), the bone blocks (dicts with their line) and the hierarchy lines; errors for
    malformed blocks, a file without bones or without a hierarchy."""
    units = {"length": 1.0, "angle": "deg"}
    root: dict[str, tuple[list[str], int]] = {}
    bones: list[dict] = []
    hierarchy: list[tuple[list[str], int]] = []
    section = None
    bone: dict | None = None
    for lineno, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            section = line[1:].split()[0].lower()
            rest = line.split()[1:]
            if section in ("name", "version", "documentation") or not rest:
                continue
            continue
        tok = line.split()
        key = tok[0].lower()
        if section == "units":
            if key == "length":
                units["length"] = _floats(tok[1:2], 1, "length", spath, lineno,
                                          _limits.MAX_LENGTH_UNIT)[0]
                if units["length"] <= 0:
                    raise MtannoError("':units length' must be positive", path=spath, line=lineno)
                if units["length"] < 1 / _limits.MAX_LENGTH_UNIT:
                    raise MtannoError(f"':units length' {tok[1]} is absurd (below "
                                      f"{1 / _limits.MAX_LENGTH_UNIT:g})", path=spath,
                                      line=lineno)
            elif key == "angle":
                if len(tok) < 2 or tok[1].lower() not in ("deg", "rad"):
                    raise MtannoError("':units angle' must be deg or rad", path=spath, line=lineno)
                units["angle"] = tok[1].lower()
        elif section == "root":
            root[key] = (tok[1:], lineno)
        elif section == "bonedata":
            if key == "begin":
                bone = {"line": lineno, "dof": []}
            elif key == "end":
                if bone is None:
                    raise MtannoError("'end' without 'begin'", path=spath, line=lineno)
                for need in ("name", "direction", "length"):
                    if need not in bone:
                        raise MtannoError(f"bone has no '{need}'", path=spath, line=bone["line"])
                bones.append(bone)
                bone = None
            elif bone is None:
                raise MtannoError(f"unexpected '{tok[0]}' outside a begin/end block",
                                  path=spath, line=lineno)
            elif key == "name":
                bone["name"] = tok[1] if len(tok) > 1 else ""
            elif key == "direction":
                bone["direction"] = _floats(tok[1:], 3, "direction", spath, lineno)
            elif key == "length":
                bone["length"] = _floats(tok[1:2], 1, "length", spath, lineno)[0]
                bone["length_line"] = lineno
            elif key == "axis":
                if len(tok) != 5:
                    raise MtannoError("'axis' needs three angles and an order", path=spath,
                                      line=lineno)
                bone["axis"] = (_floats(tok[1:4], 3, "axis", spath, lineno,
                                        _limits.MAX_ANGLE_DEG),
                                _order_to_axes(tok[4], spath, lineno))
            elif key == "dof":
                bone["dof"] = [t.lower() for t in tok[1:]]
        elif section == "hierarchy":
            if key in ("begin", "end"):
                continue
            hierarchy.append((tok, lineno))
    if bone is not None:
        raise MtannoError("bone block not closed with 'end' (truncated file?)", path=spath,
                          line=bone["line"])
    if not bones:
        raise MtannoError("no ':bonedata' section with bones (not an ASF file?)", path=spath,
                          line=1)
    if not hierarchy:
        raise MtannoError("no ':hierarchy' section", path=spath, line=len(lines))
    return units, root, bones, hierarchy


def _bone_order(bones: list[dict], hierarchy: list, spath: str):
    """(bone names in a topological order — the file's where it already is one — with
    the root first; each bone's parent), checking names and the hierarchy."""
    names = ["root"] + [b["name"] for b in bones]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise MtannoError(f"bone name '{dup}' appears twice", path=spath)
    parent_of: dict[str, str] = {}
    for tok, lineno in hierarchy:
        for child in tok[1:]:
            if tok[0] not in names:
                raise MtannoError(f"hierarchy names unknown bone '{tok[0]}'", path=spath,
                                  line=lineno)
            if child not in names:
                raise MtannoError(f"hierarchy names unknown bone '{child}'", path=spath,
                                  line=lineno)
            parent_of[child] = tok[0]
    for b in bones:
        if b["name"] not in parent_of:
            raise MtannoError(f"bone '{b['name']}' has no parent in ':hierarchy'", path=spath,
                              line=b["line"])

    # Topological order, keeping the file order where it already is one.
    order: list[str] = ["root"]
    placed = {"root"}
    pending = [b["name"] for b in bones]
    while pending:
        rest = [n for n in pending if parent_of[n] not in placed]
        progressed = [n for n in pending if parent_of[n] in placed]
        if not progressed:
            raise MtannoError(f"hierarchy has a cycle or unreachable bone '{rest[0]}'",
                              path=spath)
        for n in progressed:
            if parent_of[n] in placed:
                order.append(n)
                placed.add(n)
        pending = [n for n in pending if n not in placed]
    return order, parent_of


def _check_cm(value: float, what: str, path: str, line: int) -> None:
    """A length in centimetres (after ``:units length``) within ±10⁷ cm."""
    if not value <= _limits.MAX_LENGTH:
        raise MtannoError(f"{what} is absurdly long ({value:.3g} cm with ':units length'; "
                          f"at most {_limits.MAX_LENGTH:g})", path=path, line=line)


def read_asf(path: str | os.PathLike) -> AsfSkeleton:
    """Parse an ASF file into an :class:`AsfSkeleton` (lengths in cm, angles in radians)."""
    spath = str(path)
    units, root, bones, hierarchy = _sections(read_text_lines(path), spath)
    length_scale = INCH_CM / units["length"]
    angle_scale = np.pi / 180.0 if units["angle"] == "deg" else 1.0
    order, parent_of = _bone_order(bones, hierarchy, spath)
    by_name = {b["name"]: b for b in bones}

    n = len(order)
    parents = np.full(n, -1, dtype=np.int64)
    offsets = np.zeros((n, 3))
    axes = np.zeros((n, 3), dtype=np.int64)
    pre = np.tile(np.eye(3), (n, 1, 1))
    post = np.tile(np.eye(3), (n, 1, 1))

    # Root: order of AMC values, rotation composition order, position, orientation.
    root_order = [t.upper() for t in root.get("order", (["TX", "TY", "TZ", "RX", "RY", "RZ"], 0))[0]]
    valid = {"TX", "TY", "TZ", "RX", "RY", "RZ"}
    if not set(root_order) <= valid or len(set(root_order)) != len(root_order):
        raise MtannoError(f"bad ':root order' {' '.join(root_order)}", path=spath,
                          line=root.get("order", ([], None))[1])
    r_axis_tok, r_axis_line = root.get("axis", (["XYZ"], 0))
    root_axes = _order_to_axes(r_axis_tok[0] if r_axis_tok else "", spath, r_axis_line)
    axes[0] = root_axes[::-1]
    if "position" in root:
        offsets[0] = np.asarray(_floats(root["position"][0], 3, "position", spath,
                                        root["position"][1])) * length_scale
        _check_cm(float(np.abs(offsets[0]).max()), "the root position", spath,
                  root["position"][1])
    if "orientation" in root:
        o = _floats(root["orientation"][0], 3, "orientation", spath, root["orientation"][1],
                    _limits.MAX_ANGLE_DEG)
        pre[0] = _compose(root_axes, [o[a] * angle_scale for a in root_axes])

    dofs: dict[str, list[str]] = {}
    for k, name in enumerate(order[1:], 1):
        b = by_name[name]
        parents[k] = order.index(parent_of[name])
        d = np.asarray(b["direction"], dtype=np.float64)
        norm = np.sqrt(d @ d)
        if norm == 0:
            raise MtannoError(f"bone '{name}' has a zero direction", path=spath, line=b["line"])
        offsets[k] = d / norm * b["length"] * length_scale
        _check_cm(abs(b["length"] * length_scale), f"bone '{name}'", spath, b["length_line"])
        ang, bone_axes = b.get("axis", ([0.0, 0.0, 0.0], [0, 1, 2]))
        c = _compose(bone_axes, [ang[a] * angle_scale for a in bone_axes])
        pre[k] = c
        post[k] = c.T
        axes[k] = bone_axes[::-1]
        for t in b["dof"]:
            if t not in ("rx", "ry", "rz", "tx", "ty", "tz", "l"):
                raise MtannoError(f"bone '{name}' has unknown dof '{t}'", path=spath,
                                  line=b["line"])
        dofs[name] = b["dof"]

    rig = Rig(kind="asf", names=order, parents=parents, offsets=offsets, axes=axes, pre=pre,
              post=post, end_point=True, source=spath)
    return AsfSkeleton(rig=rig, dofs=dofs, root_order=root_order, length_scale=length_scale,
                       angle_scale=angle_scale)
