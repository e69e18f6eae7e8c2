"""Plumbing shared by every stage and command (no algorithms here):

* :mod:`~mtanno.util.output` — atomic writes, the umask, temporaries of dead writers,
  outputs checked against inputs;
* :mod:`~mtanno.util.locks` — the writer lock of an output folder (cron safety);
* :mod:`~mtanno.util.tables` — the one I/O convention of every table (CSV, Parquet, JSON
  Lines by suffix; provenance; ``-`` for standard input and output);
* :mod:`~mtanno.util.store` — feature files (Parquet): the one reader and writer, layouts;
* :mod:`~mtanno.util._parquet` — the fast writer of short feature files (private);
* :mod:`~mtanno.util._poseblock` — the optional pose block of feature files: column names
  and checks (private);
* :mod:`~mtanno.util.workers` — worker processes, dask clusters and the signal policy;
* :mod:`~mtanno.util.outcomes` — the record of a batch that goes on past failures;
* :mod:`~mtanno.util.jitnote` — the one-line note while numba compiles;
* :mod:`~mtanno.util.units` — the units every stage shares (the 30 Hz analysis rate);
* :mod:`~mtanno.util.pause` — the test hook that holds a process at a named point;
* ``_bits`` — bit kernels the stages' numba kernels share (private).

The modules are imported by name (``from mtanno.util.store import read_features``); this
file imports none of them, so that loading one does not load the others.
"""

__all__ = ["jitnote", "locks", "outcomes", "output", "pause", "store", "tables", "units",
           "workers"]
