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


import pytest  # noqa: E402


@pytest.fixture(scope="session")
def ab_orbits(tmp_path_factory):
    """AUTO's demo ab traced by the command line (ab.h5), its orbits from HB1 continued for 40
    steps (cyc.h5, through the LPC) and exported as AUTO files (b.orb, s.orb, d.orb): the
    directory.  Shared by the orbit export and orbit profile tests (one continuation, not two)."""
    from click.testing import CliRunner

    from contin.cli import main

    def run(*args):
        return CliRunner().invoke(main, [str(a) for a in args])

    d = tmp_path_factory.mktemp("ab_orbits")
    r = run("trace", "ab", "-q", "-o", d / "ab.h5")
    assert r.exit_code == 0, r.output
    r = run("continue", d / "ab.h5", "--from", "HB1", "--cycles", "--max-steps", "40", "-o", d / "cyc.h5")
    assert r.exit_code == 0, r.output
    r = run("export", d / "cyc.h5", "--auto", "orb", "-d", d)
    assert r.exit_code == 0, r.output
    return d
