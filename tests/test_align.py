"""Time alignment (mtanno.align, MRC05 §7) against the slow oracles of tests/naive_align.py,
the properties the two stages promise, and `mtanno align` on the synthetic world."""

from __future__ import annotations

import json
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive_align import (
    area_naive,
    code_cost_naive,
    dtw_naive,
    pose_cost_naive,
    segments_naive,
)
from world import assert_one_line, checksums, cli

from mtanno.align import (
    Area,
    Performance,
    Segments,
    align,
    coarse_alignment,
    load_performance,
    local_costs,
    normalize_poses,
    path_agreement,
    pose_features,
    select_features,
    warp_codes,
    warp_poses,
)
from mtanno.align.dtw import FEATURE_TIE, WarpingPath
from mtanno.errors import MtannoError
from mtanno.features import get_feature_set
from mtanno.features.store import FeatureLayout

# --------------------------------------------------------------------------- oracles


def random_codes(rng, n, n_features):
    # runs of repeated codes, so that segments are longer than one frame
    out, code = [], int(rng.integers(0, 2 ** n_features))
    for _ in range(n):
        if rng.random() < 0.4:
            code = int(rng.integers(0, 2 ** n_features))
        out.append(code)
    return np.array(out, dtype=np.int64)


def same_total(got: float, want: float) -> bool:
    # the compiled kernels may fuse a multiply and an add (one rounding instead of two)
    return abs(got - want) <= 1e-12 * max(1.0, abs(want))


def check_against_oracle(seed: int) -> None:
    """Kernels = oracles on one random case: pose DTW and code DTW (with phases and tie),
    over the full matrix and over the area of a coarse alignment, and stage 1 with segment
    weights: the same paths, the same totals up to rounding. Also called with the JIT off
    (tests/test_align_nojit.py)."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 14)), int(rng.integers(1, 14))
    nf = int(rng.integers(1, 6))
    CA, CB = random_codes(rng, n, nf), random_codes(rng, m, nf)
    band = int(rng.integers(0, 3))
    coarse = coarse_alignment(CA, CB, n_features=nf, band=band)
    sa, sb = coarse.segments_a, coarse.segments_b
    # stage 1: segment DTW with lengths as weights
    want, total = dtw_naive(lambda i, j: code_cost_naive(sa.code, sb.code, i, j, nf),
                            len(sa), len(sb), wa=[float(x) for x in sa.length],
                            wb=[float(x) for x in sb.length])
    assert list(zip(coarse.pairs.a.tolist(), coarse.pairs.b.tolist())) == want
    assert same_total(coarse.pairs.total, total)
    # the area
    cells = area_naive(list(zip(sa.start.tolist(), sa.end.tolist())),
                       list(zip(sb.start.tolist(), sb.end.tolist())), want, band, n, m)
    got = {(a, b) for a in range(n) for b in range(int(coarse.area.lo[a]),
                                                     int(coarse.area.hi[a]) + 1)}
    assert got == cells
    coarse.area.check()
    # stage 2, both costs, full and restricted
    PA = rng.normal(size=(n, int(rng.integers(1, 4)), 3))
    PB = rng.normal(size=(m, PA.shape[1], 3))
    phases = (sa.phases(), sb.phases())
    tie = FEATURE_TIE / nf
    for area, restrict in ((None, None), (coarse.area, cells)):
        p = warp_poses(PA, PB, area=area)
        want, total = dtw_naive(lambda a, b: pose_cost_naive(PA, PB, a, b), n, m, restrict)
        assert list(zip(p.a.tolist(), p.b.tolist())) == want and same_total(p.total, total)
        assert p.cells == (n * m if area is None else len(cells))
        np.testing.assert_allclose(local_costs(p, poses=(PA, PB)).sum(), total, rtol=1e-12)
        q = warp_codes(CA, CB, n_features=nf, area=area, phases=phases, tie=tie)
        want, total = dtw_naive(lambda a, b: code_cost_naive(CA, CB, a, b, nf, phases, tie),
                                n, m, restrict)
        assert list(zip(q.a.tolist(), q.b.tolist())) == want and same_total(q.total, total)


@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_kernels_equal_the_oracles(seed):
    check_against_oracle(seed)


def test_larger_cases_equal_the_oracles():
    rng = np.random.default_rng(5)
    for _ in range(3):
        n, m = 40, 55
        PA, PB = rng.normal(size=(n, 5, 3)), rng.normal(size=(m, 5, 3))
        CA, CB = random_codes(rng, n, 4), random_codes(rng, m, 4)
        area = coarse_alignment(CA, CB, n_features=4, band=2).area
        cells = {(a, b) for a in range(n) for b in range(int(area.lo[a]), int(area.hi[a]) + 1)}
        p = warp_poses(PA, PB, area=area)
        want, total = dtw_naive(lambda a, b, P=PA, Q=PB: pose_cost_naive(P, Q, a, b), n, m, cells)
        assert list(zip(p.a.tolist(), p.b.tolist())) == want and same_total(p.total, total)


def test_segments_and_phases():
    codes = np.array([3, 3, 1, 1, 1, 3, 0], dtype=np.int64)
    s = Segments.of(codes)
    assert list(zip(s.start.tolist(), s.end.tolist(), s.code.tolist())) == \
        segments_naive(codes.tolist())
    np.testing.assert_allclose(s.phases(), [0.25, 0.75, 1 / 6, 0.5, 5 / 6, 0.5, 0.5])


# --------------------------------------------------------------------------- properties


def test_equal_progressions_are_matched_one_to_one_at_no_cost():
    # B is A with every segment stretched: stage 1 pairs segment k with segment k
    CA = np.array([0, 0, 1, 1, 1, 3, 2, 2], dtype=np.int64)
    CB = np.repeat(CA, 3)
    c = coarse_alignment(CA, CB, n_features=2, band=0)
    k = len(c.segments_a)
    assert c.pairs.a.tolist() == list(range(k)) and c.pairs.b.tolist() == list(range(k))
    assert c.pairs.total == 0.0


def test_a_segment_one_motion_lacks_is_merged_into_its_neighbours():
    # A has a 2-frame blip (code 2) inside a run of code 1 that B lacks: the blip's segment
    # shares B's segment with its neighbours, costing its length times the differing bit
    CA = np.array([0] * 5 + [1] * 4 + [3] * 2 + [1] * 4 + [0] * 5, dtype=np.int64)
    CB = np.array([0] * 5 + [1] * 10 + [0] * 5, dtype=np.int64)
    c = coarse_alignment(CA, CB, n_features=2, band=0)
    assert list(zip(c.pairs.a.tolist(), c.pairs.b.tolist())) == \
        [(0, 0), (1, 1), (2, 1), (3, 1), (4, 2)]
    assert c.pairs.total == 2 * 0.5
    # step weights: 5 (start), max(4, 10) (diagonal), 2 and 4 (A advances), 5 (diagonal)
    assert c.pairs.weight == 26.0 and c.pairs.mean == 1.0 / 26


def test_the_area_is_a_staircase_from_corner_to_corner_and_grows_with_the_band():
    rng = np.random.default_rng(2)
    CA, CB = random_codes(rng, 200, 5), random_codes(rng, 170, 5)
    sizes = []
    for band in (0, 2, 8, 400):
        area = coarse_alignment(CA, CB, n_features=5, band=band).area
        area.check()
        sizes.append(area.cells)
    assert sizes == sorted(sizes) and sizes[-1] == 200 * 170


def test_a_restricted_path_equals_the_full_one_when_the_full_one_lies_inside():
    rng = np.random.default_rng(4)
    PA = rng.normal(size=(60, 3, 3))
    PB = PA[np.sort(rng.integers(0, 60, size=75))]  # a re-timed copy
    full = warp_poses(PA, PB)
    lo = np.maximum.accumulate(np.array([full.b[full.a == a].min() for a in range(60)]))
    hi = np.array([full.b[full.a == a].max() for a in range(60)])
    area = Area(np.maximum(0, lo - 1), np.minimum(74, hi + 1), 75)
    part = warp_poses(PA, PB, area=area)
    assert part.a.tolist() == full.a.tolist() and part.b.tolist() == full.b.tolist()
    assert part.total == full.total and part.cells < full.cells
    assert path_agreement(part, full) == 1.0


def test_path_agreement_counts_frames_matched_alike():
    p = WarpingPath(np.array([0, 1, 2, 3]), np.array([0, 1, 2, 3]), 0.0, 4.0, 16, 4, 4)
    q = WarpingPath(np.array([0, 1, 1, 2, 3]), np.array([0, 0, 1, 2, 3]), 0.0, 5.0, 16, 4, 4)
    # frame 1 of A: (1, 1) vs (0, 1); frame 0 of B: (0, 0) vs (0, 1); the rest agree
    assert path_agreement(p, q) == 6 / 8
    assert path_agreement(p, q, tolerance=1) == 1.0
    assert path_agreement(p, p) == 1.0


def test_pose_normalisation_removes_floor_translation_heading_and_size():
    rng = np.random.default_rng(8)
    P = rng.normal(size=(6, 22, 3)) * 10
    P[:, :, 1] += 90.0
    phi = rng.uniform(0, 2 * np.pi, size=6)  # a turn per frame about the vertical axis
    R = np.zeros((6, 3, 3))
    R[:, 0, 0] = R[:, 2, 2] = np.cos(phi)
    R[:, 0, 2] = np.sin(phi)
    R[:, 2, 0] = -np.sin(phi)
    R[:, 1, 1] = 1.0
    Q = np.einsum("fij,fkj->fki", R, P) + np.array([30.0, 0.0, -7.0])  # floor shift only
    np.testing.assert_allclose(normalize_poses(Q), normalize_poses(P), atol=1e-9)
    np.testing.assert_allclose(normalize_poses(2.54 * P), normalize_poses(P), atol=1e-12)
    N = normalize_poses(P)
    assert np.allclose(N[:, 0, [0, 2]], 0.0)  # root at the origin of the floor
    axis = (N[:, 2] - N[:, 1]) + (N[:, 15] - N[:, 14])  # rhip−lhip + rshoulder−lshoulder
    assert np.allclose(axis[:, 2], 0.0) and np.all(axis[:, 0] > 0)
    with pytest.raises(MtannoError, match="legs have no length"):
        normalize_poses(np.zeros((3, 22, 3)))


# --------------------------------------------------------------------------- API checks


def test_feature_selection():
    fs = get_feature_set("ak40")
    groups = {g: tuple(fs.names[i] for i in rows) for g, rows in fs.groups.items()}
    assert select_features(fs.names, groups) == tuple(fs.names)
    assert select_features(fs.names, groups, group="lower") == groups["lower"]
    pose = select_features(fs.names, groups, group="pose")
    assert pose == pose_features(fs.names) and "rknee_bent" in pose
    assert "rfoot_fast" not in pose and "rhand_forward" not in pose and len(pose) == 25
    for kw, msg in [({"group": "legs"}, "unknown group 'legs'"),
                    ({"features": ["rknee_bent", "nope"]}, "unknown feature 'nope'"),
                    ({"features": ["rknee_bent"] * 2}, "named twice"),
                    ({"features": ["rknee_bent"], "group": "all"}, "not both")]:
        with pytest.raises(MtannoError, match=msg):
            select_features(fs.names, groups, **kw)


def perf(X, joints=None, feature_set="mr06-ak40", names=None, name="p"):
    names = names or tuple(f"f{i}" for i in range(X.shape[0]))
    return Performance(name, np.asarray(X, np.uint8), FeatureLayout(feature_set, names, 30.0),
                       np.arange(1, X.shape[1] + 1), joints=joints)


def test_align_refuses_what_cannot_be_compared():
    rng = np.random.default_rng(0)
    X = (rng.random((4, 10)) < 0.5).astype(np.uint8)
    a = perf(X, joints=rng.normal(size=(10, 22, 3)))
    with pytest.raises(MtannoError, match="feature set 'mrc05' differs"):
        align(a, perf(X, feature_set="mrc05"), cost="features")
    with pytest.raises(MtannoError, match="feature 1 is 'g0' here"):
        align(a, perf(X, names=("g0", "f1", "f2", "f3")), cost="features")
    with pytest.raises(MtannoError, match="no joint positions"):
        align(a, perf(X), cost="positions")
    with pytest.raises(MtannoError, match="motion has no frames"):
        align(a, perf(X[:, :0]), cost="features")
    with pytest.raises(MtannoError, match="unknown cost"):
        align(a, a, cost="angles")
    with pytest.raises(MtannoError, match="band must be"):
        align(a, a, band=-1)
    with pytest.raises(MtannoError, match="connected staircase"):
        Area(np.array([0, 3]), np.array([1, 4]), 5).check()
    with pytest.raises(MtannoError, match="last cell"):
        warp_poses(np.zeros((2, 1, 3)), np.zeros((5, 1, 3)), area=Area(
            np.array([0, 1]), np.array([1, 3]), 5))


def test_pair_area_refuses_pairs_outside_the_segments():
    """Segment numbers past either motion's segments, ragged pairs and segments without
    frames raise instead of reading past the arrays in the kernel; so do warping paths
    outside their matrix."""
    from mtanno.align.coarse import pair_area

    rng = np.random.default_rng(3)
    co = coarse_alignment(rng.integers(0, 4, 60), rng.integers(0, 4, 50), n_features=2, band=2)
    sa, sb, pairs = co.segments_a, co.segments_b, co.pairs
    area = pair_area(sa, sb, pairs, band=2)
    assert np.array_equal(area.lo, co.area.lo) and np.array_equal(area.hi, co.area.hi)
    bad = [(pairs.a + len(sa), pairs.b), (pairs.a, pairs.b - len(sb)),
           (np.zeros(10**6, np.int64), np.zeros(1, np.int64)), (pairs.a[:0], pairs.b[:0])]
    for a, b in bad:
        path = WarpingPath(a, b, 0.0, 1.0, 1, len(sa), len(sb))
        with pytest.raises(MtannoError, match="segment pairs must number segments of A"):
            pair_area(sa, sb, path, band=2)
    with pytest.raises(MtannoError, match="segments of A need one start frame per length"):
        pair_area(Segments(sa.start, sa.length[:3], sa.code), sb, pairs, band=2)
    with pytest.raises(MtannoError, match="segments of B need one start frame per length"):
        pair_area(sa, Segments.of(np.zeros(0)), pairs, band=2)
    # paths whose cells leave the matrix (numpy would take −1 from the end)
    codes = (rng.integers(0, 4, 6), rng.integers(0, 4, 5))
    p = warp_codes(*codes, n_features=2)
    assert path_agreement(p, p) == 1.0
    for a, b in [(p.a - 1, p.b), (p.a, p.b + 1), (p.a[:2], p.b)]:
        off = WarpingPath(a, b, p.total, p.weight, p.cells, p.n, p.m)
        with pytest.raises(MtannoError, match="must lie in the 6 × 5 matrix"):
            local_costs(off, codes=codes, n_features=2)
        with pytest.raises(MtannoError, match="must lie in the 6 × 5 matrix"):
            path_agreement(p, off)


# --------------------------------------------------------------------------- command line


def clip_pair(world):
    clips = sorted(world.clips.rglob("*.amc"))
    return clips[0], clips[1]


def test_align_command_writes_the_path_table_with_provenance(world, tmp_path):
    a, b = clip_pair(world)
    before = checksums(world.clips)
    out = tmp_path / "path.csv"
    r = cli("align", a, b, "-o", out)
    assert r.exit_code == 0, r.output
    assert "computed" in r.output and "of the matrix (band 4)" in r.output
    lines = out.read_text().splitlines()
    assert lines[0] == "frame_a,frame_b,native_a,native_b,cost"
    rows = [list(map(float, ln.split(","))) for ln in lines[1:]]
    assert rows[0][:2] == [1, 1] and rows[0][2:4] == [1, 1]
    pa, pb = load_performance(a), load_performance(b)
    assert rows[-1][:4] == [pa.frames, pb.frames, pa.native_frames[-1], pb.native_frames[-1]]
    meta = json.loads((tmp_path / "path.csv.meta.json").read_text())
    al = align(pa, pb)
    assert meta["total_cost"] == pytest.approx(al.total_cost)
    assert meta["fraction_computed"] == al.fraction and meta["band"] == 4
    assert meta["cost"] == "positions" and len(meta["inputs"]) == 2
    assert sum(r[4] for r in rows) == pytest.approx(al.total_cost)
    assert checksums(world.clips) == before
    # Parquet and JSON Lines by suffix, CSV on standard output for -
    r = cli("align", a, b, "--cost", "features", "--full", "-o", tmp_path / "p.parquet")
    assert r.exit_code == 0, r.output
    t = pq.read_table(tmp_path / "p.parquet")
    assert t.column_names == ["frame_a", "frame_b", "native_a", "native_b", "cost"]
    assert json.loads(t.schema.metadata[b"mtanno"])["fraction_computed"] == 1.0
    r = cli("align", a, b, "--group", "lower", "--band", "0", "-o", tmp_path / "p.jsonl")
    assert r.exit_code == 0 and json.loads((tmp_path / "p.jsonl").read_text().splitlines()[0])
    r = cli("align", a, b, "-q")
    assert r.exit_code == 0 and r.output.splitlines()[0] == lines[0]


def test_align_command_bad_input_is_one_line(world, tmp_path):
    a, b = clip_pair(world)
    feats = sorted(world.feats.rglob("*.parquet"))
    empty = tmp_path / "empty.amc"
    lines = a.read_text(errors="replace").splitlines(keepends=True)
    empty.write_text("".join(lines[:next(i for i, ln in enumerate(lines)
                                          if ln.strip().isdigit())]))  # header, no frames
    r = cli("align", feats[0], b, "-o", tmp_path / "x.csv")
    assert "no joint positions" in assert_one_line(r, feats[0], codes=(2,))
    r = cli("align", a, feats[0], "--cost", "features", "--feature-set", "mrc05",
            "-o", tmp_path / "x.csv")
    assert "feature set" in assert_one_line(r, feats[0], codes=(2,))
    r = cli("align", empty, b, "--asf", next(world.clips.rglob("*.asf")), "-o",
            tmp_path / "x.csv")
    assert "no frames" in assert_one_line(r, empty, codes=(2,))
    r = cli("align", a, b, "--group", "legs", "-o", tmp_path / "x.csv")
    assert r.exit_code == 2 and "unknown group 'legs'" in r.output
    r = cli("align", a, b, "-o", tmp_path / "x.csv", "--plot", tmp_path / "x.jpg")
    assert "unknown plot file type" in assert_one_line(r, tmp_path / "x.jpg", codes=(2,))
    side = tmp_path / "in.csv"
    side.write_text("x\n")
    r = cli("align", a, side, "-o", side)
    assert r.exit_code == 2 and "overwrite an input" in r.output
    assert not list(tmp_path.glob("x.csv*"))


def test_align_command_says_how_to_install_matplotlib(world, tmp_path, monkeypatch):
    a, b = clip_pair(world)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib fails
    r = cli("align", a, b, "-o", tmp_path / "x.csv", "--plot", tmp_path / "x.png")
    assert r.exit_code == 2 and "pip install 'mtanno[plot]'" in r.output
    assert not (tmp_path / "x.csv").exists()


def test_plot_draws_area_pairs_and_path(world, tmp_path):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from mtanno.align.plot import plot_alignment

    a, b = clip_pair(world)
    al = align(load_performance(a), load_performance(b))
    full = align(load_performance(a), load_performance(b), full=True)
    ax = Figure().add_subplot()
    plot_alignment(al, ax=ax, compare=full.path)
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    np.testing.assert_array_equal(lines["path"].get_xdata(), al.path.b + 1)
    np.testing.assert_array_equal(lines["path"].get_ydata(), al.path.a + 1)
    np.testing.assert_array_equal(lines["full DTW"].get_xdata(), full.path.b + 1)
    assert len(ax.patches) == len(al.coarse.pairs.a)
    fill = next(c for c in ax.collections if c.get_label() == "computed area")
    xs = fill.get_paths()[0].vertices[:, 0]
    assert xs.min() == al.coarse.area.lo.min() + 0.5
    assert xs.max() == al.coarse.area.hi.max() + 1.5
    r = cli("align", a, b, "-o", tmp_path / "x.csv", "--plot", tmp_path / "x.png")
    assert r.exit_code == 0 and (tmp_path / "x.png").read_bytes()[:4] == b"\x89PNG"
