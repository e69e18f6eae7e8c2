"""Each kind of bad input through `mtanno features`: one-line message with path and line,
the other files of the batch still written, no partial output for the bad one."""

from __future__ import annotations

import pytest
from click.testing import CliRunner
from test_bvh import SMALL_BVH

from mtanno import synthetic
from mtanno.cli import main


def _amc_lines():
    return synthetic.amc_text(6, 1).splitlines()


def _replace_line(lines, prefix, nth, new):
    hits = [k for k, s in enumerate(lines) if s.startswith(prefix)]
    k = hits[nth]
    lines = list(lines)
    lines[k] = new(lines[k])
    return lines, k + 1


def _cases():
    amc = _amc_lines()
    cases = []
    lines, n = _replace_line(amc, "lfemur ", 2, lambda s: " ".join(s.split()[:-1]))
    cases.append(("amc-too-few", "bad.amc", "\n".join(lines), n, "too few values"))
    lines, n = _replace_line(amc, "rtibia ", 1, lambda s: s + " 0.5")
    cases.append(("amc-too-many", "bad.amc", "\n".join(lines), n, "too many values"))
    lines, n = _replace_line(amc, "head ", 3, lambda s: s.replace("head", "hat", 1))
    cases.append(("amc-unknown-bone", "bad.amc", "\n".join(lines), n, "unknown bone 'hat'"))
    lines, n = _replace_line(amc, "ltibia ", 2, lambda s: "ltibia NaN")
    cases.append(("amc-nan", "bad.amc", "\n".join(lines), n, "NaN"))
    cut = [k for k, s in enumerate(amc) if s.startswith("rhumerus ")][-1]
    cases.append(("amc-truncated", "bad.amc", "\n".join(amc[:cut]), cut, "truncated"))
    cases.append(("amc-empty", "bad.amc", "", 1, "empty"))
    cases.append(("amc-binary", "bad.amc", b"\x00\x01\x02\x03", 1, "binary"))
    rows = SMALL_BVH.split("\n")
    k = max(i for i, s in enumerate(rows) if s.strip())  # last motion row
    rows[k] += " 7"
    cases.append(("bvh-row-vs-channels", "bad.bvh", "\n".join(rows), k + 1, "too many values"))
    cases.append(("bvh-binary", "bad.bvh", b"\x1f\x8b\x08\x00\x00", 1, "binary"))
    return cases


@pytest.mark.parametrize("case", _cases(), ids=lambda c: c[0])
def test_bad_file_reported_and_batch_continues(tmp_path, case):
    _, name, content, line, words = case
    src = tmp_path / "in"
    src.mkdir()
    (src / "synth.asf").write_text(synthetic.asf_text())
    (src / "good.amc").write_text(synthetic.amc_text(20, 2))
    bad = src / name
    if isinstance(content, bytes):
        bad.write_bytes(content)
    else:
        bad.write_text(content + "\n")
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["features", str(src), "-o", str(out)])
    assert r.exit_code == 1, r.output
    msgs = [m for m in r.output.splitlines() if m.startswith("mtanno: ")]
    assert len(msgs) == 1 and "Traceback" not in r.output
    assert msgs[0].startswith(f"mtanno: {bad}:{line}: "), msgs[0]
    assert words in msgs[0]
    assert (out / "good.parquet").exists()
    assert sorted(p.name for p in out.iterdir()) == ["good.parquet"]
    assert "1 written" in r.output and "1 failed" in r.output


def test_missing_asf_reported_and_batch_continues(tmp_path):
    src = tmp_path / "in"
    (src / "a").mkdir(parents=True)
    (src / "a" / "synth.asf").write_text(synthetic.asf_text())
    (src / "a" / "good.amc").write_text(synthetic.amc_text(8, 2))
    (src / "b").mkdir()
    (src / "b" / "orphan.amc").write_text(synthetic.amc_text(8, 3))
    r = CliRunner().invoke(main, ["features", str(src / "a"), str(src / "b"), "-o",
                                  str(tmp_path / "out")])
    assert r.exit_code == 1
    assert f"{src / 'b' / 'orphan.amc'}: no ASF skeleton found" in r.output
    assert (tmp_path / "out" / "good.parquet").exists()
    assert not (tmp_path / "out" / "orphan.parquet").exists()
