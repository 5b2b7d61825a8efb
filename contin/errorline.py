"""The one-line form of an error for the user (``Error: ...`` on the command line, ``warning:``
lines of a scene's after-run passes): no traceback, the reason in the exception's own words.

Here and not in :mod:`contin.cli._base`, so that core modules (``contin.scene``'s stability pass
after a run, which ``contin sweep`` tasks run too) word their warnings as the command line does
without importing the command line.
"""

from __future__ import annotations

import re


def error_line(exc: BaseException) -> str:
    """One line describing ``exc`` for the user (no traceback)."""
    if isinstance(exc, OSError) and not type(exc).__module__.startswith("h5py") and exc.strerror:
        msg = f"{exc.strerror}: {exc.filename!r}" if exc.filename else exc.strerror
        if exc.args and isinstance(exc.args[0], str) and len(exc.args) == 1:
            msg = exc.args[0]
    elif isinstance(exc, ValueError | OSError | LookupError) and str(exc):
        msg = str(exc)
        if isinstance(exc, KeyError) and len(exc.args) == 1:
            msg = str(exc.args[0])
    elif isinstance(exc, ArithmeticError):  # Python-float overflow or 0-division of a model's formulas
        msg = (f"arithmetic failure ({type(exc).__name__}: {exc}): a parameter or step is probably out of the "
               "model's range; rerun with --debug for the traceback")
    else:
        msg = f"internal error ({type(exc).__name__}: {exc}); rerun with --debug for the traceback"
    return re.sub(r"\s*\n\s*", " ", msg).strip()
