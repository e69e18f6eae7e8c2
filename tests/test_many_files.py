"""Many short files as cheap as one long document (issue 34, part 2): a batch's setup
reaches each worker once and tasks carry document names only, several per task; the
outputs are those of one process; the verification bank is checked once, not with every
segment."""

from __future__ import annotations

import numpy as np
import pytest

from mtanno.annotate import AnnotateOptions, annotate_files, load_annotation_setup
from mtanno.annotate.batch import MAX_CHUNK, _annotate_chunk, _chunks
from mtanno.errors import MtannoError


def test_chunks_hold_several_documents_and_keep_every_worker_busy():
    names = [f"d{i}" for i in range(100)]
    assert _chunks(names, 1) == [[n] for n in names]  # no pool: one at a time
    for jobs in (2, 3):
        got = _chunks(names, jobs)
        assert [n for c in got for n in c] == names
        assert max(len(c) for c in got) <= MAX_CHUNK and len(got) >= 4 * jobs
    assert _chunks(names[:3], 2) == [["d0"], ["d1"], ["d2"]]
    assert _chunks([], 2) == []


def test_a_pool_gets_the_setup_once_and_names_of_documents(world, monkeypatch):
    from mtanno.util import workers

    setup = load_annotation_setup(world.mt)
    paths = [world.doc_files[i % 2] for i in range(12)]
    want = annotate_files(paths, setup.models, layout=setup.layout,
                          options=AnnotateOptions(n_jobs=1))
    seen, shared = [], []
    map_ = workers.WorkerPool.map
    init = workers.WorkerPool.__init__

    def spy_map(self, fn, args, chunksize=1):
        args = list(args)
        seen.append((fn, args))
        return map_(self, fn, args, chunksize=chunksize)

    def spy_init(self, n_jobs, *, shared=None):
        seen_shared.append(shared)
        init(self, n_jobs, shared=shared)

    seen_shared = shared
    monkeypatch.setattr(workers.WorkerPool, "map", spy_map)
    monkeypatch.setattr(workers.WorkerPool, "__init__", spy_init)
    got = annotate_files(paths, setup.models, layout=setup.layout,
                         options=AnnotateOptions(n_jobs=2))
    assert got.rows == want.rows and got.files == want.files and got.failed == want.failed
    (fn, args), = seen
    assert fn is _annotate_chunk
    # the first document was annotated before the pool (kernels loaded), the others go
    # by name, several to a task; models and configuration went once, with the pool
    tasks = [a[0] for a in args]
    assert [p for t in tasks for p, _ in t] == [str(p) for p in paths[1:]]
    assert all(dst is None for t in tasks for _, dst in t) and max(map(len, tasks)) > 1
    (batch_setup, provenance), = seen_shared
    assert batch_setup[0] is setup.models and provenance is None


def test_annotate_chunk_reads_the_setup_of_its_worker(world, monkeypatch):
    """A task annotates each named document with the setup its worker holds."""
    from mtanno.annotate.batch import _annotate_file
    from mtanno.util import workers

    setup = load_annotation_setup(world.mt)
    args = (setup.models, setup.layout, setup.config, "reference", "reference", None, False,
            None, None)
    monkeypatch.setattr(workers, "_SHARED", (args, None))
    doc = str(world.doc_files[0])
    (got,) = _annotate_chunk([(doc, None)])
    want = _annotate_file(doc, *args)
    assert got[0] == want[0] and got[1] == want[1] and got[1]
    assert np.array_equal(got[2], want[2]) and got[3] == want[3]


def test_the_bank_is_checked_once_and_costs_what_subsequence_dtw_says():
    from mtanno.confidence.verify import build_bank, subsequence_costs

    rng = np.random.default_rng(3)
    seqs = [rng.random((rng.integers(3, 12), 5)).astype(np.float32) for _ in range(9)]
    bank = build_bank([(c, p, s) for c, p, s in zip("aabbbcca" + "c", "xyxyzxyz" + "x",
                                                    seqs)], [seqs[0][:4]],
                      representation="features")
    q = rng.random((6, 5)).astype(np.float32)
    want = subsequence_costs(q, bank.items, bank.offsets)
    assert np.array_equal(bank.costs(q), want)
    near = bank.nearest(q)
    for lab in set(bank.labels):
        idx = [k for k, x in enumerate(bank.labels) if x == lab]
        assert near[lab] == min(want[k] for k in idx)
    with pytest.raises(MtannoError, match="same dims"):
        bank.costs(q[:, :3])
    with pytest.raises(MtannoError, match="finite"):
        bank.costs(np.full((2, 5), np.nan, np.float32))
