"""Writing outputs safely: atomic replacement, the umask, temporary files.

Every file mtanno writes goes through :func:`atomic_path`, so a command that fails, is
interrupted or is killed never leaves half a file under the output's name:

* the data is written to a temporary file beside the target, ``.NAME.HOST-PID.XXXXXXXX.tmp``
  (NAME cut short where the whole would not fit in a folder entry), and renamed over the
  target (``os.replace``, atomic on POSIX) only when complete;
* the temporary file is removed when writing fails or is interrupted (Ctrl-C, SIGTERM: see
  :mod:`mtanno.util.workers`); a writer killed outright (SIGKILL, power loss) cannot clean up, so
  the next write into the same folder removes the temporary files of writers that are no
  longer alive (same host, process gone);
* the file gets the permissions an ordinary ``open`` would give it (0666 less the umask),
  not the 0600 of a temporary file, so a shared archive stays readable;
* an unwritable location is one :class:`~mtanno.errors.MtannoError` naming the path.

Before any work, every command checks its outputs against its inputs
(:func:`mtanno.util.preflight.check_outputs`).
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import NoReturn

from mtanno.errors import MtannoError

__all__ = ["EXIT_CLOSED_OUTPUT", "SIDECAR_SUFFIX", "SIDECAR_TABLES", "atomic_path",
           "current_umask", "end_closed_output", "make_folder", "output_closed",
           "remove_stale_temporaries", "write_bytes", "write_error", "write_stdout",
           "write_text"]

#: Suffix of every temporary file :func:`atomic_path` creates.
TMP_SUFFIX = ".tmp"
#: Longest name of a folder entry (bytes) on the file systems mtanno writes to (POSIX
#: NAME_MAX of ext4, XFS, btrfs, tmpfs, NFS).
_NAME_MAX = 255


def _host_tag() -> str:
    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:40] or "host"


_HOST = _host_tag()
# .NAME.HOST-PID.RANDOM.tmp (RANDOM: tempfile's eight characters)
_TMP_RE = re.compile(r"^\..+\.(?P<host>[A-Za-z0-9-]+?)-(?P<pid>\d+)\.[a-z0-9_]+\.tmp$")
_CLEANED: set[str] = set()


def current_umask() -> int:
    """The process's umask (read from ``/proc`` where possible: setting and restoring it
    would race with other threads creating files)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _alive(pid: int) -> bool:
    """True if a process ``pid`` exists on this host and is not a zombie."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def remove_stale_temporaries(folder: str | os.PathLike, *, force: bool = False) -> list[Path]:
    """Remove the temporary files of dead writers in ``folder`` (see module docstring).

    Only files named as :func:`atomic_path` names them, created on this host by a process
    that no longer exists, are removed; each folder is looked at once per process unless
    ``force``. Returns the files removed.
    """
    folder = Path(folder)
    key = str(folder)  # as named: a folder named two ways is merely looked at twice
    if key in _CLEANED and not force:
        return []
    _CLEANED.add(key)
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return []
    for entry in entries:
        m = _TMP_RE.match(entry.name)
        if m is None or m["host"] != _HOST:
            continue
        pid = int(m["pid"])
        if pid == os.getpid() or _alive(pid):
            continue
        with contextlib.suppress(OSError):
            if entry.is_file(follow_symlinks=False):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


def write_error(target: Path, exc: OSError) -> MtannoError:
    what = exc.strerror or str(exc)
    if isinstance(exc, (NotADirectoryError, FileExistsError)) and exc.filename \
            and Path(exc.filename) != target:
        what = f"{exc.filename} is not a folder"
    return MtannoError(f"cannot write here: {what}", path=str(target))


def make_folder(folder: str | os.PathLike) -> Path:
    """Create an output folder (and its parents) with the umask's permissions; an existing
    file in the way or an unwritable location is a :class:`MtannoError` naming it."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise MtannoError("output folder exists and is not a folder", path=str(folder))
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise write_error(folder, exc) from None
    return folder


@contextlib.contextmanager
def output_folder(folder: str | os.PathLike) -> Iterator[Path]:
    """:func:`make_folder` for the ``with`` block; the folders it made (``folder`` and parents
    that did not exist) are removed again on leaving, innermost first, while they are empty
    — after an error or an interrupt too — so a run that wrote nothing leaves no new folder
    behind. A folder another run has written into meanwhile is kept."""
    folder = Path(folder)
    made = []
    f = folder
    while not f.exists() and not f.is_symlink() and f != f.parent:
        made.append(f)
        f = f.parent
    make_folder(folder)
    try:
        yield folder
    finally:
        for f in made:
            try:
                os.rmdir(f)
            except OSError:
                break


def _check_target(target: Path) -> bool:
    """False if ``target`` exists and is not a regular file (``/dev/null``, a FIFO): it is
    written in place, since renaming over a device would replace it. A folder, or a
    location the file system refuses, is a :class:`MtannoError`."""
    import stat

    try:
        st = os.stat(target)
    except (FileNotFoundError, NotADirectoryError):
        return True
    except OSError as exc:
        raise write_error(target, exc) from None
    if stat.S_ISDIR(st.st_mode):
        raise MtannoError("output is a folder, not a file", path=str(target))
    return stat.S_ISREG(st.st_mode)


def _temporary(target: Path, mode: int, made: list[str]) -> int:
    """Create the temporary file beside ``target`` and return its open descriptor.

    Its name is ``.NAME.HOST-PID.XXXXXXXX.tmp`` (eight random characters); it is created
    with ``O_EXCL`` and permissions ``mode``, which the kernel reduces by the umask as for
    any ``open`` (no ``chmod`` afterwards). The folder is created when missing. The name
    is appended to ``made`` *before* the file is created, so that a caller whose cleanup
    covers this call removes the file even when an interruption (SIGINT, SIGTERM) is raised
    the moment ``open`` returns."""
    remove_stale_temporaries(target.parent)
    tail = f".{_HOST}-{os.getpid()}."
    # the name cut so that the temporary's fits in a folder entry (NAME_MAX) wherever the
    # target's own does: an output named near the limit is still written
    room = _NAME_MAX - len(os.fsencode(tail)) - 1 - 8 - len(TMP_SUFFIX)
    name = os.fsencode(target.name)
    name = os.fsdecode(name[:room]) if len(name) > room else target.name
    prefix = os.path.join(str(target.parent), f".{name}{tail}")
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0) \
        | getattr(os, "O_BINARY", 0)
    made_folder = False
    for _ in range(100):  # as tempfile.mkstemp: another name when one is taken
        made.append(prefix + os.urandom(5).hex()[:8] + TMP_SUFFIX)
        try:
            return os.open(made[-1], flags, mode)
        except FileExistsError:
            made.pop()  # not ours
            continue
        except FileNotFoundError as exc:  # the folder does not exist yet
            made.pop()
            if made_folder:
                raise write_error(target, exc) from None
            make_folder(target.parent)
            made_folder = True
        except OSError as exc:
            made.pop()
            raise write_error(target, exc) from None
    raise write_error(target, FileExistsError(f"no free temporary name beside {target}"))


def _remove(made: list[str]) -> None:
    for tmp in made:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def _replace(tmp: str, target: Path, fd: int | None = None) -> None:
    """Rename ``tmp`` over ``target`` (closing ``fd`` first); on any failure or
    interruption the temporary file is removed and ``target`` left as it was."""
    try:
        if fd is not None:
            os.close(fd)
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise write_error(target, exc) from None
        raise


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike, *, mode: int = 0o666) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it over ``target`` on success.

    A failure or interruption inside the block removes the temporary file and leaves
    ``target`` as it was. The new file's permissions are ``mode`` less the umask. A
    ``target`` that exists and is not a regular file (``/dev/null``, a FIFO) is yielded
    itself and written in place: renaming over a device would replace it. Errors of the
    file system (unwritable folder, a file where a folder should be, disk full) are raised
    as :class:`MtannoError` naming ``target``.
    """
    target = Path(target)
    if not _check_target(target):
        try:
            yield target
        except OSError as exc:  # a device written in place (/dev/full: disk full)
            raise write_error(target, exc) from None
        return
    made: list[str] = []
    try:
        os.close(_temporary(target, mode, made))
        yield Path(made[0])
    except OSError as exc:
        _remove(made)
        raise write_error(target, exc) from None
    except BaseException:
        _remove(made)
        raise
    _replace(made[0], target)


def write_bytes(target: str | os.PathLike, data, *, mode: int = 0o666) -> None:
    """Write ``data`` (bytes or any buffer) to ``target`` atomically, as :func:`atomic_path`
    does (same temporary file, same permissions, same errors), but through the descriptor
    the temporary file was created with: one ``open`` per output, for writers of many
    small files (``mtanno features``)."""
    target = Path(target)
    if not _check_target(target):  # written in place, as atomic_path's caller would
        try:
            with open(target, "wb") as fh:
                fh.write(data)
        except OSError as exc:
            raise write_error(target, exc) from None
        return
    made: list[str] = []
    fd = -1
    try:
        fd = _temporary(target, mode, made)
        view = memoryview(data).cast("B")
        while view:
            view = view[os.write(fd, view):]
    except BaseException as exc:
        if fd >= 0:
            with contextlib.suppress(OSError):
                os.close(fd)
        _remove(made)
        if isinstance(exc, OSError):
            raise write_error(target, exc) from None
        raise
    _replace(made[0], target, fd)


#: Exit code of a command whose standard output was closed by its reader
#: (``mtanno info X | head -2``): 128 + SIGPIPE, what a shell reports for a program that
#: SIGPIPE ended (docs/reliability.md, exit codes).
EXIT_CLOSED_OUTPUT = 141


def output_closed() -> bool:
    """True if the reader of standard output or standard error is gone (a pipe whose
    reading end was closed: ``mtanno show X | head -1``). Only the process's real streams
    count; a stream that is no file (a test runner's buffer) is never closed."""
    import select
    import sys

    for stream in (sys.stdout, sys.stderr):
        try:
            poll = select.poll()
            poll.register(stream.fileno(), select.POLLOUT)
            if any(events & (select.POLLERR | select.POLLHUP) for _, events in poll.poll(0)):
                return True
        except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation: no file
            continue
    return False


def end_closed_output() -> NoReturn:
    """End the command quietly because its reader closed standard output (the SIGPIPE
    convention: no message, exit code :data:`EXIT_CLOSED_OUTPUT`). Standard output and
    error are pointed at the null device first, so the final flushes write nowhere instead
    of failing again."""
    import sys

    devnull = os.open(os.devnull, os.O_WRONLY)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, OSError, ValueError):
            os.dup2(devnull, stream.fileno())
    os.close(devnull)
    sys.exit(EXIT_CLOSED_OUTPUT)


def write_stdout(text: str) -> None:
    """Write ``text`` to standard output and flush it; a failure (a full device) is one
    :class:`MtannoError` that says it was standard output. A reader that closed the pipe
    early is no error: :class:`BrokenPipeError` goes up to the command's edge, which ends
    quietly (:func:`end_closed_output`)."""
    import sys

    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise MtannoError(f"cannot write to standard output: {exc.strerror or exc}") from None


def write_text(target: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``target`` atomically, or to standard output for ``-``."""
    if str(target) == "-":
        write_stdout(text)
        return
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")


#: Appended to a CSV or JSON Lines table's name to name its provenance sidecar
#: (:mod:`mtanno.util.tables`); an input's sidecar is an input too (:func:`check_outputs`).
SIDECAR_SUFFIX = ".meta.json"
#: Table suffixes that have a sidecar.
SIDECAR_TABLES = (".csv", ".jsonl")
