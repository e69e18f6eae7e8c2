"""The tables of ``mtanno report`` as text: per-class rows of
:meth:`mtanno.evaluation.metrics.Report.rows` as Markdown and LaTeX (for papers), any rows
as Markdown and as an HTML table (for the page); "–" where a value is undefined."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence

from mtanno.evaluation.metrics import SEGMENTATION_COLUMNS


def _number(x: float | None) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:.3f}"


def _cells(r: dict) -> list[str]:
    """The cells of a :meth:`Report.rows` row after its class, "–" where undefined."""
    return [_number(r["P1"]), _number(r["R1"]), _number(r["F1"]), str(r["frames"]),
            _number(r["P2"]), _number(r["R2"]), _number(r["F2"]), str(r["segments"]),
            *(_number(r.get(c)) for c in SEGMENTATION_COLUMNS)]


def markdown_table(rows: Sequence[dict]) -> str:
    """Per-class rows of :meth:`Report.rows` as a Markdown (GitHub) table."""
    head = ("| class | P1 | R1 | F1 | frames | P2 | R2 | F2 | segments | "
            + " | ".join(SEGMENTATION_COLUMNS) + " |")
    lines = [head, "|---|" + "---:|" * (8 + len(SEGMENTATION_COLUMNS))]
    for r in rows:
        lines.append(f"| {r['class']} | " + " | ".join(_cells(r)) + " |")
    return "\n".join(lines) + "\n"


def plain_markdown(rows: Sequence[dict]) -> str:
    """Rows of any columns (the first row's) as a Markdown table; numbers as they are,
    missing values "–"."""
    cols = list(rows[0]) if rows else []
    lines = ["| " + " | ".join(cols) + " |", "|---|" + "---:|" * (len(cols) - 1)]
    for r in rows:
        lines.append("| " + " | ".join("–" if r[c] is None else str(r[c]) for c in cols) + " |")
    return "\n".join(lines) + "\n"


def _tex(text: str) -> str:
    """Text with LaTeX's special characters escaped."""
    text = text.replace("\\", "\0")
    for a, b in (("_", r"\_"), ("&", r"\&"), ("%", r"\%"), ("#", r"\#"), ("$", r"\$"),
                 ("{", r"\{"), ("}", r"\}")):
        text = text.replace(a, b)
    return text.replace("\0", r"\textbackslash{}")


def latex_table(rows: Sequence[dict]) -> str:
    """Per-class rows as a LaTeX ``tabular`` (booktabs rules), the overall row last."""
    lines = [r"\begin{tabular}{l" + "r" * (8 + len(SEGMENTATION_COLUMNS)) + "}", r"\toprule",
             r"class & $P_1$ & $R_1$ & $F_1$ & frames & $P_2$ & $R_2$ & $F_2$ & segments & "
             r"Acc & Edit & F1@10 & F1@25 & F1@50 \\",
             r"\midrule"]
    for r in rows:
        if r["class"] == "overall":
            lines.append(r"\midrule")
        lines.append(" & ".join([_tex(str(r["class"])), *_cells(r)]) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines) + "\n"




def html_table(rows: Sequence[dict]) -> str:
    cols = list(rows[0]) if rows else []
    out = ["<table class='scores'><tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in cols)
           + "</tr>"]
    for r in rows:
        cells = []
        for c in cols:
            v = r[c]
            text = _number(v) if v is None or isinstance(v, float) else html.escape(str(v))
            cells.append(f"<td>{text}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out) + "</table>"
