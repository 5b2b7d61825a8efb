"""Cooperative stop on Ctrl-C: the first SIGINT asks the tracer to end the branch in progress at
its last accepted point, so that a command whose one result is that branch (``contin continue``:
a two-parameter curve, written only at its end) keeps what it computed; a second SIGINT
interrupts at once (KeyboardInterrupt, as without this module).

Only a command that can save a partial branch installs it (:func:`stop_on_sigint`); the tracer
asks :func:`stop_requested` once per step (``contin.continuation.trace``), which costs a module
global read.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

_requested = False


def stop_requested() -> bool:
    """Whether a stop was asked for (by the first Ctrl-C inside :func:`stop_on_sigint`)."""
    return _requested


def request_stop() -> None:
    """Ask the running tracer to end its branch at the last accepted point."""
    global _requested
    _requested = True


class StopRequest:
    """What :func:`stop_on_sigint` yields: ``requested`` tells after the block whether Ctrl-C asked
    for a stop (the result is then partial)."""

    requested = False


@contextmanager
def stop_on_sigint() -> Iterator[StopRequest]:
    """Within the block, the first SIGINT sets :func:`stop_requested` instead of raising; the
    next one raises KeyboardInterrupt.  On exit the request is moved into the yielded
    :class:`StopRequest` and cleared, so later traces in the same process run normally.
    Outside the main thread (where signal handlers cannot be set) the block runs unchanged."""
    global _requested
    _requested = False
    outcome = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield outcome
        return

    def handler(signum: int, frame: Any) -> None:
        if _requested:
            raise KeyboardInterrupt
        request_stop()

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield outcome
    finally:
        signal.signal(signal.SIGINT, previous)
        outcome.requested = _requested
        _requested = False
