"""Worker processes and signals: the one policy of every command that runs in parallel.

* **SIGTERM and SIGHUP are handled like SIGINT.** Inside :func:`interruptible` (the command
  line wraps every command in it) they raise :class:`Interrupted`, a
  :class:`KeyboardInterrupt`, so the same code runs for all three: temporary files are
  removed (:func:`mtanno.util.output.atomic_path`), workers are stopped, and the command line
  prints one line and exits 130 (129 for SIGHUP). Before and after the command (imports,
  interpreter shutdown) :mod:`mtanno.__main__` holds the same policy.
* **An interruption inside a ctypes callback is delivered again.** numba loads its cached
  kernels through ctypes callbacks; an exception raised there is printed ("Exception
  ignored on calling ctypes callback") and dropped by ctypes. :func:`interruptible` and the
  workers catch that :class:`Interrupted` in ``sys.unraisablehook`` and send the signal
  again, so it is raised at the next point outside the callback.
* **An interruption wrapped in another exception is still one.** Python 3.11 wraps an
  exception raised in a descriptor's ``__set_name__`` while a class is created in
  ``RuntimeError("Error calling __set_name__ …")`` (an :class:`enum.Enum` creates its
  members that way): a signal that lands while a module defining such a class is imported
  late (numba's typing modules, the pool's) came out as that RuntimeError, a traceback and
  exit code 1. :func:`interruption_in` finds the interruption in an exception's chain;
  :func:`interruptible`, the workers and the per-file error reports raise it as itself.
* **Workers never outlive the parent.** A :class:`WorkerPool` worker asks the Linux kernel
  for SIGTERM when its parent dies (``prctl(PR_SET_PDEATHSIG)`` through :mod:`ctypes`) and,
  as a fallback on every system, watches the parent's pid from a thread: when the parent
  is gone (killed with SIGKILL, say), the worker stops within a fraction of a second.
* **Workers ignore SIGINT and SIGHUP.** Ctrl-C (or a hangup) reaches the whole process
  group; the parent decides: it stops its workers (SIGTERM, then SIGKILL for one that does
  not end) and unwinds. Also a worker forked a moment ago that has not set its own handlers
  yet (:func:`_raise_interrupted` sees another pid) ignores them, and exits on SIGTERM.
* **A worker that gets SIGTERM** unwinds the task it is running (so its temporary files are
  removed) and exits; an idle worker exits at once; further SIGTERMs are ignored while it
  unwinds (the watchdog ends it after :data:`STOP_GRACE` if it has not). Nothing is
  reported back and no traceback is printed.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

__all__ = ["DaskPool", "Interrupted", "SerialPool", "WorkerPool", "interruptible",
           "interruption_in", "make_pool", "must_hard_exit", "scheduler_address", "shared"]

#: How often a worker checks that its parent is alive (seconds).
WATCHDOG_INTERVAL = 0.2
#: How long a stopped worker may take to unwind before it is killed (seconds).
STOP_GRACE = 0.5
#: How soon an interruption lost in a ctypes callback is delivered again (seconds).
REDELIVER_DELAY = 0.005

_PR_SET_PDEATHSIG = 1


#: The signals a command handles alike (SIGINT, SIGTERM, SIGHUP where there is one).
SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))
_SIGHUP = getattr(signal, "SIGHUP", None)


def exit_code(signum: int) -> int:
    """The exit code of a command stopped by ``signum``: 129 for SIGHUP (128 + 1, as a shell
    reports it), else 130 (SIGINT's, also for SIGTERM: "interrupted")."""
    return 129 if signum == _SIGHUP else 130


class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP received: unwind like Ctrl-C. ``signum`` says which."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signum)
        self.signum = signum

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        return exit_code(self.signum)


def interruption_in(exc: BaseException) -> KeyboardInterrupt | None:
    """The interruption (:class:`Interrupted`, or Ctrl-C's :class:`KeyboardInterrupt`) that
    ``exc`` is or wraps, following its ``__cause__`` and ``__context__`` chain; None when
    there is none. Python wraps an exception raised inside some of its hooks (3.11: a
    descriptor's ``__set_name__`` while a class is created, ``RuntimeError("Error calling
    __set_name__ …")``), so a signal handled there arrives as another exception."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return None


#: The process that installed :func:`_raise_interrupted` (a forked worker inherits it).
_HANDLER_PID = 0


def _raise_interrupted(signum, frame):
    if os.getpid() != _HANDLER_PID:
        # a worker just forked, before its initializer set the worker's handlers: it
        # behaves as a worker (no traceback from the pool's bootstrap code)
        if signum == signal.SIGTERM:
            os._exit(128 + signum)
        return
    raise Interrupted(signum)


def _redeliver_interrupt(unraisable) -> None:
    """``sys.unraisablehook`` while signals are handled: an :class:`Interrupted` raised
    where Python cannot propagate it (a ctypes callback, numba loading its cached kernels;
    a ``__del__``) is not printed and lost but delivered again, so that it is raised at
    the next point that can propagate it. Anything else goes to the previous hook."""
    exc = unraisable.exc_value
    if not isinstance(exc, Interrupted):
        _PREVIOUS_HOOK(unraisable)
        return
    if os.getpid() != _HANDLER_PID and exc.signum == signal.SIGTERM:
        signal.signal(signal.SIGTERM, _worker_sigterm)  # the worker's handler, re-armed
    # From another thread, a moment later: sent from here, the handler would run at once,
    # still inside this hook (and be lost again). Should it land in a callback once more,
    # this hook sends it again.
    # Once per signal: a callback called again and again (qsort's comparator) may be hit
    # by the same interruption several times, and a second delivery after the command
    # has unwound would meet the default handler.
    if exc.signum in _PENDING:
        return
    again = threading.Timer(REDELIVER_DELAY, _deliver, (os.getpid(), exc.signum))
    again.daemon = True
    _PENDING[exc.signum] = again
    again.start()


def _deliver(pid: int, signum: int) -> None:
    if _PENDING.pop(signum, None) is not None:
        os.kill(pid, signum)


def _cancel_redeliveries() -> None:
    """Drop the deliveries not yet made: the interruption they carry has been handled."""
    for signum in list(_PENDING):
        timer = _PENDING.pop(signum, None)
        if timer is not None:
            timer.cancel()


#: Signals waiting to be delivered again (:func:`_redeliver_interrupt`), with their timers.
_PENDING: dict[int, threading.Timer] = {}
_PREVIOUS_HOOK = sys.unraisablehook


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """While inside, SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted` in the main thread
    (also when they arrive inside a ctypes callback: :func:`_redeliver_interrupt`).

    Outside the main thread (where Python cannot install handlers) nothing changes. The
    previous handlers are restored on exit.
    """
    global _HANDLER_PID
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _HANDLER_PID = os.getpid()
    old = {s: signal.signal(s, _raise_interrupted) for s in SIGNALS}
    old_hook, sys.unraisablehook = sys.unraisablehook, _redeliver_interrupt
    try:
        yield
    except Interrupted:
        _cancel_redeliveries()  # handled: a late copy must not meet the default handler
        raise
    except Exception as exc:  # an interruption Python wrapped (module docstring)
        found = interruption_in(exc)
        if found is None:
            raise
        _cancel_redeliveries()
        raise found from None
    finally:
        sys.unraisablehook = old_hook
        for s, handler in old.items():
            signal.signal(s, handler)


# ----------------------------------------------------------------------------- in a worker

_IN_TASK = False


def _set_parent_death_signal(signum: int) -> bool:
    """Ask the kernel to send ``signum`` when the parent dies (Linux only)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, signum, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _worker_sigterm(signum, frame):
    # Once: the parent-death signal and the watchdog may both send SIGTERM, and a second
    # one raised inside the unwinding would skip the removal of a temporary file.
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if _IN_TASK:
        raise Interrupted(signum)  # unwind the task (temporary files removed), then exit
    os._exit(128 + signum)


def _watchdog(parent: int) -> None:
    while True:
        time.sleep(WATCHDOG_INTERVAL)
        if os.getppid() != parent:
            with contextlib.suppress(OSError):
                os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(STOP_GRACE)
            os._exit(128 + signal.SIGTERM)


#: Data every task of a pool may read (:func:`shared`), set once per worker.
_SHARED: Any = None


def shared() -> Any:
    """The ``shared`` object of the pool (or dask run) this task runs in: large read-only
    data (a GA's training set, say) sent to each worker once instead of with every task."""
    return _SHARED


def _init_worker(parent: int, data: Any = None) -> None:
    global _SHARED
    _SHARED = data
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if _SIGHUP is not None:
        signal.signal(_SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _worker_sigterm)
    sys.unraisablehook = _redeliver_interrupt  # SIGTERM inside a ctypes callback
    _set_parent_death_signal(signal.SIGTERM)
    if os.getppid() != parent:  # the parent died before the kernel was asked
        os._exit(128 + signal.SIGTERM)
    threading.Thread(target=_watchdog, args=(parent,), name="mtanno-watchdog",
                     daemon=True).start()


def _run_task(fn: Callable[..., Any], args: tuple) -> Any:
    global _IN_TASK
    _IN_TASK = True
    try:
        return fn(*args)
    except KeyboardInterrupt:
        os._exit(128 + signal.SIGTERM)
    except Exception as exc:  # an interruption Python wrapped (module docstring)
        if interruption_in(exc) is not None:
            os._exit(128 + signal.SIGTERM)
        raise
    finally:
        _IN_TASK = False


# ----------------------------------------------------------------------------- in the parent


_ABANDONED = False


def must_hard_exit() -> bool:
    """True after a :class:`WorkerPool` was stopped: the caller should end the process with
    :func:`os._exit` (after flushing its output) instead of a normal interpreter shutdown,
    which could wait forever for the pool's manager thread (see :meth:`WorkerPool.stop`)."""
    return _ABANDONED


class WorkerPool:
    """A process pool whose workers follow the policy of this module.

    Use it as a context manager: leaving the block normally waits for the workers; leaving
    it with an exception (an interruption, say) stops them at once and waits until they
    are gone, so no worker outlives the command.
    """

    def __init__(self, n_jobs: int, *, shared: Any = None):
        ctx = None
        if sys.platform != "win32":
            import multiprocessing

            ctx = multiprocessing.get_context("fork")  # no re-import of numba per worker
        self.n_jobs = int(n_jobs)
        self._pool = ProcessPoolExecutor(max_workers=self.n_jobs, mp_context=ctx,
                                         initializer=_init_worker,
                                         initargs=(os.getpid(), shared))

    def map(self, fn: Callable[..., Any], args: Iterable[Sequence[Any]], *,
            chunksize: int = 1) -> Iterator[Any]:
        """``fn(*a)`` for every ``a`` of ``args`` in the workers; results in input order.
        ``fn`` must be a module-level function (it is sent to the workers by name)."""
        items = [tuple(a) for a in args]
        return self._pool.map(_run_task, [fn] * len(items), items, chunksize=chunksize)

    def submit(self, fn: Callable[..., Any], *args: Any):
        """Run ``fn(*args)`` in a worker; returns a :class:`concurrent.futures.Future`."""
        return self._pool.submit(_run_task, fn, args)

    def stop(self) -> None:
        """Stop every worker now (SIGTERM, then SIGKILL after :data:`STOP_GRACE`) and wait
        until they are gone.

        A worker killed while it was sending a result can leave half a message in the
        result pipe, and the executor's manager thread then waits for the rest forever
        (interpreter shutdown joins that thread). So a stopped pool marks the process as
        one that must leave with :func:`os._exit` once it has cleaned up
        (:func:`must_hard_exit`)."""
        global _ABANDONED
        _ABANDONED = True
        procs = list((getattr(self._pool, "_processes", None) or {}).values())
        with contextlib.suppress(Exception):
            self._pool.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            with contextlib.suppress(Exception):
                p.terminate()
        deadline = time.monotonic() + STOP_GRACE
        for p in procs:
            with contextlib.suppress(Exception):
                p.join(max(0.0, deadline - time.monotonic()))
                if p.is_alive():
                    p.kill()
                    p.join()

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self._pool.shutdown(wait=True)
        else:
            self.stop()


# ----------------------------------------------------------------------------- dask and serial


class SerialPool:
    """The pool interface in this process (``--jobs 1``): tasks run one after another."""

    def __init__(self, *, shared: Any = None):
        self._shared = shared

    def map(self, fn: Callable[..., Any], args: Iterable[Sequence[Any]], *,
            chunksize: int = 1) -> Iterator[Any]:
        global _SHARED
        previous, _SHARED = _SHARED, self._shared
        try:
            for a in args:
                yield fn(*a)
        finally:
            _SHARED = previous

    def __enter__(self) -> SerialPool:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        pass


def _dask_task(fn: Callable[..., Any], data: Any, args: tuple) -> Any:
    global _SHARED
    _SHARED = data
    return fn(*args)


#: A scheduler address: [PROTOCOL://]HOST[:PORT], HOST a name, an IPv4 or a bracketed IPv6.
_ADDRESS = re.compile(r"(?:(?:tcp|tls|ws|wss|ucx)://)?"
                      r"(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9._-]*[A-Za-z0-9])?)"
                      r"(?::(\d{1,5}))?")


def scheduler_address(scheduler: str) -> str:
    """``scheduler`` checked: ``local:N`` with N ≥ 1, or the address of a dask scheduler,
    ``[tcp://]HOST[:PORT]`` (also ``tls://``, ``ws://``, ``wss://``, ``ucx://``). Anything
    else is a :class:`~mtanno.errors.MtannoError`, raised before any work (dask itself
    would raise a ValueError, or wait 30 s for a host that is none)."""
    from mtanno.errors import MtannoError

    text = str(scheduler).strip()
    if text.startswith("local:"):
        n = text.split(":", 1)[1]
        if not (n.isascii() and n.isdigit() and int(n) >= 1):
            raise MtannoError(f"{{scheduler}} local:N needs a positive number of workers, "
                              f"got {scheduler!r}", options=("scheduler",))
        return f"local:{int(n)}"
    m = _ADDRESS.fullmatch(text)
    if m is None or (m.group(1) is not None and not 1 <= int(m.group(1)) <= 65535):
        raise MtannoError(f"{{scheduler}} must be a dask scheduler address such as "
                          f"tcp://HOST:8786, or local:N, got {scheduler!r}",
                          options=("scheduler",))
    return text


class DaskPool:
    """The pool interface on a dask.distributed cluster (``--scheduler``).

    ``scheduler`` is the address of a running scheduler (``tcp://host:8786``) or
    ``local:N`` for a local cluster of N single-threaded worker processes started for this
    run. Tasks are the same functions with the same arguments as in a :class:`WorkerPool`
    (file paths and small records; every worker reads its inputs from the shared file
    system), so results are identical; ``shared`` data is scattered to every worker once.
    Results come back in input order. ``docs/scaling.md`` says how to run a cluster.
    """

    def __init__(self, scheduler: str, *, shared: Any = None):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            from mtanno.errors import MtannoError

            raise MtannoError("{scheduler} needs dask.distributed, an optional extra: "
                              "pip install 'mtanno[dask]'", options=("scheduler",)) from None
        self._cluster = None
        scheduler = scheduler_address(scheduler)
        if scheduler.startswith("local:"):
            n = int(scheduler.split(":", 1)[1])
            with warnings.catch_warnings():
                # Its scheduler's HTTP server falls back to a free port when another dask
                # holds 8787; that is no concern of this run.
                warnings.filterwarnings("ignore", message="Port .* is already in use")
                self._cluster = LocalCluster(n_workers=n, threads_per_worker=1,
                                             processes=True, dashboard_address=None)
            self._client = Client(self._cluster)
        else:
            try:
                self._client = Client(scheduler)  # dask's connect timeout (30 s by default)
            except OSError as exc:
                from mtanno.errors import MtannoError

                raise MtannoError(f"cannot reach the dask scheduler {scheduler}: {exc}") \
                    from None
        # One object under a key of this pool's own: scattered as it is, a dict's keys
        # ("examples", …) or a content hash would be the same keys for the next pool that
        # shares such data, and the scheduler's late release of the closing pool's keys
        # would cancel the next pool's tasks (FutureCancelledError).
        self._shared = (self._client.scatter([shared], broadcast=True, hash=False)[0]
                        if shared is not None else None)

    def map(self, fn: Callable[..., Any], args: Iterable[Sequence[Any]], *,
            chunksize: int = 1) -> Iterator[Any]:
        items = [tuple(a) for a in args]
        futures = self._client.map(_dask_task, [fn] * len(items), [self._shared] * len(items),
                                   items, pure=False)
        for fut in futures:
            yield fut.result()

    def __enter__(self) -> DaskPool:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        with contextlib.suppress(Exception):
            self._client.close()
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                self._cluster.close()


def make_pool(*, jobs: int = 1, scheduler: str | None = None, shared: Any = None,
              n_tasks: int | None = None):
    """The executor of a batch: a :class:`DaskPool` with ``scheduler``; else a
    :class:`WorkerPool` of ``jobs`` processes, or a :class:`SerialPool` for one job (or one
    task). All three give ``fn(*args)`` results in input order, with ``shared`` readable
    through :func:`shared` inside the tasks — and the same results."""
    if scheduler:
        return DaskPool(scheduler, shared=shared)
    if jobs > 1 and (n_tasks is None or n_tasks > 1):
        return WorkerPool(jobs, shared=shared)
    return SerialPool(shared=shared)
