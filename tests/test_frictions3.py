"""Issue 31, what a new user meets first: every ``mtanno.x.y`` name the README and docs/
give resolves after a bare ``import mtanno``; no help text cites a document the repository
does not hold or an issue number; messages name flags and say what a wrong folder holds;
no stray symlink is tracked; ``make demo`` says what each stage took."""

from __future__ import annotations

import pickle
import re
import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from world import cli

from mtanno.cli import main as mtanno_main
from mtanno.errors import MtannoError

REPO = Path(__file__).resolve().parents[1]
#: ``mtanno.a.b`` in prose or code, not a file name (``.mtanno.lock``) or a schema name
#: (``mtanno.template/1``).
NAME = re.compile(r"(?<![\w./-])mtanno(?:\.[A-Za-z_][A-Za-z0-9_]*)+(?![\w/-])")


def _documented_names() -> dict[str, str]:
    names = {}
    for p in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        for m in NAME.finditer(p.read_text(encoding="utf-8")):
            names.setdefault(m.group(0), p.name)
    return names


def test_every_documented_name_resolves_after_a_bare_import():
    names = _documented_names()
    assert "mtanno.annotate.load_class_config" in names  # the README's own example
    code = ("import importlib, json, sys, mtanno\n"
            "bad = []\n"
            "for name in json.loads(sys.argv[1]):\n"
            "    obj = mtanno\n"
            "    try:\n"
            "        for part in name.split('.')[1:]:\n"
            "            obj = getattr(obj, part) if not part.startswith('__') else \\\n"
            "                importlib.import_module(f'{obj.__name__}.{part}')\n"
            "    except (AttributeError, ImportError) as exc:\n"
            "        bad.append(f'{name}: {exc}')\n"
            "print(json.dumps(bad))\n")
    import json

    r = subprocess.run([sys.executable, "-c", code, json.dumps(sorted(names))],
                       capture_output=True, text=True, check=True)
    bad = json.loads(r.stdout)
    assert not bad, [f"{b} (in {names[b.split(':')[0]]})" for b in bad]


def test_a_bare_import_stays_light_and_unknown_names_are_attribute_errors():
    code = ("import sys, mtanno\n"
            "heavy = [m for m in ('numba', 'pyarrow', 'mtanno.annotate') if m in sys.modules]\n"
            "for chain in ('mtanno.nothing', 'mtanno.util.nothing'):\n"
            "    try:\n"
            "        eval(chain)\n"
            "    except AttributeError as exc:\n"
            "        print(exc)\n"
            "print(heavy)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       check=True)
    assert r.stdout.splitlines() == ["module 'mtanno' has no attribute 'nothing'",
                                     "module 'mtanno.util' has no attribute 'nothing'", "[]"]


def test_pandas_is_an_extra():
    text = (REPO / "pyproject.toml").read_text()
    assert re.search(r'^pandas = \["pandas', text, re.M)
    with pytest.raises(MtannoError, match=r"pip install 'mtanno\[pandas\]'"):
        try:
            import pandas  # noqa: F401
        except ImportError:
            from mtanno.annotate.batch import AnnotationBatch

            AnnotationBatch([], {}).to_pandas()
        else:
            raise MtannoError("pip install 'mtanno[pandas]'")  # pandas here: nothing to check


def _commands(cmd: click.Command, path: list[str]):
    yield path, cmd
    if isinstance(cmd, click.Group):
        for name, sub in cmd.commands.items():
            yield from _commands(sub, [*path, name])


#: A document a help text cites: a path ending .md (docs/annotation.md, README.md).
CITED = re.compile(r"(?<![\w.])((?:[\w-]+/)*[\w-]+\.md)\b")


def test_no_help_cites_a_missing_document_or_an_issue():
    runner = CliRunner()
    bad = []
    for path, _ in _commands(mtanno_main, []):
        out = runner.invoke(mtanno_main, [*path, "--help"], terminal_width=200).output
        assert "Usage:" in out, (path, out)
        where = " ".join(["mtanno", *path])
        bad += [f"{where}: {m.group(0)}" for m in re.finditer(r"\bissues? \d+", out)]
        for m in CITED.finditer(out):
            if not (REPO / m.group(1)).is_file():
                bad.append(f"{where}: cites {m.group(1)}, which is not in the repository")
    assert not bad, bad


def test_an_error_crosses_processes_whole_and_names_flags_on_the_command_line():
    e = MtannoError("pass {skeleton} MAP.toml", path="a.bvh", line=3, options=("skeleton",))
    f = pickle.loads(pickle.dumps(e))
    assert (str(f), f.for_command()) == ("a.bvh:3: pass skeleton= MAP.toml",
                                         "a.bvh:3: pass --skeleton MAP.toml")


def test_a_rig_no_map_fits_is_reported_with_the_flag_in_a_batch(tmp_path):
    """A failure in the features batch (a worker's or this process's) is shown with the
    command's flags ("pass --skeleton MAP.toml", not the API's "skeleton=")."""
    bvh = tmp_path / "chain.bvh"  # one chain of three bones: no humanoid rig
    bvh.write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition "
                   "Zposition Zrotation Xrotation Yrotation\n JOINT b\n {\n  OFFSET 0 1 0\n"
                   "  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n"
                   "   OFFSET 0 1 0\n  }\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.033333\n"
                   + "0 0 0 0 0 0 0 0 0\n" * 2)
    r = cli("features", bvh, "-o", tmp_path / "out")
    assert r.exit_code != 0
    assert "skeleton=" not in r.output, r.output
    lines = [ln for ln in r.output.splitlines() if ln.startswith("mtanno:")]
    assert len(lines) == 1 and str(bvh) in lines[0], r.output


def test_a_folder_of_something_else_where_feature_files_are_expected(world, tmp_path):
    r = cli("annotate", "--mt", world.mt, world.mt, "-o", tmp_path / "a.csv")
    assert r.exit_code == 2
    assert f"{world.mt}: a folder of motion templates, not of feature files (give it to " \
           "--mt)" in r.output
    r = cli("index", world.clips, "-o", tmp_path / "idx")
    assert r.exit_code == 2 and "a folder of motion files, not of feature files (make them " \
                                "with `mtanno features` first)" in r.output
    (tmp_path / "empty").mkdir()
    r = cli("index", tmp_path / "empty", "-o", tmp_path / "idx")
    assert "no feature files (*.parquet) in this folder" in r.output


def test_no_symlink_is_tracked():
    r = subprocess.run(["git", "-C", str(REPO), "ls-files", "-s"], capture_output=True,
                       text=True)
    if r.returncode != 0:
        pytest.skip("not a git checkout")
    links = [ln.split("\t")[1] for ln in r.stdout.splitlines() if ln.startswith("120000")]
    assert not links, f"symbolic links tracked in the repository: {links}"


def test_make_demo_names_every_stage_with_its_time():
    script = (REPO / "scripts" / "demo.sh").read_text()
    assert "scripts/demo.sh" in (REPO / "Makefile").read_text()
    stages = re.findall(r'^stage "([^"]+)"', script, re.M)
    commands = re.findall(r'"\$M" (\S+)', script)
    assert len(stages) >= 7
    # every mtanno command of the demo but evaluate (its table is the output) is a stage
    assert len([c for c in commands if c != "evaluate"]) == len(stages), (stages, commands)


def test_a_lazy_name_may_not_be_a_submodule_name():
    """``mtanno.features.hysteresis`` was the function until the module was imported, then
    the module: a package's lazily attached name may not be one of its modules' names."""
    from mtanno.util.lazy import lazy_exports

    with pytest.raises(ValueError, match=r"names that are also submodules: \['table'\]"):
        lazy_exports("mtanno.features", {"table": ("table", "FEATURES")})
    import mtanno.features.hysteresis as module

    assert callable(module.hysteresis) and not callable(mtanno_features().hysteresis)


def mtanno_features():
    import mtanno.features

    return mtanno.features
