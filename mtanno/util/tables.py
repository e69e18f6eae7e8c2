"""Tables in and out: the one I/O convention of every command (``docs/formats.md``).

Hit tables (``retrieve``, ``query``), annotation tables (``annotate``), truth tables
(``truth``, ``compose``), evaluation tables (``evaluate``, ``evaluate-retrieval``) and
index tables (``index info``) are all written by :func:`write_table` and read by
:func:`read_table`:

* the format follows the file name's suffix: ``.csv``, ``.parquet`` or ``.jsonl`` (JSON
  Lines); any other suffix is an error; ``-`` is standard output (CSV) when writing and
  standard input (CSV) when reading; an existing FIFO or device is written as CSV;
* CSV is UTF-8 with a header line, commas, ``\\n`` line ends, and quotes only where a
  value needs them (a comma, quote or line break inside); numbers are written in their
  shortest exact form; a missing value is an empty field (``null`` in JSON Lines);
* every table file carries its provenance (:func:`mtanno.util.provenance.provenance`: mtanno version, command
  line, inputs with SHA-256, templates, τ, δ, feature set …): in the Parquet schema
  metadata under the key ``mtanno``, and for CSV and JSON Lines in a JSON sidecar
  ``FILE.meta.json`` beside ``FILE`` (``hits.csv`` → ``hits.csv.meta.json``), so the table
  itself stays a plain table any tool reads. Standard output carries none.

Files are written atomically (:func:`mtanno.util.output.atomic_path`).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa

from mtanno.errors import JSONError, MtannoError, open_regular, parse_json, read_input, read_json
from mtanno.util.output import SIDECAR_SUFFIX, atomic_path, write_stdout

__all__ = ["FORMATS", "Table", "arrow_table", "dumps", "json_compact", "json_list_lines",
           "json_object_lines", "output_files", "parse_float", "parse_int", "parse_text",
           "provenance_as_read", "read_provenance", "read_table", "sidecar_path",
           "string_array", "table_format", "table_provenance", "text", "write_json",
           "write_table"]

#: Table formats by file suffix.
FORMATS = {".csv": "csv", ".parquet": "parquet", ".jsonl": "jsonl"}
_META_KEY = b"mtanno"

def table_format(path: str | os.PathLike) -> str:
    """``"csv"``, ``"parquet"`` or ``"jsonl"`` for a table file name (``-``: CSV); any other
    suffix is an :class:`MtannoError`."""
    if str(path) == "-":
        return "csv"
    p = Path(path)
    if p.exists() and not p.is_file() and not p.is_dir():
        return "csv"  # a FIFO or a device (/dev/stdout): written in place, as CSV
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise MtannoError(f"unknown table format {suffix or '(no suffix)'!r}: name the file "
                          f".csv, .parquet or .jsonl, or - for standard output",
                          path=str(path))
    return FORMATS[suffix]


def sidecar_path(path: str | os.PathLike) -> Path | None:
    """The provenance sidecar of a CSV or JSON Lines table file (None for Parquet and -)."""
    if str(path) == "-" or table_format(path) == "parquet":
        return None
    return Path(str(path) + SIDECAR_SUFFIX)


def output_files(path: str | os.PathLike | None) -> list[str]:
    """Every file that writing the table ``path`` creates (the table and its sidecar), for
    :func:`mtanno.util.preflight.check_outputs`."""
    if path is None or str(path) == "-":
        return []
    side = sidecar_path(path)
    return [str(path)] + ([str(side)] if side is not None else [])


# --------------------------------------------------------------------------- writing


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("" if math.isnan(value) else
                                                          ("inf" if value > 0 else "-inf"))
    return str(value)


def _json_value(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _write_csv(table: pa.Table, fh) -> None:
    w = csv.writer(fh, lineterminator="\n", quoting=csv.QUOTE_MINIMAL)
    w.writerow(table.column_names)
    cols = [table.column(i).to_pylist() for i in range(table.num_columns)]
    for row in zip(*cols):
        w.writerow([_cell(v) for v in row])


def _write_jsonl(table: pa.Table, fh) -> None:
    names = table.column_names
    cols = [table.column(i).to_pylist() for i in range(table.num_columns)]
    for row in zip(*cols):
        fh.write(dumps({n: _json_value(v) for n, v in zip(names, row)}, allow_nan=False)
                 + "\n")


# A lone surrogate: how Python holds the bytes of a file name that are not UTF-8
# (os.fsdecode's surrogateescape). No UTF-8 writer takes one.
_SURROGATE = re.compile("[\ud800-\udfff]")


def _byte_escape(m: re.Match) -> str:
    code = ord(m.group())
    return f"\\x{code - 0xDC00:02x}" if 0xDC80 <= code <= 0xDCFF else f"\\u{code:04x}"


def text(value: str) -> str:
    """``value`` as text a UTF-8 table can hold: each byte of a file name that is not
    UTF-8 (a lone surrogate, as :func:`os.fsdecode` decodes it) written as ``\\xNN``, so
    ``caf\\xe9`` names the document of the file ``caf<0xE9>.parquet`` and two such names
    stay apart. Any other text is returned as it is."""
    return _SURROGATE.sub(_byte_escape, value) if _SURROGATE.search(value) else value


def string_array(values: Sequence[str | None]) -> pa.Array:
    """A string column of ``values`` (None: null), made of :func:`text` where a value holds
    the bytes of a non-UTF-8 file name (pyarrow refuses them)."""
    try:
        return pa.array(values, pa.string())
    except UnicodeEncodeError:
        return pa.array([None if v is None else text(str(v)) for v in values], pa.string())


def arrow_table(columns: dict[str, Sequence], types: dict[str, pa.DataType], *,
                default: pa.DataType | None = None) -> pa.Table:
    """A :class:`pyarrow.Table` of ``columns`` (name → values), each of the type ``types``
    gives it (else ``default``, int64); string columns through :func:`string_array`. The
    table builders of the commands (hits, annotations) use it, so a document named after
    a non-UTF-8 file name is written, not a traceback."""
    default = pa.int64() if default is None else default
    return pa.table({c: string_array(v) if types.get(c, default) == pa.string()
                     else pa.array(v, type=types.get(c, default)) for c, v in columns.items()})


def dumps(obj: Any, **kwargs: Any) -> str:
    """JSON text of ``obj`` (non-finite numbers as null), non-ASCII characters kept as
    they are, but a lone surrogate (a non-UTF-8 byte of a file name in a path) written as
    its ``\\uDCxx`` escape: valid UTF-8 that reads back as the same string, so
    :func:`os.fsencode` of a path read back gives the file's name again."""
    return _escape_surrogates(json.dumps(_clean(obj), ensure_ascii=False, **kwargs))


def _escape_surrogates(text: str) -> str:
    """JSON text with each lone surrogate as its ``\\uDCxx`` escape (:func:`dumps`)."""
    return _SURROGATE.sub(lambda m: f"\\u{ord(m.group()):04x}", text) \
        if _SURROGATE.search(text) else text


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Write a JSON document atomically (``-``: standard output); non-finite numbers are
    written as null, so every JSON reader accepts the file; file names that are not UTF-8
    are escaped (:func:`dumps`)."""
    from mtanno.util.output import write_text

    write_text(path, dumps(obj, indent=1) + "\n")


def json_compact(x: Any) -> str:
    """One value as compact JSON with non-ASCII characters kept, lone surrogates escaped as
    :func:`dumps` does (no other change: the value of one line of
    :func:`json_object_lines`)."""
    return _escape_surrogates(json.dumps(x, ensure_ascii=False))


def json_list_lines(items: Iterable[str], level: int = 1) -> str:
    """A JSON array of items already written as JSON text, one a line, for a file meant
    to be read and edited; ``level`` is how deep it stands (two spaces a level)."""
    pad = "  " * level
    return "[\n" + ",\n".join(pad + "  " + it for it in items) + "\n" + pad + "]"


def json_object_lines(d: Mapping[str, Any], layouts: Mapping[str, Callable[[Any], str]] | None
                      = None, level: int = 0) -> str:
    """A JSON object meant to be read and edited: one line per key, its value as
    :func:`json_compact`, or as the function ``layouts`` gives for its key writes it
    (such as :func:`json_list_lines`); ``level`` as there. The one layout of template,
    keyframe and provenance files."""
    layouts = layouts or {}
    pad = "  " * level
    lines = [f"{pad}  {json_compact(k)}: {layouts[k](v) if k in layouts else json_compact(v)}"
             for k, v in d.items()]
    return "{\n" + ",\n".join(lines) + "\n" + pad + "}"


def _clean(x: Any) -> Any:
    """``x`` with non-finite floats replaced by None (JSON has no NaN or ∞)."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return x


def write_table(path: str | os.PathLike, table: pa.Table, *,
                provenance: dict | None = None) -> None:
    """Write ``table`` to ``path`` in the format its suffix names (module docstring), with
    its provenance (Parquet metadata, or the ``FILE.meta.json`` sidecar); ``-`` writes CSV
    to standard output."""
    fmt = table_format(path)
    if str(path) == "-":
        buf = io.StringIO()
        _write_csv(table, buf)
        write_stdout(buf.getvalue())
        return
    if fmt == "parquet":
        import pyarrow.parquet as pq

        if provenance is not None:
            table = table.replace_schema_metadata(
                {_META_KEY: json.dumps(_clean(provenance), sort_keys=True)})
        # through a file object: pyarrow cannot open a path that is not UTF-8
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            pq.write_table(table, fh)
        return
    side = sidecar_path(path)
    if side is None or provenance is None or (Path(path).exists() and not Path(path).is_file()):
        with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
            (_write_csv if fmt == "csv" else _write_jsonl)(table, fh)
        return
    # the old sidecar goes before the new table is in place, the new one right after: an
    # interruption between the two leaves a table without provenance, never a wrong one
    with atomic_path(side) as stmp:
        stmp.write_text(dumps(provenance, indent=1) + "\n", encoding="utf-8")
        with atomic_path(path) as tmp:
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                (_write_csv if fmt == "csv" else _write_jsonl)(table, fh)
            side.unlink(missing_ok=True)


# --------------------------------------------------------------------------- reading


@dataclass
class Table:
    """A table read by :func:`read_table`: rows as dicts of column → value (strings for
    CSV; None for a missing value), with where each row came from."""

    path: str
    columns: list[str]
    rows: list[dict]
    lines: list[int | None] = field(default_factory=list)
    provenance: dict | None = None
    header_line: int | None = None

    def error(self, i: int, message: str) -> MtannoError:
        """An error about row ``i`` (0-based): ``path:line: message`` for CSV and JSON
        Lines, ``path: row N: message`` for Parquet."""
        line = self.lines[i] if i < len(self.lines) else None
        if line is None:
            return MtannoError(f"row {i + 1}: {message}", path=self.path)
        return MtannoError(message, path=self.path, line=line)

    def require(self, columns: Iterable[str]) -> None:
        """Every one of ``columns`` must be present."""
        need = list(columns)
        missing = [c for c in need if c not in self.columns]
        if missing:
            raise MtannoError(f"needs the columns {', '.join(need)} (missing "
                              f"{', '.join(missing)}; found {', '.join(self.columns) or 'none'})",
                              path=self.path, line=self.header_line)


def _text(raw: bytes, spath: str) -> str:
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise MtannoError("binary data (NUL byte) in a text file", path=spath,
                          line=raw[:nul].count(b"\n") + 1)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise MtannoError("not a UTF-8 text file", path=spath,
                          line=raw[:exc.start].count(b"\n") + 1) from None


def _read_csv(text: str, spath: str) -> Table:
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = next(reader, None)
        while header is not None and not any(h.strip() for h in header):
            header = next(reader, None)
        if header is None:
            raise MtannoError("file is empty (no header line)", path=spath, line=1)
        header = [h.strip() for h in header]
        hline = reader.line_num
        if len(set(header)) != len(header) or "" in header:
            raise MtannoError("header names a column twice or has an empty name",
                              path=spath, line=hline)
        rows, lines = [], []
        for rec in reader:
            if not rec or not any(c.strip() for c in rec):
                continue  # blank line
            if len(rec) != len(header):
                raise MtannoError(f"{len(rec)} fields, but the header has {len(header)}",
                                  path=spath, line=reader.line_num)
            rows.append({h: (v if v != "" else None) for h, v in zip(header, rec)})
            lines.append(reader.line_num)
    except csv.Error as exc:
        raise MtannoError(f"malformed CSV: {exc}", path=spath, line=reader.line_num) from None
    return Table(spath, header, rows, lines, header_line=hline)


def _read_jsonl(text: str, spath: str) -> Table:
    rows, lines, columns = [], [], []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        obj = parse_json(line, path=spath, line=n)
        if not isinstance(obj, dict):
            raise MtannoError("each line must be a JSON object", path=spath, line=n)
        for k in obj:
            if k not in columns:
                columns.append(k)
        rows.append(obj)
        lines.append(n)
    return Table(spath, columns, rows, lines)


def _read_parquet(raw: bytes, spath: str) -> Table:
    import pyarrow.parquet as pq

    try:
        t = pq.ParquetFile(pa.BufferReader(raw), pre_buffer=False).read(use_threads=False)
    except (pa.ArrowException, OSError, ValueError, IndexError) as exc:
        raise MtannoError(f"not a readable Parquet table ({exc})", path=spath) from None
    meta = (t.schema.metadata or {}).get(_META_KEY)
    prov = None
    if meta is not None:
        try:
            prov = parse_json(meta)
        except JSONError:
            prov = None
    try:
        rows = t.to_pylist()
    except (pa.ArrowException, ValueError) as exc:
        raise MtannoError(f"not a readable Parquet table ({exc})", path=spath) from None
    return Table(spath, list(t.column_names), rows, [None] * len(rows),
                 prov if isinstance(prov, dict) else None)


def read_provenance(path: str | os.PathLike) -> dict | None:
    """The provenance sidecar of a CSV or JSON Lines table, if there is a readable one."""
    side = sidecar_path(path)
    if side is None or not side.is_file():
        return None
    try:
        obj, _ = read_json(side, what="provenance sidecar")
    except MtannoError:
        return None
    return obj if isinstance(obj, dict) else None


def table_provenance(path: str | os.PathLike) -> dict | None:
    """The provenance a table file records (Parquet metadata, or the sidecar of a CSV or
    JSON Lines table) without reading its rows; None when it has no readable one."""
    if table_format(path) != "parquet":
        return read_provenance(path)
    import pyarrow.parquet as pq

    try:
        # a file object: pyarrow cannot open non-UTF-8 names (and a FIFO would block)
        with open_regular(path) as fh:
            raw = (pq.read_schema(fh).metadata or {}).get(_META_KEY)
        prov = parse_json(raw) if raw else None
    except (OSError, ValueError, TypeError, pa.ArrowException, JSONError):
        return None
    return prov if isinstance(prov, dict) else None


def provenance_as_read(prov: dict) -> dict:
    """``prov`` as a table file gives it back (JSON: tuples become lists, non-finite
    numbers null), to compare a run's provenance with a recorded one."""
    return json.loads(json.dumps(_clean(prov)))


def read_table(path: str | os.PathLike, *, what: str = "table") -> Table:
    """Read a table in the format its suffix names (``-``: CSV from standard input), with
    its provenance when it has one. A file that cannot be read as such a table is one
    :class:`MtannoError` naming it (and the line, where there is one)."""
    spath = str(path)
    fmt = table_format(path)
    if spath == "-":
        raw = sys.stdin.buffer.read() if hasattr(sys.stdin, "buffer") else \
            sys.stdin.read().encode("utf-8")
        spath = "<stdin>"
    else:
        raw = read_input(path, what=what)
    if fmt == "parquet":
        return _read_parquet(raw, spath)
    text = _text(raw, spath)
    if not text.strip():
        raise MtannoError(f"{what} is empty", path=spath, line=1)
    table = _read_csv(text, spath) if fmt == "csv" else _read_jsonl(text, spath)
    if spath != "<stdin>":
        table.provenance = read_provenance(path)
    return table


def parse_int(table: Table, i: int, column: str, *, minimum: int | None = None,
              maximum: int | None = None) -> int:
    """Row ``i``'s ``column`` as an integer (``"12"``, ``12`` or ``12.0``), in range."""
    value = table.rows[i].get(column)
    try:
        if isinstance(value, bool):
            raise ValueError
        if isinstance(value, str):
            value = value.strip()
            number = int(value) if value.lstrip("+-").isdigit() else float(value)
        else:
            number = value
        if isinstance(number, float):
            if not math.isfinite(number) or number != int(number):
                raise ValueError
            number = int(number)
        if not isinstance(number, int):
            raise ValueError
    except (TypeError, ValueError, OverflowError):
        raise table.error(i, f"{column} must be an integer, got {value!r}") from None
    if minimum is not None and number < minimum:
        raise table.error(i, f"{column} must be ≥ {minimum}, got {number}")
    if maximum is not None and number > maximum:
        raise table.error(i, f"{column} {number} is too large (at most {maximum})")
    return number


def parse_float(table: Table, i: int, column: str, *, default: float | None = None,
                positive: bool = False) -> float:
    """Row ``i``'s ``column`` as a finite number (``default`` when missing)."""
    value = table.rows[i].get(column)
    if value is None and default is not None:
        return default
    try:
        if isinstance(value, bool):
            raise ValueError
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise table.error(i, f"{column} must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise table.error(i, f"{column} must be a finite number, got {value!r}")
    if positive and number <= 0:
        raise table.error(i, f"{column} must be a positive number, got {value!r}")
    return number


def parse_text(table: Table, i: int, column: str) -> str:
    """Row ``i``'s ``column`` as a non-empty string."""
    value = table.rows[i].get(column)
    if value is None or (isinstance(value, str) and not value.strip()):
        raise table.error(i, f"empty {column}")
    return str(value).strip()
