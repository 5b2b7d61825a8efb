"""The ``contin`` command line (click): one module per command.

Adding a command: write ``contin/cli/<name>.py`` defining a click command decorated with
``@main.command()`` (import ``main`` from :mod:`contin.cli._base`) and add ``<name>`` to the
import line below.  Heavy libraries (numpy, scipy, h5py, matplotlib) are imported inside the
command bodies so that ``contin --help`` stays fast.
"""

try:  # Ctrl-C while the command line loads (its first ~0.2 s) printed a KeyboardInterrupt traceback (qa16)
    from contin.cli._base import EXIT_INCOMPLETE, main

    # one module per command; importing a module registers its command on `main`
    from contin.cli import accuracy, continue_cmd, diagram, export, fit, info, profiles, scenes, stability, sweep, trace, verify  # noqa: E402,F401,I001
except KeyboardInterrupt:
    import sys as _sys

    _sys.stderr.write("Error: interrupted (Ctrl-C)\n")
    raise SystemExit(130) from None

__all__ = ["EXIT_INCOMPLETE", "main"]
