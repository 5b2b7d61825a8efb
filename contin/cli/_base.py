"""The ``contin`` click group, error handling and small shared helpers.

Exit codes: 0 success; 1 bad input or error (one ``Error: ...`` line on stderr, traceback only
with ``--debug``); 2 usage error (click); 3 the run finished but a branch ended with MX
(:data:`EXIT_INCOMPLETE`); 143 stopped by SIGTERM (handled like Ctrl-C, one ``Error:`` line).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import sys
from collections.abc import Mapping, Sequence
from typing import Any, NoReturn

import click

from contin import __version__
from contin.errorline import error_line  # noqa: F401 (re-exported: the commands import it from here)

#: exit code of a run that finished but left a branch with status MX
EXIT_INCOMPLETE = 3

CONTEXT_SETTINGS = {"help_option_names": ["-h", "--help"], "show_default": True}


#: Exit code after Ctrl-C (SIGINT): 128 + 2, the shell's convention (SIGTERM: 143).
EXIT_INTERRUPTED = 130


class ContinGroup(click.Group):
    """A group whose commands turn any exception into one ``Error:`` line (exit 1)."""

    def make_context(self, info_name: str | None, args: list[str], parent: click.Context | None = None,
                     **extra: Any) -> click.Context:
        # Ctrl-C while click parses the group's arguments (before invoke) printed click's 'Aborted!'
        # and exit 1 (qa17): the same Error line and exit 130 as during a command
        try:
            return super().make_context(info_name, args, parent=parent, **extra)
        except KeyboardInterrupt:
            click.echo("Error: interrupted (Ctrl-C)", err=True)
            raise click.exceptions.Exit(EXIT_INTERRUPTED) from None

    def invoke(self, ctx: click.Context) -> Any:
        from contin.cli._runctl import EXIT_TERMINATED, Terminated, sigterm_as_interrupt

        try:
            with sigterm_as_interrupt():  # every command: SIGTERM unwinds like Ctrl-C, with a message
                return super().invoke(ctx)
        except Terminated:
            click.echo("Error: terminated by SIGTERM", err=True)
            raise click.exceptions.Exit(EXIT_TERMINATED) from None
        except KeyboardInterrupt:  # Ctrl-C: one Error line and the shell's 128 + SIGINT, as SIGTERM gets
            # 143 (click printed 'Aborted!' and exited 1, the code of bad input; session 14)
            click.echo("Error: interrupted (Ctrl-C)", err=True)
            raise click.exceptions.Exit(EXIT_INTERRUPTED) from None
        except (click.ClickException, click.exceptions.Exit, click.Abort):
            raise
        except Exception as exc:
            if ctx.params.get("debug") or os.environ.get("CONTIN_DEBUG"):
                raise
            raise click.ClickException(error_line(exc)) from None


class ContinCommand(click.Command):
    """A ``contin`` subcommand: numpy's developer tools are deferred and BLAS threads limited when
    its body runs, after its arguments are parsed, so ``contin CMD --help`` and usage errors load
    no numpy or scipy."""

    def invoke(self, ctx: click.Context) -> Any:
        from contin.blas import limit_blas_threads
        from contin.lazyimports import defer_numpy_tools

        defer_numpy_tools()  # before scipy is imported: numpy.f2py/testing only if used (contin/lazyimports.py)
        limit_blas_threads()  # one BLAS thread for small matrices (contin/blas.py); CONTIN_BLAS_THREADS
        return super().invoke(ctx)


ContinGroup.command_class = ContinCommand  # every @main.command()


class _SinkOnBrokenPipe:
    """``sys.stderr`` (and ``sys.stdout``) that becomes a sink once its reader has gone.

    stdout too: ``contin scenes | head -1`` and ``contin info F | head`` ended with
    ``Error: Broken pipe``, exit 1 (qa18's leftover), where a reader that took what it wanted is
    the user's choice, not a failure.  The file descriptor is pointed at /dev/null once the reader
    has gone, so that the interpreter's final flush of the buffered rest does not raise again.

    Progress, notes and tables go to stderr; with ``contin trace ... 2>&1 | head -1`` the second
    progress line raised BrokenPipeError, which ended the run (exit 1, 'incomplete: the run failed:
    Broken pipe', 2 of 7 branches traced).  A reader that stopped reading is no reason to stop
    computing: the output file and the exit code still report the run.  A stderr closed before the
    start (``2>&-``: ``sys.stderr`` is None) is a reader gone from the start: the first message
    raised AttributeError, then click's report of it, and the run ended with exit 120 and no
    file (qa18).
    """

    def __init__(self, stream: Any) -> None:
        self._stream = stream
        self._gone = stream is None

    def write(self, text: str) -> int:
        if not self._gone:
            try:
                return self._stream.write(text)  # type: ignore[no-any-return]
            except BrokenPipeError:
                self._reader_gone()
        return len(text)

    def flush(self) -> None:
        if not self._gone:
            try:
                self._stream.flush()
            except BrokenPipeError:
                self._reader_gone()

    def _reader_gone(self) -> None:
        self._gone = True
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):  # no real descriptor (a test runner's stream)
            pass

    def isatty(self) -> bool:
        return self._stream is not None and bool(self._stream.isatty())

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _one_line_formatter(logging: Any) -> Any:
    """``level: message`` lines (the logging module is passed in: it is imported lazily)."""

    class OneLine(logging.Formatter):
        def format(self, record: Any) -> str:
            return f"{record.levelname.lower()}: {record.getMessage()}"

    return OneLine()


def _setup_logging(verbose: int) -> None:
    import logging  # here, not at import: `contin --help` / `--version` never log

    log = logging.getLogger("contin")
    if not any(getattr(h, "_contin_cli", False) for h in log.handlers):
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(_one_line_formatter(logging))
        handler._contin_cli = True  # type: ignore[attr-defined]
        log.addHandler(handler)
    log.setLevel(logging.DEBUG if verbose > 1 else logging.INFO if verbose else logging.WARNING)
    # broken scene modules are reported by `contin scenes` and in unknown-scene errors
    logging.getLogger("contin.scene").setLevel(logging.WARNING if verbose else logging.ERROR)


@click.group(cls=ContinGroup, context_settings=CONTEXT_SETTINGS,
             epilog="Examples:\n\n  contin scenes\n\n  contin trace bratu -o bratu.h5 --json\n\n"
                    "  contin diagram bratu.h5 -o bratu.png\n\n  contin info bratu.h5")
@click.option("--debug", is_flag=True, help="Show full tracebacks instead of one-line errors.")
@click.option("-v", "--verbose", count=True, help="Log more (-v info, -vv debug).")
@click.version_option(__version__, package_name="contin")  # given: no metadata scan at start-up
def main(debug: bool, verbose: int) -> None:
    """contin: numerical continuation and bifurcation diagrams.

    Exit codes: 0 success, 1 error, 2 usage error, 3 a branch ended with MX (failure), 130 Ctrl-C, 143 SIGTERM.
    """
    if not isinstance(sys.stderr, _SinkOnBrokenPipe):
        sys.stderr = _SinkOnBrokenPipe(sys.stderr)  # type: ignore[assignment]
    if sys.stdout is not None and not isinstance(sys.stdout, _SinkOnBrokenPipe):
        sys.stdout = _SinkOnBrokenPipe(sys.stdout)  # type: ignore[assignment]
    _setup_logging(verbose)  # BLAS threads: ContinCommand.invoke, when a command runs
    _one_line_warnings(debug or bool(os.environ.get("CONTIN_DEBUG")))


def _one_line_warnings(debug: bool) -> None:
    """Python warnings as one ``warning: ...`` line each, like every other message of the CLI.

    The default format is two lines, the second the source line that warned (``.../blas.py:146:
    UserWarning: stability of branch 0: ...`` then ``  return fn(*args, **kwargs)``: session 14,
    ``contin trace stretched-bratu``).  ``--debug`` adds the location.  Filters (``-W error``)
    still apply; the previous hook is restored when the command ends (tests run many commands
    in one process)."""
    import warnings

    previous = warnings.showwarning

    def show(message: Any, category: type[Warning], filename: str, lineno: int, file: Any = None,
             line: str | None = None) -> None:
        kind = "" if category is UserWarning else f"{category.__name__}: "
        where = f" ({filename}:{lineno})" if debug else ""
        text = re.sub(r"\s*\n\s*", " ", f"{kind}{message}").strip()
        try:
            (file or sys.stderr).write(f"warning: {text}{where}\n")
        except (OSError, ValueError):  # a closed stream: a warning is never worth a failure
            pass

    warnings.showwarning = show
    ctx = click.get_current_context(silent=True)
    if ctx is not None:
        ctx.call_on_close(lambda: setattr(warnings, "showwarning", previous))


# --------------------------------------------------------------------------- helpers

def fail(message: str) -> NoReturn:
    raise click.ClickException(message)


def continued_from(meta: Mapping[str, Any]) -> str | None:
    """The label a ``contin continue`` curve file was continued from (its ``extra["from"]``, written
    with ``extra["free"]``), or None for the file of a ``contin trace`` run."""
    extra = meta.get("extra")
    if isinstance(extra, Mapping) and "free" in extra:
        return str(extra.get("from", "its point"))
    return None


def warn_if_incomplete(file: str, meta: Mapping[str, Any]) -> None:
    """A ``warning:`` line when ``file`` holds an unfinished run (``complete=False``: interrupted,
    killed, failed or still running) or a curve cut short: what a command draws, exports or fits from it is only
    what was computed before the stop (a diagram of a run stopped after 1 of 7 branches looked
    finished, exit 0; qa18)."""
    if meta.get("complete", True):
        return
    # no reason recorded: a checkpoint of a run still going, or of one killed (SIGKILL, power loss)
    stopped = str(meta.get("stopped") or "") or "still running, or killed"
    what = ("its curve ends where it stopped" if continued_from(meta) is not None
            else "it holds only the branches computed before that")
    echo_err(f"warning: {file} is incomplete (its run was {stopped}): {what}")


def parse_value(text: str) -> Any:
    """A ``-s name=value`` value: a float (``inf`` allowed), else the string itself."""
    t = text.strip()
    try:
        v = float(t)
    except ValueError:
        return t
    if math.isnan(v):
        raise click.BadParameter(f"{text!r} is not a number (NaN is not a valid parameter value)")
    return v


def parse_resolution_tol(text: str | None) -> float | None:
    """``--resolution-tol`` value: a finite number > 0, or 'off' (the guard switched off, None).

    A bad value is one ``Error:`` line (exit 1), like any other invalid value.
    """
    from contin.options import check_resolution_tol

    t = (text or "").strip()
    if t.lower() == "off":
        return None
    try:
        return check_resolution_tol(float(t))
    except ValueError:
        fail(f"--resolution-tol must be a number > 0 (largest estimated relative discretization error "
             f"of a stored state) or 'off', got {text!r}")


def resolution_guard(text: str | None) -> tuple[contextlib.AbstractContextManager[None], float | None]:
    """(a block that applies ``--resolution-tol`` to every trace of the run, the tolerance used).

    Scenes build continuation options of their own (fold curves, homotopies), so the option is
    a run-wide :func:`contin.options.resolution_override`.  Without the option: no override and
    the core's default tolerance.
    """
    from contin.options import ContinuationOptions, resolution_override

    if text is None:
        return contextlib.nullcontext(), ContinuationOptions().resolution_tol
    tol = parse_resolution_tol(text)
    return resolution_override(tol), tol


def engine_option(f: Any) -> Any:
    """The ``--engine auto|numpy|numba`` option (SceneRequest.engine)."""
    from contin.engines import ENGINES  # not contin.scene: it imports numpy

    return click.option(
        "--engine", type=click.Choice(ENGINES), default="auto", show_default=True,
        help="Residual/Jacobian implementation where a problem has several: numba (compiled; "
             "the 'fast' extra), numpy, or auto (numba where installed and applicable).")(f)


def resolution_tol_option(f: Any) -> Any:
    """The ``--resolution-tol FLOAT|off`` option (None when not given: the run's own settings)."""
    return click.option(
        "--resolution-tol", "resolution_tol", default=None, metavar="FLOAT|off",
        help="Resolution guard: largest estimated relative discretization error of a stored state "
             "(ContinuationOptions.resolution_tol, default 3e-5); 'off' switches the guard off.")(f)


def parse_settings(items: Sequence[str], option: str = "'-s'") -> dict[str, Any]:
    """NAME=VALUE items -> {name: value}; a malformed item is a usage error naming ``option``
    (`contin profiles F --at lam=` said "Invalid value for '-s'", an option it does not have)."""
    out: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise click.BadParameter(f"expected name=value, got {item!r}", param_hint=option)
        out[name.strip()] = parse_value(value)
    return out


def fmt(v: Any, digits: int = 10) -> str:
    """Compact number formatting for tables ('inf', 'nan', 10 significant digits)."""
    if isinstance(v, bool) or v is None:
        return str(v)
    if isinstance(v, int) or type(v).__name__.startswith(("int", "uint")):
        return str(int(v))
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if math.isnan(f):
        return "nan"
    if math.isinf(f):
        return "inf" if f > 0 else "-inf"
    return f"{f:.{digits}g}"


def table(rows: Sequence[Sequence[Any]], header: Sequence[str]) -> str:
    """A plain left-aligned text table."""
    cells = [[str(h) for h in header]] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def special_points_table(branches: Sequence[Any]) -> str:
    """Table of special points: branch, label, type, free parameters, phi, converged, note."""
    rows = []
    for b in branches:
        for sp in b.special_points:
            names = [n for n in b.free if n in sp.params] or [b.parameter]
            pv = ", ".join(f"{n}={fmt(sp.params.get(n, math.nan))}" for n in names)
            data = ", ".join(f"{k}={fmt(v)}" for k, v in getattr(sp, "data", {}).items())  # HB omega, l1; UZ value
            note = "; ".join(t for t in (data, sp.note) if t)
            rows.append((b.id, sp.name, sp.type, pv, fmt(sp.order_parameter), "yes" if sp.converged else "NO", note))
    if not rows:
        return "no special points"
    return table(rows, ("branch", "label", "type", "parameters", "phi", "converged", "note"))


def branches_table(branches: Sequence[Any]) -> str:
    rows = []
    for b in branches:
        p = b.params.get(b.parameter)
        rng = f"[{fmt(min(p), 6)}, {fmt(max(p), 6)}]" if p is not None and len(p) else "-"
        rows.append((b.id, b.kind, b.parent or "-", b.parameter, rng, len(b), b.status,
                     "closed" if b.closed else "", b.message))
    return table(rows, ("branch", "kind", "parent", "param", "range", "points", "status", "", "message"))


def echo_err(text: str = "") -> None:
    click.echo(text, err=True)


def echo_json(doc: Mapping[str, Any]) -> None:
    from contin.jsonout import dumps

    click.echo(dumps(doc, indent=2))
