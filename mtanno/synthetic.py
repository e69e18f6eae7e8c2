"""Synthetic ASF/AMC data made by mtanno itself.

Used by the tests that must run without ``../shared/data`` and by ``make demo`` on a machine
without the real data. The skeleton is a hand-written HDM05-like rig (28 bones, the CMU/HDM05
bone names so the ``cmu-asf`` skeleton map applies). :func:`amc_text` makes smooth random
motion (sums of sines) for kernel tests.

:func:`write_class_set` writes a small labelled clip set of procedurally animated classes
(squat, kick, jumping jack, wave, walk) for several synthetic actors, laid out like the
HDM05 clips with a ``clips.csv`` manifest: ``python -m mtanno.synthetic OUTDIR``.
"""

from __future__ import annotations

from pathlib import Path

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


def asf_text(length_unit: float = 0.45, scale: float = 1.0) -> str:
    out = [":version 1.10", ":name synth", ":units", "  mass 1.0", f"  length {length_unit}",
           "  angle deg", ":documentation", "  synthetic test skeleton", ":root",
           "   order TX TY TZ RX RY RZ", "   axis XYZ", "   position 0 0 0",
           "   orientation 0 0 0", ":bonedata"]
    for i, (name, _, d, length, ax, dof) in enumerate(BONES, 1):
        out += ["  begin", f"     id {i}", f"     name {name}",
                f"     direction {d[0]} {d[1]} {d[2]}", f"     length {length * scale:.6g}",
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


# --- procedurally animated motion classes -------------------------------------------------

#: Standing pose (degrees, ASF dof order): legs vertical, arms hanging.
NEUTRAL: dict[str, list[float]] = {
    "root": [0.0, 17.2, 0.0, 0.0, 0.0, 0.0],
    "lfemur": [0.0, 0.0, -15.0], "rfemur": [0.0, 0.0, 15.0],
    "ltibia": [5.0], "rtibia": [5.0], "lfoot": [-10.0, 0.0], "rfoot": [-10.0, 0.0],
    "ltoes": [0.0], "rtoes": [0.0],
    "lowerback": [5.0, 0.0, 0.0], "upperback": [0.0, 0.0, 0.0], "thorax": [0.0, 0.0, 0.0],
    "lowerneck": [0.0, 0.0, 0.0], "upperneck": [0.0, 0.0, 0.0], "head": [0.0, 0.0, 0.0],
    "lclavicle": [0.0, 0.0], "rclavicle": [0.0, 0.0],
    "lhumerus": [-60.0, -60.0, 135.0], "rhumerus": [-60.0, 60.0, -135.0],
    "lradius": [20.0], "rradius": [20.0], "lwrist": [0.0], "rwrist": [0.0],
    "lhand": [0.0, 0.0], "rhand": [0.0, 0.0], "lfingers": [0.0], "rfingers": [0.0],
}
#: Upper arm raised above the head, to the side (found by search on this rig).
ARM_UP = {"lhumerus": (60.0, 60.0, -15.0), "rhumerus": (60.0, -60.0, 15.0)}


def _bump(u: np.ndarray) -> np.ndarray:
    return np.sin(np.pi * np.clip(u, 0.0, 1.0)) ** 2


def _towards(bone: str, target, b: np.ndarray):
    """Deltas moving ``bone`` from the neutral pose to ``target`` by the blend ``b``."""
    diff = [t - n for t, n in zip(target, NEUTRAL[bone])]
    return list(range(len(diff))), tuple(d * b for d in diff)


def _squat(u, a):
    b = _bump(u)
    return {"lfemur": ([0], -70 * a * b), "rfemur": ([0], -70 * a * b),
            "ltibia": ([0], 110 * a * b), "rtibia": ([0], 110 * a * b),
            "lowerback": ([0], 25 * a * b), "root": ([1], -5.0 * a * b)}


def _kick(u, a):
    b = _bump(u)
    ext = _bump(np.clip((u - 0.3) / 0.4, 0, 1))
    return {"lfemur": ([0], -85 * a * b), "ltibia": ([0], 90 * a * b - 80 * a * ext),
            "lowerback": ([0], -10 * a * b)}


def _jack(u, a):
    b = _bump(u) * a
    hop = 1.5 * a * np.abs(np.sin(2 * np.pi * u))
    return {"lhumerus": _towards("lhumerus", ARM_UP["lhumerus"], b),
            "rhumerus": _towards("rhumerus", ARM_UP["rhumerus"], b),
            "lfemur": ([2], 20 * b), "rfemur": ([2], -20 * b), "root": ([1], hop)}


def _wave(u, a):
    b = _bump(u) * a
    return {"rhumerus": _towards("rhumerus", ARM_UP["rhumerus"], b),
            "rradius": ([0], 70 * b * (0.6 + 0.4 * np.sin(6 * np.pi * u)))}


def _walk(u, a):
    s = np.sin(2 * np.pi * u)
    return {"lfemur": ([0], -30 * a * s), "rfemur": ([0], 30 * a * s),
            "ltibia": ([0], 40 * a * np.clip(-s, 0, None)),
            "rtibia": ([0], 40 * a * np.clip(s, 0, None)),
            "lradius": ([0], 15 * a * s), "rradius": ([0], -15 * a * s),
            "root": ([2], 14.0 * a * u)}


#: Class name → (animation, mean duration in seconds).
CLASSES = {"squat": (_squat, 1.6), "kickLFront": (_kick, 1.2), "jumpingJack": (_jack, 1.4),
           "waveRHand": (_wave, 2.0), "walk2Steps": (_walk, 1.3)}


def class_clip(label: str, *, rng: np.random.Generator, fps: float = 120.0,
               lead: float = 0.25) -> list[list[tuple[str, list[float]]]]:
    """One take of a class: neutral lead-in, the movement with random amplitude (±15 %)
    and duration (±20 %), neutral lead-out; AMC frames as (bone, values) lists."""
    anim, dur = CLASSES[label]
    dur *= rng.uniform(0.8, 1.2)
    amp = rng.uniform(0.85, 1.15)
    n_lead = int(lead * fps * rng.uniform(0.5, 1.5))
    n = int(dur * fps)
    u = np.concatenate([np.zeros(n_lead), np.linspace(0, 1, n), np.ones(n_lead)])
    offsets = anim(u, amp)
    frames = []
    for k in range(u.size):
        row = []
        for name in ["root"] + [b[0] for b in BONES if b[5]]:
            vals = list(NEUTRAL[name])
            if name in offsets:
                idx, delta = offsets[name]
                deltas = delta if isinstance(delta, tuple) else (delta,)
                for i, d in zip(idx, deltas):
                    vals[i] += float(d[k])
            row.append((name, vals))
        frames.append(row)
    return frames


def _amc_from_frames(frames, asf_name: str) -> str:
    out = [f"#!OML:ASF {asf_name}", ":FULLY-SPECIFIED", ":DEGREES"]
    for k, row in enumerate(frames, 1):
        out.append(str(k))
        for name, vals in row:
            out.append(name + " " + " ".join(f"{v:.6f}" for v in vals))
    return "\n".join(out) + "\n"


def write_class_set(folder, *, actors: tuple[str, ...] = ("a", "b", "c", "d"),
                    takes: int = 4, seed: int = 0) -> Path:
    """A labelled clip set like HDM05's: ``SYN_<actor>.asf`` (bone lengths ×0.9–1.1),
    ``<class>/SYN_<actor>_<class>_<take>.amc`` and ``clips.csv`` (file, actor, class, take,
    split; the last actor is the dev split). Returns the manifest path."""
    import csv

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    rows = []
    for i, actor in enumerate(actors):
        asf = f"SYN_{actor}.asf"
        (folder / asf).write_text(asf_text(scale=float(rng.uniform(0.9, 1.1))))
        for label in CLASSES:
            (folder / label).mkdir(exist_ok=True)
            for take in range(1, takes + 1):
                rel = f"{label}/SYN_{actor}_{label}_{take:03d}.amc"
                (folder / rel).write_text(_amc_from_frames(class_clip(label, rng=rng), asf))
                rows.append([rel, actor, label, f"{take:03d}",
                             "dev" if i == len(actors) - 1 else "train"])
    manifest = folder / "clips.csv"
    with open(manifest, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["file", "actor", "class", "take", "split"])
        w.writerows(rows)
    return manifest


def write_demo_set(folder, n_docs: int = 4, n_frames: int = 600):
    """Write ``folder/synth.asf`` and ``n_docs`` AMC documents; return their paths."""
    from pathlib import Path

    folder = Path(folder)
    return [write_pair(folder, stem=f"synth_{k:03d}", n_frames=n_frames, seed=k)
            for k in range(1, n_docs + 1)]


if __name__ == "__main__":  # pragma: no cover
    import sys

    manifest = write_class_set(sys.argv[1])
    print(f"wrote a synthetic labelled clip set ({len(CLASSES)} classes) -> {manifest}")
