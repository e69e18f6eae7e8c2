"""Motion-template objects: quantization (docs/method.md §3.3), mirroring (MR06 §5.4), the
JSON file and every way ``load_template`` rejects a bad one."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mtanno.errors import MtannoError
from mtanno.features import FEATURE_NAMES, MIRROR_PAIRS
from mtanno.templates import SCHEMA, MotionTemplate, load_template, mirror, quantize, save_template


def make_mt(K=6, seed=0, **kw) -> MotionTemplate:
    rng = np.random.default_rng(seed)
    V = rng.random((len(FEATURE_NAMES), K))
    V[:5] = np.round(V[:5])
    args = dict(class_name="kickLFront", feature_names=list(FEATURE_NAMES), values=V,
                weights=rng.random(K) + 0.5, iterations=3, final_cost=0.004,
                training=[{"file": "f/a.parquet", "document": "a", "sha256": "0" * 64,
                           "frames": [1, 30]}],
                params={"iter_max": 10}, history={"max": [0.1, 0.004]})
    args.update(kw)
    return MotionTemplate(**args)


# --------------------------------------------------------------------------- quantize


def test_quantize_thresholds_are_inclusive():
    mt = make_mt(K=7)
    mt.values[0] = [0.0, 0.1, 0.10000000000000002, 0.5, 0.9, 0.8999999999999999, 1.0]
    q = quantize(mt, 0.1)
    assert q.values[0].tolist() == [0.0, 0.0, 0.5, 0.5, 1.0, 0.5, 1.0]
    assert q.quantized and q.delta == 0.1
    assert np.isin(q.values, (0.0, 0.5, 1.0)).all()
    assert not mt.quantized and mt.values[0, 1] == 0.1  # original untouched
    assert np.array_equal(q.weights, mt.weights)


def test_quantize_delta_zero_keeps_only_unanimous_entries():
    mt = make_mt(K=5)
    mt.values[0] = [0.0, 1e-12, 0.5, 1 - 1e-12, 1.0]
    q = quantize(mt, 0)
    assert q.values[0].tolist() == [0.0, 0.5, 0.5, 0.5, 1.0]
    assert q.delta == 0.0
    unanimous = (mt.values == 0) | (mt.values == 1)
    assert np.array_equal(q.values[unanimous], mt.values[unanimous])
    assert (q.values[~unanimous] == 0.5).all()


def test_quantize_delta_half_leaves_no_wildcard():
    mt = make_mt(K=5)
    mt.values[0] = [0.0, 0.49, 0.5, 0.51, 1.0]
    q = quantize(mt, 0.5)
    assert q.values[0].tolist() == [0.0, 0.0, 0.0, 1.0, 1.0]
    assert not (q.values == 0.5).any()


def test_quantize_is_idempotent_and_rejects_bad_delta():
    q = quantize(make_mt(), 0.05)
    assert quantize(q, 0.05) == q
    for bad in (-0.1, 0.6, float("nan"), True, "0.1", None):
        with pytest.raises(MtannoError, match="delta"):
            quantize(make_mt(), bad)


# --------------------------------------------------------------------------- mirror


def test_mirror_swaps_pairs_by_name():
    mt = make_mt()
    m = mirror(mt)
    idx = {n: i for i, n in enumerate(FEATURE_NAMES)}
    assert np.array_equal(m.values[idx["rhand_fast"]], mt.values[idx["lhand_fast"]])
    assert np.array_equal(m.values[idx["lknee_bent"]], mt.values[idx["rknee_bent"]])
    assert np.array_equal(m.values[idx["hands_apart"]], mt.values[idx["hands_apart"]])
    paired = {i for p in MIRROR_PAIRS for i in p}
    for i in range(len(FEATURE_NAMES)):
        if i not in paired:
            assert np.array_equal(m.values[i], mt.values[i])
    assert m.class_name == "kickLFront_mirrored" and m.params["mirrored"] is True
    assert m.feature_names == mt.feature_names and np.array_equal(m.weights, mt.weights)


def test_mirror_twice_is_identity_and_custom_name():
    mt = make_mt()
    assert mirror(mirror(mt)) == mt
    assert mirror(mt, name="kickRFront").class_name == "kickRFront"


def test_mirror_follows_names_not_positions():
    names = ["lhand_fast", "hands_apart", "rhand_fast"]
    mt = make_mt(feature_names=names, values=np.array([[1.0] * 3, [0.5] * 3, [0.0] * 3]),
                 K=3, weights=np.ones(3))
    m = mirror(mt)
    assert m.values.tolist() == [[0.0] * 3, [0.5] * 3, [1.0] * 3]


def test_mirror_errors():
    with pytest.raises(MtannoError, match="no mirror table"):
        mirror(make_mt(feature_set="other-set"))
    with pytest.raises(MtannoError, match="partner"):
        mirror(make_mt(feature_names=["rhand_fast"], values=np.zeros((1, 3)), K=3,
                       weights=np.ones(3)))
    with pytest.raises(MtannoError, match="not in the"):
        mirror(make_mt(feature_names=["nonsense"], values=np.zeros((1, 3)), K=3,
                       weights=np.ones(3)))


# --------------------------------------------------------------------------- JSON


def test_json_round_trip_is_bit_exact(tmp_path):
    mt = make_mt(K=13)
    mt.values[6, :4] = [0.1 + 0.2, 1e-300, 5e-324, 1 / 3]
    p = tmp_path / "sub" / "kick.json"
    save_template(p, mt)
    back = load_template(p)
    assert back == mt
    assert np.array_equal(back.values, mt.values) and np.array_equal(back.weights, mt.weights)
    assert back.values.dtype == np.float64 and back.length == 13 and back.n_features == 40
    assert [f.name for f in p.parent.iterdir()] == ["kick.json"]  # no temporary left over
    d = json.loads(p.read_text())
    assert d["schema"] == SCHEMA and d["length"] == 13 and d["delta"] is None
    # readable: one line per feature row
    lines = p.read_text().splitlines()
    first_row = lines.index('  "values": [') + 1
    assert json.loads(lines[first_row].rstrip(",")) == mt.values[0].tolist()
    q = quantize(mt, 0.05)
    save_template(p, q)
    assert load_template(p) == q and load_template(p).delta == 0.05


def test_constructor_validates():
    with pytest.raises(MtannoError, match="weights"):
        make_mt(weights=np.ones(3))
    with pytest.raises(MtannoError, match="outside"):
        make_mt(values=np.full((40, 6), 2.0))
    with pytest.raises(MtannoError, match="kind"):
        make_mt(kind="medium")


def _good_dict(tmp_path):
    p = tmp_path / "good.json"
    save_template(p, make_mt())
    return json.loads(p.read_text())


def _write(tmp_path, d, name="t.json"):
    p = tmp_path / name
    p.write_text(json.dumps(d) if not isinstance(d, str) else d, encoding="utf-8")
    return p


BAD_FIELDS = [
    (lambda d: d.update(schema="mtanno.template/0"), "unsupported template schema"),
    (lambda d: d.pop("schema"), "unsupported template schema"),
    (lambda d: d.pop("weights"), "missing field"),
    (lambda d: d.update({"class": ""}), "class name"),
    (lambda d: d.update(feature_names="x"), "feature_names"),
    (lambda d: d.update(feature_names=d["feature_names"][:-1]), "values must be a list of 39"),
    (lambda d: d["values"].pop(), "values must be a list of 40"),
    (lambda d: d["values"][3].pop(), "row 4 .* has 5 entries, expected 6"),
    (lambda d: d["values"][2].__setitem__(1, "0.5"), "row 3 .* numbers"),
    (lambda d: d["values"][2].__setitem__(1, 1.5), "row 3 .* column 2 is 1.5"),
    (lambda d: d["values"][2].__setitem__(1, -0.25), "row 3 .* column 2"),
    (lambda d: d.update(weights=[1.0] * 5), "expected 5"),
    (lambda d: d["weights"].__setitem__(0, 0.0), "weight 1"),
    (lambda d: d["weights"].__setitem__(0, "1"), "weights must be numbers"),
    (lambda d: d.update(weights=[]), "weights must be a non-empty"),
    (lambda d: d.update(length=7), "length is 7"),
    (lambda d: d.update(kind="medium"), "kind"),
    (lambda d: d.update(fps=-30), "fps"),
    (lambda d: d.update(fps="30"), "fps must be a number"),
    (lambda d: d.update(quantized="yes"), "quantized"),
    (lambda d: d.update(quantized=True, delta=0.1), "quantized template has value"),
    (lambda d: d.update(delta=0.7), "delta"),
    (lambda d: d.update(feature_set=""), "feature_set"),
    (lambda d: d.update(iterations=-1), "iterations"),
    (lambda d: d.update(final_cost=-1.0), "final_cost"),
    (lambda d: d.update(training=[{"file": "x"}]), "training entry 1 lacks"),
    (lambda d: d.update(training=[{"file": "x", "document": "x", "sha256": "",
                                   "frames": [5, 2]}]), "frames"),
    (lambda d: d.update(params=[]), "params"),
    (lambda d: d["feature_names"].__setitem__(1, d["feature_names"][0]), "duplicate feature"),
]


@pytest.mark.parametrize("mutate,message", BAD_FIELDS)
def test_load_rejects_bad_fields(tmp_path, mutate, message):
    d = _good_dict(tmp_path)
    mutate(d)
    p = _write(tmp_path, d)
    with pytest.raises(MtannoError, match=message) as info:
        load_template(p)
    assert str(info.value).startswith(str(p) + ":")


def test_load_rejects_quantized_without_delta(tmp_path):
    d = _good_dict(tmp_path)
    d["values"] = [[0.0] * 6 for _ in d["values"]]
    d.update(quantized=True, delta=None)
    with pytest.raises(MtannoError, match="needs the delta"):
        load_template(_write(tmp_path, d))


@pytest.mark.parametrize("literal, match", [("NaN", "finite"), ("Infinity", "finite"),
                                            ("-Infinity", "finite"),
                                            ("1.5", "is 1.5, outside"), ("-0.25", "is -0.25")])
def test_load_rejects_bad_values_with_line(tmp_path, literal, match):
    p = tmp_path / "t.json"
    save_template(p, make_mt())
    lines = p.read_text().splitlines()
    row = lines.index('  "values": [') + 3  # 0-based line of feature row 3
    lines[row] = lines[row].replace("[", f"[{literal}, ", 1)
    lines[row] = lines[row].rsplit(",", 2)[0] + ("]," if lines[row].endswith(",") else "]")
    p.write_text("\n".join(lines))
    with pytest.raises(MtannoError, match=f"row 3 .* {match}") as info:
        load_template(p)
    assert info.value.line == row + 1


def test_load_file_level_errors(tmp_path):
    with pytest.raises(MtannoError, match="not found") as info:
        load_template(tmp_path / "missing.json")
    assert "missing.json" in str(info.value)
    with pytest.raises(MtannoError, match="directory"):
        load_template(tmp_path)
    bad = tmp_path / "latin.json"
    bad.write_bytes(b'{"class": "\xe9"}')
    with pytest.raises(MtannoError, match="UTF-8"):
        load_template(bad)
    p = _write(tmp_path, '{\n  "schema": "mtanno.template/1",\n  "class": oops\n}')
    with pytest.raises(MtannoError, match="malformed JSON") as info:
        load_template(p)
    assert info.value.line == 3 and str(info.value).startswith(f"{p}:3: ")
    with pytest.raises(MtannoError, match="one JSON object"):
        load_template(_write(tmp_path, "[1, 2]"))
    with pytest.raises(MtannoError, match="malformed JSON"):
        load_template(_write(tmp_path, ""))


def test_mirror_mrc05_template():
    from mtanno.features import get_feature_set

    fs = get_feature_set("mrc05")
    names = list(fs.names)
    a, b = fs.mirror_pairs[0]
    values = np.zeros((len(names), 2))
    values[a] = 1.0
    m = mirror(make_mt(feature_set="mrc05", feature_names=names, values=values, K=2,
                       weights=np.ones(2)))
    assert m.values[b].tolist() == [1.0, 1.0] and m.values[a].tolist() == [0.0, 0.0]


def test_rank_features_most_fixed_entries_first():
    from mtanno.templates.model import rank_features

    V = np.full((len(FEATURE_NAMES), 4), 0.5)
    V[5] = [1, 1, 0, 0.5]      # 3 fixed, 2 ones
    V[2] = [0, 0, 0, 0.5]      # 3 fixed, 0 ones
    V[7] = [1, 1, 1, 1]        # 4 fixed, 4 ones
    V[1] = [0, 1, 0.5, 0.5]    # 2 fixed, 1 one
    mt = make_mt(K=4, values=V)
    q = quantize(mt, 0.0)
    ranked = rank_features(q)
    names = mt.feature_names
    assert [(f.name, f.fixed, f.ones) for f in ranked[:4]] == [
        (names[7], 4, 4), (names[5], 3, 2), (names[2], 3, 0), (names[1], 2, 1)]
    assert [f.name for f in ranked[4:]] == [n for i, n in enumerate(names)
                                            if i not in (1, 2, 5, 7)]
    with pytest.raises(MtannoError, match="quantized"):
        rank_features(mt)
