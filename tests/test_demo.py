"""`make demo`, the README's first command, on its synthetic fallback data (no ../shared):
every stage runs, the outputs it announces exist, and the tuned annotation it reports is
the one `mtanno evaluate` scores from the written table."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.prefix) / "bin"


@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
@pytest.mark.skipif(not (BIN / "mtanno").exists(),
                    reason=f"no mtanno command in this environment ({BIN})")
def test_make_demo_on_synthetic_data(tmp_path):
    out = tmp_path / "out"
    # -o: never reinstall the environment the tests run in.
    run = subprocess.run(
        ["make", "-s", "-C", str(REPO), "-o", str(BIN / "mtanno"), "demo",
         f"VENV={sys.prefix}", f"SHARED={tmp_path / 'no-shared'}", f"OUT={out}"],
        capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    demo = out / "demo"
    assert "not found — a synthetic labelled clip set" in run.stdout
    for name in ("tuned.toml", "annotation_untuned.csv", "annotation.csv",
                 "annotation.parquet", "report.json", "report/index.html"):
        assert (demo / name).is_file(), name
    config = (demo / "tuned.toml").read_text()
    assert "[tau]" in config and "training inputs" in config

    lines = run.stdout.splitlines()
    timed = [x for x in lines if re.fullmatch(r"demo: .+ +\d+\.\d s", x)]
    assert [x.split()[1] for x in timed] == ["features", "learn-mt", "tune", "compose",
                                             "features", "annotate", "annotate", "report"]
    untuned = lines[lines.index(next(x for x in lines if x.startswith("demo: untuned"))) + 2]
    assert untuned.startswith("overall")
    report = json.loads((demo / "report.json").read_text())
    f1, f2 = report["frame"]["F"], report["segment"]["F"]
    tuned = next(x for x in reversed(lines) if x.startswith("overall")).split()
    assert float(tuned[3]) == pytest.approx(f1, abs=5e-4)
    assert float(tuned[7]) == pytest.approx(f2, abs=5e-4)
    # The synthetic classes are easy: both annotations find nearly every frame.
    assert f1 > 0.9 and float(untuned.split()[3]) > 0.8
    assert run.stdout.rstrip().endswith("report/index.html (open it in a browser)")
