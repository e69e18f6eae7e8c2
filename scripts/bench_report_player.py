"""Benchmark of ``mtanno report --motions`` at archive size (issue 33 targets: all 2 148
Bandai set-2 clips, and 10 000 documents made from them by copying: the whole command
< 60 s on 2 cores, its output < 100 MB in all; in headless Chromium the page's
DOMContentLoaded < 2 s and a selected document's player shown < 0.5 s).

Setup (cached in ``--out``): the five set-2 archives unpacked (``.cache/data``), their
features, templates per content learned from the fold that holds out style ``normal``
(``scripts/bandai_folds.py``: 12 clips per content of each other style), every clip
annotated with them, the truth of every clip (whole clip, its content). For 10 000
documents the clips are repeated under new names (hard links to the same BVH files, new
rows and truth).

Timed, for each archive: the whole command ``mtanno report ANNOTATION --truth TRUTH
--motions STYLE_DIR... -o DIR -q --jobs 2`` into a fresh folder (median of ``--repeats``, peak memory
from ``/usr/bin/time -v``), then once more into the same folder (a rerun: the figures and
data files are reused); the output's size and file count. The same run with one data file
per document (``chunk_bytes=0``; the API, as a whole ``python -c`` run) against the default
files of about 256 KB: time, size, files, time to show. In Chromium (``tests/browser.py``;
the page loaded ``--loads`` times afresh): DOMContentLoaded from the navigation timing, and
for ``--picks`` documents from different data files the time from selecting it to its
player's ``mtanno:shown`` event with the motion drawn (a data file loaded by a script
element, inflated and drawn), medians.

    .venv/bin/python scripts/bench_report_player.py [--repeats 3] [--sizes 2148 10000]
        [--out .cache/bench/report] [--baseline DIR [--baseline-docs 500]]

``--baseline DIR``: a folder holding an earlier ``mtanno`` package (the page before issue
33: ``git archive b1c3633 mtanno | tar -x -C DIR``), run on the same first
``--baseline-docs`` documents beside this one (``PYTHONPATH=DIR``), without and with
``--motions``: the peer of this benchmark, in the same run.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from _machine import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
MTANNO = REPO / ".venv" / "bin" / "mtanno"
PYTHON = REPO / ".venv" / "bin" / "python"
STYLES = ("active", "elderly", "feminine", "masculine", "normal")


def run(*args, env=None) -> tuple[float, int]:
    """Wall time (s) and peak resident memory (KB) of a whole command."""
    t0 = time.perf_counter()
    r = subprocess.run(["/usr/bin/time", "-v", *map(str, args)], capture_output=True,
                       text=True, env=env)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"bench_report_player: {' '.join(map(str, args))} failed:\n"
                         f"{r.stderr[-2000:]}")
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr).group(1))
    return wall, rss


def setup(out: Path) -> tuple[list[Path], Path, Path]:
    """The five unpacked style folders, the annotation of every clip and its truth."""
    from data_cache import SHARED_DATA, unpack_archive

    dirs = [unpack_archive(SHARED_DATA / "bandai" / f"set2-{s}.tar.xz") / "data"
            for s in STYLES]
    feats = out / "features"
    for s, d in zip(STYLES, dirs):
        if not (feats / s).is_dir():
            subprocess.run([MTANNO, "features", d, "-o", feats / s, "--jobs", "2", "-q"],
                           check=True)
    if not (out / "folds" / "normal" / "train.csv").exists():
        subprocess.run([PYTHON, REPO / "scripts" / "bandai_folds.py", "folds", feats,
                        out / "folds"], check=True)
    if not (out / "mt").is_dir():
        subprocess.run([MTANNO, "learn-mt", "--manifest", out / "folds" / "normal" / "train.csv",
                        "--features-dir", feats, "-o", out / "mt", "-q"], check=True)
    ann = out / "annotation.csv"
    if not ann.exists():
        subprocess.run([MTANNO, "annotate", "--mt", out / "mt", *(feats / s for s in STYLES),
                        "-o", ann, "--jobs", "2", "-q"], check=True)
    truth = out / "truth.csv"
    if not truth.exists():
        lines = ["doc,start,end,label"]
        for s in STYLES:
            lines += (out / "folds" / s / "truth.csv").read_text().splitlines()[1:]
        truth.write_text("\n".join(lines) + "\n")
    return dirs, ann, truth


def copies(out: Path, dirs: list[Path], ann: Path, truth: Path, n: int
           ) -> tuple[list[Path], Path, Path]:
    """``n`` documents: the clips repeated under new names (``NAME~K``; hard links to the
    same files), with their annotation rows, recorded frame counts and truth."""
    folder = out / f"copies{n}"
    motions = folder / "motions"
    if not (folder / "annotation.csv").exists():
        clips = sorted(p for d in dirs for p in d.glob("*.bvh"))
        shutil.rmtree(folder, ignore_errors=True)
        motions.mkdir(parents=True)
        names = []
        for i in range(n):
            src = clips[i % len(clips)]
            name = f"{src.stem}~{i // len(clips)}"
            try:
                os.link(src, motions / f"{name}.bvh")
            except OSError:
                shutil.copyfile(src, motions / f"{name}.bvh")
            names.append((src.stem, name))
        with open(ann, newline="") as fh:
            rows = list(csv.reader(fh))
        head, by_doc = rows[0], {}
        for r in rows[1:]:
            by_doc.setdefault(r[0], []).append(r)
        frames = json.loads(ann.with_name(ann.name + ".meta.json").read_text())["documents"]
        with open(truth, newline="") as fh:
            t_rows = list(csv.reader(fh))
        t_by = {r[0]: r for r in t_rows[1:]}
        out_rows, out_truth, out_frames = [head], [t_rows[0]], {}
        for stem, name in names:
            out_rows += [[name, *r[1:]] for r in by_doc.get(stem, [])]
            out_truth.append([name, *t_by[stem][1:]])
            out_frames[name] = frames[stem]
        for path, table in ((folder / "annotation.csv", out_rows),
                            (folder / "truth.csv", out_truth)):
            with open(path, "w", newline="") as fh:
                csv.writer(fh).writerows(table)
        (folder / "annotation.csv.meta.json").write_text(json.dumps({"documents": out_frames}))
    return [motions], folder / "annotation.csv", folder / "truth.csv"


def size(folder: Path) -> tuple[float, int]:
    files = [p for p in folder.rglob("*") if p.is_file()]
    return sum(p.stat().st_size for p in files) / 1e6, len(files)


def browse(page: Path, loads: int, picks: int, profile: Path) -> tuple[float, float, float, int]:
    """Median DOMContentLoaded (ms) of ``loads`` fresh loads; median and largest time (ms)
    from selecting a document to its player shown, over ``picks`` documents of different
    data files (each file's first load)."""
    from browser import Browser, chromium

    if chromium() is None:
        raise SystemExit("bench_report_player: headless Chromium not found")
    b = Browser(chromium(), profile, width=1400, height=900)
    try:
        dcl = []
        for _ in range(loads):
            b.open(page.as_uri())
            dcl.append(b.evaluate("performance.getEntriesByType('navigation')[0]"
                                  ".domContentLoadedEventEnd"))
            b.wait_for("['ready', 'none', 'error'].includes(document.querySelector("
                       "'[data-mtanno-player]').dataset.state)", "the first document")
        b.open(page.as_uri())
        b.wait_for("['ready', 'none', 'error'].includes(document.querySelector("
                   "'[data-mtanno-player]').dataset.state)", "the first document")
        docs = b.evaluate("(() => { const D = mtanno.data.docs, seen = new Set([D.chunk["
                          "mtanno.current]]), out = []; for (let d = 0; d < D.name.length;"
                          " d += 7) if (D.chunk[d] >= 0 && !seen.has(D.chunk[d])) {"
                          " seen.add(D.chunk[d]); out.push(d); } return out; })()")
        step = max(1, len(docs) // picks)
        shown, states = [], []
        for d in docs[::step][:picks]:
            ms, state = b.evaluate(
                "new Promise(ok => { const p = document.querySelector('[data-mtanno-player]');"
                " const t0 = performance.now(); p.addEventListener('mtanno:shown', e =>"
                " ok([performance.now() - t0, e.detail.state]), {once: true});"
                f" mtanno.select({d}, {{hash: true}}); }})")
            shown.append(ms)
            states.append(state)
        return statistics.median(dcl), statistics.median(shown), max(shown), states.count("ready")
    finally:
        b.close()


def report(args_motions, ann, truth, out: Path, *, chunk_bytes=None, jobs=1
           ) -> tuple[float, int]:
    if chunk_bytes is None:
        return run(MTANNO, "report", ann, "--truth", truth,
                   *(a for m in args_motions for a in ("--motions", m)), "-o", out, "-q",
                   "--jobs", jobs)
    code = ("from mtanno.evaluation.report import ReportOptions, report_files; "
            f"report_files([{str(ann)!r}], {str(out)!r}, truth_path={str(truth)!r}, "
            f"motions={[str(m) for m in args_motions]!r}, "
            f"options=ReportOptions(chunk_bytes={chunk_bytes}), failures=[], jobs={jobs})")
    return run(PYTHON, "-c", code)


def subset(out: Path, ann: Path, truth: Path, dirs: list[Path], n: int
           ) -> tuple[list[Path], Path, Path]:
    """The first ``n`` documents (by name): their annotation rows, truth and motions (a
    folder of links)."""
    folder = out / f"first{n}"
    if not (folder / "annotation.csv").exists():
        clips = {p.stem: p for d in dirs for p in d.glob("*.bvh")}
        keep = sorted(clips)[:n]
        shutil.rmtree(folder, ignore_errors=True)
        (folder / "motions").mkdir(parents=True)
        for d in keep:
            os.symlink(clips[d].resolve(), folder / "motions" / f"{d}.bvh")
        wanted = set(keep)
        for src, name in ((ann, "annotation.csv"), (truth, "truth.csv")):
            with open(src, newline="") as fh:
                rows = list(csv.reader(fh))
            with open(folder / name, "w", newline="") as fh:
                csv.writer(fh).writerows([rows[0]] + [r for r in rows[1:] if r[0] in wanted])
        frames = json.loads(ann.with_name(ann.name + ".meta.json").read_text())["documents"]
        (folder / "annotation.csv.meta.json").write_text(json.dumps(
            {"documents": {d: frames[d] for d in keep}}))
    return [folder / "motions"], folder / "annotation.csv", folder / "truth.csv"


def baseline(a, dirs, ann, truth) -> None:
    """This report and the one of ``--baseline`` on the same first documents."""
    motions, an, tr = subset(a.out, ann, truth, dirs, a.baseline_docs)
    env = {**os.environ, "PYTHONPATH": str(a.baseline.resolve())}
    print(f"\n== the first {a.baseline_docs} documents: this page and the one in {a.baseline}")
    for label, m in (("without --motions", []), ("with --motions", motions)):
        got = {}
        for who, e in (("this", None), ("baseline", env)):
            dest = a.out / f"base_{who}_{bool(m)}"
            shutil.rmtree(dest, ignore_errors=True)
            wall, rss = run(MTANNO, "report", an, "--truth", tr,
                            *(x for d in m for x in ("--motions", d)), "-o", dest, "-q",
                            env=e)
            got[who] = (wall, rss, *size(dest), (dest / "index.html").stat().st_size / 1e6)
        for who in ("this", "baseline"):
            wall, rss, mb, files, page = got[who]
            print(f"{label}, {who}: {wall:.1f} s, peak RSS {rss / 1024:.0f} MB, {mb:.1f} MB "
                  f"in {files} files, page {page:.2f} MB")
        print(f"{label}: {got['baseline'][0] / got['this'][0]:.1f}× faster, "
              f"{got['baseline'][2] / got['this'][2]:.1f}× smaller")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--loads", type=int, default=5)
    ap.add_argument("--picks", type=int, default=15)
    ap.add_argument("--sizes", type=int, nargs="*", default=[2148, 10000])
    ap.add_argument("--out", type=Path, default=REPO / ".cache" / "bench" / "report")
    ap.add_argument("--jobs", type=int, default=2, help="report --jobs (default: the two "
                    "cores the targets name)")
    ap.add_argument("--baseline", type=Path, default=None)
    ap.add_argument("--baseline-docs", type=int, default=500)
    a = ap.parse_args(argv)
    print(machine())
    dirs, ann, truth = setup(a.out)
    with open(ann, newline="") as fh:
        n_rows = sum(1 for _ in fh) - 1
    print(f"Bandai set 2: {len(list(ann.parent.glob('features/*/*.parquet')))} clips, "
          f"{n_rows} annotation rows")
    if a.baseline is not None:
        baseline(a, dirs, ann, truth)
    for n in a.sizes:
        motions, an, tr = (dirs, ann, truth) if n == 2148 else copies(a.out, dirs, ann,
                                                                        truth, n)
        print(f"\n== {n} documents (report --jobs {a.jobs})")
        for label, chunk in (("data files of ~256 KB (default)", None),
                             ("one data file per document", 0)):
            runs = []
            for _ in range(a.repeats):
                dest = a.out / f"rep{n}_{chunk}"
                shutil.rmtree(dest, ignore_errors=True)
                runs.append(report(motions, an, tr, dest, chunk_bytes=chunk, jobs=a.jobs))
            rerun = report(motions, an, tr, dest, chunk_bytes=chunk, jobs=a.jobs)
            mb, files = size(dest)
            page_mb = (dest / "index.html").stat().st_size / 1e6
            print(f"{label}: whole command {statistics.median(w for w, _ in runs):.1f} s "
                  f"(median of {a.repeats}; runs {', '.join(f'{w:.1f}' for w, _ in runs)}), "
                  f"peak RSS {max(r for _, r in runs) / 1024:.0f} MB; rerun into the same "
                  f"folder {rerun[0]:.1f} s; output {mb:.1f} MB in {files} files, page "
                  f"{page_mb:.2f} MB")
            dcl, shown, worst, ready = browse(dest / "index.html", a.loads, a.picks,
                                              a.out / f"profile{n}_{chunk}")
            print(f"  Chromium: DOMContentLoaded {dcl:.0f} ms (median of {a.loads}); "
                  f"player shown {shown:.0f} ms median, {worst:.0f} ms at most (of "
                  f"{a.picks} documents in different data files, {ready} with a motion)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
