"""Atomic file writes: a reader sees the old file or the new one, never a partial file.

The temporary file lives beside the target and is removed on every exit path: an error, Ctrl-C
(KeyboardInterrupt) or a SIGTERM or SIGHUP that the command line turns into an exception. Its
name is recorded before the file is created (exclusively), so a signal can never land between the
creation and the record. Only SIGKILL can leave one behind, named ``.<target>.<random><suffix>``.
The written file gets the permissions a plain ``open(path, "w")`` would give it: 0666 less the
process umask.
"""

from __future__ import annotations

import errno
import os
import secrets
from collections.abc import Callable
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_atomic(path: Path, write: Callable[[Path], None]) -> Path:
    """Let ``write`` fill a temporary file in the same directory as ``path``, flush it to disk
    and move it onto ``path`` with os.replace; on any error or interruption the temporary file is
    removed and ``path`` is left as it was. An OSError that names no file (a full disk, a file
    size limit) is raised again naming ``path``; a ``path`` that exists and is not a regular file
    (a directory, a FIFO, a device) is never replaced: IsADirectoryError."""
    path = Path(path)
    if path.exists() and not path.is_file():
        raise IsADirectoryError(errno.EISDIR, "not a regular file: a write would replace it", str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp: Path | None = None
    try:
        while True:  # the name first, then the file: ``finally`` can always remove it
            tmp = path.parent / f".{path.name}.{secrets.token_hex(8)}{path.suffix or '.tmp'}"
            try:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
                break
            except FileExistsError:
                continue
        write(tmp)
        with open(tmp, "rb+") as stream:
            os.fsync(stream.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
        tmp = None
    except OSError as error:
        if error.filename is not None:
            raise
        raise OSError(error.errno, error.strerror or str(error), str(path)) from error
    finally:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
    return path


def write_text_atomic(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (:func:`write_atomic`)."""
    return write_atomic(path, lambda tmp: tmp.write_text(text))
