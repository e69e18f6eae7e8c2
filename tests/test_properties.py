"""Properties of kinematics and features on real clips: rigid bones, invariances."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import HDM05, require_data

from mtanno import synthetic as synth
from mtanno.features import compute_features_native
from mtanno.io import canonical_positions, read_motion

CLIPS = ["squat1Reps/HDM_bd_squat1Reps_001_120.amc",
         "jogLeftCircle4StepsRstart/HDM_mm_jogLeftCircle4StepsRstart_001_120.amc",
         "kickLFront1Reps/HDM_dg_kickLFront1Reps_001_120.amc",
         "lieDownFloor/HDM_bk_lieDownFloor_001_120.amc"]


def _motion(rel, tmp_path):
    if rel == "synthetic":
        return read_motion(synth.write_pair(tmp_path, n_frames=240))
    require_data()
    path = HDM05 / rel
    if not path.exists():  # take any clip of that class
        path = sorted((HDM05 / rel.split("/")[0]).glob("*.amc"))[0]
    return read_motion(path)


@pytest.mark.parametrize("rel", CLIPS + ["synthetic"])
def test_bone_lengths_constant_and_equal_to_skeleton(rel, tmp_path):
    m = _motion(rel, tmp_path)
    rig = m.rig
    for j in range(1, rig.n_nodes):
        d = np.linalg.norm(m.positions[:, j] - m.positions[:, rig.parents[j]], axis=1)
        assert np.allclose(d, np.linalg.norm(rig.offsets[j]), atol=1e-8), rig.names[j]


def _yrot(deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


@pytest.mark.parametrize("rel", CLIPS + ["synthetic"])
def test_features_invariant_to_rotation_translation_scale(rel, tmp_path):
    m = _motion(rel, tmp_path)
    J = canonical_positions(m)
    base = compute_features_native(J, m.heading, m.fps)
    for deg, shift, scale in ((37.0, (120.0, -3.0, 55.5), 1.0), (-90.0, (0, 0, 0), 2.5),
                              (180.0, (-1e3, 10.0, 4e2), 0.37)):
        R = _yrot(deg)
        J2 = (J @ R.T) * scale + np.asarray(shift)
        H2 = m.heading @ R.T
        got = compute_features_native(J2, H2, m.fps)
        diff = (got != base).sum(axis=1)
        assert not diff.any(), f"features changed under rotation {deg}°: rows {np.flatnonzero(diff) + 1}"
