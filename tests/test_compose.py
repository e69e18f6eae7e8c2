"""Composed documents: reproducible, exact truth, continuous root at the seams."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mtanno import synthetic
from mtanno.errors import MtannoError
from mtanno.evaluation.compose import Clip, _root_matrix, _yaw, _zyx_angles, compose_documents, read_clips
from mtanno.features.extract import features_from_motion
from mtanno.io import canonical_positions, read_motion
from mtanno.labels.truth import read_truth


@pytest.fixture
def clips(tmp_path):
    src = tmp_path / "clips"
    out = []
    for k, label in enumerate(["walk", "jump", "walk", "wave", "jump"]):
        p = synthetic.write_pair(src, stem=f"synth_c{k}", n_frames=37 + 10 * k, seed=k)
        out.append(Clip(p, label, "s"))
    return out


def test_euler_round_trip():
    rng = np.random.default_rng(0)
    for _ in range(50):
        rx, ry, rz = rng.uniform(-1.4, 1.4, 3)
        m = _root_matrix(rx, ry, rz)
        assert np.allclose(_root_matrix(*_zyx_angles(m)), m)


def test_reproducible_and_truth_exact(clips, tmp_path):
    docs1, truth1 = compose_documents(clips, tmp_path / "a", n_docs=3, seed=7, pause=6)
    docs2, truth2 = compose_documents(clips, tmp_path / "b", n_docs=3, seed=7, pause=6)
    assert truth1 == truth2
    assert [p.read_bytes() for p in docs1] == [p.read_bytes() for p in docs2]
    _, truth3 = compose_documents(clips, tmp_path / "c", n_docs=3, seed=8, pause=6)
    assert truth3 != truth1
    assert read_truth(tmp_path / "a" / "truth.csv") == truth1
    lengths = {c.path.stem: 37 + 10 * k for k, c in enumerate(clips)}
    for doc in docs1:
        m = read_motion(doc)
        X, native = features_from_motion(m)
        segs = [s for s in truth1 if s.doc == doc.stem]
        assert len(segs) == len(clips)
        total = sum(lengths.values()) + 6 * len(clips)
        assert m.n_frames == total
        # each segment holds exactly the analysis frames of its clip's native frames
        for s in segs:
            nat = native[s.start - 1:s.end]
            assert nat.size and np.all(np.diff(nat) == 4)
        covered = sum(s.length for s in segs)
        assert covered < X.shape[1]  # pauses are unlabelled
        starts = [s.start for s in segs]
        assert starts == sorted(starts) and all(a.end < b.start for a, b in zip(segs, segs[1:]))


def test_root_continuous_at_seams(clips, tmp_path):
    docs, truth = compose_documents(clips, tmp_path / "a", n_docs=1, seed=3)
    m = read_motion(docs[0])
    root = canonical_positions(m)[:, 0]
    step = np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=1)
    # synthetic clips move 4 file units/s forward: a seam must not jump more than a frame does
    assert step.max() < 3 * np.median(step) + 1e-6
    h = np.unwrap(np.arctan2(m.heading[:, 2], m.heading[:, 0]))
    assert np.degrees(np.abs(np.diff(h))).max() < 5


def test_yaw_of_turned_matrix():
    m = _root_matrix(0.2, 0.3, -0.1)
    from mtanno.io.skeleton import euler_matrix

    assert math.isclose(_yaw(euler_matrix(1, 0.5) @ m), _yaw(m) + 0.5, abs_tol=1e-12)


def test_manifest_and_errors(tmp_path):
    (tmp_path / "clips.csv").write_text("file,class,actor,split\na.amc,jump,x,dev\nb.amc,kick,y,train\n")
    (tmp_path / "a.amc").write_text("")
    with pytest.raises(MtannoError, match=r"clips.csv:3: clip file .*b.amc not found"):
        read_clips(tmp_path / "clips.csv")
    got = read_clips(tmp_path / "clips.csv", actor="x")
    assert got == [Clip(tmp_path / "a.amc", "jump", "x")]
    with pytest.raises(MtannoError, match="no clips"):
        read_clips(tmp_path / "clips.csv", actor="z")
    (tmp_path / "bad.csv").write_text("name,label\n")
    with pytest.raises(MtannoError, match="bad.csv:1: needs the columns file, class"):
        read_clips(tmp_path / "bad.csv")
    with pytest.raises(MtannoError, match="no clips to compose"):
        compose_documents([], tmp_path / "o")


def test_in_order(clips, tmp_path):
    _, truth = compose_documents(clips, tmp_path / "o", n_docs=1, shuffle=False)
    assert [s.label for s in truth] == [c.label for c in clips]


def test_compose_command(clips, tmp_path):
    from click.testing import CliRunner

    from mtanno.cli import main

    manifest = tmp_path / "m.csv"
    manifest.write_text("file,class,actor\n" + "".join(
        f"{c.path.relative_to(tmp_path)},{c.label},s\n" for c in clips))
    r = CliRunner().invoke(main, ["compose", str(manifest), "-o", str(tmp_path / "docs"),
                                  "--docs", "2", "--seed", "4", "--pause", "3"])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "docs").iterdir()) == [
        "compose.json", "synth.asf", "synth_doc01.amc", "synth_doc02.amc", "truth.csv",
        "truth.csv.meta.json"]
    r = CliRunner().invoke(main, ["features", str(tmp_path / "docs"), "-o", str(tmp_path / "f")])
    assert r.exit_code == 0, r.output
