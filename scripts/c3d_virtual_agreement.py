"""Virtual markers on real motion (issue 36): the 41 Vicon markers placed rigidly on the
bones of every HDM05 clip (``tests/virtual_markers.py``: offsets as a real placement puts
them), written as Z-up C3D files in millimetres with the ``c3d`` package, read back through
the vicon-41 marker set; the 40 features compared with the AMC features frame by frame, and
the joints with the skeleton's joints.

Prints, per feature, the share of the 30 Hz frames of all clips where the two agree (and
the worst clip), and per joint the median and 95th percentile of the distance (cm). Run:

    .venv/bin/python scripts/c3d_virtual_agreement.py [--every N] [--csv OUT.csv]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "scripts"))

from _machine import machine  # noqa: E402
from c3d_support import write_c3d  # noqa: E402
from virtual_markers import place_markers  # noqa: E402

from mtanno.features import FEATURE_SETS  # noqa: E402
from mtanno.features.extract import extract_file  # noqa: E402
from mtanno.io import canonical_positions, read_channels, read_motion  # noqa: E402
from mtanno.io.rigs import CANONICAL_JOINTS  # noqa: E402

HDM05 = REPO.parent / "shared" / "data" / "hdm05_cut"


def clip_agreement(amc: Path, tmp: Path) -> tuple[np.ndarray, int, np.ndarray]:
    """(agreeing frames per feature, frames, joint distances frames × 22 in cm) of one
    clip read as AMC and as C3D of its virtual markers."""
    rig, ch = read_channels(amc)
    labels, pts = place_markers(rig, ch)
    zup = np.stack([pts[..., 0], -pts[..., 2], pts[..., 1]], axis=-1)  # Y up → Z up
    c3d = write_c3d(tmp / (amc.stem + ".c3d"), labels, zup)
    Xa, _ = extract_file(amc)
    Xc, _ = extract_file(c3d)
    ja = canonical_positions(read_motion(amc))
    jc = canonical_positions(read_motion(c3d))
    c3d.unlink()
    return (Xa == Xc).sum(axis=1), Xa.shape[1], np.linalg.norm(ja - jc, axis=2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=int, default=1, help="every Nth clip (default all)")
    ap.add_argument("--csv", type=Path, default=None, help="per-clip, per-feature agreement")
    args = ap.parse_args()
    clips = sorted(HDM05.glob("*/*.amc"))[::args.every]
    if not clips:
        sys.exit(f"no HDM05 clips in {HDM05}")
    print(machine())
    names = FEATURE_SETS["mr06-ak40"].names
    agree = np.zeros(len(names))
    total = 0
    per_clip, dists = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for amc in clips:
            a, n, d = clip_agreement(amc, Path(tmp))
            agree += a
            total += n
            per_clip.append((amc.name, a / n))
            dists.append(d)
    share = agree / total
    worst = np.array([c[1] for c in per_clip]).min(axis=0)
    print(f"{len(clips)} clips, {total} frames at 30 Hz; features agreeing on ≥ 98 % of "
          f"frames: {int((share >= 0.98).sum())} of {len(names)}; lowest "
          f"{share.min():.3f} ({names[int(share.argmin())]})")
    print("| feature | agreement | worst clip |")
    print("|---|---|---|")
    for k, nm in enumerate(names):
        print(f"| F{k + 1:02d} {nm} | {share[k]:.3f} | {worst[k]:.2f} |")
    D = np.concatenate(dists)
    print("| joint | median cm | 95th percentile cm |")
    print("|---|---|---|")
    for k, j in enumerate(CANONICAL_JOINTS):
        print(f"| {j} | {np.median(D[:, k]):.1f} | {np.percentile(D[:, k], 95):.1f} |")
    if args.csv:
        with open(args.csv, "w") as fh:
            fh.write("clip," + ",".join(names) + "\n")
            for name, s in per_clip:
                fh.write(name + "," + ",".join(f"{v:.4f}" for v in s) + "\n")


if __name__ == "__main__":
    main()
