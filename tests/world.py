"""A small complete mtanno world on synthetic data, built once per test session: clips,
feature files, templates, composed documents with truth, an index and an annotation
table. The hostile-input suite and the I/O-convention tests run every command on it.

Tests must not change it: they copy what they break into their own folder
(:func:`World.copy`), and :func:`checksums` lets them prove no input was written.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner

from mtanno import synthetic
from mtanno.cli import main


def cli(*args, input=None):
    """Run ``mtanno ARGS`` in this process; exceptions are kept in the result, never
    raised, so a traceback would show as ``result.exception``."""
    return CliRunner().invoke(main, [str(a) for a in args], input=input)


@dataclass
class World:
    root: Path
    clips: Path          # synthetic clip tree with SYN_<actor>.asf and clips.csv
    manifest: Path
    feats: Path          # feature files of the clips, feats/<class>/<clip>.parquet
    mt: Path             # one template per class
    docs: Path           # composed documents (AMC + ASF + truth.csv)
    docfeats: Path       # feature files of the documents
    truth: Path
    index: Path
    annotation: Path     # annotation table (CSV) of the documents
    labels: Path         # a mocap6-style labels.json for `truth mocap6`

    def copy(self, item: Path, dest: Path) -> Path:
        """Copy a file or folder of the world to ``dest`` (tests break copies only)."""
        dest.parent.mkdir(parents=True, exist_ok=True)
        if item.is_dir():
            shutil.copytree(item, dest)
        else:
            shutil.copyfile(item, dest)
        return dest

    @property
    def doc_files(self) -> list[Path]:
        return sorted(self.docfeats.glob("*.parquet"))

    @property
    def template(self) -> Path:
        return self.mt / "squat.json"


def _check(r, what):
    if r.exit_code != 0:
        raise RuntimeError(f"building the test world failed at {what}: {r.output}")


def build_world(root: Path) -> World:
    clips = root / "clips"
    manifest = synthetic.write_class_set(clips, actors=("a", "b", "c"), takes=2, seed=2)
    feats, mt = root / "feats", root / "mt"
    _check(cli("features", clips, "-o", feats, "-q"), "features")
    _check(cli("learn-mt", "--manifest", manifest, "--features-dir", feats, "--split", "train",
               "-o", mt, "-q"), "learn-mt")
    docs, docfeats = root / "docs", root / "docfeats"
    _check(cli("compose", manifest, "--actor", "c", "--docs", "2", "--seed", "5", "-o", docs),
           "compose")
    _check(cli("features", docs, "-o", docfeats, "-q"), "features of the documents")
    index = root / "idx"
    _check(cli("index", docfeats, "-o", index, "-q"), "index")
    annotation = root / "annotation.csv"
    _check(cli("annotate", "--mt", mt, docfeats, "-o", annotation, "-q"), "annotate")
    labels = root / "labels.json"
    labels.write_text(json.dumps({
        "fps": 120, "classes": ["JumpJack", "Twist"],
        "documents": {"13_29": {"frames": 480, "segments": [
            {"label": "JumpJack", "start": 1, "end": 240},
            {"label": "Twist", "start": 241, "end": 480}]}}}))
    return World(root, clips, manifest, feats, mt, docs, docfeats, docs / "truth.csv", index,
                 annotation, labels)


@pytest.fixture(scope="session")
def world(tmp_path_factory) -> World:
    return build_world(tmp_path_factory.mktemp("world"))


def checksums(*roots: Path) -> dict[str, str]:
    """SHA-256 of every file under ``roots`` (files or folders), by path."""
    out = {}
    for root in roots:
        files = [root] if root.is_file() else sorted(p for p in root.rglob("*") if p.is_file())
        for p in files:
            out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def temporaries(*roots: Path) -> list[Path]:
    """Temporary files and folders of interrupted writes under ``roots``."""
    out = []
    for root in roots:
        if not root.exists():
            continue
        for p in root.rglob("*"):
            if p.name.endswith(".tmp") or p.name.startswith(".tmp-"):
                out.append(p)
    return out


def assert_one_line(r, path: Path | str, *, codes=(1, 2)) -> str:
    """The command failed cleanly: exit code in ``codes``, no traceback, and exactly one
    ``mtanno:`` error line, which names ``path``. Returns that line."""
    assert r.exception is None or isinstance(r.exception, SystemExit), (
        f"traceback: {r.exception!r}\n{r.output}")
    assert "Traceback" not in r.output, r.output
    assert r.exit_code in codes, (r.exit_code, r.output)
    lines = [ln for ln in r.output.splitlines() if ln.startswith("mtanno:")]
    assert len(lines) == 1, r.output
    assert str(path) in lines[0], (str(path), lines[0])
    return lines[0]




#: Longest wait for another process to reach a point (a loaded machine is slow, not stuck).
HANG = 120.0


def wait_for(condition, proc, what: str, *, hang: float = HANG, poll: float = 0.01) -> None:
    """Wait until ``condition()`` holds — an event of process ``proc`` (a file written, a
    line printed), never a fixed time; fail if the process ends first or after ``hang``
    seconds."""
    import time

    deadline = time.monotonic() + hang
    while not condition():
        if proc.poll() is not None:
            pytest.fail(f"the run ended (exit {proc.returncode}) before {what}: "
                        f"{proc.communicate()[1]}")
        if time.monotonic() > deadline:
            pytest.fail(f"the run did not get to {what} in {hang:.0f} s")
        time.sleep(poll)


def children(pid: int) -> list[int]:
    """The process ids whose parent is ``pid`` (read from /proc)."""
    kids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                kids.append(int(d.name))
    return kids
