"""The built wheel works for a pip user: installed into a fresh virtual environment outside
the repository, `mtanno features` reads a real ASF/AMC, a real BVH and a real C3D file.

This is what catches run-time files that are not package data (the skeleton maps were once
looked up in the source tree, so every installed copy failed on every motion file).
"""

from __future__ import annotations

import os
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest
from conftest import DATA, HDM05, REPO, require_data

try:
    from data_cache import bandai_clips
except ImportError:  # pragma: no cover
    from tests.data_cache import bandai_clips


def _clean_env(home: Path) -> dict[str, str]:
    """Environment of a user who has never seen the repository: no PYTHONPATH, an empty
    home and config folder."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "MTANNO_SKELETON_PATH", "VIRTUAL_ENV")}
    env.update(HOME=str(home), XDG_CONFIG_HOME=str(home / ".config"))
    env.setdefault("PIP_DISABLE_PIP_VERSION_CHECK", "1")
    return env


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out),
                        str(REPO)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    (whl,) = out.glob("mtanno-*.whl")
    return whl


def test_wheel_contents(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    for m in ("cmu-asf", "bandai-bvh", "cmu-bvh"):
        assert f"mtanno/skeletons/{m}.toml" in names
    assert "mtanno/markersets/vicon-41.toml" in names  # the C3D marker set
    assert "mtanno/py.typed" in names
    assert "mtanno/evaluation/player.js" in names  # the report page's player
    assert any(n.endswith("licenses/LICENSE") for n in names)
    meta = next(n for n in names if n.endswith("METADATA"))
    text = zipfile.ZipFile(wheel).read(meta).decode()
    assert "License-Expression: MIT" in text


@pytest.mark.realdata
def test_installed_wheel_reads_real_motion_files(wheel, tmp_path):
    require_data()
    bvh = bandai_clips("set1.tar.xz")[0]
    amc = HDM05 / "squat1Reps" / "HDM_bd_squat1Reps_001_120.amc"
    home = tmp_path / "home"
    home.mkdir()
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    py = env_dir / "bin" / "python"
    env = _clean_env(home)
    r = subprocess.run([str(py), "-m", "pip", "install", "-q", str(wheel)], capture_output=True,
                       text=True, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "deprecat" not in r.stderr.lower(), r.stderr
    # the installed package, not the source tree, is what runs
    r = subprocess.run([str(py), "-c", "import mtanno, sys; print(mtanno.__file__)"],
                       capture_output=True, text=True, env=env, cwd=tmp_path)
    assert str(env_dir) in r.stdout and str(REPO) not in r.stdout, r.stdout
    mtanno = env_dir / "bin" / "mtanno"
    out = tmp_path / "feats"
    c3d = DATA / "c3d" / "85_02.c3d"  # (the c3d package is a dependency: pip installed it)
    r = subprocess.run([str(mtanno), "features", str(amc), str(bvh), str(c3d), "-o", str(out),
                        "-q"], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (out / f"{amc.stem}.parquet").is_file()
    assert (out / f"{bvh.stem}.parquet").is_file()
    assert (out / f"{c3d.stem}.parquet").is_file()
    r = subprocess.run([str(mtanno), "info", str(c3d)], capture_output=True, text=True, env=env,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "marker set     vicon-41" in r.stdout and str(env_dir) in r.stdout
    r = subprocess.run([str(mtanno), "info", str(bvh)], capture_output=True, text=True, env=env,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "bandai-bvh" in r.stdout and str(env_dir) in r.stdout
    # a user map in $XDG_CONFIG_HOME/mtanno/skeletons is found before the built-in one
    user = home / ".config" / "mtanno" / "skeletons"
    user.mkdir(parents=True)
    src = (env_dir / "lib").glob("python*/site-packages/mtanno/skeletons/bandai-bvh.toml")
    (user / "mine.toml").write_text(next(src).read_text().replace(
        'name = "bandai-bvh"', 'name = "mine"'))
    r = subprocess.run([str(mtanno), "info", str(bvh)], capture_output=True, text=True, env=env,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "skeleton map   mine" in r.stdout, r.stdout
