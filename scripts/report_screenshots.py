"""The report page's screenshots in docs/ (README links them): the archive view and the
player, taken in headless Chromium (tests/browser.py) at 1400 × 900.

    .venv/bin/python scripts/report_screenshots.py ARCHIVE_REPORT/ PLAYER_REPORT/ [--out docs]
        [--filter wave] [--doc NAME --frame F]

ARCHIVE_REPORT is a report of many documents (the benchmark's 2 148 Bandai set-2 clips:
scripts/bench_report_player.py writes ``.cache/bench/report/rep2148_None``); the archive
view is shown filtered by ``--filter``, its fourth document selected. PLAYER_REPORT is a
report with motions and Δ curves (``make demo`` writes ``out/demo/report``); the player is
shown at ``--doc`` (default: its third document) and ``--frame``. Writes
``report_archive.png`` and ``report_player.png``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from browser import Browser, chromium  # noqa: E402

READY = "document.querySelector('[data-mtanno-player]').dataset.state === 'ready'"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("archive", type=Path)
    ap.add_argument("player", type=Path)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs")
    ap.add_argument("--filter", default="wave")
    ap.add_argument("--doc", default=None)
    ap.add_argument("--frame", type=int, default=700)
    a = ap.parse_args(argv)
    if chromium() is None:
        raise SystemExit("report_screenshots: headless Chromium not found")
    with tempfile.TemporaryDirectory() as profile:
        b = Browser(chromium(), Path(profile), width=1400, height=900)
        try:
            b.open((a.archive / "index.html").resolve().as_uri())
            b.wait_for(READY, "a motion")
            b.evaluate("(() => { const f = document.getElementById('mtanno-filter');"
                       f" f.value = {json.dumps(a.filter)}; f.dispatchEvent(new Event('input'));"
                       " mtanno.select(mtanno.shown[3], {frame: 30});"
                       " document.getElementById('archive').scrollIntoView(); })()")
            b.wait_for(READY, "the selected motion")
            (a.out / "report_archive.png").write_bytes(b.screenshot())
            page = (a.player / "index.html").resolve().as_uri()
            b.open(page)
            doc = a.doc or b.evaluate("mtanno.data.docs.name[2]")
            b.open(f"{page}#doc={doc}&frame={a.frame}")
            b.wait_for(READY, "the motion")
            b.evaluate("(() => { document.getElementById('archive').scrollIntoView();"
                       " document.getElementById('mtanno-list').focus(); })()")
            # the row at the frame is the current one in the review list under the player
            b.evaluate(f"(() => {{ const R = mtanno.data.rows, at = mtanno.rowsOf(mtanno.current)"
                       f".find(r => R.start[r] <= {a.frame} && {a.frame} <= R.end[r]);"
                       f" if (at !== undefined) mtanno.setRow(at); mtanno.player.seek({a.frame});"
                       " })()")
            (a.out / "report_player.png").write_bytes(b.screenshot())
        finally:
            b.close()
    for name in ("report_archive.png", "report_player.png"):
        print(f"{a.out / name}: {(a.out / name).stat().st_size / 1e3:.0f} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
