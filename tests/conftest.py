"""Test-session set-up: one BLAS thread, as the CLI uses (contin.blas).

The tests factorize and diagonalize many small matrices; multithreaded OpenBLAS on a shared
2-core machine made some of them ten times slower without changing any result.
"""

from contin.blas import limit_blas_threads

limit_blas_threads(1)

# No heartbeat progress lines (contin.cli._runctl) unless a test asks for them: a slow machine
# must not add lines to the output of commands whose stderr the tests compare line by line.
import os  # noqa: E402

os.environ.setdefault("CONTIN_PROGRESS_SECONDS", "0")
