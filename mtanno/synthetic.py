"""Synthetic ASF/AMC data made by mtanno itself.

Used by the tests that must run without ``../shared/data`` and by ``make demo`` on a machine
without the real data. The skeleton is a hand-written HDM05-like rig (28 bones, the CMU/HDM05
bone names so the ``cmu-asf`` skeleton map applies); motions are smooth sums of sines, not
real human movement.

Run ``python -m mtanno.synthetic OUTDIR [N]`` to write N documents with their ASF.
"""

from __future__ import annotations

import numpy as np

# name, parent, direction, length (ASF length units), axis, dof
BONES = [
    ("lhipjoint", "root", (0.6, -0.8, 0.25), 2.3, (0, 0, 0), ""),
    ("lfemur", "lhipjoint", (0.34, -0.94, 0), 7.3, (0, 0, 20), "rx ry rz"),
    ("ltibia", "lfemur", (0.34, -0.94, 0), 7.0, (0, 0, 20), "rx"),
    ("lfoot", "ltibia", (0.14, -0.37, 0.92), 2.3, (-90, 0, 20), "rx rz"),
    ("ltoes", "lfoot", (0, 0, 1), 1.1, (-90, 0, 20), "rx"),
    ("rhipjoint", "root", (-0.6, -0.8, 0.25), 2.3, (0, 0, 0), ""),
    ("rfemur", "rhipjoint", (-0.34, -0.94, 0), 7.3, (0, 0, -20), "rx ry rz"),
    ("rtibia", "rfemur", (-0.34, -0.94, 0), 7.0, (0, 0, -20), "rx"),
    ("rfoot", "rtibia", (-0.14, -0.37, 0.92), 2.3, (-90, 0, -20), "rx rz"),
    ("rtoes", "rfoot", (0, 0, 1), 1.1, (-90, 0, -20), "rx"),
    ("lowerback", "root", (0.02, 1, -0.04), 2.2, (0, 0, 0), "rx ry rz"),
    ("upperback", "lowerback", (0.03, 1, -0.07), 2.2, (0, 0, 0), "rx ry rz"),
    ("thorax", "upperback", (0.02, 1, -0.06), 2.2, (0, 0, 0), "rx ry rz"),
    ("lowerneck", "thorax", (-0.1, 1, 0.1), 1.7, (0, 0, 0), "rx ry rz"),
    ("upperneck", "lowerneck", (0.25, 0.96, -0.1), 1.7, (0, 0, 0), "rx ry rz"),
    ("head", "upperneck", (0.09, 0.99, -0.06), 1.8, (0, 0, 0), "rx ry rz"),
    ("lclavicle", "thorax", (0.95, 0.24, -0.2), 3.8, (0, 0, 0), "ry rz"),
    ("lhumerus", "lclavicle", (1, 0, 0), 4.8, (180, -30, -90), "rx ry rz"),
    ("lradius", "lhumerus", (1, 0, 0), 3.0, (180, -30, -90), "rx"),
    ("lwrist", "lradius", (1, 0, 0), 1.5, (0, 90, 90), "ry"),
    ("lhand", "lwrist", (1, 0, 0), 1.3, (0, 90, 90), "rx rz"),
    ("lfingers", "lhand", (1, 0, 0), 1.0, (0, 90, 90), "rx"),
    ("rclavicle", "thorax", (-0.95, 0.24, -0.2), 3.8, (0, 0, 0), "ry rz"),
    ("rhumerus", "rclavicle", (-1, 0, 0), 4.8, (180, 30, 90), "rx ry rz"),
    ("rradius", "rhumerus", (-1, 0, 0), 3.0, (180, 30, 90), "rx"),
    ("rwrist", "rradius", (-1, 0, 0), 1.5, (0, -90, -90), "ry"),
    ("rhand", "rwrist", (-1, 0, 0), 1.3, (0, -90, -90), "rx rz"),
    ("rfingers", "rhand", (-1, 0, 0), 1.0, (0, -90, -90), "rx"),
]


def asf_text(length_unit: float = 0.45) -> str:
    out = [":version 1.10", ":name synth", ":units", "  mass 1.0", f"  length {length_unit}",
           "  angle deg", ":documentation", "  synthetic test skeleton", ":root",
           "   order TX TY TZ RX RY RZ", "   axis XYZ", "   position 0 0 0",
           "   orientation 0 0 0", ":bonedata"]
    for i, (name, _, d, length, ax, dof) in enumerate(BONES, 1):
        out += ["  begin", f"     id {i}", f"     name {name}",
                f"     direction {d[0]} {d[1]} {d[2]}", f"     length {length}",
                f"     axis {ax[0]} {ax[1]} {ax[2]}  XYZ"]
        if dof:
            out.append(f"    dof {dof}")
            out.append("    limits (-180.0 180.0)")
            out += ["           (-180.0 180.0)"] * (len(dof.split()) - 1)
        out.append("  end")
    out.append(":hierarchy")
    out.append("  begin")
    children: dict[str, list[str]] = {}
    for name, parent, *_ in BONES:
        children.setdefault(parent, []).append(name)
    for parent, kids in children.items():
        out.append(f"    {parent} {' '.join(kids)}")
    out.append("  end")
    return "\n".join(out) + "\n"


def amc_values(n_frames: int, seed: int = 0) -> list[list[tuple[str, list[float]]]]:
    """Smooth random motion: per frame a list of (bone, values)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / 120.0
    frames = []
    phases = rng.uniform(0, 2 * np.pi, size=(len(BONES) + 1, 6))
    amps = rng.uniform(5, 40, size=(len(BONES) + 1, 6))
    for k in range(n_frames):
        row = [("root", [float(v) for v in (
            3 * np.sin(t[k] + phases[0, 0]), 17 + np.sin(2 * t[k]), 4 * t[k],
            amps[0, 3] * 0.2 * np.sin(t[k] + phases[0, 3]),
            40 * np.sin(0.7 * t[k] + phases[0, 4]), 5 * np.sin(t[k]))])]
        for b, (name, _, _, _, _, dof) in enumerate(BONES, 1):
            if not dof:
                continue
            n = len(dof.split())
            vals = [float(amps[b, i] * np.sin(2.0 * t[k] * (1 + i) + phases[b, i])) for i in range(n)]
            row.append((name, vals))
        frames.append(row)
    return frames


def amc_text(n_frames: int = 40, seed: int = 0, header: str = "#!OML:ASF synth.asf\n") -> str:
    out = [header.rstrip("\n"), ":FULLY-SPECIFIED", ":DEGREES"]
    for k, row in enumerate(amc_values(n_frames, seed), 1):
        out.append(str(k))
        for name, vals in row:
            out.append(name + " " + " ".join(f"{v:.6f}" for v in vals))
    return "\n".join(out) + "\n"


def write_pair(folder, stem: str = "synth_walk", n_frames: int = 40, seed: int = 0,
               asf_name: str = "synth.asf"):
    """Write ``folder/asf_name`` and ``folder/stem.amc``; return the AMC path."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / asf_name).write_text(asf_text())
    amc = folder / f"{stem}.amc"
    amc.write_text(amc_text(n_frames, seed))
    return amc


def write_demo_set(folder, n_docs: int = 4, n_frames: int = 600):
    """Write ``folder/synth.asf`` and ``n_docs`` AMC documents; return their paths."""
    from pathlib import Path

    folder = Path(folder)
    return [write_pair(folder, stem=f"synth_{k:03d}", n_frames=n_frames, seed=k)
            for k in range(1, n_docs + 1)]


if __name__ == "__main__":  # pragma: no cover
    import sys

    paths = write_demo_set(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 4)
    print(f"wrote {len(paths)} synthetic AMC documents to {sys.argv[1]}")
