#!/usr/bin/env python3
"""Are two runs' outputs the same? Compares every file below two folders (e.g. the
``out/demo`` of ``make demo`` at two commits: ``make demo OUT=out/before`` at the old
commit, ``make demo OUT=out/after`` at the new one), byte for byte except for what says
*when* and *with which version* a file was made:

* provenance timestamps (``"created"``) and version strings (``"mtanno_version"``,
  ``extractor_version``), in JSON sidecars, Parquet metadata, TOML and HTML headers;
* the command line recorded in provenance, where it names the output folder (``out/before``
  vs ``out/after``): the folder names are replaced by one placeholder before comparing;
* SHA-256 digests (a file's provenance records the digests of inputs that carry their own
  timestamps), the random clip-path and marker ids matplotlib writes into SVG files, and
  the folder the package is installed in (a skeleton map's recorded path).

Parquet files are compared by their data (every column, every row) and their metadata
after the same normalisation; PNG/SVG figures by bytes (matplotlib writes a creation date
into SVG and PNG metadata; those lines are normalised too). Prints one line per file that
differs and a summary; exits 1 when any file differs or is missing on one side.

Usage: ``python scripts/same_outputs.py out/before/demo out/after/demo``
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

_STAMP = re.compile(rb'("created"\s*:\s*)"[^"]*"|(\bcreated: )[0-9T:+.-]+'
                    rb'|("mtanno_version"\s*:\s*)"[^"]*"'
                    rb'|("extractor_version"\s*:\s*)"[^"]*"'
                    rb'|(<dc:date>)[^<]*(</dc:date>)|(CreationDate\s*\(?)[^)\n]*'
                    rb'|(mtanno )\d+\.\d+\.\d+[^\s"<,]*|(Date: )[^\n]*'
                    rb'|(\b)[0-9a-f]{64}\b|(#|id=")(?:[mp]|image)[0-9a-f]{10}\b'
                    rb'|()(?<![\w./-])[\w./-]+(/mtanno/skeletons/)')


def _norm(data: bytes, roots: tuple[bytes, bytes]) -> bytes:
    for r in roots:
        data = data.replace(r, b"<ROOT>")
    return _STAMP.sub(lambda m: b"".join(g for g in m.groups() if g) + b"<X>", data)


def _parquet(path: Path, roots) -> bytes:
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    meta = {k: _norm(v, roots) for k, v in (table.schema.metadata or {}).items()}
    rows = json.dumps(table.replace_schema_metadata(None).to_pylist(), sort_keys=True,
                      default=str).encode()
    return rows + b"\n" + json.dumps({k.decode(): v.decode("utf-8", "replace")
                                      for k, v in sorted(meta.items())}).encode()


_PNG = re.compile(rb"data:image/png;base64,([A-Za-z0-9+/=\s]+)")


def _pixels(m: re.Match) -> bytes:
    """An image embedded in an SVG file by its pixels (the PNG's own bytes vary from run
    to run while the picture does not)."""
    import base64
    import hashlib
    import io

    from matplotlib.image import imread

    data = imread(io.BytesIO(base64.b64decode(b"".join(m.group(1).split()))), format="png")
    return b"data:image/png;pixels=" + hashlib.sha256(data.tobytes()).hexdigest().encode()


def _content(path: Path, roots) -> bytes:
    if path.suffix == ".parquet":
        return _parquet(path, roots)
    data = path.read_bytes()
    if path.suffix in (".svg", ".html"):
        data = _PNG.sub(_pixels, data)
    return _norm(data, roots)


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    a, b = (Path(x) for x in argv)
    roots = (str(a).encode(), str(b).encode())
    fa = {p.relative_to(a) for p in a.rglob("*") if p.is_file() and not p.name.startswith(".")}
    fb = {p.relative_to(b) for p in b.rglob("*") if p.is_file() and not p.name.startswith(".")}
    bad = 0
    for rel in sorted(fa ^ fb):
        print(f"only in {'the first' if rel in fa else 'the second'}: {rel}")
        bad += 1
    same = 0
    for rel in sorted(fa & fb):
        if _content(a / rel, roots) == _content(b / rel, roots):
            same += 1
        else:
            print(f"differs: {rel}")
            bad += 1
    print(f"{same} files the same, {bad} differ or missing ({a} vs {b})")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
