"""Feature extraction for batches (``mtanno features``): :func:`plan_batch` maps inputs
(files, directories, lists) to output paths that mirror the input tree, :func:`up_to_date`
skips outputs of the same inputs and code, :func:`run_batch` runs a plan in one or more
processes (a few short files per task), continuing past files that fail, and
:func:`extract_to` is the command's whole run, as :class:`ExtractOptions` say. One file:
:func:`mtanno.features.extract.extract_file`.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.features.compute import FeatureSet, get_feature_set
from mtanno.features.extract import EXTRACTOR_VERSION, extract_file, skeleton_digest
from mtanno.features.table import FEATURE_SET
from mtanno.io import find_asf
from mtanno.io.formats import SUFFIXES, expected, format_of, is_motion_path
from mtanno.io.skeleton import to_y_up
from mtanno.util.provenance import sha256_file


@dataclass
class Job:
    """One document of a batch: motion file, output file, optional ASF. ``error`` is set for
    an input found unusable while planning (a name listed on standard input that does not
    exist, a FIFO in an input folder): the job is reported as failed and never run."""

    src: Path
    dst: Path
    asf: Path | None = None
    error: str = ""


@dataclass
class Outcome:
    """``invalid``: analysis frames of a written file that carry no evidence (a marker
    file's joints that could not be computed); ``message``: of a failure, or a note on
    them."""

    job: Job
    status: str  # "written", "skipped" or "failed"
    message: str = ""
    frames: int = 0
    invalid: int = 0
    #: the failure as raised, when it was an :class:`MtannoError` (a command shows its
    #: options as flags: :meth:`MtannoError.for_command`)
    error: MtannoError | None = None

    @classmethod
    def of(cls, job: Job, status: str, message: str | MtannoError, frames: int,
           invalid: int = 0) -> Outcome:
        """The outcome of a job run by :func:`_extract_one`."""
        if isinstance(message, MtannoError):
            return cls(job, status, str(message), frames, invalid, message)
        return cls(job, status, message, frames, invalid)


@dataclass
class Summary:
    """Counts and failures of a batch run."""

    outcomes: list[Outcome] = field(default_factory=list)

    def count(self, status: str) -> int:
        return sum(o.status == status for o in self.outcomes)

    @property
    def failed(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.status == "failed"]

    def line(self) -> str:
        frames = sum(o.frames for o in self.outcomes if o.status == "written")
        invalid = sum(o.invalid for o in self.outcomes if o.status == "written")
        share = f", {100 * invalid / frames:.1f} % invalid" if invalid else ""
        return (f"{self.count('written')} written ({frames} frames at 30 Hz{share}), "
                f"{self.count('skipped')} up to date, {self.count('failed')} failed")


def _is_motion(p: Path) -> bool:
    return is_motion_path(p)


def _not_regular(p: Path, mode: int | None = None) -> str | None:
    """Why ``p`` cannot be read as a motion file without opening it (a FIFO would block
    the batch), or None for a regular file or a folder; ``mode``: its ``st_mode``, when the
    caller has it."""
    import stat

    if mode is None:
        try:
            mode = os.stat(p).st_mode
        except FileNotFoundError:
            return ("motion file not found (a broken symbolic link)" if p.is_symlink() else
                    "motion file not found")
        except OSError as exc:
            return f"cannot read motion file: {exc.strerror or exc}"
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    kind = ("a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else
            "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")
    return f"not a regular file ({kind}): not read"


def _unknown_type(p: Path) -> str:
    return f"unknown motion file type '{p.suffix}' (expected {expected()})"


def _folder_jobs(folder: Path, outdir: Path) -> list[Job]:
    """The motion files below ``folder``, each mirrored under ``outdir``; an entry with a
    motion suffix that is not a regular file or a folder (a FIFO, a socket, a broken link)
    is a failed job, so it is reported instead of silently skipped. A folder named like a
    motion file (``x.amc/``) is searched like any other."""
    import stat

    jobs = []
    for q in sorted(folder.rglob("*")):
        if not _is_motion(q):
            continue
        try:  # one stat per entry: is it a folder, and can it be read
            mode = os.stat(q).st_mode
        except OSError:
            mode = None
        if mode is not None and stat.S_ISDIR(mode):
            continue
        rel = q.relative_to(folder).with_suffix(".parquet")
        jobs.append(Job(q, outdir / rel, error=_not_regular(q, mode) or ""))
    return jobs


def plan_batch(inputs: Iterable[str | os.PathLike], outdir: str | os.PathLike, *,
               asf: str | os.PathLike | None = None,
               listed: Iterable[str | os.PathLike] = (),
               inside_input: bool = False) -> list[Job]:
    """Map inputs to output paths under ``outdir``.

    A file gives ``outdir/<stem>.parquet``; a directory is searched recursively for
    motion files (:data:`mtanno.io.formats.SUFFIXES`), each giving
    ``outdir/<path below the directory>.parquet``.
    An input that is missing or neither a motion file nor a folder is a failed job
    (reported, the batch goes on: exit code 1), as is a folder that holds no motion file
    (an empty folder named like one, ``x.amc/``, too) and an entry of a folder with a
    motion suffix that is not a regular file (a FIFO is never opened); when no input is
    usable, the first such input on the command line is raised instead (exit code 2).
    ``listed`` are more inputs, read from a list (``features -``), whose failures are
    always failed jobs. Raises :class:`MtannoError` for two inputs with the same output,
    an output that is one of the inputs, and, unless ``inside_input``, an ``outdir`` that
    is or lies inside an input folder (:func:`mtanno.util.preflight.check_outputs`).
    """
    outdir = Path(outdir)
    inputs, listed = list(inputs), list(listed)
    jobs: list[Job] = []
    refused: list[MtannoError] = []  # bad command-line inputs, raised when nothing is usable
    for item, strict in [*((i, True) for i in inputs), *((i, False) for i in listed)]:
        p = Path(item)
        why = _not_regular(p)
        if why is None and p.is_dir():
            found = _folder_jobs(p, outdir)
            if found:
                jobs.extend(found)
                continue
            why = (f"a folder (named like a motion file) holding no {expected()} file"
                   if _is_motion(p) else f"no {expected()} files in this folder or below")
        if why is None and not _is_motion(p):
            why = _unknown_type(p)
        if why is not None and strict:
            why = "no such file or directory" if why == "motion file not found" else why
            refused.append(MtannoError(why, path=str(p)))
        jobs.append(Job(p, outdir / (p.stem + ".parquet"), error=why or ""))
    if refused and all(j.error for j in jobs):
        raise refused[0]
    seen: dict[Path, Path] = {}
    for j in jobs:
        if j.error:
            continue  # never written
        if j.dst in seen and seen[j.dst] != j.src:
            raise MtannoError(f"two inputs would write {j.dst}: {seen[j.dst]} and {j.src}")
        seen[j.dst] = j.src
        if asf is not None and format_of(j.src).skeleton_file is not None:
            j.asf = Path(asf)
    # one job per output (a file given twice, or as a file and in its folder); failed
    # jobs write nothing, so one per input
    unique = list({(j.dst, j.error and str(j.src)): j for j in jobs}.values())
    from mtanno.util.preflight import check_outputs

    good = [j for j in unique if not j.error]
    check_outputs([j.dst for j in good],
                  [*(j.src for j in good), *({j.asf for j in good} - {None})],
                  folders={outdir: []}, inside_input=inside_input,
                  scanned={p: SUFFIXES for p in map(Path, [*inputs, *listed])
                           if p.is_dir()},
                  writable=False)  # a file whose output cannot be written fails alone
    return unique


def _stored_meta(path: Path) -> dict | None:
    """The ``mtanno`` metadata of an existing output (None if it cannot be read)."""
    import pyarrow.parquet as pq

    from mtanno.errors import parse_json
    from mtanno.features.store import META_KEY

    try:
        raw = (pq.read_schema(path).metadata or {}).get(META_KEY)
        meta = parse_json(raw) if raw else None
    except (OSError, ValueError, TypeError, MtannoError):
        return None
    return meta if isinstance(meta, dict) else None


def up_to_date(job: Job, *, feature_set: str | FeatureSet = FEATURE_SET,
               skeleton: str | os.PathLike | None = None, up: str | None = None,
               poses: bool = False, markers: str | os.PathLike | None = None) -> bool:
    """True if ``job.dst`` holds the features this job would compute now, judged by the
    provenance the output records: the same motion file (SHA-256), the same skeleton file
    (the ASF that would be used, SHA-256), the same skeleton map (the one that would be
    chosen for the recorded rig, by content), the same feature set and table, the same up
    axis, the same extractor version, and a pose block exactly when ``poses`` is asked
    (with the same ``poses`` description: joints, unit, normalisation); for a marker file,
    the same marker set (by content) and the up axis taken from the file or the same
    ``up``. Modification times
    are not used: a touched but unchanged input is still up to date, a changed ASF with an
    old time stamp is not."""
    from mtanno.features.poses import pose_metadata
    from mtanno.io.rigs import select_map

    try:  # (a name too long for the file system is no output: written, and failing, later)
        meta = _stored_meta(job.dst) if stat.S_ISREG(os.stat(job.dst).st_mode) else None
    except OSError:
        meta = None
    if meta is None:
        return False
    fs = get_feature_set(feature_set)
    fmt = format_of(job.src)
    stored_up = "file" if meta.get("up_from") == "file" else meta.get("up", "y")
    if (meta.get("feature_set"), meta.get("feature_set_version"),
            meta.get("feature_table_sha256"), meta.get("extractor_version")) != \
            (fs.name, fs.version, fs.digest, EXTRACTOR_VERSION) or \
            stored_up != (up or fmt.up):
        return False
    if meta.get("poses") != (pose_metadata() if poses else None):
        return False
    try:
        if meta.get("source_sha256") != sha256_file(job.src):
            return False
        asf = job.asf
        if asf is None and fmt.skeleton_file is not None:
            asf = find_asf(job.src)
        if (None if asf is None else skeleton_digest(Path(asf))) != \
                meta.get("skeleton_file_sha256"):
            return False
        nodes = meta.get("rig_nodes")
        if not isinstance(nodes, list):
            return False
        if meta.get("rig") == "c3d":
            from mtanno.io.markerset import choose_set

            return choose_set([str(n) for n in nodes], markers).digest == \
                meta.get("skeleton_map_sha256")
        try:
            smap = select_map(str(meta.get("rig")), [str(n) for n in nodes], skeleton)
        except MtannoError:
            if (skeleton is not None or meta.get("skeleton_map_file") != "generated"
                    or meta.get("rig") != "bvh"):
                return False
            return _guessed_digest(job.src) == meta.get("skeleton_map_sha256")
    except (OSError, MtannoError):
        return False
    return smap.digest == meta.get("skeleton_map_sha256")


def _guessed_digest(src: Path) -> str:
    """The content hash of the skeleton map :func:`mtanno.io.guess.guess_map` makes for a
    BVH file no map fits (the map is made from the file's names, tree and first frames, so
    the same file gives the same map): an output whose recorded map has this hash is up to
    date, instead of recomputed on every run."""
    from mtanno.io.bvh import read_bvh
    from mtanno.io.guess import guess_map

    return guess_map(*read_bvh(src)).digest


def _run_one(job: Job, skeleton: str | None, feature_set: str = FEATURE_SET,
             up: str | None = None, poses: bool = False, markers: str | None = None,
             ) -> Outcome:
    return Outcome.of(job, *_extract_one(job.src, job.dst, job.asf, skeleton, feature_set,
                                         up, poses, markers))


def _invalid_note(src: Path, meta: dict, frames: int) -> tuple[str, int]:
    """(a note naming the invalid share of a written file and what caused it, invalid
    analysis frames); ("", 0) when every frame is valid."""
    invalid = sum(b - a + 1 for a, b in meta.get("invalid", []))
    if not invalid:
        return "", 0
    lost = meta.get("markers", {}).get("lost", {})
    why = (f" (markers lost beyond filling: {', '.join(sorted(lost)[:6])})" if lost else "")
    return (f"{src}: note: {invalid} of {frames} frames ({100 * invalid / frames:.1f} %) are "
            f"invalid: joints could not be computed{why}; annotation leaves them "
            f"unlabelled", invalid)


def _extract_one(src: Path, dst: Path, asf: Path | None, skeleton: str | None,
                 feature_set: str, up: str | None, poses: bool = False,
                 markers: str | None = None) -> tuple[str, str | MtannoError, int, int]:
    """One document: (status, message, analysis frames, invalid frames); every error is
    caught and reported for this file alone, so the batch goes on (an
    :class:`MtannoError` as it was raised)."""
    try:
        X, meta = extract_file(src, dst, asf=asf, skeleton=skeleton, feature_set=feature_set,
                               up=up, poses=poses, markers=markers)
        note, invalid = _invalid_note(src, meta, int(X.shape[1]))
        return "written", note, int(X.shape[1]), invalid
    except MtannoError as exc:
        return "failed", exc, 0, 0
    except OSError as exc:  # a file system error not caught where it happened
        return "failed", f"{exc.filename or src}: {exc.strerror or exc}", 0, 0
    except Exception as exc:  # a bug, reported per file so the batch goes on
        from mtanno.util.workers import interruption_in

        found = interruption_in(exc)  # a signal Python wrapped: the run is interrupted
        if found is not None:
            raise found from None
        return "failed", f"{src}: internal error: {type(exc).__name__}: {exc}", 0, 0


def _run_chunk(items: list[tuple[Path, Path, Path | None]], skeleton: str | None,
               feature_set: str, up: str | None, poses: bool = False,
               markers: str | None = None) -> list[tuple[str, str, int, int]]:
    """A task of a pool: several documents one after another, each failing alone. Tasks
    carry paths and return (status, message, frames, invalid frames) per document: the
    parent keeps the jobs, so nothing else crosses between the processes."""
    return [_extract_one(src, dst, asf, skeleton, feature_set, up, poses, markers)
            for src, dst, asf in items]


#: Most documents in one pool task. Short clips take a few milliseconds each, so one task
#: per file spent much of its time passing tasks and results between processes; tasks of
#: several files shrink that, and shrink towards the end of a batch (see :func:`_chunks`)
#: so that no worker is left with a long task while the others are idle.
CHUNK_FILES = 8


def _chunks(n: int, workers: int, most: int = CHUNK_FILES) -> list[tuple[int, int]]:
    """(start, stop) of the tasks for ``n`` documents on ``workers`` processes: up to
    ``most`` documents per task, fewer as the batch nears its end (a task holds at most
    1/(4 · workers) of what remains)."""
    out = []
    i = 0
    while i < n:
        size = max(1, min(most, (n - i) // (4 * max(1, workers))))
        out.append((i, min(n, i + size)))
        i += size
    return out


def run_batch(jobs: list[Job], *, n_jobs: int = 1, force: bool = False,
              skeleton: str | None = None,
              progress: Callable[[Outcome], None] | None = None,
              feature_set: str = FEATURE_SET, up: str | None = None,
              scheduler: str | None = None, poses: bool = False,
              markers: str | None = None) -> Summary:
    """Extract features for every job; failures are recorded, the batch goes on.

    ``up`` is the up axis of every motion file ("y" or "z", :func:`to_y_up`; None: each
    format's rule, :func:`extract_file`); ``markers``: the marker set of C3D files
    (:func:`extract_file`). ``poses``:
    every output also holds the normalised poses of its frames (:func:`extract_file`); an
    output with a pose block is not up to date without ``poses``, one without is not with
    it.

    ``n_jobs`` > 1 runs documents in that many processes (:class:`mtanno.util.workers.WorkerPool`:
    they stop with this process); ``scheduler`` sends them to a dask.distributed cluster
    instead (:class:`mtanno.util.workers.DaskPool`; same results). Outputs that are up to date
    (:func:`up_to_date`) are skipped unless ``force``. ``progress`` is called once per
    finished job, in the order of ``jobs``.

    In a pool of local processes the first document is done here before the workers start:
    the workers are forked from this process and inherit what it loaded (the compiled
    kernels, the skeleton and its map) instead of each loading it again.
    """
    from mtanno.util.workers import SerialPool, WorkerPool, make_pool

    feature_set = get_feature_set(feature_set).name
    if up is not None:
        to_y_up(np.zeros(3), up)  # refuse an unknown axis before any work
    summary = Summary()

    def record(o: Outcome) -> None:
        summary.outcomes.append(o)
        if progress:
            progress(o)

    todo = []
    for j in jobs:
        if j.error:  # found unusable while planning: reported, never run
            record(Outcome(j, "failed", f"{j.src}: {j.error}"))
        elif not force and up_to_date(j, feature_set=feature_set, skeleton=skeleton, up=up,
                                      poses=poses, markers=markers):
            record(Outcome(j, "skipped"))
        else:
            todo.append(j)
    with make_pool(jobs=n_jobs, scheduler=scheduler, n_tasks=len(todo)) as pool:
        if isinstance(pool, WorkerPool) and todo:
            record(_run_one(todo[0], skeleton, feature_set, up, poses, markers))
            todo = todo[1:]
        # in this process one document per task, so progress is reported file by file
        chunks = _chunks(len(todo), getattr(pool, "n_jobs", 1),
                         1 if isinstance(pool, SerialPool) else CHUNK_FILES)
        tasks = [([(j.src, j.dst, j.asf) for j in todo[a:b]], skeleton, feature_set, up, poses,
                  markers) for a, b in chunks]
        for (a, b), results in zip(chunks, pool.map(_run_chunk, tasks)):
            for j, result in zip(todo[a:b], results):
                record(Outcome.of(j, *result))
    return summary


@dataclass(frozen=True)
class ExtractOptions:
    """How :func:`extract_to` extracts (``mtanno features``' options; the defaults are the
    command's, those of :func:`run_batch`).

    ``feature_set``: the features computed (``ak40``, ``mrc05``, ``mrc05-reference``;
    :func:`mtanno.features.compute.get_feature_set`); ``poses``: every output also holds
    the normalised poses of its frames (:func:`extract_file`); ``skeleton``: a skeleton map
    (TOML file or name) instead of the detected one; ``markers``: the marker set of C3D
    files; ``up``: the up axis of every motion file (``"y"`` or ``"z"``; None: each
    format's rule). ``force``: rewrite outputs that are up to date (:func:`up_to_date`).
    ``n_jobs`` worker processes, or ``scheduler``, a dask.distributed address
    (``local:N``) — the same files either way."""

    feature_set: str = FEATURE_SET
    poses: bool = False
    skeleton: str | None = None
    markers: str | None = None
    up: str | None = None
    force: bool = False
    n_jobs: int = 1
    scheduler: str | None = None

    def __post_init__(self):
        get_feature_set(self.feature_set)
        if self.up is not None:
            to_y_up(np.zeros(3), self.up)  # an unknown axis, in the words of every reader
        if not isinstance(self.n_jobs, int) or isinstance(self.n_jobs, bool) \
                or self.n_jobs < 1:
            raise MtannoError(f"{{n_jobs}} must be a positive integer, got {self.n_jobs!r}",
                              options=("n_jobs",))


def extract_to(inputs: Iterable[str | os.PathLike], outdir: str | os.PathLike,
               options: ExtractOptions | None = None, *,
               listed: Iterable[str | os.PathLike] = (), asf: str | os.PathLike | None = None,
               inside_input: bool = False, wait: bool = False,
               on_wait: Callable[[str], None] | None = None,
               on_start: Callable[[int], None] | None = None,
               progress: Callable[[Outcome], None] | None = None) -> Summary:
    """The whole ``mtanno features`` run: the jobs of :func:`plan_batch` (``inputs``,
    ``listed``, ``asf``, ``inside_input``), an error when they hold no motion file, the
    output folder made and locked (:func:`mtanno.util.locks.folder_lock`: busy is
    :class:`~mtanno.util.locks.LockBusy`, or with ``wait`` waited for after one
    ``on_wait(holder)`` call) and :func:`run_batch` as ``options`` say
    (:class:`ExtractOptions`; ``progress`` as there). A run that writes nothing leaves no
    new folder behind (:func:`mtanno.util.output.output_folder`). ``on_start(n)`` is
    called before the first of ``n`` jobs."""
    from mtanno.util.locks import folder_lock
    from mtanno.util.output import output_folder

    o = options or ExtractOptions()
    if not str(outdir).strip():
        raise MtannoError("the output folder name ({outdir}) is empty; name a folder ('.' "
                          "for this one)", options=("outdir",))
    items = list(inputs)
    jobs = plan_batch(items, outdir, asf=asf, listed=listed, inside_input=inside_input)
    if not jobs:
        folders = [str(i) for i in items if Path(i).is_dir()]
        raise MtannoError(f"no motion files ({expected()}) found in the inputs" + (
            f" (searched the folder{'s' if len(folders) > 1 else ''} "
            f"{', '.join(folders[:3])}{' …' if len(folders) > 3 else ''} and below)"
            if folders else ""))
    if on_start:
        on_start(len(jobs))
    with output_folder(outdir), folder_lock(outdir, wait=wait, on_wait=on_wait):
        return run_batch(jobs, n_jobs=o.n_jobs, force=o.force, skeleton=o.skeleton,
                         progress=progress, feature_set=o.feature_set, up=o.up,
                         scheduler=o.scheduler, poses=o.poses, markers=o.markers)
