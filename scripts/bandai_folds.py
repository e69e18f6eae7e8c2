#!/usr/bin/env python3
"""The Bandai set-2 leave-one-style-out protocol of scripts/experiment_bandai.sh (issue 10).

    bandai_folds.py unpack                 print the five unpacked style folders (.cache/data)
    bandai_folds.py folds FEATS OUT [--per 12] [--seed 0]

``folds`` reads the feature files ``FEATS/<style>/dataset-2_<content>_<style>_<id>.parquet``
(``mtanno features`` of each unpacked style folder) and writes, for every style S:

* ``OUT/S/train.csv`` — the training clips: ``--per`` clips per content of each of the four
  other styles, drawn with a seeded generator (``random.Random("SEED:STYLE:CONTENT")``, so
  the draw of a style does not depend on which style is held out); columns
  ``file,class,actor,take`` with ``actor`` = the style (the performer ``tune`` holds out);
* ``OUT/S/truth.csv`` — every clip of S as one document, labelled with its content over all
  its frames.
"""

from __future__ import annotations

import argparse
import random
import re
import sys
from collections import defaultdict
from pathlib import Path

STYLES = ("active", "elderly", "feminine", "masculine", "normal")
_NAME = re.compile(r"dataset-2_(?P<content>.+)_(?P<style>[a-z]+)_(?P<take>\d+)$")


def unpack() -> list[Path]:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from data_cache import SHARED_DATA, unpack_archive

    return [unpack_archive(SHARED_DATA / "bandai" / f"set2-{s}.tar.xz") / "data"
            for s in STYLES]


def clips(feats: Path) -> dict[tuple[str, str], list[tuple[str, str, int]]]:
    """(style, content) → sorted (feature path relative to FEATS without suffix, take,
    frames)."""
    import pyarrow.parquet as pq

    out: dict[tuple[str, str], list] = defaultdict(list)
    for style in STYLES:
        for p in sorted((feats / style).glob("*.parquet")):
            m = _NAME.match(p.stem)
            if m is None or m["style"] != style:
                raise SystemExit(f"bandai_folds: unexpected file {p}")
            out[(style, m["content"])].append((f"{style}/{p.stem}", m["take"],
                                               pq.ParquetFile(p).metadata.num_rows))
    return out


def folds(feats: Path, out: Path, per: int, seed: int) -> None:
    data = clips(feats)
    for held in STYLES:
        d = out / held
        d.mkdir(parents=True, exist_ok=True)
        rows = ["file,class,actor,take"]
        for (style, content), items in sorted(data.items()):
            if style == held:
                continue
            rng = random.Random(f"{seed}:{style}:{content}")
            for rel, take, _ in sorted(rng.sample(items, min(per, len(items)))):
                rows.append(f"{rel}.bvh,{content},{style},{take}")
        (d / "train.csv").write_text("\n".join(rows) + "\n")
        truth = ["doc,start,end,label"]
        for (style, content), items in sorted(data.items()):
            if style == held:
                truth += [f"{Path(rel).name},1,{n},{content}" for rel, _, n in items]
        (d / "truth.csv").write_text("\n".join(truth) + "\n")
        print(f"bandai_folds: {held}: {len(rows) - 1} training clips, {len(truth) - 1} "
              f"documents -> {d}", file=sys.stderr)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("unpack")
    f = sub.add_parser("folds")
    f.add_argument("feats", type=Path)
    f.add_argument("out", type=Path)
    f.add_argument("--per", type=int, default=12)
    f.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    if a.cmd == "unpack":
        for p in unpack():
            print(p)
        return 0
    folds(a.feats, a.out, a.per, a.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
