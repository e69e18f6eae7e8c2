"""Hostile outputs (issue 22, OUT): outputs that would destroy an input, break the next
run, be written despite an error, or fail without naming the file.

Each test runs the command line on copies of the synthetic world (``tests/world.py``) and
checks the exact behaviour: exit code 2, one ``mtanno:`` line naming the output, every
input unchanged (SHA-256), nothing written (no new file, no temporary).
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
from world import assert_one_line, checksums, cli, temporaries

from mtanno.errors import MtannoError


def _files(root: Path) -> set[str]:
    """Every file and folder below ``root``."""
    return {str(p) for p in root.rglob("*")}


class Scene:
    """A folder of copies of the world's inputs; ``refused`` checks a run wrote nothing."""

    def __init__(self, world, tmp_path: Path):
        self.w, self.dir = world, tmp_path
        self.truth = world.copy(world.truth, tmp_path / "truth.csv")
        world.copy(Path(str(world.truth) + ".meta.json"), tmp_path / "truth.csv.meta.json")
        self.blocked = tmp_path / "blocked"  # a file: nothing can be written below it
        self.blocked.write_text("a file, not a folder")

    def annotation(self, dest: Path) -> Path:
        """A copy of the world's annotation table (and its sidecar) at ``dest``."""
        self.w.copy(self.w.annotation, dest)
        self.w.copy(Path(str(self.w.annotation) + ".meta.json"), Path(str(dest) + ".meta.json"))
        return dest

    def features(self, dest: Path) -> Path:
        """A folder of copies of the documents' feature files."""
        for f in self.w.doc_files:
            self.w.copy(f, dest / f.name)
        return dest

    def snapshot(self) -> None:
        self.sums = checksums(self.dir, self.w.root)
        self.files = _files(self.dir)

    def refused(self, r, named, *, what: str | None = None) -> str:
        line = assert_one_line(r, named, codes=(2,))
        if what is not None:
            assert what in line, line
        assert checksums(self.dir, self.w.root) == self.sums, "an input was written"
        assert _files(self.dir) == self.files, sorted(_files(self.dir) - self.files)
        assert temporaries(self.dir) == []
        return line


# ------------------------------------------------------------ 1: an input destroyed


@pytest.mark.parametrize("case", ["annotation is per_class.csv", "annotation is confusion.csv",
                                  "truth is confusion.csv", "truth is per_class.csv"])
def test_report_never_writes_over_its_inputs(world, tmp_path, case):
    """Every file report writes into its folder (tables, sidecars, figures, page) is
    checked against the inputs and their sidecars: an input inside the report folder under
    one of those names is refused, not replaced by the report's own table."""
    s = Scene(world, tmp_path)
    rep = tmp_path / "rep"
    rep.mkdir()
    which, name = case.split(" is ")
    ann, truth = world.annotation, s.truth
    if which == "annotation":
        ann = s.annotation(rep / name)
    else:
        truth = world.copy(s.truth, rep / name)
    s.snapshot()
    r = cli("report", ann, "--truth", truth, "-o", rep)
    s.refused(r, rep / name, what="would overwrite")


@pytest.mark.parametrize("case", ["evaluate annotation", "evaluate truth",
                                  "evaluate-retrieval truth"])
def test_no_output_replaces_an_inputs_sidecar(world, tmp_path, case):
    """``--json ann.csv.meta.json`` would replace the provenance of the input ``ann.csv``;
    the sidecar of every CSV or JSON Lines input counts as an input."""
    s = Scene(world, tmp_path)
    ann = s.annotation(tmp_path / "ann.csv")
    of = ann if case == "evaluate annotation" else s.truth
    target = Path(str(of) + ".meta.json")
    s.snapshot()
    if case.startswith("evaluate "):
        r = cli("evaluate", ann, "--truth", s.truth, "--json", target)
    else:
        r = cli("evaluate-retrieval", world.doc_files[0], "--mt", world.mt, "--truth",
                s.truth, "--json", target)
    s.refused(r, target, what=f"provenance sidecar of the input {of}")


def test_check_outputs_counts_input_sidecars_and_folder_names(tmp_path):
    """The one place (mtanno.util.preflight.check_outputs): inputs' sidecars, names and patterns
    written inside output folders, and folders the command owns."""
    from mtanno.util.preflight import check_outputs

    (tmp_path / "rep").mkdir()
    ann = tmp_path / "rep" / "timeline_d1.png"
    ann.write_text("x")
    table = tmp_path / "t.jsonl"
    table.write_text("{}\n")
    with pytest.raises(MtannoError, match="provenance sidecar of the input"):
        check_outputs([tmp_path / "t.jsonl.meta.json"], [table])
    check_outputs([tmp_path / "t.parquet.meta.json"], [tmp_path / "t.parquet"])  # none
    with pytest.raises(MtannoError, match="would overwrite") as e:
        check_outputs([], [ann], folders={tmp_path / "rep": ["timeline_*.png"]})
    assert str(e.value).startswith(str(ann))
    check_outputs([], [ann], folders={tmp_path / "rep": ["index.html", "delta_*.png"]})
    with pytest.raises(MtannoError, match="lies inside this output folder"):
        check_outputs([], [ann], folders={tmp_path: None})


# ------------------------------------------------------ 2: outputs that break the next run


@pytest.mark.parametrize("case", ["evaluate -o", "evaluate --json", "report",
                                  "annotate --output-dir -o", "annotate --output-dir -o new",
                                  "annotate -o parquet", "annotate --output-dir parquet",
                                  "index", "index add", "evaluate-retrieval -o",
                                  "retrieve -o"])
def test_no_output_inside_a_folder_the_next_run_reads(world, tmp_path, case):
    """An output inside a folder whose files are read as inputs (annotation folders of
    evaluate and report, feature folders, annotate's --output-dir, which `mtanno evaluate
    OUT/` reads) is refused before any work; outputs the scan does not read are fine."""
    s = Scene(world, tmp_path)
    ad = tmp_path / "ad"
    s.annotation(ad / "a.csv")
    fd = s.features(tmp_path / "fd")
    od = tmp_path / "od"
    if case != "annotate --output-dir -o new":
        assert cli("annotate", "--mt", world.mt, fd, "--output-dir", od, "-q").exit_code == 0
    if case == "index add":  # an index that was moved into the folder of its features
        assert cli("index", fd, "-o", tmp_path / "idx", "-q").exit_code == 0
        (tmp_path / "idx").rename(fd / "idx")
    s.snapshot()
    if case == "evaluate -o":
        named = ad / "per_class.csv"
        r = cli("evaluate", ad, "--truth", s.truth, "-o", named)
    elif case == "evaluate --json":  # a JSON report is not an annotation table: fine
        r = cli("evaluate", ad, "--truth", s.truth, "--json", ad / "report.json")
        assert r.exit_code == 0, r.output
        assert cli("evaluate", ad, "--truth", s.truth).exit_code == 0  # the next run
        return
    elif case == "report":
        named = ad / "rep"
        r = cli("report", ad, "--truth", s.truth, "-o", named)
    elif case.startswith("annotate --output-dir -o"):
        named = od / "all.csv"
        r = cli("annotate", "--mt", world.mt, fd, "--output-dir", od, "-o", named)
    elif case == "annotate -o parquet":
        named = fd / "all.parquet"
        r = cli("annotate", "--mt", world.mt, fd, "-o", named)
    elif case == "annotate --output-dir parquet":
        named = fd / "ann"
        r = cli("annotate", "--mt", world.mt, fd, "--output-dir", named, "--format",
                "parquet")
    elif case == "index":
        named = fd / "idx"
        r = cli("index", fd, "-o", named)
    elif case == "index add":
        named = fd / "idx"
        r = cli("index", "add", named, fd)
    elif case == "retrieve -o":
        named = fd / "hits.parquet"
        r = cli("retrieve", "--mt", world.template, fd, "-o", named)
    else:
        named = fd / "r.parquet"
        r = cli("evaluate-retrieval", fd, "--mt", world.mt, "--truth", s.truth, "-o", named)
    s.refused(r, named)


def test_outputs_beside_what_a_scan_reads_are_fine(world, tmp_path):
    """Only what the scan reads is refused: a CSV table among feature files is not read
    as a feature file by the next annotate."""
    s = Scene(world, tmp_path)
    fd = s.features(tmp_path / "fd")
    r = cli("annotate", "--mt", world.mt, fd, "-o", fd / "all.csv", "-q")
    assert r.exit_code == 0, r.output
    assert cli("annotate", "--mt", world.mt, fd, "-o", tmp_path / "again.csv",
               "-q").exit_code == 0
    del s


# ------------------------------------------- 2b: an output folder among the input data


INSIDE = ["features DATA -o DATA", "features DATA -o DATA/feats", "annotate --output-dir FEATS",
          "annotate --output-dir FEATS/ann", "annotate --output-dir MT",
          "learn-mt -o FEATS/mt", "learn-mt -o TRAINING", "learn-keyframes -o MT/kf",
          "tune --ablation FEATS/abl", "compose -o CLIPS/docs", "report -o FEATS/rep",
          "report -o MOTIONS/rep", "report -o MOTIONS", "report -o MT/rep"]


def _inside_case(world, tmp_path, case):
    """(arguments, the output folder named) of an INSIDE case, on copies of the world."""
    data, feats = tmp_path / "data", tmp_path / "feats"
    if case.startswith(("features", "compose")):
        world.copy(world.clips, data)
    if case.startswith("report"):  # the documents' feature files and motions
        world.copy(world.docfeats, feats)
        world.copy(world.docs, data)
    elif not case.startswith(("features", "compose")):
        world.copy(world.feats, feats)
    mt = world.copy(world.mt, tmp_path / "mt")
    out = {"features DATA -o DATA": data, "features DATA -o DATA/feats": data / "feats",
           "annotate --output-dir FEATS": feats, "annotate --output-dir FEATS/ann": feats / "ann",
           "annotate --output-dir MT": mt, "learn-mt -o FEATS/mt": feats / "mt",
           "learn-mt -o TRAINING": feats, "learn-keyframes -o MT/kf": mt / "kf",
           "tune --ablation FEATS/abl": feats / "abl",
           "compose -o CLIPS/docs": data / "squat" / "docs", "report -o FEATS/rep": feats / "rep",
           "report -o MOTIONS/rep": data / "rep", "report -o MOTIONS": data,
           "report -o MT/rep": mt / "rep"}[case]
    train = ["--manifest", world.manifest, "--features-dir", feats, "--split", "train"]
    args = {"features": ["features", data, "-o", out, "-q"],
            "annotate": ["annotate", "--mt", mt, feats, "--output-dir", out, "-q"],
            "learn-mt": (["learn-mt", *train, "-o", out, "-q"] if case.endswith("mt") else
                         ["learn-mt", feats, "-o", out, "-q"]),
            "learn-keyframes": ["learn-keyframes", "--mt", mt, *train, "--method", "hard",
                                "-o", out, "-q"],
            "tune": ["tune", "--mt", mt, *train, "-o", tmp_path / "t.toml", "--ablation", out,
                     "-q"],
            "compose": ["compose", data / "clips.csv", "--actor", "c", "--docs", "1", "-o",
                        out],
            "report": ["report", world.annotation, "--truth", world.truth, "--mt", mt,
                       "--features", feats, "--motions", data, "-o", out, "-q"],
            }[case.split()[0]]
    return args, out


@pytest.mark.parametrize("case", INSIDE)
def test_an_output_folder_inside_an_input_folder_is_refused(world, tmp_path, case):
    """Issue 31 (6): `features DATA -o DATA` wrote feature files into a read-only data set
    and `annotate --output-dir` took the input folder. An output folder that is, or lies
    inside, a folder the command reads inputs from is refused before any work, in one line
    that names --inside-input, the flag that says it is meant (exit 2, nothing written)."""
    s = Scene(world, tmp_path)
    args, out = _inside_case(world, tmp_path, case)
    s.snapshot()
    line = s.refused(cli(*args), out, what="--inside-input")
    assert "the output folder is the input folder" in line or \
        "the output folder lies inside the input folder" in line, line


@pytest.mark.parametrize("case", ["features DATA -o DATA/feats", "annotate --output-dir FEATS",
                                  "learn-mt -o FEATS/mt", "compose -o CLIPS/docs",
                                  "report -o FEATS/rep", "report -o MOTIONS", "report -o MT/rep"])
def test_inside_input_says_an_output_folder_among_the_inputs_is_meant(world, tmp_path, case):
    """With --inside-input the same runs write, and the next run over the input folder
    reads what it read before (the outputs are not among what it reads)."""
    args, out = _inside_case(world, tmp_path, case)
    r = cli(*args, "--inside-input")
    assert r.exit_code == 0, r.output
    assert any(out.iterdir())
    if case.startswith("report"):
        assert (out / "index.html").is_file()
    r = cli(*args, "--inside-input")
    assert r.exit_code == 0, r.output


def test_inside_input_never_lets_the_next_run_read_an_output(world, tmp_path):
    """--inside-input allows a folder among the inputs, not an output the next run reads:
    Parquet annotation tables inside a folder of feature files stay refused (it was
    annotate's own rule; now the one of every command, mtanno.util.output)."""
    s = Scene(world, tmp_path)
    fd = s.features(tmp_path / "fd")
    s.snapshot()
    r = cli("annotate", "--mt", world.mt, fd, "--output-dir", fd / "ann", "--format",
            "parquet", "--inside-input")
    line = s.refused(r, fd / "ann")
    assert "the next run over that folder would read this output" in line, line
    r = cli("index", fd, "-o", fd / "idx")  # an index inside its features: never
    s.refused(r, fd / "idx")
    # a report in the templates' folder: its figures.json would be read as a template
    mt = world.copy(world.mt, tmp_path / "mt")
    s.snapshot()
    r = cli("report", world.annotation, "--mt", mt, "-o", mt, "--inside-input")
    line = s.refused(r, mt)
    assert "the next run over that folder would read this output" in line, line


def test_check_outputs_inside_input(tmp_path):
    """The API's words: inside_input=; None (an index's folder) leaves the rule out."""
    from mtanno.util.preflight import check_outputs

    data = tmp_path / "data"
    data.mkdir()
    for out in (data, data / "a" / "b"):
        with pytest.raises(MtannoError, match="inside_input="):
            check_outputs([], [data], folders={out: []}, scanned={data: ()},
                          inside_input=False)
        check_outputs([], [data], folders={out: []}, scanned={data: ()}, inside_input=True)
        check_outputs([], [data], folders={out: []}, scanned={data: ()})
    # beside the input folder, or holding it: fine
    check_outputs([], [data], folders={tmp_path / "out": []}, scanned={data: ()},
                  inside_input=False)
    check_outputs([], [data], folders={tmp_path: []}, scanned={data: ()}, inside_input=False)


# --------------------------------------------------------- 3: written despite an error


def _tune_args(world):
    return ["tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir",
            world.feats, "--split", "train", "-q"]


@pytest.mark.parametrize("case", ["align --plot", "tune --ablation", "tune -o",
                                  "evaluate --json + -o", "evaluate-retrieval --json + -o",
                                  "annotate -o -o", "report page is a folder",
                                  "annotate -o is a folder"])
def test_a_command_that_fails_on_an_output_writes_nothing(world, tmp_path, case):
    """Every output location is tried before the work: one that cannot be written (below a
    file, or a folder where a file goes) is one line naming it, exit 2, and no other output
    is written."""
    s = Scene(world, tmp_path)
    a, b = world.doc_files[:2]
    ok = tmp_path / "ok.csv"
    bad = s.blocked / "x.csv"
    if case == "report page is a folder":
        (tmp_path / "rep" / "index.html").mkdir(parents=True)
    if case == "annotate -o is a folder":
        (tmp_path / "dir.csv").mkdir()
    s.snapshot()
    if case == "align --plot":
        r, named = cli("align", a, b, "--cost", "features", "-o", ok, "--plot",
                       s.blocked / "p.png"), s.blocked
    elif case == "annotate -o is a folder":
        r, named = cli("annotate", "--mt", world.mt, a, "-o", ok, "-o",
                       tmp_path / "dir.csv"), tmp_path / "dir.csv"
    elif case == "tune --ablation":
        r, named = cli(*_tune_args(world), "-o", tmp_path / "t.toml", "--ablation",
                       s.blocked / "abl"), s.blocked
    elif case == "tune -o":
        r, named = cli(*_tune_args(world), "-o", s.blocked / "t.toml", "--ablation",
                       tmp_path / "abl"), s.blocked
    elif case == "evaluate --json + -o":
        r, named = cli("evaluate", world.annotation, "--truth", s.truth, "--json",
                       tmp_path / "e.json", "-o", bad), s.blocked
    elif case == "evaluate-retrieval --json + -o":
        r, named = cli("evaluate-retrieval", a, "--mt", world.mt, "--truth", s.truth,
                       "--json", tmp_path / "e.json", "-o", bad), s.blocked
    elif case == "annotate -o -o":
        r, named = cli("annotate", "--mt", world.mt, a, "-o", ok, "-o", bad), s.blocked
    else:
        r, named = cli("report", world.annotation, "--truth", s.truth, "-o",
                       tmp_path / "rep"), tmp_path / "rep" / "index.html"
    line = s.refused(r, named)
    assert "internal error" not in line


def test_preflight_leaves_nothing_and_creates_no_folder(tmp_path):
    """The preflight tries the nearest existing folder with a temporary file it removes;
    it creates no folder."""
    from mtanno.util.preflight import check_outputs

    check_outputs([tmp_path / "a" / "b" / "x.csv"], [], folders={tmp_path / "c": None})
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "f").write_text("x")
    with pytest.raises(MtannoError, match="is not a folder"):
        check_outputs([], [], folders={tmp_path / "f": None})
    with pytest.raises(MtannoError, match="output is a folder"):
        check_outputs([tmp_path], [])
    check_outputs([tmp_path], [], writable=False)  # a batch's outputs fail alone later


# ------------------------------------------------------------- 4: non-UTF-8 file names


def _non_utf8_folder(world, folder: Path) -> bytes:
    """A folder of feature files, one of them named ``caf<0xE9>.parquet`` (not UTF-8);
    returns that file's name as bytes."""
    folder.mkdir()
    world.copy(world.doc_files[1], folder / world.doc_files[1].name)
    name = os.fsencode(folder) + b"/caf\xe9.parquet"
    try:
        with open(name, "wb") as fh:
            fh.write(world.doc_files[0].read_bytes())
    except OSError:
        pytest.skip("this file system refuses names that are not UTF-8")
    return name


@pytest.mark.parametrize("case", ["annotate -o csv", "annotate -o parquet", "annotate -o jsonl",
                                  "annotate --output-dir", "annotate --output-dir parquet",
                                  "retrieve -o csv"])
def test_tables_of_documents_named_by_non_utf8_file_names(world, tmp_path, case):
    """A document whose file name is not UTF-8 is written, not a UnicodeEncodeError: in
    the table its name's undecodable bytes are \\xNN (valid UTF-8 text, as every table
    reader wants it), and the provenance records the path exactly (its \\uDCxx escape
    reads back as the file's name)."""
    from mtanno.util.tables import read_table, table_provenance

    raw = _non_utf8_folder(world, tmp_path / "in")
    fmt = case.split()[-1] if case.split()[-1] in ("csv", "parquet", "jsonl") else "csv"
    if case.startswith("annotate -o"):
        out = tmp_path / f"all.{fmt}"
        r = cli("annotate", "--mt", world.mt, tmp_path / "in", "-o", out, "-q")
    elif case == "retrieve -o csv":
        out = tmp_path / "hits.csv"
        r = cli("retrieve", "--mt", world.template, tmp_path / "in", "-o", out, "-q")
    else:
        od = tmp_path / "od"
        r = cli("annotate", "--mt", world.mt, tmp_path / "in", "--output-dir", od, "--format",
                fmt, "-q")
        out = Path(os.fsdecode(os.fsencode(od) + b"/caf\xe9." + fmt.encode()))
    assert r.exit_code == 0 and r.exception is None, (r.exception, r.output)
    docs = {row["doc"] for row in read_table(out).rows}
    assert "caf\\xe9" in docs, docs
    prov = table_provenance(out)
    paths = [i["path"] for i in prov["inputs"]]
    assert raw in [os.fsencode(p) for p in paths], paths
    if case.startswith("annotate --output-dir"):  # the rerun finds the table up to date
        r = cli("annotate", "--mt", world.mt, tmp_path / "in", "--output-dir", od, "--format",
                fmt)
        assert r.exit_code == 0 and "2 up to date" in r.output, r.output
        r = cli("evaluate", od, "--truth", world.truth, "--all-docs")
        assert r.exit_code == 0, r.output


def test_an_index_of_documents_named_by_non_utf8_file_names(world, tmp_path):
    """Issue 31: index build and add crashed on a feature file whose name is not UTF-8
    (UnicodeEncodeError writing documents.parquet). The name and path are kept exactly
    (as bytes where no Parquet string can hold them): the index reads back, the document
    is found by its name, in query hits as \\xNN, and removed by its name."""
    from mtanno.index import open_index
    from mtanno.util.tables import read_table

    _non_utf8_folder(world, tmp_path / "in")
    name = os.fsdecode(b"caf\xe9")
    r = cli("index", tmp_path / "in", "-o", tmp_path / "idx", "-q")
    assert r.exit_code == 0 and r.exception is None, (r.exception, r.output)
    docs = {d.name: d for d in open_index(tmp_path / "idx").documents}
    assert name in docs and os.fsencode(docs[name].path).endswith(b"/caf\xe9.parquet")
    world.copy(world.index, tmp_path / "idx2")
    r = cli("index", "add", tmp_path / "idx2", tmp_path / "in", "-q")
    assert r.exit_code == 0 and r.exception is None, (r.exception, r.output)
    assert name in [d.name for d in open_index(tmp_path / "idx2").documents]
    r = cli("query", tmp_path / "idx2", "--example", name, "--features", "rknee_bent", "-o",
            tmp_path / "h.csv", "-q")
    assert r.exit_code == 0, r.output
    assert "caf\\xe9" in {row["doc"] for row in read_table(tmp_path / "h.csv").rows}
    r = cli("index", "remove", tmp_path / "idx2", name)
    assert r.exit_code == 0, r.output
    assert name not in [d.name for d in open_index(tmp_path / "idx2").documents]


def test_json_of_non_utf8_names_is_valid_utf8(tmp_path):
    """tables.dumps, used for every sidecar and JSON output: a lone surrogate becomes its
    JSON escape, so the file is UTF-8 and reads back as the same string."""
    import json

    from mtanno.util.tables import dumps, text, write_json

    name = os.fsdecode(b"caf\xe9.parquet")
    write_json(tmp_path / "x.json", {"path": name, name: 1, "ok": "café"})
    raw = (tmp_path / "x.json").read_bytes()
    assert json.loads(raw.decode("utf-8")) == {"path": name, name: 1, "ok": "café"}
    assert "café" in raw.decode("utf-8")  # other text stays as it is
    assert json.loads(dumps([name])) == [name]
    assert text(os.fsdecode(b"a\xff\xfe")) == "a\\xff\\xfe" and text("café") == "café"


def test_a_template_learned_from_non_utf8_file_names(world, tmp_path):
    """learn-mt of examples whose file names are not UTF-8 writes the template (it was a
    UnicodeEncodeError): the training records' paths read back as the files' names, and the
    template annotates."""
    from mtanno.templates.store import load_template

    folder = tmp_path / "train" / "squat"
    folder.mkdir(parents=True)
    raw = []
    for i, src in enumerate(sorted((world.feats / "squat").glob("*.parquet"))[:3]):
        name = os.fsencode(folder) + b"/ex\xff%d.parquet" % i
        try:
            with open(name, "wb") as fh:
                fh.write(src.read_bytes())
        except OSError:
            pytest.skip("this file system refuses names that are not UTF-8")
        raw.append(name)
    r = cli("learn-mt", tmp_path / "train", "-o", tmp_path / "mts", "-q")
    assert r.exit_code == 0 and r.exception is None, (r.exception, r.output)
    mt = load_template(tmp_path / "mts" / "squat.json")
    assert sorted(os.fsencode(t["file"]) for t in mt.training) == raw
    r = cli("annotate", "--mt", tmp_path / "mts", world.docfeats, "-o", tmp_path / "a.csv", "-q")
    assert r.exit_code == 0, r.output


# ----------------------------------------------------------------------- 5: a full device


FULL = Path("/dev/full")
needs_full = pytest.mark.skipif(not FULL.exists(), reason="no /dev/full on this system")


@needs_full
@pytest.mark.parametrize("case", ["evaluate -o", "evaluate --json", "retrieve -o",
                                  "annotate -o"])
def test_an_output_on_a_full_device_names_it(world, tmp_path, case):
    """A write that the device refuses (no space left) is one line naming the output."""
    s = Scene(world, tmp_path)
    s.snapshot()
    if case == "evaluate -o":
        r = cli("evaluate", world.annotation, "--truth", s.truth, "-o", FULL)
    elif case == "evaluate --json":
        r = cli("evaluate", world.annotation, "--truth", s.truth, "--json", FULL)
    elif case == "retrieve -o":
        r = cli("retrieve", "--mt", world.template, world.doc_files[0], "-o", FULL, "-q")
    else:
        r = cli("annotate", "--mt", world.mt, world.doc_files[0], "-o", FULL, "-q")
    line = s.refused(r, FULL, what="No space left on device")
    assert line.startswith(f"mtanno: {FULL}: "), line


@needs_full
def test_standard_output_on_a_full_device_says_so(world, tmp_path):
    """`-o -` (and the printed report) on a full device: one line saying it is standard
    output, exit code 2. Issue 31: what commands print with click (info, show, mt show,
    index info, keyframes show, --help, --version) said "No space left on device" naming
    nothing, and a help text was a traceback."""
    import subprocess
    import sys

    cmd = [sys.executable, "-c", "import sys; from mtanno.cli import main; "
           "sys.argv[0] = 'mtanno'; main()"]
    kf = tmp_path / "kf"
    assert cli("learn-keyframes", "--mt", world.mt, "--manifest", world.manifest,
               "--features-dir", world.feats, "--method", "hard", "-o", kf,
               "-q").exit_code == 0
    for args in (["evaluate", world.annotation, "--truth", world.truth, "-o", "-"],
                 ["evaluate", world.annotation, "--truth", world.truth],
                 ["info", world.doc_files[0]], ["show", world.doc_files[0]],
                 ["mt", "show", world.template], ["index", "info", world.index],
                 ["keyframes", "show", next(kf.glob("*.json"))], ["--help"],
                 ["features", "--help"], ["--version"]):
        with open(FULL, "w") as full:
            p = subprocess.run([*cmd, *map(str, args)], stdout=full, stderr=subprocess.PIPE,
                               text=True)
        lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
        assert p.returncode == 2 and lines == [
            "mtanno: cannot write to standard output: No space left on device"], (args,
                                                                                  p.stderr)


def test_a_write_that_fails_in_place_or_to_stdout_names_it(tmp_path, monkeypatch):
    """The writers' own paths (mtanno.util.output): a device written in place and standard
    output raise one MtannoError that names where, for any OSError (simulated here)."""
    import io
    import sys

    import pyarrow as pa

    from mtanno.util import output
    from mtanno.util.tables import write_table

    class Full(io.StringIO):
        def write(self, text):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(sys, "stdout", Full())
    with pytest.raises(MtannoError, match="cannot write to standard output: No space"):
        write_table("-", pa.table({"a": [1]}))
    monkeypatch.undo()
    fifo = tmp_path / "device"
    fifo.write_text("")
    monkeypatch.setattr(output, "_check_target", lambda target: False)  # "not a file"
    with pytest.raises(MtannoError, match="cannot write here: No space") as e, \
            output.atomic_path(fifo):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert str(e.value).startswith(str(fifo))
