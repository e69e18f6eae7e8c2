"""The method is in the repository (issue 32): every document the package's docstrings and
comments, the scripts, the tests and the documentation cite exists in the repository, and
every section they cite ("docs/method.md §3.4", "docs/method/features.md §A",
"docs/method/features31.md §5.1–5.3") is a heading of that document; the feature tables of
docs/method/features*.md are the code's."""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import pytest

from mtanno.features.table import FEATURES
from mtanno.features.table31 import FEATURES31, FEATURES31_REFERENCE

REPO = Path(__file__).resolve().parents[1]

#: A document named in text: a path ending ``.md`` (``docs/method.md``,
#: ``../shared/spec/algorithms.md``, ``features31.md``).
DOC = re.compile(r"(?<![\w.-])((?:\.\./|\./)?(?:[\w.-]+/)*[\w-]+\.md)(?![\w-])")
#: A section after a document: ``§3.4``, ``§A``, a range ``§5.1–5.3``, possibly after closing
#: backticks, followed by more sections joined by ``,``, ``and``, ``or`` or ``/``.
SECTION = r"§\s?([0-9]+(?:\.[0-9]+)*|[A-Z])(?:\s?[–-]\s?([0-9]+(?:\.[0-9]+)*))?"
SECTIONS = re.compile(r"`*\s*(" + SECTION + r"(?:(?:\s?,\s?|\s(?:and|or)\s|\s?/\s?)"
                      + SECTION + r")*)")
ONE_SECTION = re.compile(SECTION)
#: A markdown link to a document: ``[text](annotation.md#anchor)``.
LINK = re.compile(r"\]\(([^)\s#]+\.md)(?:#[^)]*)?\)")
#: Names of the project's first specification (``../shared/spec/``), which is not in the
#: repository: any mention of them must resolve to a file that is.
SPEC_NAMES = {"algorithms.md", "features.md", "features31.md", "features_spec.md", "style.md"}
#: Data lives beside the repository by rule (its READMEs describe the golden files); a
#: reference to it is not a reference to documentation.
DATA = "../shared/data/"


def _resolve(doc: str, where: Path) -> Path | None:
    """The repository file a document name means: relative to the repository root, or to
    the citing file's folder (markdown links); None when neither is a file inside the
    repository."""
    for base in (REPO, where.parent):
        p = (base / doc).resolve()
        if p.is_file() and REPO in p.parents:
            return p
    return None


@cache
def _headings(doc: Path) -> frozenset[str]:
    """The section numbers of a document's headings (``## §3.4 Matching`` → ``3.4``)."""
    text = doc.read_text(encoding="utf-8")
    return frozenset(m.group(1) for m in re.finditer(r"(?m)^#+\s+§(\S+)", text))


def citation_problems(text: str, where: Path) -> list[str]:
    """One message per citation in ``text`` (the contents of file ``where``) that does not
    resolve: a cited document that is not in the repository, or a cited section that is not
    a heading of it."""
    bad = []
    for m in DOC.finditer(text):
        doc = m.group(1)
        if doc.startswith(DATA):
            continue
        line = text.count("\n", 0, m.start()) + 1
        sec = SECTIONS.match(text, m.end())
        sections = []
        if sec:
            for s in ONE_SECTION.finditer(sec.group(1)):
                sections += [x for x in s.groups() if x]
        checked = (sections or doc.startswith(("docs/", "../"))
                   or Path(doc).name in SPEC_NAMES)
        if not checked:
            continue  # an output file's name (per_class.md), not a citation
        target = _resolve(doc, where)
        if target is None:
            bad.append(f"{where.name}:{line}: cites {doc}, which is not in the repository")
            continue
        for s in sections:
            if s not in _headings(target):
                bad.append(f"{where.name}:{line}: cites {doc} §{s}, which has no heading §{s}")
    for m in LINK.finditer(text):
        if not m.group(1).startswith(("http:", "https:")) and _resolve(m.group(1), where) is None:
            line = text.count("\n", 0, m.start()) + 1
            bad.append(f"{where.name}:{line}: links to {m.group(1)}, which is not in the "
                       f"repository")
    return bad


def _scanned() -> list[Path]:
    """The package's code and data files, the scripts, the tests (this file excepted: it
    holds made-up citations on purpose), the documentation and the README."""
    files = [REPO / "README.md", REPO / "Makefile"]
    for folder, patterns in (("mtanno", ("*.py", "*.toml", "*.js")),
                             ("scripts", ("*.py", "*.sh")), ("tests", ("*.py", "*.md")),
                             ("docs", ("*.md",))):
        for pattern in patterns:
            files += sorted((REPO / folder).rglob(pattern))
    return [p for p in files if p.is_file() and p.resolve() != Path(__file__).resolve()]


def test_every_cited_document_and_section_exists():
    files = _scanned()
    assert len(files) > 100 and REPO / "docs" / "method.md" in files
    bad = [msg for p in files for msg in citation_problems(p.read_text(encoding="utf-8"), p)]
    assert not bad, "\n".join(bad)


def test_the_check_finds_made_up_citations():
    where = REPO / "mtanno" / "example.py"
    good = ("docs/method.md §3.4; ``docs/method.md`` §1, §2 and §3; docs/method.md §7 step 2; "
            "docs/method/features.md §A; docs/method/features31.md §5.1–5.3; "
            "docs/method/features.md §1.1–1.3; see docs/annotation.md; "
            "../shared/data/reference/retrieval/README.md; per_class.md")
    assert citation_problems(good, where) == []
    for made_up in ("docs/method.md §99", "docs/method.md §3.4–3.9",
                    "``docs/method.md`` §1 and §42", "docs/method/features.md §B",
                    "docs/nowhere.md §1", "docs/nowhere.md", "algorithms.md §3.4",
                    "features.md App. A", "../shared/spec/algorithms.md §5",
                    "[the index](nowhere.md#top)"):
        assert citation_problems(made_up, where), made_up
    # a markdown link resolves against the citing document's folder
    assert citation_problems("[features](features31.md)",
                             REPO / "docs" / "method" / "features.md") == []


def test_the_pages_number_their_sections_as_the_specification_did():
    method = _headings(REPO / "docs" / "method.md")
    assert {"1", "2", "3", "3.1", "3.2", "3.3", "3.4", "3.5", "4", "5", "6", "7", "8",
            "9"} <= method
    features = _headings(REPO / "docs" / "method" / "features.md")
    assert {"0", "1", "1.1", "1.5", "2", "3", "4", "5", "5.1", "5.2", "5.3", "6", "7", "8",
            "A"} <= features
    features31 = _headings(REPO / "docs" / "method" / "features31.md")
    assert {"1", "2", "3", "3.1", "3.2", "3.3", "4", "5", *(f"5.{i}" for i in range(1, 10)),
            "6", "7"} <= features31


def _test_text(spec: tuple, f) -> str:
    """A feature's test as the docs' tables write it: ``> 1.8 hlL/s``, ``[0, 110]°``."""
    number = lambda x: f"{x:g}".replace("-", "−")  # noqa: E731
    speed = f.measure in ("move_plane", "move_dir", "move_diff", "fast")
    if f.measure in ("angle", "angle_up", "angle_max"):
        unit = "°"
    elif f.measure == "heading_rate":
        unit = "°/s"
    elif f.measure == "touch":
        unit = ""
    else:
        unit = " " + (f.unit or "cm") + ("/s" if speed else "")
    if spec[0] == "in":
        return f"[{number(spec[1])}, {number(spec[2])}]{unit}"
    symbol = {">": ">", ">=": "≥", "<": "<", "<=": "≤"}[spec[0]]
    return f"{symbol} {number(spec[1])}{unit}"


@pytest.mark.parametrize("page, table", [("features.md", FEATURES),
                                         ("features31.md", FEATURES31),
                                         ("features31.md", FEATURES31_REFERENCE)])
def test_feature_tables_are_the_code(page, table):
    """Each feature's row: id, name, group, mirror partner, and both tests of the
    hysteresis with their units, as the code's table has them."""
    text = (REPO / "docs" / "method" / page).read_text(encoding="utf-8")
    for f in table:
        head = f"| {f.id} | {f.name} | {f.group} | {f.mirror or '–'} |"
        tail = f"| {_test_text(f.on, f)} | {_test_text(f.off, f)} |"
        rows = [ln for ln in text.splitlines() if ln.startswith(head) and ln.endswith(tail)]
        assert rows, f"{page}: no row {head} … {tail}"


def test_names_on_the_method_pages_exist():
    """Every ``mtanno.a.b`` the method pages name resolves (the README and docs/*.md are
    checked after a bare import by test_frictions3; the pages under docs/method/ here)."""
    import importlib

    name = re.compile(r"(?<![\w./-])mtanno(?:\.[A-Za-z_][A-Za-z0-9_]*)+(?![\w/-])")
    names = {m.group(0) for p in (REPO / "docs" / "method").glob("*.md")
             for m in name.finditer(p.read_text(encoding="utf-8"))}
    assert "mtanno.features.measures.body_units" in names
    bad = []
    for n in sorted(names):
        parts = n.split(".")
        for i in range(len(parts), 0, -1):
            try:
                obj = importlib.import_module(".".join(parts[:i]))
                break
            except ImportError:
                continue
        try:
            for part in parts[i:]:
                obj = getattr(obj, part)
        except AttributeError:
            bad.append(n)
    assert not bad, bad
