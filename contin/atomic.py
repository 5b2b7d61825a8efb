"""Atomic file publication: a file at PATH is either absent, the old version, or complete.

Everything contin writes (HDF5 runs, sweep task files and summaries, figures) goes through
:func:`publish`: the content is written to a temporary file in the same directory, flushed to
disk, and renamed over PATH (``os.replace`` is atomic on POSIX), so a crash or SIGKILL at any
moment never leaves a truncated PATH.

Targets.  The rename replaces whatever PATH names, so only a regular file or a new path is a
valid target (:func:`check_target`): a device (``/dev/null``, ``/dev/full``), FIFO, directory or
symbolic link is refused with one sentence (as root, renaming over ``/dev/null`` replaced the
device node).  A full disk (ENOSPC/EDQUOT/EFBIG) is one sentence too; the temporary file is
removed and PATH keeps its previous version.

Locks.  :class:`OutputLock` holds an exclusive ``flock`` on ``.NAME.lock`` next to an output
(or inside an output directory) for the whole run, so a second writer of the same output is
refused up front instead of losing or mixing work.  The kernel drops the lock when the process
dies (even by SIGKILL), so a stale lock file never blocks a later run.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from collections.abc import Callable, Sequence
from pathlib import Path

#: errno values that mean "the disk (or the quota, or the file-size limit) is full".
_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}


class OutputRefused(OSError):
    """An output path contin will not write (not a regular file, or locked by another run)."""


def check_target(path: str | os.PathLike[str]) -> Path:
    """``path`` if it is a regular file or does not exist yet; else :class:`OutputRefused`.

    Symbolic links are refused too (even to a regular file): the rename would replace the
    link, not the file it points to.
    """
    p = Path(path)
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        return p
    except OSError as exc:
        raise OutputRefused(f"cannot write {str(p)!r}: {exc.strerror or exc}") from None
    if stat.S_ISLNK(st.st_mode):
        raise OutputRefused(f"refusing to write {str(p)!r}: it is a symbolic link (the rename would replace "
                            f"the link); name the file itself")
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(f"output path {str(p)!r} is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise OutputRefused(f"refusing to write {str(p)!r}: it is not a regular file (a device, FIFO or socket); "
                            f"contin writes only regular files or new paths")
    return p


def disk_full_message(target: Path, exc: OSError) -> str:
    return (f"cannot write {str(target)!r}: {exc.strerror or 'no space left on device'} "
            f"(disk or quota full); the previous version of the file is unchanged")


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

    ``temporary`` defaults to PATH.tmp.  ``path`` must be a regular file or new
    (:func:`check_target`).  On any exception the temporary file is removed, PATH is left as it
    was, and the exception propagates (a full disk as one-sentence ``OSError``).
    """
    target = check_target(path)
    tmp = temporary if temporary is not None else target.with_name(target.name + ".tmp")
    try:
        if os.path.lexists(tmp) and not os.path.isfile(tmp) or os.path.islink(tmp):
            tmp.unlink()  # a stale link or node must not redirect the write
        write(tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.errno in _FULL:
            raise OSError(exc.errno, disk_full_message(target, exc)) from None
        raise
    fsync_directory(target.parent)
    return target


def publish_together(items: Sequence[tuple[str | os.PathLike[str], Callable[[Path], None]]]) -> list[Path]:
    """:func:`publish` of several files that belong together (AUTO's b.NAME and s.NAME): every
    ``write(tmp)`` is done and synced first, and only then is each renamed onto its path, so a full
    disk or an unwritable directory leaves every previous version in place (`contin export --auto`
    on a full disk replaced b.NAME and then failed on s.NAME: a new diagram beside the old solutions,
    qa19).  Errors are one sentence naming the target, not the temporary."""
    targets = [check_target(path) for path, _ in items]
    tmps = [t.with_name(t.name + ".tmp") for t in targets]
    try:
        for (_, write), target, tmp in zip(items, targets, tmps):
            try:
                if os.path.lexists(tmp) and not os.path.isfile(tmp) or os.path.islink(tmp):
                    tmp.unlink()
                write(tmp)
                with open(tmp, "rb") as fh:
                    os.fsync(fh.fileno())
            except OSError as exc:
                if exc.errno in _FULL:
                    raise OSError(exc.errno, disk_full_message(target, exc).replace(
                        "the previous version of the file is unchanged",
                        f"the previous versions of {', '.join(repr(t.name) for t in targets)} are unchanged")) from None
                if exc.errno is not None and not isinstance(exc, OutputRefused):
                    raise OSError(exc.errno, f"cannot write {str(target)!r}: {exc.strerror or exc}") from None
                raise
        for target, tmp in zip(targets, tmps):
            os.replace(tmp, target)
    except BaseException:
        for tmp in tmps:
            with contextlib.suppress(OSError):  # (a read-only file system refuses even this: EROFS)
                tmp.unlink(missing_ok=True)
        raise
    for directory in {t.parent for t in targets}:
        fsync_directory(directory)
    return targets


def write_bytes(tmp: Path, data: bytes) -> None:
    """Write ``data`` to ``tmp`` (new file, no symlink followed); ENOSPC surfaces as OSError."""
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0), 0o644)
    with os.fdopen(fd, "wb") as fh:
        fh.write(data)
        fh.flush()


class OutputLock:
    """Exclusive lock of one output (a file, or a directory with ``directory=True``).

    The lock file is ``.NAME.lock`` beside the file, or ``DIR/.contin.lock``.  ``acquire`` raises
    :class:`OutputRefused` (one sentence) when another process holds it.  Re-acquiring in the
    same process is a no-op.  Used as a context manager or released by :meth:`release`.
    """

    _held: dict[str, OutputLock] = {}

    def __init__(self, path: str | os.PathLike[str], *, directory: bool = False) -> None:
        p = Path(path).absolute()
        self.target = p
        self.lockfile = p / ".contin.lock" if directory else p.with_name(f".{p.name}.lock")
        self.fd: int | None = None

    def acquire(self) -> OutputLock:
        import fcntl

        key = str(self.lockfile)
        if key in OutputLock._held:
            return OutputLock._held[key]
        while True:
            try:
                fd = os.open(self.lockfile, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
            except OSError as exc:
                if exc.errno in _FULL:
                    raise OSError(exc.errno, disk_full_message(self.target, exc)) from None
                raise OSError(exc.errno, f"cannot create the lock file {str(self.lockfile)!r}: "
                                         f"{exc.strerror or exc}") from None
            if not stat.S_ISREG(os.fstat(fd).st_mode):  # a FIFO or device there: 'Error: Invalid argument' (qa18)
                os.close(fd)
                raise OSError(errno.EINVAL, f"the lock file {str(self.lockfile)!r} is not a regular file (a FIFO, "
                                            "socket or device); remove it") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise OutputRefused(f"{str(self.target)!r} is being written by another contin run "
                                    f"(lock {str(self.lockfile)!r} is held); wait for it or choose another output") from None
            try:  # the holder before us may have removed the file between our open and flock
                same = os.fstat(fd).st_ino == os.stat(self.lockfile).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self.fd = fd
        OutputLock._held[key] = self
        return self

    def release(self) -> None:
        # the descriptor is forgotten before it is closed: a Ctrl-C that landed between the close
        # and `self.fd = None` made the caller's second release close it again ('Error: Bad file
        # descriptor', exit 1, after a finished `contin trace bp-curve`; qa17)
        fd, self.fd = self.fd, None
        if fd is None:
            return
        OutputLock._held.pop(str(self.lockfile), None)
        try:
            self.lockfile.unlink(missing_ok=True)
        finally:
            os.close(fd)  # closing drops the flock

    def __enter__(self) -> OutputLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
