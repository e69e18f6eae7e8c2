"""Writing outputs safely: atomic replacement, the umask, temporary files, and inputs.

Every file mtanno writes goes through :func:`atomic_path`, so a command that fails, is
interrupted or is killed never leaves half a file under the output's name:

* the data is written to a temporary file beside the target, ``.NAME.HOST-PID.XXXXXXXX.tmp``,
  and renamed over the target (``os.replace``, atomic on POSIX) only when complete;
* the temporary file is removed when writing fails or is interrupted (Ctrl-C, SIGTERM: see
  :mod:`mtanno.workers`); a writer killed outright (SIGKILL, power loss) cannot clean up, so
  the next write into the same folder removes the temporary files of writers that are no
  longer alive (same host, process gone);
* the file gets the permissions an ordinary ``open`` would give it (0666 less the umask),
  not the 0600 of a temporary file, so a shared archive stays readable;
* an unwritable location is one :class:`~mtanno.errors.MtannoError` naming the path.

:func:`check_outputs` is called by every command before any work: an output that is one of
the command's inputs, or would replace one (same resolved path, or the same file through a
hard link or symbolic link: same device and inode), is refused.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
from collections.abc import Iterable, Iterator
from pathlib import Path

from mtanno.errors import MtannoError

__all__ = ["atomic_path", "check_outputs", "current_umask", "remove_stale_temporaries",
           "write_bytes", "write_text"]

#: Suffix of every temporary file :func:`atomic_path` creates.
TMP_SUFFIX = ".tmp"


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


def _write_error(target: Path, exc: OSError) -> MtannoError:
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
        raise _write_error(folder, exc) from None
    return folder


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
        raise _write_error(target, exc) from None
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
    prefix = os.path.join(str(target.parent), f".{target.name}.{_HOST}-{os.getpid()}.")
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
                raise _write_error(target, exc) from None
            make_folder(target.parent)
            made_folder = True
        except OSError as exc:
            made.pop()
            raise _write_error(target, exc) from None
    raise _write_error(target, FileExistsError(f"no free temporary name beside {target}"))


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
            raise _write_error(target, exc) from None
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
        yield target
        return
    made: list[str] = []
    try:
        os.close(_temporary(target, mode, made))
        yield Path(made[0])
    except OSError as exc:
        _remove(made)
        raise _write_error(target, exc) from None
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
        with open(target, "wb") as fh:
            fh.write(data)
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
            raise _write_error(target, exc) from None
        raise
    _replace(made[0], target, fd)


def write_text(target: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``target`` atomically, or to standard output for ``-``."""
    if str(target) == "-":
        import sys

        sys.stdout.write(text)
        sys.stdout.flush()
        return
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def check_outputs(outputs: Iterable[str | os.PathLike | None],
                  inputs: Iterable[str | os.PathLike | None]) -> None:
    """Refuse outputs that are, or would replace, one of the inputs; and an output named
    twice. Compared by resolved path (symbolic links followed) and by device and inode
    (hard links), so ``-o r.parquet`` cannot overwrite the input ``r.parquet`` under any of
    its names. ``None`` and ``-`` (standard input/output) are skipped.

    Call it before any work: the command then fails at once, with one line, and writes
    nothing.
    """
    import stat

    folders: dict[str, str] = {}

    def in_folder(parent: str, name: str) -> str:
        # the folder resolved once per folder (batches name thousands of files in a few
        # folders); a file that is itself a link is caught by its inode below
        if parent not in folders:
            folders[parent] = os.path.realpath(parent)
        return os.path.join(folders[parent], name)

    def resolved(p: Path) -> str:
        return in_folder(str(p.parent), p.name)

    def link_target(p: Path) -> str:
        # where a symbolic link leads (os.path.realpath), its folder resolved once per
        # folder as above; a link to a link is left to realpath
        target = os.path.join(str(p.parent), os.readlink(p))
        folder, name = os.path.split(target)
        if name in ("", ".", "..") or os.path.islink(target):
            return os.path.realpath(p)
        return in_folder(folder or ".", name)

    by_path: dict[str, str] = {}
    by_inode: dict[tuple[int, int], str] = {}
    for item in inputs:
        if item is None or str(item) == "-":
            continue
        p = Path(item)
        by_path.setdefault(resolved(p), str(item))
        try:
            st = os.lstat(p)
            if stat.S_ISLNK(st.st_mode):  # also where it leads
                by_path.setdefault(link_target(p), str(item))
                st = os.stat(p)
        except OSError:
            continue
        if stat.S_ISREG(st.st_mode):
            by_inode.setdefault((st.st_dev, st.st_ino), str(item))
    seen: dict[str, str] = {}
    for item in outputs:
        if item is None or str(item) == "-":
            continue
        p = Path(item)
        rp = resolved(p)
        if rp in seen:
            raise MtannoError(f"the same output is named twice ({seen[rp]} and {item})",
                              path=str(item))
        seen[rp] = str(item)
        hit = by_path.get(rp)
        if hit is None:
            ident = _identity(p)
            hit = by_inode.get(ident) if ident is not None else None
        if hit is not None:
            same = "" if hit == str(item) else f" ({hit})"
            raise MtannoError(f"output would overwrite an input of this command{same}; "
                              "choose another output name", path=str(item))


# ----------------------------------------------------------------------------- folder locks

#: Exit code of a command that finds its output folder locked by another run (cron safety).
EXIT_BUSY = 3


class LockBusy(MtannoError):
    """The output folder is locked by another running mtanno process; commands exit with
    :data:`EXIT_BUSY`."""

    exit_code = EXIT_BUSY


def _holder(fh) -> dict:
    from mtanno.errors import parse_json

    try:
        fh.seek(0)
        data = parse_json(fh.read() or "{}")
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError, MtannoError):
        return {}


def _holder_text(h: dict) -> str:
    if not h:
        return "another process"
    return (f"pid {h.get('pid', '?')} on {h.get('host', '?')} since {h.get('started', '?')}"
            + (f" ({h['command']})" if h.get("command") else ""))


@contextlib.contextmanager
def folder_lock(folder: str | os.PathLike, *, wait: bool = False, what: str = "output folder",
                name: str = ".mtanno.lock", on_wait=None) -> Iterator[None]:
    """Hold the exclusive writer lock of an output folder while the block runs.

    Two runs that write into the same folder (two cron jobs, say) must not interleave: the
    lock is an ``fcntl.flock`` on ``FOLDER/.mtanno.lock`` (``name``), which the kernel
    releases when the holder ends in any way — a lock left by a dead process is simply taken
    over. The holder writes who it is (pid, host, start time, command line) into the file,
    so a second run that finds the lock held says which run holds it and raises
    :class:`LockBusy` (the commands exit with code 3), or, with ``wait``, waits for it
    (``on_wait(holder_text)`` is called once before waiting). The folder is created; the
    lock file is removed when the block ends (a killed holder leaves it, unlocked, and the
    next run takes it over).
    """
    import json
    import time

    folder = Path(folder)
    path = folder / name
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no locking
        fcntl = None
    waited = False
    while True:
        try:
            make_folder(folder)
            fh = open(path, "a+", encoding="utf-8")
        except OSError as exc:
            raise _write_error(folder, exc) from None
        if fcntl is None:  # pragma: no cover
            break
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder_text(_holder(fh))
            if not wait:
                fh.close()
                raise LockBusy(f"{what} is locked by {holder}; try again later or pass "
                               "--wait", path=str(folder)) from None
            if on_wait is not None and not waited:
                on_wait(holder)
            waited = True
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        # the holder removes the file when it is done: a lock taken on a file that is no
        # longer at the path (removed, or replaced by a newer one) is no lock; take it again
        try:
            if os.fstat(fh.fileno()).st_ino == os.stat(path).st_ino:
                break
        except FileNotFoundError:
            pass
        fh.close()
    try:
        from mtanno.tables import command_line

        fh.seek(0)
        fh.truncate()
        fh.write(json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                             "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                             "command": " ".join(command_line() or [])}))
        fh.flush()
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)  # while still holding it: a waiter then takes it again
        fh.close()
