"""Cooperative stop on Ctrl-C (and, where asked, SIGTERM): the first signal asks the tracer to end
the branch in progress at its last accepted point, so that a command keeps what it computed
(``contin continue``: a two-parameter curve, written only at its end; ``contin trace``: the branch
in progress besides the finished ones); a second signal interrupts at once (KeyboardInterrupt, as
without this module).

Only a command that can save a partial branch installs it (:func:`stop_on_sigint`); the tracer
asks :func:`stop_requested` once per step (``contin.continuation.trace``), which costs a module
global read, and marks the branch MX with :func:`stop_reason` (``"interrupted (Ctrl-C)"`` or
``"terminated by SIGTERM"``).  :func:`is_stopped_branch` tells such a partial branch from a
finished one (``contin trace --resume`` retraces it).  Inside :func:`deferred` (locating the special
points of a result already traced) the request waits until the block ends.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

#: the reason of a stop asked for by Ctrl-C (SIGINT) and by SIGTERM
CTRL_C = "interrupted (Ctrl-C)"
SIGTERM = "terminated by SIGTERM"
#: what a run file records as ``stopped`` (``complete=False``) when a stop request ended it, by
#: reason (``contin trace``'s writer, ``contin continue``'s curve; ``contin info`` prints it)
STOPPED = {CTRL_C: "interrupted", SIGTERM: "terminated by SIGTERM"}
#: the tail of the message of a branch a stop ended (after the reason)
ENDS_AT_LAST_POINT = ": the branch ends at its last point"

_reason: str | None = None
_deferred = 0  # depth of nested deferred() blocks


def stop_requested() -> bool:
    """Whether a stop was asked for (by the first Ctrl-C or SIGTERM inside :func:`stop_on_sigint`);
    False inside :func:`deferred` (the request is seen after it)."""
    return _reason is not None and not _deferred


@contextmanager
def deferred() -> Iterator[None]:
    """Within the block a stop request is not seen by the tracer (:func:`stop_requested` is False);
    it is kept and seen after the block.  For the short computations that finish a result already
    traced -- locating its special points with a local trace -- which a stop request would cut to
    nothing: a fold curve that had reached its bounds lost the XT points not yet located and was
    stored as finished (EP), so ``--resume`` kept it without them (qa18).  A second signal still
    interrupts at once (the handlers look at the request itself)."""
    global _deferred
    _deferred += 1
    try:
        yield
    finally:
        _deferred -= 1


def stop_reason() -> str:
    """Why the stop was asked for (:data:`CTRL_C` or :data:`SIGTERM`); :data:`CTRL_C` when none was."""
    return _reason or CTRL_C


def request_stop(reason: str = CTRL_C) -> None:
    """Ask the running tracer to end its branch at the last accepted point."""
    global _reason
    if _reason is None:
        _reason = reason


def stopped_by(branch: Any) -> str | None:
    """The reason (:data:`CTRL_C`, :data:`SIGTERM`) if a stop request ended ``branch`` or a part of
    it (MX, its message holds ``"<reason>: the branch ends at its last point"``, also inside a
    joined ``"backward: ...; forward: ..."``), else None."""
    message = str(getattr(branch, "message", "") or "")
    if getattr(branch, "status", None) != "MX":
        return None
    return next((reason for reason in (CTRL_C, SIGTERM) if reason + ENDS_AT_LAST_POINT in message), None)


def is_stopped_branch(branch: Any) -> bool:
    """Whether a stop request ended ``branch`` (:func:`stopped_by`): a partial branch, not a finished one."""
    return stopped_by(branch) is not None


class StopRequest:
    """What :func:`stop_on_sigint` yields: ``requested`` tells after the block whether a signal
    asked for a stop (the result is then partial), ``reason`` which (:data:`CTRL_C`, :data:`SIGTERM`)."""

    requested = False
    reason: str | None = None


@contextmanager
def stop_on_sigint(*, sigterm: type[BaseException] | None = None) -> Iterator[StopRequest]:
    """Within the block, the first SIGINT sets :func:`stop_requested` instead of raising; the
    next one raises KeyboardInterrupt.  With ``sigterm`` (an exception class, e.g. the CLI's
    ``Terminated``) the first SIGTERM asks for a stop too (reason :data:`SIGTERM`) and the next
    SIGTERM raises ``sigterm``.  On exit the request is moved into the yielded
    :class:`StopRequest` and cleared, so later traces in the same process run normally.
    Outside the main thread (where signal handlers cannot be set) the block runs unchanged."""
    global _reason
    _reason = None
    outcome = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield outcome
        return

    def handler(signum: int, frame: Any) -> None:
        if _reason is not None:
            raise KeyboardInterrupt
        request_stop(CTRL_C)

    def term_handler(signum: int, frame: Any) -> None:
        if _reason is not None:
            assert sigterm is not None
            raise sigterm()
        request_stop(SIGTERM)

    previous = signal.signal(signal.SIGINT, handler)
    previous_term = signal.signal(signal.SIGTERM, term_handler) if sigterm is not None else None
    try:
        yield outcome
    finally:
        signal.signal(signal.SIGINT, previous)
        if sigterm is not None:
            signal.signal(signal.SIGTERM, previous_term)
        outcome.requested = _reason is not None
        outcome.reason = _reason
        _reason = None
