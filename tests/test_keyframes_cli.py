"""Keyframe query files (schema mtanno.keyframes/1): exact stiffness arithmetic, round trips,
every invalid-input path through `keyframes show`, `query --keyframes` and `annotate
--keyframes` (one line naming the file, exit 2, nothing written), and the commands' output
against the Python API."""

from __future__ import annotations

import json
from fractions import Fraction

import numpy as np
import pytest
from world import assert_one_line, cli

from mtanno.errors import MtannoError
from mtanno.features import FEATURE_NAMES, GROUPS
from mtanno.features.store import read_features
from mtanno.keyframes import (
    Extension,
    Gap,
    Keyframe,
    KeyframeQuery,
    format_query,
    load_keyframes,
    save_keyframes,
    search_documents,
    stiffness_bounds,
)
from mtanno.keyframes.model import feature_groups_of
from mtanno.util.tables import read_table


def test_stiffness_in_exact_arithmetic():
    assert stiffness_bounds(10, 0.3) == (3, 33)  # 10·0.3 in floats is 3.0000000000000004
    assert stiffness_bounds(10, "1/3") == (4, 30)
    assert stiffness_bounds(0, 0.5) == (0, 0)
    assert stiffness_bounds(7, 1) == (7, 7)
    g = Gap.from_stiffness(10, 0.7)
    assert (g.dmin, g.dmax, g.stiffness) == (7, 14, Fraction(7, 10))
    for bad in (0, 1.5, -0.1, float("nan"), "x"):
        with pytest.raises(MtannoError):
            stiffness_bounds(5, bad)


def sample_query(**kw) -> KeyframeQuery:
    groups = feature_groups_of("mr06-ak40")
    kfs = [Keyframe("lower", "*" * 5 + "11" + "*" * 5, 5),
           Keyframe("upper", "00" + "*" * 12, 12),
           Keyframe("mix", "*" * 13 + "0", 12, 0)]
    gaps = [Gap.from_stiffness(7, 0.5), Gap(0, 0)]
    return KeyframeQuery("squat", "mr06-ak40", groups, kfs, gaps, 30, **kw)


def test_round_trip_and_show(tmp_path):
    q = sample_query(extension=Extension(3, 3), provenance={"method": "hand", "seed": 1})
    save_keyframes(tmp_path / "q.json", q)
    back = load_keyframes(tmp_path / "q.json")
    assert back == q and back.provenance == q.provenance
    assert back.gaps[0].stiffness == Fraction(1, 2)
    # only the groups the keyframes use, in the feature set's order
    assert list(json.loads((tmp_path / "q.json").read_text())["groups"]) == ["upper", "lower",
                                                                              "mix"]
    assert q.widths() == (3 * 4 + 3, 3 * 18 + 3)
    text = format_query(q)
    assert "lower:rknee_bent" in text and "4..14 (s=0.5)" in text and "0..0" in text
    r = cli("keyframes", "show", tmp_path / "q.json")
    assert r.exit_code == 0 and r.output.strip() == format_query(
        back, path=str(tmp_path / "q.json")).strip()


BAD = {  # name: (edit of the JSON object, expected text)
    "malformed": (None, "malformed JSON"),
    "schema": (lambda d: d.update(schema="x/1"), "unsupported keyframe schema"),
    "vector length": (lambda d: d["keyframes"][0].update(vector="11"),
                      "vector has 2 entries but group 'lower' has 12 features"),
    "vector chars": (lambda d: d["keyframes"][0].update(vector="2" * 12), "string of 0, 1"),
    "unknown group": (lambda d: d["keyframes"][0].update(group="nope"), "unknown group 'nope'"),
    "positions": (lambda d: d["keyframes"][1].update(position=2),
                  "position 2 is before the previous keyframe's 5"),
    "stiffness 0": (lambda d: d["keyframes"][1].update(stiffness=0), "stiffness must lie in"),
    "stiffness 1.5": (lambda d: d["keyframes"][1].update(stiffness=1.5), "stiffness must lie in"),
    "dmin > dmax": (lambda d: d["keyframes"][2].update(gap=[5, 3]), "dmin 5 > dmax 3"),
    "both gap kinds": (lambda d: d["keyframes"][2].update(stiffness=0.5), "either 'stiffness'"),
    "first with gap": (lambda d: d["keyframes"][0].update(gap=[0, 1]), "no previous keyframe"),
    "no keyframes": (lambda d: d.update(keyframes=[]), "at least one keyframe"),
    "all wildcards": (lambda d: [k.update(vector="*" * len(k["vector"]))
                                 for k in d["keyframes"]], "constrains nothing"),
    "unknown key": (lambda d: d.update(colour=1), "unknown key 'colour'"),
    "template length": (lambda d: d.update(template_length=0), "template_length"),
    "position beyond": (lambda d: d["keyframes"][2].update(position=99), "position must be"),
    "mismatches": (lambda d: d["keyframes"][0].update(mismatches=1), "only 2 fixed entries"),
    "extension": (lambda d: d.update(extension={"left": 3}), "extension needs both"),
    "not an object": (lambda d: d.clear() or d.update(x=1), "unsupported keyframe schema"),
}


def _bad_file(tmp_path, name):
    q = sample_query()
    path = tmp_path / "bad.json"
    if BAD[name][0] is None:
        path.write_text(json.dumps(q.to_dict())[:-5])
    else:
        d = json.loads(json.dumps(q.to_dict(), default=str))
        BAD[name][0](d)
        path.write_text(json.dumps(d, indent=1))
    return path


@pytest.mark.parametrize("name", list(BAD))
def test_bad_keyframe_files(world, tmp_path, name):
    path = _bad_file(tmp_path, name)
    with pytest.raises(MtannoError, match=BAD[name][1].replace("(", r"\(")):
        load_keyframes(path)
    line = assert_one_line(cli("keyframes", "show", path), path, codes=(2,))
    assert BAD[name][1] in line
    out = tmp_path / "hits.csv"
    assert_one_line(cli("query", world.index, "--keyframes", path, "-o", out), path,
                    codes=(2,))
    kf = tmp_path / "kf"
    kf.mkdir()
    path.rename(kf / "squat.json")
    assert_one_line(cli("annotate", "--mt", world.mt, "--keyframes", kf, world.docfeats,
                        "-o", tmp_path / "a.csv"), kf / "squat.json", codes=(2,))
    assert not out.exists() and not (tmp_path / "a.csv").exists()


def test_keyframes_of_another_feature_set(world, tmp_path):
    groups = {"upper": tuple(f"F{i:02d}" for i in range(1, 15))}
    q = KeyframeQuery("squat", "mrc05", groups, [Keyframe("upper", "1" + "*" * 13, 1)], [], 5)
    kf = tmp_path / "kf"
    save_keyframes(kf / "squat.json", q)
    r = cli("query", world.index, "--keyframes", kf / "squat.json", "-o", tmp_path / "h.csv")
    assert r.exit_code == 2 and "feature set 'mrc05' but the index holds" in r.output
    r = cli("annotate", "--mt", world.mt, "--keyframes", kf, world.docfeats, "-o",
            tmp_path / "a.csv")
    assert r.exit_code == 2 and "for feature set 'mrc05' but the templates use" in r.output
    assert not (tmp_path / "h.csv").exists() and not (tmp_path / "a.csv").exists()


def _rows(path) -> list[dict]:
    return read_table(path).rows


def _world_query(world) -> KeyframeQuery:
    """A keyframe query that fires in the synthetic documents: knees bent, then not."""
    rows = [FEATURE_NAMES[i] for i in GROUPS["lower"]]
    bent = "".join("1" if n in ("rknee_bent", "lknee_bent") else "*" for n in rows)
    straight = "".join("0" if n in ("rknee_bent", "lknee_bent") else "*" for n in rows)
    return KeyframeQuery("squat", "mr06-ak40", feature_groups_of("mr06-ak40"),
                         [Keyframe("lower", bent, 10), Keyframe("lower", straight, 20)],
                         [Gap(1, 30)], 30)


def test_query_keyframes_equals_the_api(world, tmp_path):
    q = _world_query(world)
    save_keyframes(tmp_path / "q.json", q)
    out = tmp_path / "hits.csv"
    r = cli("query", world.index, "--keyframes", tmp_path / "q.json", "-o", out)
    assert r.exit_code == 0, r.output
    assert "keyframes: 2 of class squat" in r.output
    table = _rows(out)
    docs = [(ff.document, ff.X) for ff in map(read_features, world.doc_files)]
    want = search_documents(docs, FEATURE_NAMES, q)
    got = [(r["doc"], int(r["start"]), int(r["end"])) for r in table]
    assert got and got == [(want.names[d], s + 1, e + 1)
                           for d, s, e in zip(want.doc, want.start, want.end)]
    first = table[0]["boundaries"]
    assert first == "keyframes=" + " ".join(str(int(t) + 1) for t in want.chains[0]) + \
        f" {int(want.end[0]) + 1}"
    r = cli("query", world.index, "--keyframes", tmp_path / "q.json", "--windows", "-o",
            tmp_path / "win.csv")
    assert r.exit_code == 0, r.output
    wd, ws, we = want.windows()
    win = _rows(tmp_path / "win.csv")
    assert [(int(r["start"]), int(r["end"])) for r in win] == \
        [(int(s) + 1, int(e) + 1) for s, e in zip(ws, we)]
    r = cli("query", world.index, "--windows", "--example", world.doc_files[0],
            "--features", "rknee_bent")
    assert r.exit_code == 2 and "--windows goes with --keyframes" in r.output


def test_annotate_with_keyframes(world, tmp_path):
    q = _world_query(world)
    kf = tmp_path / "kf"
    save_keyframes(kf / "squat.json", q)
    r = cli("annotate", "--mt", world.mt, "--keyframes", kf, world.docfeats, "-o",
            tmp_path / "a.csv")
    assert r.exit_code == 0, r.output
    assert "no keyframe query for" in r.output and "matched everywhere" in r.output
    rows = _rows(tmp_path / "a.csv")
    # squat segments lie inside the windows of the query
    windows = {}
    for ff in map(read_features, world.doc_files):
        h = search_documents([(ff.document, ff.X)], FEATURE_NAMES, q)
        _, s, e = h.windows()
        windows[ff.document] = list(zip(s.tolist(), e.tolist()))
    for doc, s, e, lab in ((r["doc"], int(r["start"]), int(r["end"]), r["label"])
                           for r in rows):
        if lab == "squat":
            assert any(a <= s - 1 and e - 1 <= b + 1 for a, b in windows[doc]) or \
                any(a <= s - 1 <= b for a, b in windows[doc])
    prov = json.loads((tmp_path / "a.csv.meta.json").read_text())
    assert prov["keyframes"][0]["class"] == "squat"


def test_windows_are_clipped_and_merged():
    from mtanno.keyframes.search import widen

    d, s, e = widen(np.array([0, 0, 1]), np.array([2, 9, 0]), np.array([3, 12, 1]), 3, 4,
                    np.array([15, 5]))
    assert list(zip(d.tolist(), s.tolist(), e.tolist())) == [(0, 0, 14), (1, 0, 4)]
    with pytest.raises(MtannoError):
        widen(d, s, e, -1, 0, np.array([15, 5]))
