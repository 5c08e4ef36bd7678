"""Files written whole or not at all: the one atomic write of optik.

The data go to a temporary file in the target's folder (so the final rename stays on one
file system), are flushed and ``fsync``-ed, and ``os.replace`` (atomic on POSIX and
Windows) renames the temporary file over the target. A reader sees the old file or the
new one, never a partial one; a failed write removes its temporary file and leaves the
old file as it was.
"""

from __future__ import annotations

import contextlib
import os
import stat
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from optik.errors import OutputFileError

__all__ = ["check_folder", "output_path", "prepare_folder", "write_atomic", "write_atomic_with"]

_O_BINARY = getattr(os, "O_BINARY", 0)  # Windows: no newline translation at the fd level


def output_path(path: Any) -> Path:
    """``path`` as a :class:`~pathlib.Path` to write, once it is one the system can name.

    Checked before any output is written, so that a path no file system accepts fails
    at once rather than after a folder was created or the work was done.

    Raises:
        OutputFileError: ``path`` is not a string or path-like, is empty, or holds a NUL
            character (no file system allows one; ``os`` would raise a bare ValueError).
    """
    if not isinstance(path, str | os.PathLike):
        raise OutputFileError(repr(path), f"expected a path, got {type(path).__name__}")
    text = os.fspath(path)
    if isinstance(text, bytes):
        raise OutputFileError(repr(path), "expected a text path, not bytes")
    if not text:
        raise OutputFileError(repr(text), "the path is empty")
    if "\x00" in text:
        raise OutputFileError(repr(text), "the path holds a NUL character")
    return Path(text)


def check_folder(folder: str | Path) -> Path:
    """``folder`` as a path that can be a folder for output, without creating it.

    For a check before long work whose output goes there at the end: the nearest folder
    that exists (``folder`` itself or a parent) must be one this process may write in,
    where the missing ones are created later. The system's permission bits are asked
    (``os.access``), so a place root may write in by them but the file system refuses
    (``/proc``) is found only by the write itself.

    Raises:
        OutputFileError: ``folder`` is not a usable path (:func:`output_path`), it or
            one of its parents is a file, or the nearest existing one is not writable
            (the message names it).
    """
    folder = output_path(folder)
    for parent in (folder, *folder.parents):
        try:
            if not parent.exists():
                continue
        except OSError as exc:  # a parent we may not look into (EACCES), a name too long
            raise OutputFileError(str(folder), exc.strerror or str(exc)) from exc
        if not parent.is_dir():
            raise OutputFileError(str(folder), f"{parent} is a file, not a folder")
        # Writing a new entry needs both: w to add it, x to reach into the folder.
        if not os.access(parent, os.W_OK | os.X_OK):
            raise OutputFileError(str(folder), f"{parent} is not a writable folder")
        break
    return folder


def prepare_folder(folder: str | Path) -> Path:
    """Create ``folder`` (and its parents) for output, or say clearly why it cannot be.

    Raises:
        OutputFileError: as :func:`check_folder`, or the place is not writable (the
            message names the path).
    """
    folder = check_folder(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputFileError(str(folder), exc.strerror or str(exc)) from exc
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputFileError(str(folder), "the folder is not writable")
    return folder


def _create_temporary(target: Path) -> tuple[int, str]:
    """A new hidden file beside ``target``, with the permissions ``open(target, "w")`` gives.

    ``tempfile.mkstemp`` would create it private (0600); a report is meant to be read by
    others, so the file is created with mode 0666 less the umask, or with the mode of the
    file it replaces.
    """
    for _ in range(100):
        tmp = target.with_name(f".{target.name}.{uuid.uuid4().hex[:12]}.tmp")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _O_BINARY, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputFileError(str(target), exc.strerror or str(exc)) from exc
        # A new file (or a mode we may not copy) keeps the umask's permissions.
        with contextlib.suppress(OSError):
            os.chmod(tmp, stat.S_IMODE(target.stat().st_mode))
        return fd, str(tmp)
    raise OutputFileError(str(target), "no free temporary name in its folder")  # pragma: no cover


def write_atomic_with(
    path: str | Path,
    writer: Callable[[IO[Any]], object],
    *,
    binary: bool = False,
    create_folder: bool = True,
) -> Path:
    """Write ``path`` whole through ``writer(handle)`` (text UTF-8, or bytes if ``binary``).

    Args:
        path: the target file.
        writer: writes the content to the open handle it is given.
        binary: open the handle in binary mode.
        create_folder: create the file's folder if missing; if false, a missing folder
            is an error (a folder removed since its owner created it stays removed).

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        OutputFileError: ``path`` is a folder, a parent is a file, the place is not
            writable, or (``create_folder`` false) the folder does not exist.
    """
    target = output_path(path)
    try:
        is_folder = target.is_dir()
    except OSError as exc:  # a name too long for the system, a loop of links, ...
        raise OutputFileError(str(target), exc.strerror or str(exc)) from exc
    if is_folder:
        raise OutputFileError(str(target), "it is a folder")
    if create_folder:
        prepare_folder(target.parent)
    elif not target.parent.is_dir():
        raise OutputFileError(str(target), f"its folder {target.parent} does not exist")
    fd, tmp = _create_temporary(target)
    try:
        mode = "wb" if binary else "w"
        encoding = None if binary else "utf-8"
        newline = None if binary else ""
        with os.fdopen(fd, mode, encoding=encoding, newline=newline) as handle:
            writer(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputFileError(str(target), exc.strerror or str(exc)) from exc
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


def write_atomic(path: str | Path, data: str | bytes) -> Path:
    """Write ``data`` (text as UTF-8, or bytes) to ``path`` whole; see :func:`write_atomic_with`.

    Raises:
        OutputFileError: ``path`` is a folder, a parent is a file, or the place is not
            writable.
    """
    binary = isinstance(data, bytes)
    return write_atomic_with(path, lambda handle: handle.write(data), binary=binary)
