"""Folder locks (cron safety, ``docs/reliability.md``): the writer lock every command that
writes into a folder holds while it works, an ``fcntl`` lock on ``FOLDER/.mtanno.lock``
(``INDEX/.lock`` for an index) recording who holds it; the kernel releases it when its
holder ends in any way. A second run that finds it held raises :class:`LockBusy` (exit code
:data:`EXIT_BUSY`), or waits with ``wait=True``.
"""

from __future__ import annotations

import contextlib
import os
import socket
from collections.abc import Iterator
from pathlib import Path

from mtanno.errors import MtannoError
from mtanno.util.output import make_folder, write_error

__all__ = ["EXIT_BUSY", "LockBusy", "folder_lock"]

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
            raise write_error(folder, exc) from None
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
        from mtanno.util.provenance import command_line

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
