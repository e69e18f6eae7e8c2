#!/usr/bin/env python3
"""Speed of two checkouts in the same run: each checkout's own benchmark scripts, run in
turn (A, B, A, B, …) so that both see the same machine load, and the figures of each round
printed side by side (issue 23: a move of code must not cost speed).

Each checkout needs its own ``.venv`` (``make install``) and reads ``../shared/data``
beside it. The benchmarks are ``scripts/bench_annotate.py`` and ``scripts/bench_features.py
--whole-only``; every line of their output that holds a time (``s``, ``ms``) is kept.

Usage: ``python scripts/bench_interleaved.py BEFORE_REPO AFTER_REPO [--rounds 2]``
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402

BENCHES = (["scripts/bench_annotate.py", "--repeats", "3"],
           ["scripts/bench_features.py", "--whole-only", "--repeats", "3"])
_TIMED = re.compile(r"\d[\d.,]*\s*(ms|s)\b")


def run(repo: Path, bench: list[str]) -> list[str]:
    """The timed lines of one benchmark run in ``repo``."""
    out = subprocess.run([str(repo / ".venv" / "bin" / "python"), *bench], cwd=repo,
                         capture_output=True, text=True, check=True).stdout
    return [line.strip() for line in out.splitlines() if _TIMED.search(line)
            and not line.startswith("machine")]


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args(argv)
    print(f"machine: {machine()}")
    for bench in BENCHES:
        for r in range(1, args.rounds + 1):
            for name, repo in (("before", args.before), ("after", args.after)):
                print(f"\n== {' '.join(bench)} · round {r} · {name} ({repo})", flush=True)
                for line in run(repo.resolve(), bench):
                    print(f"   {line}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
