"""The one exception type of mtanno.

Every error a user can cause (bad input file, unknown option value, missing joint in a
skeleton map) is raised as :class:`MtannoError`. Its string form is one line,
``path:line: what is wrong`` when a file position is known, so the command line prints it
as it is and never shows a traceback for user error.
"""

from __future__ import annotations

import json
import os
import re
import sys


class MtannoError(Exception):
    """An error caused by input a user can fix.

    Parameters
    ----------
    message:
        What is wrong, as one sentence without a trailing period. With ``options``, the
        names of the caller's parameters it speaks of are written ``{name}``: the message
        then reads ``name=`` from Python and ``--name`` on the command line
        (:meth:`for_command`), so the API never speaks in flags.
    path:
        The file the error is about, if any.
    line:
        The 1-based line number in ``path``, if known.
    options:
        The parameter names the message names as ``{name}``.
    """

    def __init__(self, message: str, *, path: str | None = None, line: int | None = None,
                 options: tuple[str, ...] = ()):
        self.template = message
        self.options = tuple(options)
        self.message = self._render({o: f"{o}=" for o in self.options})
        self.path = None if path is None else str(path)
        self.line = line
        super().__init__(str(self))

    def __reduce__(self):
        # sent between processes whole (a batch's worker reports it to the command, which
        # names the options as flags)
        return (_rebuild, (type(self), self.template, self.path, self.line, self.options,
                           self.__dict__))

    def _render(self, names: dict[str, str]) -> str:
        out = self.template
        for name, text in names.items():  # (not str.format: other braces stay as they are)
            out = out.replace("{" + name + "}", text)
        return out

    def for_command(self, flags: dict[str, str] | None = None) -> str:
        """The one-line message as the command line shows it: each option as its flag
        (``flags[name]``, else ``--name`` with dashes for underscores)."""
        names = {o: (flags or {}).get(o, "--" + o.replace("_", "-")) for o in self.options}
        message = self._render(names)
        if self.path is None:
            return message
        return f"{self.path}: {message}" if self.line is None else \
            f"{self.path}:{self.line}: {message}"

    def __str__(self) -> str:
        if self.path is None:
            return self.message
        if self.line is None:
            return f"{self.path}: {self.message}"
        return f"{self.path}:{self.line}: {self.message}"


def _rebuild(cls, template, path, line, options, state):
    exc = cls.__new__(cls)
    MtannoError.__init__(exc, template, path=path, line=line, options=options)
    exc.__dict__.update(state)
    return exc


def interrupted_line(name: str) -> str:
    """The one line of a command interrupted by signal ``name`` (``SIGINT`` …), wherever the
    interruption lands (:mod:`mtanno.__main__`, :mod:`mtanno.cli`)."""
    return (f"mtanno: interrupted ({name}); finished outputs are complete, unfinished ones "
            "were not written")


def _kind(mode: int) -> str:
    import stat

    return ("a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else
            "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")


class NotRegularFile(OSError):
    """What :func:`open_regular` refuses to read: a FIFO, a device, a socket."""


def open_regular(path: str | os.PathLike):
    """A regular file opened for reading (binary), the one way mtanno opens a file it
    reads; anything else is refused before a byte is read: a FIFO (opening one waits for a
    writer, reading it for the writer's end), a device (``/dev/zero`` never ends), a
    socket (:class:`NotRegularFile`), a folder (:class:`IsADirectoryError`). The file is
    opened without waiting (``O_NONBLOCK``, so a FIFO cannot hold the open) and checked
    with ``fstat`` on the descriptor (what was opened, not what the name pointed to a
    moment before). Errors are :class:`OSError` (for callers that treat an unreadable file
    as absent); :func:`open_input` makes them one :class:`MtannoError`."""
    import errno
    import stat

    nonblock = getattr(os, "O_NONBLOCK", 0)
    # io.open (a binary read, as audit hooks see it) with a descriptor opened not to wait
    fh = open(path, "rb", opener=lambda p, flags: os.open(p, flags | nonblock))
    try:
        mode = os.fstat(fh.fileno()).st_mode
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
        if not stat.S_ISREG(mode):
            raise NotRegularFile(errno.EINVAL, f"not a regular file ({_kind(mode)}): not read",
                                 str(path))
        if nonblock:
            os.set_blocking(fh.fileno(), True)
        return fh
    except BaseException:
        fh.close()
        raise


def open_input(path: str | os.PathLike, *, what: str = "file"):
    """:func:`open_regular`, its refusals one :class:`MtannoError` naming the file
    (``what`` names the kind of file): missing, unreadable, a folder, or not a regular
    file (a FIFO, a device: "is not a regular file (a FIFO): not read")."""
    try:
        return open_regular(path)
    except FileNotFoundError:
        raise MtannoError(f"{what} not found", path=str(path)) from None
    except NotRegularFile as exc:
        raise MtannoError(f"{what} is {exc.strerror}", path=str(path)) from None
    except OSError as exc:
        raise MtannoError(f"cannot read {what}: {exc.strerror or exc}", path=str(path)) from None


def read_input(path: str | os.PathLike, *, what: str = "file") -> bytes:
    """The bytes of an input file (:func:`open_input`: a regular file, never a FIFO or a
    device); a missing or unreadable file is a :class:`MtannoError` naming it (``what``
    names the kind of file in the message)."""
    with open_input(path, what=what) as fh:
        try:
            return fh.read()
        except OSError as exc:
            raise MtannoError(f"cannot read {what}: {exc.strerror or exc}",
                              path=str(path)) from None


def read_text_input(path: str | os.PathLike, *, what: str = "file") -> bytes:
    """:func:`read_input` for a text format: also rejects an empty file and one with a NUL
    byte (binary), naming the line."""
    raw = read_input(path, what=what)
    if not raw or raw.isspace():  # (as ``not raw.strip()``, without copying the bytes)
        raise MtannoError("file is empty", path=str(path), line=1)
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise MtannoError("binary data (NUL byte) in a text file", path=str(path),
                          line=raw[:nul].count(b"\n") + 1)
    return raw


# --------------------------------------------------------------------------- TOML files


def read_toml(path: str | os.PathLike, *, what: str = "file") -> tuple[dict, str]:
    """(value, text) of a TOML file (skeleton maps, class configurations), read as
    :func:`read_input` reads (a regular file) and parsed so that any input is one
    :class:`MtannoError` naming the file: not UTF-8, malformed (tomllib's message, with its
    line), or nested so deeply that the parser, which recurses, cannot follow (arrays or
    inline tables thousands deep: "nested too deeply", never a RecursionError)."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib

    spath = str(path)
    raw = read_input(path, what=what)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise MtannoError(f"not a valid TOML {what}: not UTF-8 text", path=spath) from None
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as exc:
        raise MtannoError(f"not a valid TOML {what}: {exc}", path=spath) from None
    except RecursionError:  # tomllib recurses once per level of nesting
        raise MtannoError(f"not a valid TOML {what}: nested too deeply (arrays or tables "
                          "inside each other thousands of levels deep)", path=spath) from None


# --------------------------------------------------------------------------- JSON files

#: Deepest nesting of arrays and objects accepted in a JSON file mtanno reads. Its own
#: files nest a few levels; Python's parser (and any recursive walk of the result) fails
#: with RecursionError near a thousand, so deeper input is refused before parsing.
MAX_JSON_DEPTH = 100
#: Largest JSON file read (bytes). An index manifest of a large archive or a provenance
#: sidecar listing every input is a few megabytes; parsing a gigabyte would need many.
MAX_JSON_BYTES = 256 << 20

# a JSON string (closed or not), or one bracket: brackets inside strings are skipped
_JSON_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"?|[][{}]', re.DOTALL)
# a \uXXXX escape of a UTF-16 surrogate: only valid as a high-low pair
_SURROGATE = re.compile(r"(?<!\\)((?:\\\\)*)\\u[dD]([89abAB]|[c-fC-F])[0-9a-fA-F]{2}")


class JSONError(MtannoError):
    """A file that is not well-formed JSON (syntax, encoding, nesting, size): raised by
    :func:`parse_json` and :func:`read_json`, so a reader can give it its own wording (an
    index manifest is a corrupt index)."""


def _nesting_at(text: str) -> int | None:
    """Offset of the first bracket nested deeper than :data:`MAX_JSON_DEPTH` in ``text``
    (brackets inside strings do not count), else None. A loop over tokens, not a
    recursion, so any depth is measured."""
    if text.count("[") + text.count("{") <= MAX_JSON_DEPTH:  # cannot be deeper
        return None
    depth = 0
    for m in _JSON_TOKEN.finditer(text):
        c = text[m.start()]
        if c == "[" or c == "{":
            depth += 1
            if depth > MAX_JSON_DEPTH:
                return m.start()
        elif c == "]" or c == "}":
            depth -= 1
    return None


def _lone_surrogate_at(text: str) -> int | None:
    """Offset of a ``\\uXXXX`` escape of a UTF-16 surrogate that is not part of a high-low
    pair, else None: JSON decodes it to a string no file or terminal can take. Low
    surrogates U+DC80 … U+DCFF are allowed alone: they are how a path's bytes that are not
    UTF-8 are written (:func:`mtanno.util.tables.dumps`, ``surrogateescape``)."""
    if "\\u" not in text:
        return None
    pending = None  # end offset of an unpaired high surrogate escape
    for m in _SURROGATE.finditer(text):
        start = m.start() + len(m.group(1))
        high = m.group(2) in "89abAB"
        if pending is not None:
            if not high and start == pending:  # the low half of a pair
                pending = None
                continue
            return pending - 6
        if not high:
            if 0xDC80 <= int(text[start + 2:start + 6], 16) <= 0xDCFF:
                continue  # a byte of a file name that is not UTF-8 (os.fsdecode's escape)
            return start
        pending = m.end()
    return pending - 6 if pending is not None else None


def _line_col(text: str, pos: int) -> tuple[int, int]:
    line = text.count("\n", 0, pos) + 1
    return line, pos - (text.rfind("\n", 0, pos) + 1) + 1


def parse_json(data: str | bytes, *, path: str | os.PathLike | None = None,
               line: int | None = None):
    """The value of JSON text (bytes are UTF-8, a leading BOM allowed), checked before and
    while parsing so that any input is one :class:`JSONError` naming ``path`` (and the line,
    offset by ``line`` for text that starts there): not UTF-8, empty, nested deeper than
    :data:`MAX_JSON_DEPTH`, malformed, a number too long to convert, or a lone UTF-16
    surrogate escape. The one JSON parser of every mtanno file (templates, keyframe and
    index queries, index manifests, provenance, feature-file metadata, mocap6 labels)."""
    spath = None if path is None else str(path)
    first = 1 if line is None else line

    def bad(msg: str, at: int | None = None, text: str = "") -> JSONError:
        if at is None:
            return JSONError(msg, path=spath, line=line)
        ln, col = _line_col(text, at)
        return JSONError(f"{msg} (column {col})", path=spath, line=first + ln - 1)

    if isinstance(data, (bytes, bytearray, memoryview)):
        try:
            text = bytes(data).decode("utf-8-sig")
        except UnicodeDecodeError:
            raise bad("not a UTF-8 text file") from None
    else:
        text = data[1:] if data.startswith("\ufeff") else data
    if not text or text.isspace():
        raise JSONError("malformed JSON: the file is empty", path=spath, line=first)
    at = _nesting_at(text)
    if at is not None:
        raise bad(f"malformed JSON: nested too deeply (more than {MAX_JSON_DEPTH} levels of "
                  "arrays and objects)", at, text)
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise JSONError(f"malformed JSON: {exc.msg} (column {exc.colno})", path=spath,
                        line=first + exc.lineno - 1) from None
    except RecursionError:  # (the scan above makes this unreachable; kept as a guard)
        raise bad("malformed JSON: nested too deeply") from None
    except ValueError:  # an integer of thousands of digits
        raise bad("malformed JSON: a number too long to convert") from None
    at = _lone_surrogate_at(text)
    if at is not None:
        raise bad("malformed JSON: a \\u escape of half a UTF-16 surrogate pair", at, text)
    return value


def read_json(path: str | os.PathLike, *, what: str = "file",
              max_bytes: int = MAX_JSON_BYTES) -> tuple[object, str]:
    """(value, text) of a JSON file (:func:`parse_json`; the text for line numbers in a
    caller's messages). A missing or unreadable file, one that is not a regular file (a
    FIFO would block) or one larger than ``max_bytes`` is one :class:`MtannoError` naming
    it (``what`` names the kind of file)."""
    import stat

    spath = str(path)
    try:
        st = os.stat(path)
    except OSError:
        st = None  # read_input says what is wrong
    if st is not None and not stat.S_ISREG(st.st_mode) and not stat.S_ISDIR(st.st_mode):
        raise JSONError(f"{what} is not a regular file", path=spath)
    if st is not None and st.st_size > max_bytes:
        raise JSONError(f"{what} is too large ({st.st_size} bytes; at most {max_bytes} for "
                        "a JSON file)", path=spath)
    raw = read_input(path, what=what)
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise JSONError("binary data (NUL byte) in a text file", path=spath,
                        line=raw[:nul].count(b"\n") + 1)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise JSONError("not a UTF-8 text file", path=spath) from None
    return parse_json(text, path=spath), text
