"""Outputs checked against the inputs before any work (:func:`check_outputs`), so that a
command that fails writes nothing.

An output that is one of the command's inputs or an input's provenance sidecar, or would
replace one (same resolved path, or the same file through a hard link or symbolic link:
same device and inode), is refused; so is any file a command writes inside its output
folder that is an input, an output inside an input folder the command reads (the next run
would read it), an output folder that is or lies inside an input folder unless the user
said it is meant (``--inside-input``: outputs among the input data are never written
silently), and an output that cannot be written (tried before the work).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from mtanno.errors import MtannoError
from mtanno.util.output import _HOST, SIDECAR_SUFFIX, SIDECAR_TABLES, TMP_SUFFIX, write_error

__all__ = ["check_outputs"]


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


_GLOB = frozenset("*?[")


def _inside(path: str, folder: str) -> bool:
    """True if the resolved ``path`` is ``folder`` or lies below it (both resolved)."""
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def check_outputs(outputs: Iterable[str | os.PathLike | None],
                  inputs: Iterable[str | os.PathLike | None], *,
                  folders: Mapping[str | os.PathLike, Iterable[str] | None] | None = None,
                  scanned: Mapping[str | os.PathLike, Iterable[str] | None] | None = None,
                  writable: bool = True, inside_input: bool | None = None) -> None:
    """Refuse, before any work, every output that would destroy an input or break the next
    run, and every output that cannot be written; so a command that fails writes nothing.

    * An output that is, or would replace, an input is refused; so is an output named
      twice. Compared by resolved path (symbolic links followed) and by device and inode
      (hard links), so ``-o r.parquet`` cannot overwrite the input ``r.parquet`` under any
      of its names. The provenance sidecar of every CSV or JSON Lines input
      (``FILE.meta.json``) counts as an input: ``--json ann.csv.meta.json`` cannot replace
      the provenance of the input ``ann.csv``.
    * ``folders`` maps each output folder to the names the command writes in it: file
      names (each an output, checked as above), glob patterns for names known only later
      (``timeline_*.png``: no input in the folder may match), or None for a folder that is
      the command's alone (an index: no input may lie anywhere below it). The folder
      itself is compared with the inputs as an output is.
    * ``scanned`` maps each input folder the command reads everything below to the
      suffixes it reads there (None: every file). An output below it with one of those
      suffixes (an output folder: one of its names) would be read as an input by the
      next run over the same folder, and is refused.
    * ``inside_input`` False: an output folder (a key of ``folders``) that is, or lies
      inside, an input folder (a key of ``scanned``; its suffixes may be empty: a folder
      inputs are read from without a scan, as compose's clip root) is refused, in one line
      naming the option that allows it (``{inside_input}``: ``--inside-input`` on the
      command line), so that no output lands among the input data silently (a read-only
      data set, a folder the next run reads). True: allowed (an output the next run would
      read is still refused, above). None: not checked (a folder that is the command's
      alone, an index, is refused inside an input folder by the rule above).
    * With ``writable`` (the default) every output location is tried before the work: an
      output file must not be a folder, and the folder it goes into, or the nearest folder
      above it that exists, must be a folder where a file can be created (a temporary file
      is created there and removed at once). Batches whose outputs each fail alone (one
      table per document) pass False.

    ``None`` and ``-`` (standard input/output) are skipped. Every refusal is one
    :class:`~mtanno.errors.MtannoError` naming the output.
    """
    outputs = _given(outputs)
    paths = _Paths()
    out_folders: list[tuple[str, str, list[str] | None]] = []  # (as given, resolved, names)
    patterns: list[tuple[str, str, str]] = []  # (folder as given, resolved folder, pattern)
    for folder, names in (folders or {}).items():
        if folder is None or str(folder) == "-":
            continue
        names = None if names is None else [str(n) for n in names]
        out_folders.append((str(folder), os.path.realpath(folder), names))
        for name in names or ():
            if _GLOB & set(name):
                patterns.append((str(folder), os.path.realpath(folder), name))
            else:
                outputs.append(os.path.join(str(folder), name))
    by_path, by_inode = _input_index(_given(inputs), paths)
    out_paths = _check_files(outputs, by_path, by_inode, paths)
    _check_folders(out_folders, patterns, by_path, paths)
    _check_scanned(scanned or {}, out_paths, out_folders)
    if inside_input is False:
        _check_inside(scanned or {}, out_folders)
    if writable:
        probed: dict[str, OSError | None] = {}
        for item, _ in out_paths:
            _preflight(Path(item), probed, folder=False)
        for given_name, _, _ in out_folders:
            _preflight(Path(given_name), probed, folder=True)


def _given(items) -> list[str]:
    """The paths of ``items``, without None and ``-`` (standard input or output)."""
    return [str(i) for i in items if i is not None and str(i) != "-"]


class _Paths:
    """Resolved paths, each folder resolved once (batches name thousands of files in a few
    folders; a file that is itself a link is caught by its inode)."""

    def __init__(self) -> None:
        self._folders: dict[str, str] = {}

    def in_folder(self, parent: str, name: str) -> str:
        if parent not in self._folders:
            self._folders[parent] = os.path.realpath(parent)
        return os.path.join(self._folders[parent], name)

    def resolved(self, p: Path) -> str:
        return self.in_folder(str(p.parent), p.name)

    def link_target(self, p: Path) -> str:
        """Where a symbolic link leads (as :func:`os.path.realpath`; a link to a link is
        left to realpath)."""
        target = os.path.join(str(p.parent), os.readlink(p))
        folder, name = os.path.split(target)
        if name in ("", ".", "..") or os.path.islink(target):
            return os.path.realpath(p)
        return self.in_folder(folder or ".", name)


def _input_index(inputs: list[str], paths: _Paths):
    """The inputs by resolved path (and where a link leads) and by device and inode, each
    mapped to (the input as given, whether this is its provenance sidecar)."""
    import stat

    by_path: dict[str, tuple[str, bool]] = {}
    by_inode: dict[tuple[int, int], tuple[str, bool]] = {}
    for item in inputs:
        items = [(item, (item, False))]
        if item.lower().endswith(SIDECAR_TABLES):  # its provenance: an input too
            items.append((item + SIDECAR_SUFFIX, (item, True)))
        for each, what in items:
            p = Path(each)
            by_path.setdefault(paths.resolved(p), what)
            try:
                st = os.lstat(p)
                if stat.S_ISLNK(st.st_mode):  # also where it leads
                    by_path.setdefault(paths.link_target(p), what)
                    st = os.stat(p)
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode):
                by_inode.setdefault((st.st_dev, st.st_ino), what)
    return by_path, by_inode


def _clash(item: str, hit: tuple[str, bool]) -> MtannoError:
    name, sidecar = hit
    if sidecar:
        what = f"the provenance sidecar of the input {name}"
    else:
        what = "an input of this command" + ("" if name == item else f" ({name})")
    return MtannoError(f"output would overwrite {what}; choose another output name", path=item)


def _check_files(outputs: list[str], by_path, by_inode, paths: _Paths) -> list[tuple[str, str]]:
    """Refuse an output named twice or that is an input (by path or inode); returns the
    outputs (as given, resolved)."""
    seen: dict[str, str] = {}
    out_paths: list[tuple[str, str]] = []
    for item in outputs:
        p = Path(item)
        rp = paths.resolved(p)
        if rp in seen:
            raise MtannoError(f"the same output is named twice ({seen[rp]} and {item})",
                              path=item)
        seen[rp] = item
        out_paths.append((item, rp))
        hit = by_path.get(rp)
        if hit is None:
            ident = _identity(p)
            hit = by_inode.get(ident) if ident is not None else None
        if hit is not None:
            raise _clash(item, hit)
    return out_paths


def _check_folders(out_folders, patterns, by_path, paths: _Paths) -> None:
    """Refuse an output folder that is an input, a folder of the command's own (names
    None) with an input below it, and an input a name pattern of an output folder
    matches."""
    from fnmatch import fnmatchcase

    for given_name, rfolder, names in out_folders:
        hit = by_path.get(rfolder) or by_path.get(paths.resolved(Path(given_name)))
        if hit is not None and not (names is not None and os.path.isdir(rfolder)):
            # (an input folder written into is not replaced: the rules below judge it)
            raise _clash(given_name, hit)
        if names is None:  # the folder is the command's: nothing of the inputs below it
            inside = next((i for rp, (i, _) in by_path.items() if _inside(rp, rfolder)),
                          None)
            if inside is not None:
                raise MtannoError(f"input {inside} lies inside this output folder, which "
                                  "the command replaces; choose another folder",
                                  path=given_name)
    for given_name, rfolder, pattern in patterns:
        for rp, item in by_path.items():
            folder, name = os.path.split(rp)
            if folder == rfolder and fnmatchcase(name, pattern):
                raise _clash(os.path.join(given_name, name), item)


def _check_scanned(scanned, out_paths, out_folders) -> None:
    """Refuse an output inside a folder the command reads as input (with a suffix it reads
    there): the next run over that folder would read it too."""
    for folder, suffixes in scanned.items():
        if folder is None or str(folder) == "-":
            continue
        rfolder = os.path.realpath(folder)
        takes = None if suffixes is None else tuple(s.lower() for s in suffixes)

        def read(name: str, takes=takes) -> bool:
            return takes is None or name.lower().endswith(takes)

        hits = [item for item, rp in out_paths
                if rp != rfolder and _inside(rp, rfolder) and read(rp)]
        for given_name, rf, names in out_folders:
            if _inside(rf, rfolder):
                hits += [given_name] if names is None else \
                    [os.path.join(given_name, n) for n in names if read(n)]
        if hits:
            what = "files" if takes is None else ", ".join(takes) + " files"
            raise MtannoError(f"output lies inside {folder}, whose {what} are read as "
                              "inputs: the next run over that folder would read this output "
                              "too; choose an output outside it", path=hits[0])


def _check_inside(scanned, out_folders) -> None:
    """Refuse an output folder that is, or lies inside, an input folder (``check_outputs``,
    ``inside_input``)."""
    for folder in scanned:
        if folder is None or str(folder) == "-":
            continue
        rfolder = os.path.realpath(folder)
        for given_name, rf, _ in out_folders:
            if _inside(rf, rfolder):
                where = "is" if rf == rfolder else "lies inside"
                raise MtannoError(f"the output folder {where} the input folder {folder}: its "
                                  "outputs would be written among the input data; choose a "
                                  "folder outside it, or give {inside_input} if this is "
                                  "meant", path=given_name, options=("inside_input",))


def _preflight(target: Path, probed: dict, *, folder: bool) -> None:
    """Raise the :class:`MtannoError` writing ``target`` (a file, or an output folder) would
    meet: a folder where a file is to be written, a file where a folder is, or a location
    where no file can be created (tried with a temporary file, removed at once; once per
    folder, ``probed`` remembers)."""
    import stat

    try:
        st = os.stat(target)
    except (FileNotFoundError, NotADirectoryError):
        st = None
    except OSError as exc:
        raise write_error(target, exc) from None
    if st is not None:
        if folder and not stat.S_ISDIR(st.st_mode):
            raise MtannoError("output folder exists and is not a folder", path=str(target))
        if not folder and stat.S_ISDIR(st.st_mode):
            raise MtannoError("output is a folder, not a file", path=str(target))
        if not folder and not stat.S_ISREG(st.st_mode):
            return  # a device or FIFO, written in place
    where = target if folder and st is not None else target.parent
    # the nearest folder that exists: the rest is created when the output is written
    while True:
        try:
            wst = os.stat(where)
            break
        except (FileNotFoundError, NotADirectoryError):
            if where.parent == where:
                raise MtannoError("cannot write here: no such folder", path=str(target)) \
                    from None
            where = where.parent
        except OSError as exc:
            raise write_error(target, exc) from None
    if not stat.S_ISDIR(wst.st_mode):
        raise MtannoError(f"cannot write here: {where} is not a folder", path=str(target))
    key = str(where)
    if key not in probed:
        probed[key] = _probe(where)
    if probed[key] is not None:
        exc = probed[key]
        raise write_error(target, exc) from None


def _probe(folder: Path) -> OSError | None:
    """Create and remove a temporary file in ``folder`` (named as :func:`atomic_path`
    names them, so a writer killed in between leaves nothing the next write keeps);
    the error the file system gives, or None."""
    name = os.path.join(str(folder), f".mtanno-probe.{_HOST}-{os.getpid()}."
                                     f"{os.urandom(5).hex()[:8]}{TMP_SUFFIX}")
    fd = -1
    try:
        fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0),
                     0o600)
    except OSError as exc:
        return exc
    finally:
        if fd >= 0:
            os.close(fd)
            with contextlib.suppress(OSError):
                os.unlink(name)
    return None
