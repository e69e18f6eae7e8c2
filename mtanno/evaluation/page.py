"""The report page (issue 33): an archive view that stays fast at thousands of documents,
one player beside it, review at speed, the rest of the report behind a table of contents.

``index.html`` holds the whole annotation as compact JSON (:func:`page_data`: columns of
documents, rows and truth segments, no object keyed by a name) in a ``<script
type=application/json>`` element whose every ``<`` is written ``\\u003c``
(:func:`json_for_script`), and the page's script (``archive.js``, ``player.js``,
``review.js``; package data, inlined). The script draws every row of the archive view in
the browser (a virtualised list: only the rows in view exist), filters, sorts and counts
there, and shows the selected document in the player.

The poses and Δ curves of the documents are not in the page: they are in data files
beside it, ``data/HASH.js``, each a few hundred kilobytes holding several documents
(:func:`write_chunks`), which the page loads with an added ``<script>`` element when a
document of theirs is selected (a page opened from disk cannot ``fetch()`` its sibling
files in Chromium; a script element can load them). A file is named by the hash of its
content: a rerun with the same motions writes nothing new, and a browser never shows a
stale file.

DOM contract (tests, scripts): the list ``#mtanno-list`` carries ``data-mtanno-count`` (the
documents matching the filter); each rendered row has ``data-mtanno-doc`` (its name) and
``data-frames``; the filter input is ``#mtanno-filter``; the player element has
``data-mtanno-player``, ``data-doc``, ``data-frames``, ``data-frame`` (1-based) and
``data-state`` (``empty``, ``loading``, ``ready``, ``none`` without a motion, ``error``),
and fires ``mtanno:shown`` when a selected document is drawn.
"""

from __future__ import annotations

import hashlib
import html
import json
import re
from collections.abc import Callable, Sequence
from importlib import resources
from pathlib import Path
from urllib.parse import quote

import numpy as np

from mtanno.errors import MtannoError

__all__ = ["CHUNK_BYTES", "DATA_FOLDER", "FORMATS", "SCRIPTS", "Figures", "curve_entries",
           "figure_html", "file_stems", "json_for_script", "page_data", "page_html",
           "pose_entries", "write_chunks"]

#: Default size of a data file (bytes of encoded poses and curves): measured in
#: docs/benchmarks.md against one file per document.
CHUNK_BYTES = 256_000
#: The folder of the data files, beside the page.
DATA_FOLDER = "data"
#: The page's scripts (package data), inlined in this order.
SCRIPTS = ("archive.js", "player.js", "review.js")
#: The formats of every figure beside the page.
FORMATS = ("png", "svg")
_CHUNK_NAME = re.compile(r"^[0-9a-f]{20}\.js$")


def json_for_script(value) -> str:
    """JSON text that cannot end or change the ``<script>`` element it is put in: every
    ``<`` written ``\\u003c`` (so neither ``</script>`` nor ``<!--`` appears: the latter
    would put the HTML parser into its "double escaped" state and swallow the scripts
    after it), ``>`` and ``&`` likewise; non-ASCII as escapes (a name with a lone
    surrogate stays writable)."""
    text = json.dumps(value, separators=(",", ":"), allow_nan=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def file_stems(names: Sequence[str]) -> dict[str, str]:
    """A file stem per name, distinct for distinct names even on a file system that
    ignores case: the name itself when it is plain (letters, digits, ``-_.``, not
    beginning with a dot) and no other name has it in another case; else its plain
    characters and a hash of the whole name (``a/b`` → ``a_b-5c0e…``, beside ``a_b``)."""
    plain = {n: re.sub(r"[^A-Za-z0-9_.-]", "_", n) for n in names}
    lower: dict[str, int] = {}
    for p in plain.values():
        lower[p.lower()] = lower.get(p.lower(), 0) + 1
    out = {}
    for n, p in plain.items():
        if p == n and not n.startswith(".") and n and lower[p.lower()] == 1:
            out[n] = n
        else:
            digest = hashlib.sha256(n.encode("utf-8", "surrogatepass")).hexdigest()[:10]
            out[n] = f"{p.lstrip('.')[:60] or 'x'}-{digest}"
    return out


def write_chunks(folder: Path, entries: dict[str, list[str]], order: Sequence[str], *,
                 chunk_bytes: int = CHUNK_BYTES) -> tuple[list[str], dict[str, tuple[int, int]]]:
    """Write the documents' encoded data (``entries``: document → list of base-64 texts)
    into ``folder/data/``, documents in ``order`` gathered into files of about
    ``chunk_bytes`` (0: one file per document). Each file is the script
    ``mtannoChunk("NAME",[[...],...]);`` named by the hash of its content; one that is
    already there is not written again, and the folder's other data files (a previous
    run's) are removed. Returns the file names (without ``.js``) and, per document, its
    file's index and its place in it."""
    from mtanno.util.output import make_folder, write_bytes

    groups: list[list[str]] = []
    size = chunk_bytes + 1
    for d in order:
        if d not in entries:
            continue
        n = sum(len(t) for t in entries[d])
        if size + n > chunk_bytes:
            groups.append([])
            size = 0
        groups[-1].append(d)
        size += n
    target = folder / DATA_FOLDER
    if groups:
        make_folder(target)
    names: list[str] = []
    where: dict[str, tuple[int, int]] = {}
    for i, group in enumerate(groups):
        body = json_for_script([entries[d] for d in group])
        name = hashlib.sha256(body.encode("ascii")).hexdigest()[:20]
        path = target / f"{name}.js"
        if not path.is_file():
            write_bytes(path, f'mtannoChunk("{name}",{body});\n'.encode("ascii"))
        names.append(name)
        where.update({d: (i, j) for j, d in enumerate(group)})
    if target.is_dir():
        keep = {f"{n}.js" for n in names}
        for old in target.iterdir():
            if _CHUNK_NAME.match(old.name) and old.name not in keep:
                old.unlink(missing_ok=True)
    return names, where


def page_data(docs: Sequence[str], frames: dict[str, int], rows: Sequence, *,
              truth: Sequence | None, colours: dict[str, str], notes: dict[str, str],
              chunks: Sequence[str], where: dict[str, tuple[int, int]],
              rigs: dict[str, int], rig_list: Sequence[dict], curves: dict | None,
              title: str) -> dict:
    """The JSON the page's script reads, as columns (a name is never an object's key, so
    ``__proto__`` is a document like any other): ``docs`` (name, frames at 30 Hz, data
    file and place, rig, note), ``rows`` (the annotation: document index, 1-based start and
    end, label index, confidence, cost; by document and start), ``truth`` (the same
    without scores, or None), ``labels`` and their ``colours``, the ``rigs`` (bones as
    joint index pairs, sides), ``curves`` (classes, τ per class) and the data files."""
    index = {d: i for i, d in enumerate(docs)}
    labels = sorted(colours)
    li = {lab: i for i, lab in enumerate(labels)}

    def num(x):
        return None if x is None or x != x or x in (float("inf"), float("-inf")) else \
            round(float(x), 4)

    ordered = sorted(rows, key=lambda a: (index[a.doc], a.start, a.end, li[a.label]))
    data = {
        "title": title, "fps": 30, "labels": labels, "colours": [colours[x] for x in labels],
        "docs": {"name": list(docs), "frames": [int(frames[d]) for d in docs],
                 "chunk": [where.get(d, (-1, 0))[0] for d in docs],
                 "slot": [where.get(d, (-1, 0))[1] for d in docs],
                 "rig": [rigs.get(d, -1) for d in docs],
                 "note": [notes.get(d, "") for d in docs]},
        "rows": {"doc": [index[a.doc] for a in ordered], "start": [a.start + 1 for a in ordered],
                 "end": [a.end + 1 for a in ordered], "label": [li[a.label] for a in ordered],
                 "conf": [num(a.confidence) for a in ordered],
                 "cost": [num(a.cost) for a in ordered]},
        "truth": None, "rigs": list(rig_list), "chunks": list(chunks), "folder": DATA_FOLDER,
        "quantum": 1e-3, "curves": curves}
    if truth is not None:
        segs = sorted((s for s in truth if s.doc in index),
                      key=lambda s: (index[s.doc], s.start, s.end))
        data["truth"] = {"doc": [index[s.doc] for s in segs], "start": [s.start for s in segs],
                         "end": [s.end for s in segs], "label": [li[s.label] for s in segs]}
    return data


def _archive_html() -> str:
    """The archive view's fixed markup (the script fills it)."""
    return """<section id="archive"><h2>Archive</h2>
<div class="bar">
<input id="mtanno-filter" type="search" spellcheck="false" aria-label="filter documents"
 placeholder="filter: part of a name or label; label:NAME  doc:TEXT  label:none">
<label>confidence <input id="mtanno-conf-min" type="number" min="0" max="1" step="0.05"
 value="0"> to <input id="mtanno-conf-max" type="number" min="0" max="1" step="0.05"
 value="1"></label>
<label>sort <select id="mtanno-sort"><option value="conf">least confident first</option>
<option value="long">longest first</option><option value="name">by name</option></select>
</label> <span id="mtanno-shown"></span></div>
<div id="mtanno-counts" class="counts"></div>
<div class="archive">
<div id="mtanno-list" class="list" role="listbox" tabindex="0" aria-label="documents"
 data-mtanno-count="0"><div class="spacer"></div></div>
<aside class="side">
<div class="player" data-mtanno-player data-doc="" data-frames="0" data-frame="1"
 data-state="empty">
<div class="head"><b class="name">no document selected</b> <span class="len"></span></div>
<p class="note"></p>
<canvas class="figure" width="400" height="280"></canvas>
<canvas class="timeline" width="400" height="30"></canvas>
<canvas class="curves" width="400" height="90" hidden></canvas>
<div class="controls"><button type="button" class="back" title="one frame back (←)">◀</button>
<button type="button" class="play" title="play or pause (space)">play</button>
<button type="button" class="fwd" title="one frame on (→)">▶</button>
<label>speed <select class="speed"><option>0.25</option><option>0.5</option>
<option selected>1</option><option>2</option><option>4</option></select></label></div>
<div class="where"></div></div>
<div class="review"><table id="mtanno-rows"></table>
<p class="keys">Keys: <kbd>j</kbd>/<kbd>k</kbd> next/previous row, <kbd>J</kbd>/<kbd>K</kbd>
next/previous document, <kbd>a</kbd> accept, <kbd>x</kbd> reject, <kbd>u</kbd> undecided,
<kbd>l</kbd> relabel, <kbd>space</kbd> play the row, <kbd>←</kbd>/<kbd>→</kbd> a frame,
<kbd>/</kbd> filter.</p>
<p><button type="button" id="download-truth">Download truth</button>
<span id="truth-count"></span> <span id="truth-refused" class="warn"></span></p>
<p>Accept the undecided rows shown with confidence ≥ <input id="mtanno-accept-p"
 type="number" min="0" max="1" step="0.05" value="0.9"> <button type="button"
 id="mtanno-accept-above">accept</button> <button type="button" id="mtanno-forget">forget
 the decisions</button></p></div>
</aside></div>
<noscript><p>The archive view needs JavaScript; <code>review.csv</code> beside this page
holds the same rows.</p></noscript></section>"""


def _resource(name: str) -> str:
    return (resources.files("mtanno.evaluation") / name).read_text(encoding="utf-8")


def page_html(*, title: str, summary: str, notes: Sequence[str],
              sections: Sequence[tuple[str, str, str]], data: dict) -> str:
    """The page: title, a summary line (HTML), the notes (text; ```code``` shown as code), a
    table of contents, the archive view, then ``sections`` (anchor, heading, HTML), the
    data and the scripts."""
    toc = [("archive", "Archive and review")] + [(a, h) for a, h, _ in sections]
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             f"<meta name='viewport' content='width=device-width'>"
             f"<title>{html.escape(title)}</title><style>{_resource('page.css')}</style>"
             f"</head><body><header><h1>{html.escape(title)}</h1><p>{summary}</p>",
             "<nav class='toc'>" + " · ".join(
                 f"<a href='#{a}'>{html.escape(h)}</a>" for a, h in toc) + "</nav>"]
    for note in notes:  # `command` in a note is code on the page, not a backtick
        text = re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(note))
        parts.append(f"<p class='note'><b>Note:</b> {text}</p>")
    parts += ["</header>", _archive_html()]
    for anchor, heading, body in sections:
        parts.append(f"<section id='{anchor}'><h2>{html.escape(heading)} "
                     f"<a class='up' href='#archive'>↑</a></h2>{body}</section>")
    parts.append(f"<script type='application/json' id='mtanno-data'>{json_for_script(data)}"
                 "</script>")
    script = "\n".join(_resource(s) for s in SCRIPTS)
    if re.search(r"<!--|<script|</script", script, re.I):  # would end or change the element
        raise MtannoError("the page's script holds HTML markup (a bug in mtanno)")
    parts.append(f"<script>\n{script}</script>")
    parts.append("</body></html>\n")
    return "\n".join(parts)


def figure_html(png: str, caption: str) -> str:
    """A figure of the folder (PNG beside the page, loaded when scrolled to)."""
    return (f"<figure><img loading='lazy' alt='{html.escape(caption)}' "
            f"src='{html.escape(quote(png))}'><figcaption>{html.escape(caption)}"
            "</figcaption></figure>")


class Figures:
    """Writes the report's figures (PNG and SVG, :data:`FORMATS`) into ``folder`` and
    remembers them for the page; a figure whose inputs (hashed with the versions of mtanno
    and matplotlib) are those ``figures.json`` records, with both files there, is not drawn
    again. ``result`` (a :class:`~mtanno.evaluation.report.ReportResult`) lists the files
    and counts the figures drawn; ``progress()`` is called after each figure."""

    def __init__(self, folder: Path, result, progress: Callable[[], None] | None = None):
        self.folder, self.result, self.progress = folder, result, progress
        self.items: list[tuple[str, str, str]] = []  # section, caption, PNG name
        self.keys: dict[str, str] = {}
        try:
            old = json.loads((folder / "figures.json").read_text(encoding="utf-8"))
            self.old = {str(k): str(v) for k, v in old["figures"].items()}
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            self.old = {}

    def figure(self, draw: Callable, stem: str, section: str, caption: str, *inputs) -> None:
        """``draw()`` → Axes, called only when ``inputs`` differ from the last run's."""
        import matplotlib

        from mtanno._version import __version__
        from mtanno.plot import save_figure

        h = hashlib.sha256(f"{__version__}\0{matplotlib.__version__}\0{stem}".encode())
        for x in inputs:
            if isinstance(x, np.ndarray):
                h.update(f"{x.dtype}{x.shape}".encode())
                h.update(np.ascontiguousarray(x).tobytes())
            else:
                h.update(repr(x).encode("utf-8", "surrogatepass"))
            h.update(b"\0")
        key = h.hexdigest()
        paths = [self.folder / f"{stem}.{fmt}" for fmt in FORMATS]
        if self.old.get(stem) != key or not all(p.is_file() for p in paths):
            ax = draw()
            for p in paths:
                save_figure(ax, p)
            self.result.figures_drawn += 1
        self.keys[stem] = key
        self.result.files += paths
        self.items.append((section, caption, f"{stem}.png"))
        if self.progress is not None:
            self.progress()

    def close(self) -> None:
        from mtanno.util.output import write_text

        write_text(self.folder / "figures.json", json.dumps(
            {"schema": "mtanno.report-figures/1", "figures": self.keys}, indent=1) + "\n")
        self.result.files.append(self.folder / "figures.json")

    def html(self, section: str) -> str:
        return "".join(figure_html(png, caption) for s, caption, png in self.items
                       if s == section)


def pose_entries(poses, docs, recorded, last, frames, sources, result, step):
    """Per document with poses its encoded poses (the first entry of its data), its rig's
    index and the rigs (bones, sides); a motion that is not the annotated one is left out
    and said (``result.motion_notes``)."""
    from mtanno.evaluation.player import (
        EncodedPoses,
        PlayerPoses,
        canonical_player_poses,
        motion_mismatch,
    )

    entries: dict[str, list[str]] = {}
    rigs: dict[str, int] = {}
    rig_list: list[dict] = []
    seen: dict[tuple, int] = {}
    for d in docs:
        step()
        P = (poses or {}).get(d)
        if P is None:
            continue
        pp = P if isinstance(P, (PlayerPoses, EncodedPoses)) else canonical_player_poses(P)
        why = motion_mismatch(d, pp.frames, recorded=recorded.get(d), last_labelled=last[d],
                              path=sources.get(d, d))
        if why is not None:
            result.motion_notes[d] = why
            continue
        frames[d] = max(frames[d], pp.frames)
        key = (tuple(pp.bones), pp.sides)
        if key not in seen:
            seen[key] = len(rig_list)
            rig_list.append({"joints": len(pp.sides), "bones": [list(b) for b in pp.bones],
                             "sides": pp.sides})
        rigs[d] = seen[key]
        entries[d] = [pp.text if isinstance(pp, EncodedPoses) else pp.encoded().text, ""]
    return entries, rigs, rig_list


def curve_entries(entries, templates, features, docs, tau, tau_per_class, delta) -> dict:
    """Each document's Δ curves of every class (the second entry of its data), with the
    templates quantized with ``delta`` as the annotation did (docs/method.md §3.4); the
    classes and their τ for the page."""
    from mtanno.annotate import class_deltas, class_models
    from mtanno.evaluation.player import encode_curves
    from mtanno.templates.params import ANNOTATION_DELTA, ANNOTATION_TAU

    models, _ = class_models(templates, delta=ANNOTATION_DELTA if delta is None else delta)
    tau = ANNOTATION_TAU if tau is None else tau
    for d in docs:
        if d in features:
            curves = np.array([c for c, _ in class_deltas(features[d], models)])
            entries.setdefault(d, ["", ""])[1] = encode_curves(curves)
    names = [m.name for m in models]
    return {"classes": names, "tau": [tau_per_class.get(n, tau) for n in names],
            "default": tau}
