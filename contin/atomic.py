"""Atomic file publication: a file at PATH is either absent, the old version, or complete.

Everything contin writes (HDF5 runs, sweep task files and summaries, figures) goes through
:func:`publish`: the content is written to a temporary file in the same directory, flushed to
disk, and renamed over PATH (``os.replace`` is atomic on POSIX), so a crash or SIGKILL at any
moment never leaves a truncated PATH.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path


def fsync_directory(directory: Path) -> None:
    """Make a rename durable (best effort; some file systems refuse directory fsync)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def publish(path: str | os.PathLike[str], write: Callable[[Path], None], *, temporary: Path | None = None) -> Path:
    """Call ``write(tmp)``, fsync tmp, and rename it onto ``path``.

    ``temporary`` defaults to PATH.tmp.  On any exception the temporary file is removed, PATH
    is left as it was, and the exception propagates.
    """
    target = Path(path)
    tmp = temporary if temporary is not None else target.with_name(target.name + ".tmp")
    try:
        write(tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    fsync_directory(target.parent)
    return target
