"""Speed of the issue-35 options against mtanno before issue 35, in the same run: ``tune``
with a background (the HDM05 protocol of ``bench_confidence.py``: 11 classes, train split,
about 200 background clips, ``--jobs 2``) and ``annotate`` of the 60-minute document with
the configuration each tune wrote (whole command, the configurations interleaved, median of
``--repeats``). Targets: tune within 1.5×, annotate within 1.3× of before.

Configurations: ``before`` (the package at git revision ``--base``, default b7ad3d8, copied
into OUT/base), ``default`` (the work tree, default options), ``classifier`` (the work
tree, ``--evidence`` the default kinds and the frame classifier), ``retarget+mirror``
(``--invariance retarget --invariance mirror``).

    .venv/bin/python scripts/bench_openworld.py [--repeats 3] [--out .cache/bench/confidence]
                                                [--only NAME ...]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402
from bench_confidence import SHARED, prepare  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
PY = str(REPO / ".venv" / "bin" / "python")
DEFAULT = ["--evidence", "cost", "--evidence", "length", "--evidence", "verify",
           "--evidence", "margin", "--evidence", "background"]
CONFIGS = {"before": [], "default": [], "classifier": [*DEFAULT, "--evidence", "classifier"],
           "retarget+mirror": ["--invariance", "retarget", "--invariance", "mirror"]}


def command(name: str, base: Path) -> list[str]:
    if name == "before":
        return [PY, "-P", "-c", f"import sys; sys.path.insert(0, {str(base)!r}); "
                "from mtanno.__main__ import main; sys.argv[0] = 'mtanno'; main()"]
    return [str(REPO / ".venv" / "bin" / "mtanno")]


def run(cmd: list[str], *args) -> float:
    t = time.perf_counter()
    subprocess.run([*cmd, *map(str, args)], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - t


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=REPO / ".cache" / "bench" / "confidence")
    ap.add_argument("--base", default="b7ad3d8")
    ap.add_argument("--only", nargs="*", default=list(CONFIGS))
    args = ap.parse_args()
    if not (SHARED / "hdm05_cut" / "clips.csv").exists():
        print(f"bench_openworld: {SHARED} not found", file=sys.stderr)
        return 2
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    base = out / "base" / args.base
    if not (base / "mtanno").is_dir():
        base.mkdir(parents=True, exist_ok=True)
        tar = subprocess.run(["git", "-C", str(REPO), "archive", args.base, "mtanno"],
                             check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(base)], input=tar, check=True)
    clips, doc = prepare(out)
    print(machine())
    train = ["--mt", out / "mt", "--manifest", clips, "--features-dir", out / "features",
             "--split", "train", "--jobs", "2", "--background", out / "background", "-q"]
    names = [n for n in CONFIGS if n in args.only]
    tune_s = {}
    for name in names:  # the first run of each also fills its JIT cache
        cfg = out / f"ow_{name}.toml"
        run(command(name, base), "tune", *train, *CONFIGS[name], "-o", cfg)
        tune_s[name] = run(command(name, base), "tune", *train, *CONFIGS[name], "-o", cfg)
        print(f"tune {name}: {tune_s[name]:.1f} s", flush=True)
    walls: dict[str, list[float]] = {n: [] for n in names}
    for name in names:  # warm-up
        run(command(name, base), "annotate", "--mt", out / "mt", "--classes",
            out / f"ow_{name}.toml", doc, "-o", out / "ow.csv", "-q")
    for _ in range(args.repeats):
        for name in names:
            walls[name].append(run(command(name, base), "annotate", "--mt", out / "mt",
                                   "--classes", out / f"ow_{name}.toml", doc, "-o",
                                   out / f"ow_{name}.csv", "-q"))
    ref = "before" if "before" in names else names[0]
    print(f"\n| configuration | tune (s) | × {ref} | annotate 60 min, median of "
          f"{args.repeats} (s) | × {ref} |\n|---|---|---|---|---|")
    a0 = statistics.median(walls[ref])
    for name in names:
        a = statistics.median(walls[name])
        print(f"| {name} | {tune_s[name]:.1f} | {tune_s[name] / tune_s[ref]:.2f} | {a:.2f} | "
              f"{a / a0:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
