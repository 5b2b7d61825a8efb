"""Start-up structure (not timed): the CLI entry point and scene lookup import only what they use."""

from __future__ import annotations

import os
import subprocess
import sys

HEAVY = ("numpy", "scipy", "h5py", "matplotlib", "numba")


def _loaded(code: str, **env: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True, env={**os.environ, **env})
    return set(out.stdout.split())


def test_import_cli_loads_no_heavy_library():
    """``contin --help`` / ``--version`` import contin.cli only: no numpy, scipy, h5py, matplotlib, numba."""
    loaded = _loaded("import contin.cli")
    assert "contin.cli.trace" in loaded  # the commands are registered
    assert not {m for m in loaded if m.split(".")[0] in HEAVY}


_HELP_RUN = """
import io, sys, contextlib
from contin.cli import main
heavy = {heavy!r}
for args in [["--version"], ["--help"]] + [[name, "--help"] for name in sorted(main.commands)]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(args, prog_name="contin", standalone_mode=False)
    loaded = sorted(m for m in sys.modules if m.split(".")[0] in heavy)
    print(" ".join(args), code, len(out.getvalue().splitlines()), ",".join(loaded) or "-")
"""


def test_help_and_version_load_no_heavy_library():
    """``contin --help``, ``--version`` and ``contin CMD --help`` for every command, run in a fresh
    interpreter: each prints its text and exits 0, and none of them loads numpy, scipy, h5py,
    matplotlib or numba (the BLAS limit runs only when a command's body does, ContinCommand)."""
    out = subprocess.run([sys.executable, "-c", _HELP_RUN.format(heavy=HEAVY + ("threadpoolctl", "problems"))],
                         capture_output=True, text=True, check=True)
    rows = [line.split(" ") for line in out.stdout.splitlines()]
    from contin.cli import main

    assert len(rows) == 2 + len(main.commands) >= 12
    for *args, code, lines, loaded in rows:
        assert code in ("0", "None"), (args, code)
        assert int(lines) >= (1 if args == ["--version"] else 5), args
        assert loaded == "-", f"contin {' '.join(args)} loaded {loaded}"
    assert rows[0][-2] == "1"  # --version: one line


def test_command_body_still_limits_blas(monkeypatch):
    """The BLAS limit moved from the group callback to ContinCommand.invoke: a command that runs
    still applies it (CONTIN_BLAS_THREADS), and a bad value is one Error: line."""
    from click.testing import CliRunner

    import contin.blas
    from contin.cli import main

    calls = []
    monkeypatch.setattr(contin.blas, "limit_blas_threads", lambda n=None: calls.append(n))
    assert CliRunner().invoke(main, ["scenes"]).exit_code == 0
    assert calls == [None]
    assert CliRunner().invoke(main, ["scenes", "--help"]).exit_code == 0
    assert calls == [None]  # --help: not applied
    monkeypatch.undo()
    res = CliRunner().invoke(main, ["scenes"], env={"CONTIN_BLAS_THREADS": "many"})
    assert res.exit_code == 1 and "Error: CONTIN_BLAS_THREADS must be a whole number" in res.output


_DEFERRED = """
import sys
from contin.lazyimports import defer_numpy_tools
print(",".join(defer_numpy_tools()) or "-")
import scipy.sparse, scipy.linalg, scipy.sparse.linalg
print("numpy.f2py.crackfortran" in sys.modules, "unittest" in sys.modules)
import numpy as np
np.testing.assert_array_equal(np.arange(3), [0, 1, 2])  # the first access runs the module in full
import numpy.testing as npt
print(type(npt).__name__, npt is np.testing, "unittest" in sys.modules, callable(npt.assert_allclose))
"""


def test_numpy_tools_deferred_until_used():
    """contin.lazyimports: scipy's import (array_api_compat's clone of numpy's namespace) no longer
    executes numpy.f2py and numpy.testing; their first use does, and they then are the ordinary
    modules.  CONTIN_LAZY_NUMPY=0 leaves numpy alone."""
    out = subprocess.run([sys.executable, "-c", _DEFERRED], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["numpy.f2py,numpy.testing", "False", "False", "module", "True", "True", "True"]
    off = subprocess.run([sys.executable, "-c", _DEFERRED], capture_output=True, text=True, check=True,
                         env={**os.environ, "CONTIN_LAZY_NUMPY": "0"}).stdout
    assert off.split()[:3] == ["-", "True", "True"]


def test_a_running_command_defers_numpy_tools():
    """A command that runs (here ``contin scenes``, which imports every scene table and scipy)
    executes neither numpy.f2py nor numpy.testing."""
    loaded = _loaded("from contin.cli import main\ntry:\n    main(['scenes'])\nexcept SystemExit:\n    pass")
    assert "scipy.sparse" in loaded and "problems.couette.scenes" in loaded
    assert "numpy.f2py.crackfortran" not in loaded and "numpy.testing._private.utils" not in loaded


def test_lazy_package_attributes():
    """``import contin`` is light; ``contin.Branch`` etc. resolve on first access."""
    loaded = _loaded("import contin")
    assert not {m for m in loaded if m.split(".")[0] in HEAVY}
    import contin
    from contin.branch import Branch
    from contin.problem import check_jacobian

    assert contin.Branch is Branch and contin.check_jacobian is check_jacobian
    assert set(contin.__all__) <= set(dir(contin))


def test_get_scene_imports_only_what_it_needs():
    """Finding one scene stops at the table holding it (no scipy.optimize at import time)."""
    loaded = _loaded("import contin.scene as s; s.get_scene('pitchfork')", CONTIN_SCENES="")
    assert "problems.couette.scenes" in loaded
    assert "scipy.optimize" not in loaded and "h5py" not in loaded and "matplotlib" not in loaded


def test_main_path_modules_import_no_sparse_solvers():
    """The modules the main job (gPCF pitchfork) runs through import scipy.sparse.linalg (SuperLU,
    ARPACK) and scipy.sparse.csgraph only inside the functions that use them: the main job's
    dense path never does (checked on the whole run when this was written: HDF5 bitwise equal)."""
    loaded = _loaded("import contin.scene as s; s.get_scene('pitchfork')\n"
                     "import contin.continuation, contin.stability, contin.adapt, contin.io, contin.hopf, contin.normalform")
    assert "problems.couette.pitchfork" in loaded and "scipy.sparse" in loaded
    assert "scipy.sparse.linalg" not in loaded and "scipy.sparse.csgraph" not in loaded
    assert "scipy.linalg" not in loaded  # the LU routines come from contin.lapack


_LAPACK_RUN = """
import sys
import contin.linalg, contin.banded
from contin.blas import limit_blas_threads
from contin.lapack import flapack
from threadpoolctl import threadpool_info
limit_blas_threads(1)
direct = sorted((i["filepath"], i["num_threads"]) for i in threadpool_info())
print(flapack().__name__, "scipy.linalg" in sys.modules)
import scipy.linalg
print(direct == sorted((i["filepath"], i["num_threads"]) for i in threadpool_info()), len(direct),
      all(n == 1 for _, n in direct))
"""


def test_lapack_routines_without_scipy_linalg():
    """contin.linalg/contin.banded take dgetrf & co. from scipy's LAPACK extension without
    importing the scipy.linalg package, and the BLAS limit still reaches scipy's BLAS: importing
    scipy.linalg afterwards loads no library that was not already limited to one thread."""
    out = subprocess.run([sys.executable, "-c", _LAPACK_RUN], capture_output=True, text=True, check=True).stdout
    name, linalg_loaded, same, count, limited = out.split()
    assert (name, linalg_loaded, same, limited) == ("contin._scipy_lapack._flapack", "False", "True", "True")
    assert int(count) >= 1  # here numpy's and scipy's OpenBLAS; one where they share a BLAS


def test_lapack_direct_is_bitwise_the_public_api(monkeypatch):
    """contin.lapack's routines are scipy.linalg.lapack's: the same LU factors, pivots and solves,
    bit for bit, dense and banded; CONTIN_LAPACK_DIRECT=0 or a failed direct load gives the public
    module itself."""
    import numpy as np
    from scipy.linalg import lapack

    import contin.lapack as cl

    direct = cl.flapack()
    assert direct is not lapack and direct.__name__ == cl.PRIVATE_NAME
    rng = np.random.default_rng(7)
    a = np.asfortranarray(rng.standard_normal((40, 40)))
    b = rng.standard_normal((40, 3))
    for mod in (direct, lapack):
        lu, piv, info = mod.dgetrf(a)
        assert info == 0
    lu1, piv1, _ = direct.dgetrf(a)
    lu2, piv2, _ = lapack.dgetrf(a)
    assert np.array_equal(lu1, lu2) and np.array_equal(piv1, piv2)
    assert np.array_equal(direct.dgetrs(lu1, piv1, b)[0], lapack.dgetrs(lu2, piv2, b)[0])
    kl = ku = 2
    ab = np.zeros((2 * kl + ku + 1, 40), order="F")
    ab[kl:] = rng.standard_normal((kl + ku + 1, 40))
    f1, f2 = direct.dgbtrf(ab, kl, ku), lapack.dgbtrf(ab, kl, ku)
    assert all(np.array_equal(x, y) for x, y in zip(f1, f2))
    assert np.array_equal(direct.dgbtrs(f1[0], kl, ku, b, f1[1])[0], lapack.dgbtrs(f2[0], kl, ku, b, f2[1])[0])

    cl.flapack.cache_clear()
    try:
        monkeypatch.setenv(cl.ENV, "0")
        assert cl.flapack() is lapack
        cl.flapack.cache_clear()
        monkeypatch.delenv(cl.ENV)

        def broken() -> None:
            raise ImportError("another scipy layout")

        monkeypatch.setattr(cl, "_load_direct", broken)
        assert cl.flapack() is lapack
    finally:
        cl.flapack.cache_clear()


def test_get_scene_later_source_wins(monkeypatch):
    """get_scene takes a name from the same table as available_scenes (later sources override)."""
    import contin.scene as sc

    first = {"x": sc.Scene("x", "first", {}, lambda r: None)}
    second = {"x": sc.Scene("x", "second", {}, lambda r: None), "y": sc.Scene("y", "y", {}, lambda r: None)}

    def broken():
        raise ImportError("no such module")

    monkeypatch.setattr(sc, "_scene_sources", lambda: [("a", lambda: first), ("b", lambda: second), ("c", broken)])
    assert sc.available_scenes()["x"].summary == "second"
    assert sc.get_scene("x").summary == "second"
    assert sc.get_scene("y").summary == "y"
    try:
        sc.get_scene("z")
    except sc.SceneError as exc:
        assert "known scenes: x, y" in str(exc) and "1 scene module(s) failed" in str(exc)
    else:  # pragma: no cover
        raise AssertionError("unknown scene accepted")
    assert sc.SCENE_LOAD_ERRORS == [("c", "ImportError: no such module")]


def test_version_matches_the_package_metadata():
    """``contin --version`` prints contin.__version__ without a metadata scan: it must stay the
    installed package's version."""
    from importlib.metadata import version

    import contin

    assert contin.__version__ == version("contin")
