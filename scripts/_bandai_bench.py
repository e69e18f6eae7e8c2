"""The Bandai set-2 inputs of the archive-size benchmarks (issue 34), made once under an
output folder and reused: the feature files (with poses) of all five styles, the pooled
training manifests of ``bandai_folds.py pooled`` (all five styles, ``per`` clips per
content and style: 10 contents × 5 styles × per clips) with their templates, and a tuned
configuration of the 600-clip set.

Used by ``bench_tune.py`` (the growth curve of ``mtanno tune``) and ``bench_clips.py``
(many short files against one long document).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"
MTANNO = [str(REPO / ".venv" / "bin" / "mtanno")]
PY = str(REPO / ".venv" / "bin" / "python")
STYLES = ("active", "elderly", "feminine", "masculine", "normal")


def run(args: list[str]) -> None:
    subprocess.run(MTANNO + args, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)


def available() -> bool:
    return all((SHARED / "bandai" / f"set2-{s}.tar.xz").is_file() for s in STYLES)


def features(out: Path) -> Path:
    """``out/features/<style>/*.parquet`` (with poses) of the five unpacked set-2 archives."""
    feats = out / "features"
    if not all((feats / s).is_dir() for s in STYLES):
        dirs = subprocess.run([PY, str(REPO / "scripts" / "bandai_folds.py"), "unpack"],
                              check=True, capture_output=True, text=True).stdout.split()
        for d in dirs:
            style = Path(d).parent.name.removeprefix("set2-")
            if not (feats / style).is_dir():
                run(["features", d, "-o", str(feats / style), "--poses", "--jobs", "2", "-q"])
    return feats


def training(out: Path, per: int) -> tuple[Path, Path]:
    """(manifest, templates) of the pooled training set of ``per`` clips per content and
    style (``bandai_folds.py pooled``), made once."""
    feats = features(out)
    manifest = out / f"train{per}.csv"
    if not manifest.is_file():
        subprocess.run([PY, str(REPO / "scripts" / "bandai_folds.py"), "pooled", str(feats),
                        str(manifest), "--per", str(per)], check=True,
                       stderr=subprocess.DEVNULL)
    mt = out / f"mt{per}"
    if not mt.is_dir():
        run(["learn-mt", "--manifest", str(manifest), "--features-dir", str(feats), "-o",
             str(mt), "-q"])
    return manifest, mt


def tune_args(out: Path, per: int) -> list[str]:
    """The ``mtanno tune`` arguments of the issue's run on the pooled set of ``per``."""
    manifest, mt = training(out, per)
    return ["tune", "--mt", str(mt), "--manifest", str(manifest), "--features-dir",
            str(out / "features"), "--seed", "5", "--jobs", "2"]


def tuned(out: Path, per: int = 12) -> tuple[Path, Path]:
    """(templates, tuned configuration) of the pooled set of ``per``, tuned once."""
    _, mt = training(out, per)
    cfg = out / f"tuned{per}.toml"
    if not cfg.is_file():
        run([*tune_args(out, per), "-o", str(cfg), "-q"])
    return mt, cfg


if __name__ == "__main__":
    sys.exit("a helper of bench_tune.py and bench_clips.py")
