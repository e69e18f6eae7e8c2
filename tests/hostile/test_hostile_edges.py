"""Process edges (issue 22): what happens before the command runs and after it failed.

Signals in the first moments (while Python imports mtanno's dependencies) and during the
interpreter's shutdown, SIGHUP, a worker stopped while numba loads its kernels, an
interrupted ``tune``; a crash at exit after a corrupt index; option values that make no
sense (NaN, empty name lists, a scheduler address that is none). Each ends with exactly one
``mtanno:`` line and the exit code of the policy (docs/reliability.md): 130 for SIGINT and
SIGTERM, 129 for SIGHUP, 2 for a usage error or bad input.

The tests that send signals start the real command as a process and wait for an event
(a marker the entry point writes at a given moment, see ``MTANNO_TEST_MARK`` in
:mod:`mtanno.cli`), never for a fixed time.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from held import held_pids, start_held
from world import checksums, children, cli, temporaries, wait_for

from mtanno import synthetic

#: The command as a user runs it: the console script's entry point.
MTANNO = [sys.executable, "-c", "import sys; from mtanno.cli import main; sys.exit(main())"]
#: Generous bound on a run (a hung run fails the test instead of hanging the suite).
HANG = 120.0


def _run(args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([*MTANNO, *map(str, args)], capture_output=True, text=True,
                          timeout=HANG, **kw)


def _one_line(r: subprocess.CompletedProcess, code: int, text: str) -> str:
    """Exit ``code``, nothing on stderr but one ``mtanno:`` line holding ``text``."""
    lines = r.stderr.splitlines()
    assert r.returncode == code, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    assert len(lines) == 1 and lines[0].startswith("mtanno: ") and text in lines[0], r.stderr
    return lines[0]


# --------------------------------------------------------------------- crash at exit


def test_a_corrupt_index_never_aborts_the_process_at_exit(world, tmp_path):
    """A segment file cut short: "corrupt index" and exit 2, every time. (Arrow's dataset
    reader dropped its last reference to the file's bytes from one of its threads after
    the read returned; at interpreter exit that thread called std::terminate: SIGABRT,
    exit 134, in about one run of five.)"""
    idx = tmp_path / "idx"
    shutil.copytree(world.index, idx)
    seg = next(idx.glob("gen-*/segments-*.parquet"))
    seg.write_bytes(seg.read_bytes()[: seg.stat().st_size // 2])
    args = ["query", idx, "--example", world.doc_files[0].stem, "--features", "rknee_bent"]
    for _ in range(20):
        _one_line(_run(args), 2, "corrupt index")


# --------------------------------------------------------------------- option values


def _usage_line(r, option: str) -> None:
    """A usage error: exit 2, no traceback, one ``mtanno:`` line naming ``option``."""
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    assert r.exit_code == 2, (r.exit_code, r.output)
    lines = r.output.splitlines()
    assert len(lines) == 1 and lines[0].startswith("mtanno: ") and option in lines[0], r.output


@pytest.mark.parametrize("args,option", [
    (["learn-mt", "--manifest", "{manifest}", "--features-dir", "{feats}", "--thresh", "nan",
      "-o", "{out}"], "--thresh"),
    (["report", "{annotation}", "--truth", "{truth}", "--tau", "nan", "-o", "{out}"], "--tau"),
    (["annotate", "--mt", "{mt}", "{docfeats}", "--tau", "nan", "-o", "{out}.csv"], "--tau"),
    (["annotate", "--mt", "{mt}", "{docfeats}", "--delta", "inf", "-o", "{out}.csv"], "--delta"),
    (["retrieve", "--mt", "{template}", "{docfeats}", "--delta", "nan", "-o", "{out}.csv"],
     "--delta"),
    (["mt", "scale", "{template}", "--factor", "nan", "-o", "{out}.json"], "--factor"),
    (["tune", "--mt", "{mt}", "--manifest", "{manifest}", "--features-dir", "{feats}",
      "--unknown-weight", "inf", "-o", "{out}.toml"], "--unknown-weight"),
    (["show", "{doc}", "--features", ""], "--features"),
    (["show", "{doc}", "--features", "rknee_bent,,lknee_bent"], "--features"),
    (["index", "{docfeats}", "--groups", "", "-o", "{out}"], "--groups"),
    (["query", "{index}", "--example", "{docname}", "--features", ""], "--features"),
    (["features", "{clips}", "-o", "{out}", "--scheduler", "not an address"], "--scheduler"),
    (["features", "{clips}", "-o", "{out}", "--scheduler", "tcp://host:99999"], "--scheduler"),
], ids=["thresh-nan", "report-tau-nan", "annotate-tau-nan", "delta-inf", "retrieve-delta-nan",
        "factor-nan", "unknown-weight-inf", "features-empty", "features-empty-name",
        "groups-empty", "query-features-empty", "scheduler-garbage", "scheduler-port"])
def test_option_values_that_make_no_sense_are_a_usage_error(world, tmp_path, args, option):
    """NaN passes every range check and ``''`` reads as "no names, so all": both are
    refused by the option's type before the command starts (exit 2, one line, nothing
    written). ``--scheduler 'not an address'`` was a ValueError traceback."""
    w = world
    values = dict(manifest=w.manifest, feats=w.feats, out=tmp_path / "out", truth=w.truth,
                  annotation=w.annotation, mt=w.mt, docfeats=w.docfeats, template=w.template,
                  doc=w.doc_files[0], index=w.index, docname=w.doc_files[0].stem,
                  clips=w.clips)
    before = checksums(w.root)
    r = cli(*[a.format(**values) for a in args])
    _usage_line(r, option)
    assert list(tmp_path.iterdir()) == [] and checksums(w.root) == before


def test_a_scheduler_address_is_checked_for_the_api_too():
    from mtanno.errors import MtannoError
    from mtanno.util.workers import scheduler_address

    assert scheduler_address("tcp://10.0.0.1:8786") == "tcp://10.0.0.1:8786"
    assert scheduler_address("local:2") == "local:2"
    for bad in ("not an address", "local:0", "tcp://", "h:0", ":8786", ""):
        with pytest.raises(MtannoError, match="scheduler="):  # the API names its parameter
            scheduler_address(bad)


# --------------------------------------------------------------------- signals at the edges

#: The program as the console script starts it (mtanno.__main__, the handlers first).
PROGRAM = [sys.executable, "-c", "import sys; from mtanno.__main__ import main; sys.exit(main())"]
LINE = "mtanno: interrupted ({}); finished outputs are complete, unfinished ones were not written"


def _signalled(proc: subprocess.Popen, sig: int) -> tuple[int, str]:
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=HANG)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail(f"the run did not end within {HANG:.0f} s of {sig!r}")
    return proc.returncode, err


SIGS = [("SIGINT", 130), ("SIGTERM", 130), ("SIGHUP", 129)]


@pytest.mark.parametrize("moment", ["imports", "shutdown"])
@pytest.mark.parametrize("name,code", SIGS, ids=[s for s, _ in SIGS])
def test_a_signal_before_the_command_or_after_it_is_one_line(world, tmp_path, moment, name,
                                                             code):
    """Before the heavy imports (the handlers are set first) and after the command returned
    (the interpreter's shutdown no longer restores the default handlers): one line, 130
    (129 for SIGHUP). It was a KeyboardInterrupt traceback and −2, −15, −1."""
    mark = tmp_path / "mark"
    env = {**os.environ, "MTANNO_TEST_PAUSE": f"{moment}:{mark}"}
    proc = subprocess.Popen([*PROGRAM, "index", "info", str(world.index)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(mark.exists, proc, f"the {moment} mark")
    rc, err = _signalled(proc, getattr(signal, name))
    assert (rc, err.splitlines()) == (code, [LINE.format(name)]), err


# --------------------------------------------------------------------- an index killed

#: The points of an index write where a kill is tried (mtanno.index.storage).
INDEX_WRITES = ["index-temporary", "index-table", "index-generation", "index-manifest",
                "index-switched"]


def _killed_at(moment: str, args, tmp_path) -> None:
    """Run mtanno ARGS held at ``moment`` (the test hook) and kill it there (SIGKILL: no
    cleanup of any kind, as a power cut)."""
    mark = tmp_path / f"mark-{moment}"
    env = {**os.environ, "MTANNO_TEST_PAUSE": f"{moment}:{mark}"}
    proc = subprocess.Popen([*PROGRAM, *map(str, args)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    wait_for(mark.exists, proc, moment)
    rc, _ = _signalled(proc, signal.SIGKILL)
    assert rc == -signal.SIGKILL


def _one_clean_generation(idx: Path) -> None:
    """The index reads, and holds its manifest and one generation: no temporary, no
    older generation, no lock left."""
    r = cli("index", "info", idx)
    assert r.exit_code == 0, r.output
    names = sorted(p.name for p in idx.iterdir())
    assert len(names) == 2 and names[1] == "manifest.json" and names[0].startswith("gen-"), \
        names


@pytest.mark.parametrize("moment", INDEX_WRITES)
def test_an_index_killed_in_its_first_build_is_built_by_the_next_run(world, tmp_path, moment):
    """Issue 31: a build killed while writing its first generation left a folder the rerun
    refused ("directory is not empty and holds no index"), with the lock and `.tmp-gen-*`
    left behind. Killed at each write point, the folder is either an index or reported as
    a partial one (one line), and the rerun builds it and removes every leftover."""
    idx = tmp_path / "idx"
    args = ["index", world.docfeats, "-o", idx, "-q"]
    _killed_at(moment, args, tmp_path)
    r = cli("index", "info", idx)
    if moment == "index-switched":
        assert r.exit_code == 0, r.output
    else:
        assert r.exit_code == 2 and "partially written index" in r.output, r.output
    r = cli(*args)  # the next run (in this process: only the killed one must be a process)
    assert r.exit_code == 0, r.output
    _one_clean_generation(idx)


@pytest.mark.parametrize("moment", INDEX_WRITES)
def test_an_index_update_killed_at_any_write_leaves_a_readable_index(world, tmp_path,
                                                                      moment):
    """An update killed at each write point leaves the index as it was or as it was to
    become (SQLite's standard), never a broken one, and the next update cleans up."""
    idx, part = tmp_path / "idx", tmp_path / "part"
    part.mkdir()
    world.copy(world.doc_files[0], part / world.doc_files[0].name)
    assert cli("index", part, "-o", idx, "-q").exit_code == 0
    args = ["index", "add", idx, world.docfeats, "-q"]
    _killed_at(moment, args, tmp_path)
    r = cli("index", "info", idx)
    assert r.exit_code == 0, r.output
    r = cli(*args)
    assert r.exit_code == 0, r.output
    _one_clean_generation(idx)
    info = cli("index", "info", idx).output.splitlines()
    assert f"documents      {len(world.doc_files)}" in info, info


def _loaded(pid: int, library: str) -> bool:
    try:
        return library in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sigint_while_python_imports_numpy_is_one_line(world, tmp_path):
    """The installed console script, SIGINT the moment numpy's library is mapped (the
    imports go on for most of a second after it). It printed a KeyboardInterrupt traceback
    and exited −2. The run is held at its shutdown (``MTANNO_TEST_PAUSE``), so it cannot
    end before the signal: on a loaded machine the signal may arrive after the imports, and
    the answer must be the same line."""
    script = Path(sys.executable).with_name("mtanno")
    if not script.exists():
        pytest.skip("no installed mtanno console script beside the interpreter")
    env = {**os.environ, "MTANNO_TEST_PAUSE": f"shutdown:{tmp_path / 'mark'}"}
    proc = subprocess.Popen([sys.executable, str(script), "index", "info", str(world.index)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    wait_for(lambda: _loaded(proc.pid, "_multiarray_umath"), proc, "numpy's import")
    rc, err = _signalled(proc, signal.SIGINT)
    assert (rc, err.splitlines()) == (130, [LINE.format("SIGINT")]), err


#: A ctypes callback (libc's qsort calling Python) inside which SIGTERM arrives, as when a
#: worker is stopped while numba loads its cached kernels through llvmlite's callbacks.
CALLBACK = """if True:
    import ctypes, os, signal, sys, time
    import mtanno.util.workers as w
    CMP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)
    def compare(a, b):
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # the handler runs here, inside the callback
            pass
        return 0
    def task():
        try:
            ctypes.CDLL(None).qsort((ctypes.c_int * 4)(), 4, 4, CMP(compare))
            time.sleep(60)  # the task goes on: here the interruption must arrive
            print("not interrupted", flush=True)
        finally:
            print("unwound", flush=True)
"""


def test_sigterm_inside_a_ctypes_callback_stops_a_worker_silently():
    """The worker's interruption raised inside a ctypes callback was printed ("Exception
    ignored on calling ctypes callback ... Interrupted: 15") and lost; now it is delivered
    again and raised outside the callback: the task unwinds, the worker exits 143, silent."""
    code = CALLBACK + "    w._init_worker(os.getppid())\n    w._run_task(task, ())\n"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=HANG)
    assert (r.returncode, r.stdout.split(), r.stderr) == (143, ["unwound"], ""), r.stderr


def test_sigterm_inside_a_ctypes_callback_interrupts_the_command():
    code = CALLBACK + (
        "    try:\n"
        "        with w.interruptible():\n"
        "            task()\n"
        "    except w.Interrupted as exc:\n"
        "        print('interrupted', exc.signum)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=HANG)
    assert (r.returncode, r.stdout.split("\n")[:2], r.stderr) == (
        0, ["unwound", "interrupted 15"], ""), (r.stdout, r.stderr)


def test_a_worker_forked_before_its_initializer_ignores_sigint_and_hangs_up_quietly():
    """A pool worker forked a moment ago still has the command's handlers until its
    initializer runs: SIGINT (Ctrl-C reaches the whole group) raised Interrupted in the
    pool's bootstrap code, whose traceback came after the command's one line (tune)."""
    code = """if True:
        import os, signal, sys, mtanno.util.workers as w
        with w.interruptible():
            results = []
            for sig in (signal.SIGINT, signal.SIGHUP, signal.SIGTERM):
                pid = os.fork()
                if pid == 0:
                    os.kill(os.getpid(), sig)
                    for _ in range(10 ** 5):
                        pass
                    os._exit(0)
                results.append(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
            print(*results)
    """
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=HANG)
    assert (r.returncode, r.stdout.split(), r.stderr) == (0, ["0", "0", "143"], ""), r.stderr


#: The program, with a module imported late by the command (annotate --output-dir imports
#: mtanno.annotate.folder once it runs) that first creates a class whose descriptor's
#: ``__set_name__`` is held by the MTANNO_TEST_PAUSE hook (moment ``late-import``) until
#: the signal: where a signal landed while Python 3.11 created an Enum of numba's
#: late-imported typing modules.
LATE_IMPORT = """if True:
    import importlib.abc, sys
    from mtanno.util.pause import pause_at

    class Held:
        def __set_name__(self, owner, name):
            pause_at("late-import")

    class Late(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path, target=None):
            if name == "mtanno.annotate.folder":
                sys.meta_path.remove(self)
                type("Module", (), {"member": Held()})  # type creation: __set_name__
            return None

    sys.meta_path.insert(0, Late())
    from mtanno.__main__ import main
    sys.argv[0] = "mtanno"
    main()
"""


@pytest.mark.parametrize("name,code", SIGS, ids=[s for s, _ in SIGS])
def test_a_signal_during_a_late_import_is_one_line(world, tmp_path, name, code):
    """Issue 31: SIGTERM while the command imported a module late (annotate --output-dir
    --jobs 2, 1 run in 32) was a traceback, "RuntimeError: Error calling `__set_name__`",
    and exit 1: Python 3.11 wraps an exception raised in ``__set_name__`` (the handler's
    interruption) in a RuntimeError. Held inside ``__set_name__`` of that import: one line,
    130 (129 for SIGHUP), no output and no temporary left."""
    mark, out = tmp_path / "mark", tmp_path / "od"
    env = {**os.environ, "MTANNO_TEST_PAUSE": f"late-import:{mark}"}
    proc = subprocess.Popen(
        [sys.executable, "-c", LATE_IMPORT, "annotate", "--mt", str(world.mt),
         str(world.docfeats), "--output-dir", str(out), "--jobs", "2", "-q"], env=env,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(mark.exists, proc, "the late import")
    rc, err = _signalled(proc, getattr(signal, name))
    assert (rc, err.splitlines()) == (code, [LINE.format(name)]), err
    assert temporaries(tmp_path) == [] and not list(out.glob("*.csv"))


def test_a_worker_stopped_during_a_late_import_exits_silently():
    """The same in a worker: the wrapped interruption ends the task silently (143), as an
    unwrapped one does; it was the task's RuntimeError, sent to the parent."""
    code = """if True:
        import os, signal, mtanno.util.workers as w

        class Held:
            def __set_name__(self, owner, name):
                os.kill(os.getpid(), signal.SIGTERM)
                for _ in range(1000):  # the handler runs here, inside __set_name__
                    pass

        def task():
            try:
                type("Module", (), {"member": Held()})
                print("not interrupted", flush=True)
            finally:
                print("unwound", flush=True)

        w._init_worker(os.getppid())
        w._run_task(task, ())
    """
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=HANG)
    assert (r.returncode, r.stdout.split(), r.stderr) == (143, ["unwound"], ""), r.stderr


def test_a_wrapped_interruption_is_not_a_failed_file(tmp_path, monkeypatch):
    """A batch's per-file report of unexpected errors ("internal error", the batch goes on)
    raises an interruption Python wrapped instead of reporting it as the file's failure."""
    from mtanno.features import batch
    from mtanno.util.workers import Interrupted, interruption_in

    def wrapped(*args, **kwargs):
        try:
            raise Interrupted(signal.SIGTERM)
        except Interrupted as exc:
            raise RuntimeError("Error calling __set_name__") from exc

    monkeypatch.setattr(batch, "extract_file", wrapped)
    with pytest.raises(Interrupted):
        batch._extract_one(tmp_path / "a.amc", tmp_path / "a.parquet", None, None, "ak40",
                             "y")
    assert interruption_in(ValueError("x")) is None


def test_sighup_stops_a_command_like_sigint_with_exit_129(world, tmp_path):
    """SIGHUP (the terminal closed) was not handled: no cleanup, exit −1. Now: workers
    stopped, no temporary left, one line, exit 129."""
    out = tmp_path / "out"
    d = tmp_path / "motions"
    d.mkdir()
    (d / "synth.asf").write_text(synthetic.asf_text())
    (d / "base.amc").write_text(synthetic.amc_text(3000, 1))
    for i in range(60):
        os.symlink("base.amc", d / f"m{i:03d}.amc")
    gate = tmp_path / "gate"  # each worker held after one file: the run cannot finish first
    proc = start_held(["features", d, "-o", out, "--jobs", "2"], gate=gate, after=1,
                      hold="mtanno.features.batch:_extract_one", start_new_session=False)
    wait_for(lambda: len(list(out.glob("*.parquet"))) >= 2, proc, "the first outputs")
    rc, err = _signalled(proc, signal.SIGHUP)
    assert rc == 129 and err.splitlines()[-1] == LINE.format("SIGHUP"), err
    assert "Traceback" not in err and temporaries(out) == []


def test_an_interrupted_tune_prints_one_line(world, tmp_path):
    """Ctrl-C (SIGINT to the process group) while tune --jobs 2 forks its pools: exactly
    one line after the command's (none from workers), exit 130, nothing written."""
    out = tmp_path / "t.toml"
    gate = tmp_path.parent / f"{tmp_path.name}.gate"  # outside the folder checked below
    proc = start_held(["tune", "--mt", world.mt, "--manifest", world.manifest,
                       "--features-dir", world.feats, "--split", "train", "-o", out,
                       "--jobs", "2", "-q"], gate=gate, after=0,
                      hold="mtanno.tuning.run:_call")  # every task held: tune cannot end
    wait_for(lambda: children(proc.pid) and held_pids(gate), proc, "its workers started")
    os.killpg(proc.pid, signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=HANG)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("tune did not end after SIGINT")
    lines = [x for x in err.splitlines() if not x.startswith("note: compiling")]
    assert (proc.returncode, lines) == (130, [LINE.format("SIGINT")]), err
    assert list(tmp_path.iterdir()) == []
