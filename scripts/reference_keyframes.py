#!/usr/bin/env python3
"""Write the reference implementation's hand-made keyframe queries as keyframe files.

Reads ``../shared/data/reference/keyframes/manual_keyframes.csv`` (one of its three tables,
default ``manualKeyframesForAnnotation_AVR``, the one the reference annotation script uses)
and writes one ``mtanno.keyframes/1`` file per class into OUTDIR, so that the experiments
can annotate "with the reference's keyframes" through the same command as with learned
ones. Feature sets map to mtanno's groups: AK_upper → upper (F01–F14), AK_lower → lower
(F15–F26), AK_mix_avr → mix (F27–F40); AK_mix (F27–F39) is written as a group ``mix39``.
Extension: 2·(q1−1), 2·(K−qn) (the annotation script's).

    scripts/reference_keyframes.py OUTDIR [--table NAME] [--shared ../shared/data]
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from mtanno.features import FEATURE_NAMES, GROUPS
from mtanno.keyframes import Extension, Gap, Keyframe, KeyframeQuery, save_keyframes

SETS = {
    "AK_upper": ("upper", list(GROUPS["upper"])),
    "AK_lower": ("lower", list(GROUPS["lower"])),
    "AK_mix_avr": ("mix", list(GROUPS["mix"])),
    "AK_mix": ("mix39", list(range(26, 39))),
}


def reference_queries(csv_path: Path, table: str) -> dict[str, KeyframeQuery]:
    with open(csv_path, newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["source"] == table]
    if not rows:
        raise SystemExit(f"reference_keyframes: no rows of table {table!r} in {csv_path}")
    by_class: dict[str, list[dict]] = {}
    for r in rows:
        by_class.setdefault(r["class"], []).append(r)
    groups = {g: tuple(FEATURE_NAMES[i] for i in feats) for g, feats in SETS.values()}
    out = {}
    for cls, rs in by_class.items():
        rs.sort(key=lambda r: int(r["keyframe"]))
        kfs, gaps = [], []
        for j, r in enumerate(rs):
            kfs.append(Keyframe(SETS[r["feature_set"]][0], r["vector"], int(r["position"])))
            if j:
                gaps.append(Gap.from_stiffness(kfs[-1].position - kfs[-2].position,
                                               rs[j - 1]["stiffness_to_next"]))
        out[cls] = KeyframeQuery(
            cls, "mr06-ak40", groups, kfs, gaps, int(rs[0]["template_length"]), Extension(2, 0),
            provenance={"method": f"reference hand-made keyframes ({table})",
                        "source": str(csv_path)})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir", type=Path)
    ap.add_argument("--table", default="manualKeyframesForAnnotation_AVR")
    ap.add_argument("--shared", type=Path,
                    default=Path(__file__).resolve().parents[1].parent / "shared" / "data")
    a = ap.parse_args(argv)
    queries = reference_queries(a.shared / "reference" / "keyframes" / "manual_keyframes.csv",
                                a.table)
    for cls, q in queries.items():
        save_keyframes(a.outdir / f"{cls}.json", q)
    print(f"reference_keyframes: {len(queries)} queries ({a.table}) -> {a.outdir}",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
