"""Sending a signal to a ``contin`` child process once it is ready (shared by the Ctrl-C and
SIGTERM tests of tests/test_fault_injection.py and tests/test_cli_qa16.py).

:func:`signalled` runs ``python -m contin ARGS``, waits until ``ready()`` holds (a file or lock
appeared, a branch was published), waits ``after`` seconds more, sends the signal and returns the
exit code and stderr.  A child that ends before it is ready fails the test at once (the signal
would hit nothing and the test would check a finished run); so does a child not ready in
``timeout`` seconds.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping


def signalled(args: list[str], sig: int, ready: Callable[[], bool], *, env: Mapping[str, str],
              what: str = "the run to be ready", after: float = 0.0, timeout: float = 60.0) -> tuple[int, str]:
    """(exit code, stderr) of ``contin ARGS`` sent ``sig`` once ``ready()`` holds and ``after``
    seconds more.  SIGINT is reset to its default in the child: a shell without job control starts
    background jobs with it ignored, and Python then never raises KeyboardInterrupt."""
    proc = subprocess.Popen([sys.executable, "-m", "contin", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=dict(env), preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        t0 = time.monotonic()
        while not ready():
            if proc.poll() is not None:
                _, stderr = proc.communicate()
                raise AssertionError(f"the run ended (exit {proc.returncode}) before {what}: {stderr[-2000:]}")
            if time.monotonic() - t0 > timeout:
                raise AssertionError(f"timed out waiting for {what}")
            time.sleep(0.05)
        time.sleep(after)
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    return proc.returncode, stderr
