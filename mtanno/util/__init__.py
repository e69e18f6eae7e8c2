"""Plumbing shared by every stage and command (no algorithms here):

* :mod:`~mtanno.util.output` — atomic writes, the umask, temporaries of dead writers;
* :mod:`~mtanno.util.preflight` — outputs checked against inputs before any work;
* :mod:`~mtanno.util.locks` — the writer lock of an output folder (cron safety);
* :mod:`~mtanno.util.tables` — the one I/O convention of every table (CSV, Parquet, JSON
  Lines by suffix; ``-`` for standard input and output);
* :mod:`~mtanno.util.provenance` — what every output records about how it was made
  (command line, inputs with content hashes, parameters);
* :mod:`~mtanno.util.clips` — clip manifests and ``--frames`` ranges;
* :mod:`~mtanno.util.workers` — worker processes, dask clusters and the signal policy;
* :mod:`~mtanno.util.outcomes` — the record of a batch that goes on past failures;
* :mod:`~mtanno.util.jitnote` — the one-line note while numba compiles;
* :mod:`~mtanno.util.units` — the units every stage shares (the 30 Hz analysis rate);
* :mod:`~mtanno.util.lazy` — modules loaded on attribute access (``mtanno.util.tables``
  after a bare ``import mtanno``);
* :mod:`~mtanno.util.pause` — the test hook that holds a process at a named point;
* :mod:`~mtanno.util.stdout` — standard output that says so when a write fails;
* ``_bits`` — bit kernels the stages' numba kernels share (private).

The feature-file format is the features stage's (:mod:`mtanno.features.store`). The modules
are imported by name (``from mtanno.util.tables import write_table``) or on
first attribute access; this file imports none of them but :mod:`~mtanno.util.lazy`, so that
loading one does not load the others.
"""

from mtanno.util.lazy import submodule_getattr

__all__ = ["clips", "jitnote", "lazy", "locks", "outcomes", "output", "pause", "preflight",
           "provenance", "stdout", "tables", "units", "workers"]


__getattr__ = submodule_getattr(__name__)  # the modules not imported above, on first use
