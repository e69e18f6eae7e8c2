"""The frictions a new user met (issue 25, section 2): each has a test here that failed on
the code before its fix."""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
from pathlib import Path

import pytest
from world import cli

import mtanno.index
from mtanno.util.jitnote import NOTE, install_compile_note

MTANNO = [sys.executable, "-m", "mtanno"]


# --- a closed standard output ends a command quietly (mtanno info X | head -2) ------------


def _run_into_closed_pipe(args: list[str]) -> subprocess.CompletedProcess:
    """Run ``mtanno ARGS`` with standard output a pipe whose reader has already gone."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        return subprocess.run([*MTANNO, *args], stdout=write_end, stderr=subprocess.PIPE,
                              text=True)
    finally:
        os.close(write_end)


@pytest.mark.parametrize("command", ["info", "show", "info --features", "help"])
def test_a_closed_standard_output_ends_the_command_quietly(world, command):
    args = ["--help"] if command == "help" else [*command.split()[:1], str(world.doc_files[0]),
                                                 *command.split()[1:]]
    r = _run_into_closed_pipe(args)
    assert r.stderr == ""  # not "mtanno: Broken pipe"
    assert r.returncode == 141  # 128 + SIGPIPE, as a shell reports a tool SIGPIPE ended


def test_a_reader_that_reads_one_line_and_closes(world, tmp_path):
    """``mtanno show X | head -1``: the reader takes one line and goes while mtanno is still
    writing (the pipe is made small, so mtanno is blocked in a write when the reader goes)."""
    doc = str(world.doc_files[0])
    full = subprocess.run([*MTANNO, "show", doc, "--width", "2000"], capture_output=True,
                          text=True, check=True).stdout
    read_end, write_end = os.pipe()
    size = fcntl.fcntl(write_end, fcntl.F_SETPIPE_SZ, 4096)  # before mtanno writes a byte
    p = subprocess.Popen([*MTANNO, "show", doc, "--width", "2000"], stdout=write_end,
                         stderr=subprocess.PIPE)
    os.close(write_end)
    line = b""
    while not line.endswith(b"\n"):  # one line, byte by byte: nothing more is taken
        byte = os.read(read_end, 1)
        assert byte, line  # mtanno ended before its first line
        line += byte
    os.close(read_end)
    first = line.decode()
    assert len(full) - len(first) > 2 * size  # more than the pipe holds was still to come
    err = p.stderr.read().decode()
    p.stderr.close()
    assert p.wait() == 141
    assert err == ""
    assert first == full.splitlines(keepends=True)[0]


# --- the compile note never prints with -q --------------------------------------------------


def _compile_a_kernel(k: int) -> None:
    """Compile a fresh numba function of an mtanno module (numba says so: the note's cue)."""
    import numba

    ns: dict = {}
    exec(f"def f(x):\n    return x + {k}\n", ns)
    ns["f"].__module__ = "mtanno.fake"
    numba.njit(ns["f"])(1)


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="no JIT, no compiling")
@pytest.mark.parametrize("quiet", [False, True])
def test_the_compile_note_is_not_printed_with_quiet(world, tmp_path, monkeypatch, quiet):
    build = mtanno.index.build_index

    def compiling_build(*args, **kwargs):
        _compile_a_kernel(1000 + quiet)  # as a first run compiles the index kernels
        return build(*args, **kwargs)

    monkeypatch.setattr(mtanno.index, "build_index", compiling_build)
    done = install_compile_note()._done
    before, done.value = done.value, 0  # as if no command of this process had said it
    try:
        r = cli("index", "build", world.docfeats, "-o", tmp_path / "idx",
                *(["-q"] if quiet else []))
    finally:
        done.value = before
    assert r.exit_code == 0, r.output
    assert (NOTE in r.output) is not quiet


# --- tune's log reads as text, not as Python values -------------------------------------------


def test_the_search_log_of_tune_prints_no_python_values():
    from test_tune import _fold_data, _with_scaled

    from mtanno.tuning.search import Tuner

    fold, prepared = _fold_data()
    tuner = Tuner([fold], _with_scaled(prepared), classes=["a", "b"], unknown_weight=0.0)
    params, _, steps = tuner.search(delta=0.05, methods=["templates", "resolve"])
    assert params.scales == {"a": (0.6,)}
    assert any(s.startswith("time-scaled templates a ×0.6:") for s in steps), steps
    assert not any(c in s for s in steps for c in ("{", "}", "'", ",)")), steps  # {'a': (0.6,)}


# --- dir(mtanno) lists the facade -------------------------------------------------------------


def test_dir_of_the_package_lists_the_facade():
    code = "import mtanno; print(' '.join(dir(mtanno)))"
    names = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True).stdout.split()
    for name in ("annotate_documents", "compute_features", "evaluate_annotation",
                 "learn_templates", "load_templates", "read_motion", "MtannoError",
                 "__version__"):
        assert name in names
    code = "import sys, mtanno; dir(mtanno); print('numpy' in sys.modules)"  # stays light
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True).stdout.strip() == "False"


# --- the API's annotations as the table the files hold ----------------------------------------


def test_an_annotation_batch_is_the_table_annotate_writes(world, tmp_path, monkeypatch):
    import pyarrow.parquet as pq

    out = tmp_path / "a.parquet"
    r = cli("annotate", "--mt", world.mt, world.docfeats, "-o", out, "-q")
    assert r.exit_code == 0, r.output
    batch = mtanno.annotate_documents(world.docfeats, world.mt)
    assert batch.rows
    table = batch.to_arrow()
    written = pq.read_table(out)
    assert table.column_names == written.column_names
    assert table.equals(written)
    assert table.column("start").to_pylist() == [row.start + 1 for row in batch.rows]
    try:
        import pandas  # noqa: F401
    except ImportError:
        pass
    else:
        assert batch.to_pandas()["end"].tolist() == [row.end + 1 for row in batch.rows]
    monkeypatch.setitem(sys.modules, "pandas", None)  # pandas not installed
    with pytest.raises(mtanno.MtannoError, match="needs pandas"):
        batch.to_pandas()


# --- errors a new user meets: a motion file for a feature file, a whole batch of the wrong set -


def test_a_motion_file_given_for_a_feature_file_says_run_features_first(world, tmp_path):
    from world import assert_one_line

    amc = next(world.docs.glob("*.amc"))
    renamed = world.copy(amc, tmp_path / "motion.parquet")  # found by its content too
    for given in (amc, renamed):
        for args in (["annotate", "--mt", world.mt, given, "-o", tmp_path / "a.csv"],
                     ["show", given]):
            line = assert_one_line(cli(*args), given)
            assert "this is a motion file: run `mtanno features` first" in line, line
            assert "magic bytes" not in line


def test_a_batch_of_the_wrong_feature_set_is_one_line_and_writes_nothing(world, tmp_path):
    from world import assert_one_line

    feats31 = tmp_path / "feats31"
    assert cli("features", world.docs, "-o", feats31, "--feature-set", "mrc05",
               "-q").exit_code == 0
    files = sorted(feats31.glob("*.parquet"))
    assert len(files) > 1
    out = tmp_path / "a.csv"
    r = cli("annotate", "--mt", world.mt, feats31, "-o", out)
    line = assert_one_line(r, files[0], codes=(1,))
    assert "feature set 'mrc05'" in line and f"all {len(files)} documents" in line, line
    assert not out.exists() and not (tmp_path / "a.csv.meta.json").exists()
    # one good document beside them: every failure said, the table written
    good = next(world.feats.rglob("*.parquet"))  # (a clip: another document name)
    r = cli("annotate", "--mt", world.mt, feats31, good, "-o", out)
    assert r.exit_code == 1
    assert sum(ln.startswith("mtanno:") for ln in r.output.splitlines()) == len(files)
    assert out.exists()


# --- compose, report and index show a progress bar on a terminal -------------------------------


def _stderr_on_a_terminal(args: list) -> tuple[int, str]:
    """Run ``mtanno ARGS`` with standard error a terminal (a pseudo-terminal read here);
    return the exit code and what it wrote there."""
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 100 columns
    p = subprocess.Popen([*MTANNO, *map(str, args)], stdin=subprocess.DEVNULL,
                         stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:  # EIO: the program ended, the terminal's other side is closed
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    return p.wait(), b"".join(chunks).decode(errors="replace")


def _progress_cases(world, tmp: Path) -> dict[str, list]:
    return {
        "compose": ["compose", world.manifest, "--actor", "c", "--docs", "2", "--seed", "5",
                    "-o", tmp / "docs"],
        "report": ["report", world.annotation, "--truth", world.truth, "-o", tmp / "report"],
        "index": ["index", world.docfeats, "-o", tmp / "idx"],
    }


@pytest.mark.parametrize("command", ["compose", "report", "index"])
def test_long_commands_show_a_progress_bar_on_a_terminal(world, tmp_path, command):
    if command == "report":
        pytest.importorskip("matplotlib")
    args = _progress_cases(world, tmp_path / "shown")[command]
    code, err = _stderr_on_a_terminal(args)
    assert code == 0, err
    assert f"{command}: 100%" in err, err  # tqdm's bar, to its end
    code, err = _stderr_on_a_terminal([*_progress_cases(world, tmp_path / "quiet")[command],
                                       "-q"])
    assert code == 0, err
    assert "%|" not in err and err == "", err  # -q: neither bar nor summary
    r = subprocess.run([*MTANNO, *map(str, _progress_cases(world, tmp_path / "piped")[command])],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "%|" not in r.stderr  # not a terminal: no bar


@pytest.mark.parametrize("command", ["learn-mt", "learn-keyframes", "tune"])
def test_a_missing_training_folder_beside_good_ones_is_reported_and_skipped(world, tmp_path,
                                                                             command):
    """One rule for batches: a training folder that gives no example is one line and the
    others are used (exit 1); only when no input is usable is it exit 2 (it was exit 2 with
    a good folder beside it)."""
    missing = tmp_path / "nope"
    extra = {"learn-mt": [], "learn-keyframes": ["--mt", world.mt, "--method", "heuristic"],
             "tune": ["--mt", world.mt, "--no-confidence", "--disable", "templates"]}[command]
    out = tmp_path / ("c.toml" if command == "tune" else "o")
    r = cli(command, world.feats, missing, "-o", out, "-q", *extra)
    assert r.exit_code == 1, r.output
    assert f"mtanno: {missing}: training folder not found" in r.output
    assert out.exists()
    r = cli(command, missing, "-o", tmp_path / ("d.toml" if command == "tune" else "p"),
            "-q", *extra)
    assert r.exit_code == 2 and "training folder not found" in r.output


def test_an_interrupted_learn_mt_leaves_no_empty_folder(world, tmp_path, monkeypatch):
    import mtanno.templates.run as learn

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
        yield  # a generator, like learn_classes

    monkeypatch.setattr(learn, "learn_classes", interrupted)
    with pytest.raises(KeyboardInterrupt):
        learn.learn_to_folder([world.feats], tmp_path / "new" / "mts")
    assert not (tmp_path / "new").exists()
