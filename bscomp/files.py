"""Writing files so that nothing is ever half-written (a leaf module: imports only bscomp.errors).

Every file bscomp writes (CSV, JSON, PNG, HTML) goes to a temporary name in the same folder and is
renamed into place only when complete, so an interrupted or failing write (full disk, ``ulimit -f``, an
exception while formatting) leaves the previous file intact. :func:`staged` does the same for a group of
outputs: either all of them are replaced or none is.
"""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
from pathlib import Path

from bscomp.errors import ArgumentTypeError, OutputFileError

__all__ = ["atomic_write", "atomic_path", "atomic_dir", "staged", "writable_path", "writable_dir", "json_default",
           "check_path_type"]


def check_path_type(path, what: str = "output file", kind: str = "file") -> None:
    """Refuse a ``path`` that is not a ``str`` or ``os.PathLike`` (``None``, a number, a list...) with
    :class:`bscomp.errors.ArgumentTypeError` naming ``what`` (e.g. ``"Comparison.to_json: path"``)."""
    if isinstance(path, bool) or not isinstance(path, (str, os.PathLike)):
        raise ArgumentTypeError(f"{what} must be a {kind} name (str or pathlib.Path), got "
                                f"{type(path).__name__} {path!r}"[:300])


def writable_path(path, what: str = "output file", suffixes=None) -> Path:
    """Check up front that ``path`` can be written: a str or path, not a directory, its folder exists, and
    (given ``suffixes``, e.g. ``(".csv",)``) its extension is one of them.

    Raises :class:`bscomp.errors.OutputFileError` naming the path and how to fix it
    (:class:`~bscomp.errors.ArgumentTypeError` for a ``path`` that is no file name at all).
    """
    check_path_type(path, what)
    p = Path(path)
    if p.is_dir():
        example = str(p / ("out" + (suffixes[0] if suffixes else "")))
        raise OutputFileError(f"{what} {str(p)!r} is a directory: give a file name, e.g. {example!r}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise OutputFileError(f"{what} {str(p)!r}: folder {str(parent)!r} does not exist (create it first)")
    if not os.access(parent, os.W_OK):
        raise OutputFileError(f"{what} {str(p)!r}: folder {str(parent)!r} is not writable")
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise OutputFileError(f"{what} {str(p)!r} has the extension {p.suffix or '(none)'!r}; use one of "
                              f"{', '.join(suffixes)}")
    return p


def writable_dir(path, what: str = "output folder") -> Path:
    """Check up front that the folder ``path`` can be created or replaced: it is not a file, the nearest
    existing folder above it is a folder (not a file) and writable.

    Raises :class:`bscomp.errors.OutputFileError` naming ``what`` (e.g. ``"--report folder"``) and the path.
    """
    check_path_type(path, what, "folder")
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputFileError(f"{what} {str(p)!r} is a file, not a folder", hint="give a folder name (it is created)")
    above = p.parent if str(p.parent) else Path(".")
    while not above.exists() and above != above.parent:
        above = above.parent
    if not above.is_dir():
        raise OutputFileError(f"{what} {str(p)!r}: {str(above)!r} is a file, not a folder",
                              hint="give a path whose folders are folders")
    if not os.access(above, os.W_OK | os.X_OK):
        raise OutputFileError(f"{what} {str(p)!r}: folder {str(above)!r} is not writable",
                              hint="choose a writable location")
    return p


def _publish(tmp, target) -> None:
    """Give ``tmp`` the mode a plainly created file would have (or the old file's), then rename it."""
    try:
        mode = os.stat(target).st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    os.chmod(tmp, mode)
    os.replace(tmp, target)


@contextlib.contextmanager
def atomic_path(path, what: str = "output file", suffixes=None):
    """Yield a temporary path next to ``path``; on success rename it onto ``path``, else delete it.

    For writers that take a file name (``matplotlib.Figure.savefig``, ``numpy.savetxt``). The temporary
    name keeps the suffix, so format detection by extension still works. ``what`` and ``suffixes`` are
    checked by :func:`writable_path` before anything is written.
    """
    p = writable_path(path, what, suffixes)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.stem}.", suffix=p.suffix, dir=p.parent if str(p.parent) else ".")
    os.close(fd)
    try:
        yield Path(tmp)
        _publish(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def atomic_write(path, mode: str = "w", encoding: str | None = "utf-8", newline: str | None = None, *,
                 what: str = "output file", suffixes=None):
    """``open(path, mode)`` that replaces ``path`` only when the block completes without error.

    ``path`` may also be an open text stream (e.g. ``sys.stdout``), which is written directly. A file name is
    checked first (:func:`writable_path`: ``what`` names it in errors, ``suffixes`` are the extensions allowed).
    """
    if isinstance(path, io.IOBase) or hasattr(path, "write"):
        yield path
        return
    with atomic_path(path, what, suffixes) as tmp:
        kw = {} if "b" in mode else {"encoding": encoding, "newline": newline}
        with open(tmp, mode, **kw) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())


class staged:
    """Stage several outputs and commit them together: all are renamed into place at the end, or none.

    >>> with staged() as st:                     # doctest: +SKIP
    ...     md.to_csv(st.path("modes.csv"))
    ...     md.plot(st.path("modes.png"))
    """

    def __init__(self):
        self._pending: list[tuple[Path, Path]] = []

    def path(self, target) -> Path:
        """A temporary path to write ``target`` to (same folder and suffix)."""
        p = Path(target)
        fd, tmp = tempfile.mkstemp(prefix=f".{p.stem}.", suffix=p.suffix, dir=p.parent if str(p.parent) else ".")
        os.close(fd)
        self._pending.append((Path(tmp), p))
        return Path(tmp)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            for tmp, target in self._pending:
                _publish(tmp, target)
        else:
            for tmp, _ in self._pending:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
        self._pending.clear()
        return False


#: the file :func:`atomic_dir` puts in every folder it writes: such a folder may be replaced as a whole
OUTPUT_MARKER = ".bscomp-output"


def _check_replaceable(p: Path) -> None:
    if not p.exists():
        return
    if not p.is_dir():
        raise OutputFileError(f"output folder {str(p)!r} is a file: give a folder name (it is created)")
    entries = sorted(e.name for e in p.iterdir())
    if entries and OUTPUT_MARKER not in entries:
        shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise OutputFileError(f"output folder {str(p)!r} holds files bscomp did not write ({shown}); it would be "
                              "replaced as a whole", hint="give a new or empty folder, or delete this one first")


@contextlib.contextmanager
def atomic_dir(path):
    """Yield a fresh temporary folder; on success it replaces ``path`` (a report is complete or absent).

    An existing ``path`` is moved aside first and deleted only after the new folder is in place. Since the
    whole folder is replaced, an existing ``path`` must be empty or a folder this function wrote (it holds
    the marker file ``.bscomp-output``); anything else raises :class:`bscomp.errors.OutputFileError` before
    the block runs, so a user's folder given by mistake is never deleted.
    """
    import shutil

    p = writable_dir(path)
    _check_replaceable(p)
    parent = p.parent if str(p.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", dir=parent))
    except OSError as exc:                  # never name the temporary folder: the user did not choose it
        raise OutputFileError(f"output folder {str(p)!r} cannot be created in {str(parent)!r}: "
                              f"{exc.strerror or exc}", hint="choose a writable location") from exc
    (tmp / OUTPUT_MARKER).write_text("written by bscomp; the folder is replaced as a whole when rewritten\n")
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if p.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{p.name}.old.", dir=parent))
        os.replace(p, old / p.name)
    os.replace(tmp, p)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def json_default(o):
    """``json.dumps(..., default=json_default)``: numpy scalars and arrays as numbers and lists, tuples as
    lists, anything else by its ``str`` (so a result object never fails to serialise)."""
    if hasattr(o, "item") and getattr(o, "ndim", None) == 0:
        return o.item()
    if hasattr(o, "tolist"):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    return str(o)
