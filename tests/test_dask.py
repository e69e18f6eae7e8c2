"""--scheduler (issue 12): features, annotate, learn-keyframes and tune on a
dask.distributed LocalCluster of 2 workers give the same outputs as --jobs 2."""

from __future__ import annotations

import pytest
from world import cli

pytest.importorskip("dask.distributed", reason="dask is an optional extra: pip install "
                    "'mtanno[dask]'")


def _files(root):
    return {p.relative_to(root).as_posix(): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def cluster():
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as c:
        yield c.scheduler_address


def test_scheduler_equals_jobs(world, tmp_path, cluster):
    """A running cluster (its scheduler's address) gives the same files as --jobs 2."""
    for name, extra in (("jobs", ["--jobs", "2"]), ("dask", ["--scheduler", cluster])):
        out = tmp_path / name
        r = cli("features", world.clips, "-o", out / "feats", "-q", *extra)
        assert r.exit_code == 0, r.output
        r = cli("annotate", "--mt", world.mt, world.docfeats, "-o", out / "ann.csv", "-q",
                *extra)
        assert r.exit_code == 0, r.output
        r = cli("learn-keyframes", "--mt", world.mt, "--manifest", world.manifest,
                "--features-dir", world.feats, "--split", "train", "-o", out / "kf",
                "--runs", "4", "--generations", "10", "-q", *extra)
        assert r.exit_code == 0, r.output
        r = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
                world.feats, "--split", "train", "-o", out / "tuned.toml", "-q", *extra)
        assert r.exit_code == 0, r.output
    a, b = tmp_path / "jobs", tmp_path / "dask"
    assert _files(a / "feats") == _files(b / "feats") and _files(a / "feats")
    assert (a / "ann.csv").read_bytes() == (b / "ann.csv").read_bytes()
    assert _files(a / "kf") == _files(b / "kf") and _files(a / "kf")

    def config(p):  # its first line is the command (--jobs 2 or --scheduler ADDRESS)
        return p.read_text().split("\n", 1)[1]

    assert config(a / "tuned.toml") == config(b / "tuned.toml")
    assert "--scheduler" in (b / "tuned.toml").read_text().split("\n", 1)[0]


def test_local_cluster_started_for_the_run(world, tmp_path):
    r = cli("features", world.clips, "-o", tmp_path / "a", "-q", "--scheduler", "local:2")
    assert r.exit_code == 0, r.output
    r = cli("features", world.clips, "-o", tmp_path / "b", "-q")
    assert _files(tmp_path / "a") == _files(tmp_path / "b")


def test_bad_scheduler_is_one_line(world, tmp_path):
    r = cli("features", world.clips, "-o", tmp_path / "f", "--scheduler", "local:0")
    assert r.exit_code == 2 and "local:N needs a positive number" in r.output
    import dask

    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        r = cli("features", world.clips, "-o", tmp_path / "g", "--scheduler",
                "tcp://127.0.0.1:9")
    assert r.exit_code == 2 and "cannot reach the dask scheduler" in r.output


def test_each_pool_scatters_under_its_own_key(cluster):
    """Two pools in a row that share the same data scatter it under different keys: with
    content-hashed keys the first pool's release, which the scheduler may handle after the
    second pool scattered, would cancel the second pool's tasks (FutureCancelledError,
    seen in learn-keyframes --scheduler on a loaded machine)."""
    from mtanno.util.workers import DaskPool

    data = {"examples": list(range(100))}
    keys = []
    for _ in range(2):
        with DaskPool(cluster, shared=data) as pool:
            keys.append(pool._shared.key)
            assert list(pool.map(len, [([1, 2],), ([3],)])) == [2, 1]
    assert keys[0] != keys[1]
