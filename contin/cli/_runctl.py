"""Run control shared by the long-running commands: progress lines, SIGTERM, output checks, limits.

* :class:`Progress` -- on a terminal one overwritten status line; on a non-terminal (logs, CI)
  every finished branch as a line and, every :data:`HEARTBEAT` seconds while a run is busy, one
  line with the elapsed time and the last status, so long jobs show life (issue 16: they were
  silent).  ``CONTIN_PROGRESS_SECONDS`` changes the interval (0: no heartbeat; the test
  session sets 0 so that one-line-error tests do not depend on machine load).
* :func:`sigterm_as_interrupt` -- SIGTERM raises :class:`Terminated` (a KeyboardInterrupt) in
  the main thread, so a terminated run unwinds like Ctrl-C: the finished branches stay in the
  published file and the command says where; exit code 143 (128 + SIGTERM).
* limits of sizes and steps (:data:`MAX_GRID`, :data:`MAX_KX`...), checked before anything is
  computed; a value outside is one ``Error:`` line (a grid of 1e9 intervals ate 330 MB/s, an
  infinite step looped forever halving itself).
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator

import click

from contin.limits import MAX_ABS_KX, MAX_GRID, MAX_KX, MAX_STEPS, MAX_TRACE_KX  # noqa: F401 (re-exported)

#: seconds between heartbeat lines on a non-terminal stderr
HEARTBEAT = 5.0
#: exit code of a run stopped by SIGTERM
EXIT_TERMINATED = 128 + signal.SIGTERM

#: suffixes that name a figure or text format, never an HDF5 run file
NOT_HDF5 = frozenset({".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".json", ".toml", ".txt", ".csv"})


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived (unwinds like Ctrl-C)."""


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` (main thread only; else a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: object) -> None:
        raise Terminated()

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def check_hdf5_output(path: str | None, option: str = "-o") -> None:
    """Refuse an HDF5 output whose suffix names another format (``-o x.png`` on ``trace``)."""
    suffix = os.path.splitext(path)[1] if path is not None else ""
    if suffix.lower() in NOT_HDF5:
        raise click.BadParameter(f"{path!r} has suffix {suffix!r}, but this command writes an HDF5 "
                                 f"run file; use FILE.h5", param_hint=f"'{option}'")


def check_finite_positive(value: float | None, option: str) -> float | None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise click.BadParameter(f"must be a finite number > 0, got {value!r}", param_hint=f"'{option}'")
    return value


def check_nonempty(value: str | None, option: str) -> str | None:
    """None stays None (the default); an empty or blank string is an error, never a silent default."""
    if value is not None and not value.strip():
        raise click.BadParameter("must not be empty (leave the option out for the default)", param_hint=f"'{option}'")
    return None if value is None else value.strip()


def check_kx(values: list[float] | tuple[float, ...], option: str = "--kx", *, most: int = MAX_KX) -> None:
    if len(values) > most:
        raise click.BadParameter(f"{len(values)} wavenumbers; at most {most}", param_hint=f"'{option}'")
    for v in values:
        if not math.isfinite(v) or abs(v) > MAX_ABS_KX:
            raise click.BadParameter(f"wavenumber {v!r} must be a finite number with |kx| <= {MAX_ABS_KX:g}",
                                     param_hint=f"'{option}'")


class Progress:
    """Status lines on stderr (module docstring): a terminal line, or lines plus a heartbeat."""

    def __init__(self, enabled: bool, *, tty: bool | None = None) -> None:
        self.enabled = enabled
        self.tty = sys.stderr.isatty() if tty is None else tty
        self.t0 = time.perf_counter()
        self.stream = sys.stderr  # the heartbeat thread writes here, not to a later sys.stderr
        self._open = False
        self._last = ""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.interval = 0.0
        if enabled and not self.tty:
            try:
                self.interval = float(os.environ.get("CONTIN_PROGRESS_SECONDS", HEARTBEAT))
            except ValueError:
                self.interval = HEARTBEAT
        if enabled and not self.tty and self.interval > 0:  # CONTIN_PROGRESS_SECONDS=0: no heartbeat
            self._thread = threading.Thread(target=self._beat, name="contin-progress", daemon=True)
            self._thread.start()

    def _stamp(self, message: str) -> str:
        return f"[{time.perf_counter() - self.t0:7.1f}s] {message}"

    def _beat(self) -> None:
        while not self._stop.wait(self.interval):
            with self._lock:
                self.stream.write(self._stamp(f"running: {self._last or 'started'}")[:300] + "\n")
                self.stream.flush()

    def note(self, message: str) -> None:
        """Remember ``message`` for the heartbeat without printing it (the caller printed it)."""
        with self._lock:
            self._last = message

    def status(self, message: str) -> None:
        if not self.enabled:
            return
        with self._lock:
            self._last = message
            if self.tty:
                sys.stderr.write("\r\x1b[K" + self._stamp(message)[:200])
                sys.stderr.flush()
                self._open = True

    def line(self, message: str) -> None:
        if self.enabled:
            self._clear()
            with self._lock:
                sys.stderr.write(self._stamp(message) + "\n")
                sys.stderr.flush()

    def _clear(self) -> None:
        with self._lock:
            if self._open:
                sys.stderr.write("\r\x1b[K")
                sys.stderr.flush()
                self._open = False

    def done(self) -> None:
        """Clear the terminal status line (before printing other output)."""
        self._clear()

    def close(self) -> None:
        """Stop the heartbeat and clear the status line (end of the run, also on errors)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        self._clear()


def end_of_curve_run(what: str, points: int, output: str | None, interrupted: bool, stop: object,
                     status: str, message: str, branch: object = None, *, cut_short: bool = True) -> None:
    """The common end of a `contin continue` run (a curve, or orbits): after a Ctrl-C/SIGTERM the
    note where the points went and the one Error line with exit 130/143; after MX a warning and
    exit 3; a warning per special point of ``branch`` whose location did not converge; a warning if
    ``branch`` ended at its step cap crawling (``contin.stall``); otherwise
    nothing.  ``what`` names the result ("the curve", "the orbits"); ``cut_short`` False: the stop
    came after the result was finished (it is complete)."""
    if interrupted:
        from contin.cancel import SIGTERM
        from contin.cli._base import EXIT_INTERRUPTED, echo_err

        term = getattr(stop, "reason", None) == SIGTERM
        signal_name = "SIGTERM" if term else "Ctrl-C"
        verb = "are" if what.endswith("s") else "is"
        if output is not None and cut_short:
            echo_err(f"note: {what} computed before {signal_name} ({points} points) {verb} saved in {output}")
        elif output is not None:
            past = "were" if verb == "are" else "was"
            echo_err(f"note: {what} ({points} points) {past} finished before the {signal_name} took effect: saved "
                     f"complete in {output}")
        echo_err("Error: terminated by SIGTERM" if term else "Error: interrupted (Ctrl-C)")
        raise click.exceptions.Exit(EXIT_TERMINATED if term else EXIT_INTERRUPTED)
    if branch is not None:
        from contin.cli._base import echo_err
        from contin.cli.trace import doubtful_special_points

        # a special point whose location did not converge was said in the table's note only, as
        # trace said it before session 15 (qa19b: LP2 of an LPC curve through a pitchfork of cycles)
        for line in doubtful_special_points(branch):
            echo_err(f"warning: {what}: {line}")
    if status == "MX":
        from contin.cli._base import EXIT_INCOMPLETE, echo_err

        mx = "the branch of periodic orbits" if what == "the orbits" else what
        echo_err(f"warning: {mx} ended with MX: {message}")
        raise click.exceptions.Exit(EXIT_INCOMPLETE)
    from contin.stall import stalled

    crawl = None if branch is None else stalled(branch)
    if crawl is not None:
        from contin.cli._base import echo_err

        echo_err(f"warning: {what} {crawl}")
