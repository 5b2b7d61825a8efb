"""The ahead-of-time build of the compiled gPCF kernels (problems.couette.aot).

The module is numba's LLVM code for the same four kernels, so the engine's results must not
depend on which of the two serves: the ahead-of-time kernels are held bitwise to the JIT ones
on every wall/chi/gravity configuration, and a process that finds the module built must not
import numba (that import and the JIT cache load are what the module saves).  The fallbacks
(CONTIN_AOT=0, another process holding the build lock, a stale lock) are tested without a
build.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest

from problems.couette import aot, compiled
from problems.couette.model import CouetteProblem

pytestmark = pytest.mark.skipif(not compiled.available(), reason="numba is not installed")

CONFIGS = [(method, n, walls, chi, gravity)
           for method, n in (("cheb", 12), ("fd4", 40))
           for walls in ("noslip", "jj") for chi in ("jj", "cs", "ls") for gravity in (False, True)]


@pytest.fixture(scope="module")
def aot_module():
    """The built module (built here on a fresh machine: the first use of the engine does it)."""
    compiled._kernels()
    mod = aot.load()
    if mod is None:
        pytest.fail("the ahead-of-time kernels were not built (see the contin log for why)")
    return mod


@pytest.mark.parametrize("method,n,walls,chi,gravity", CONFIGS)
def test_aot_kernels_equal_the_jit_kernels_bitwise(aot_module, method, n, walls, chi, gravity):
    problem = CouetteProblem(method, n, engine="numba", walls=walls, chi=chi, gravity=gravity)
    p = problem.params({"H": 17.0, "nu": 0.3, "e": 0.8, "G": 1e-3 if gravity else 0.0})
    rng = np.random.default_rng(n)
    x = problem.initial_guess(p)
    x = x * (1.0 + 0.05 * rng.standard_normal(x.size))
    kernels = problem._compiled
    assert kernels._fields is aot_module.fields  # the engine runs the ahead-of-time module
    out_aot = (kernels.residual(x, p).copy(), kernels.jacobian(x, p).copy(), kernels.residual_dh(x, p).copy())
    kernels._fields, kernels._residual, kernels._jacobian, kernels._residual_dh = compiled._jit_kernels()
    kernels._cache = None
    out_jit = (kernels.residual(x, p), kernels.jacobian(x, p), kernels.residual_dh(x, p))
    for a, b in zip(out_aot, out_jit):
        assert np.all(np.isfinite(a))
        np.testing.assert_array_equal(a, b)


def test_a_process_with_the_module_built_does_not_import_numba(aot_module):
    code = ("import sys\n"
            "from problems.couette.model import CouetteProblem\n"
            "pr = CouetteProblem('cheb', 16, engine='numba')\n"
            "p = pr.params({'H': 10.0, 'nu': 0.3, 'e': 0.8})\n"
            "r = pr.residual(pr.initial_guess(p), p)\n"
            "print(pr.engine, 'numba' in sys.modules, float(abs(r).max()) < 1e-10)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "CONTIN_AOT": "1"})
    assert out.stdout.split() == ["numba", "False", "True"]


def test_contin_aot_0_runs_the_jit_kernels(monkeypatch):
    monkeypatch.setenv("CONTIN_AOT", "0")
    compiled._kernels.cache_clear()
    try:
        kernels = compiled._kernels()
        assert kernels == compiled._jit_kernels()
        assert aot.load() is None
    finally:
        compiled._kernels.cache_clear()


def test_a_held_build_lock_leaves_the_jit_kernels(tmp_path, monkeypatch):
    monkeypatch.setenv("CONTIN_AOT_DIR", str(tmp_path))
    (tmp_path / f"{aot.module_name()}.lock").write_text("12345")
    t0 = time.perf_counter()
    assert aot.build(compiled._jit_kernels(), compiled.kernel_argtypes()) is None  # no wait, no build
    assert time.perf_counter() - t0 < 1.0
    assert aot.module_path() is None


def test_a_stale_build_lock_is_taken_over(tmp_path):
    lock = tmp_path / "x.lock"
    lock.write_text("12345")
    old = time.time() - 2 * aot.STALE_LOCK_S
    os.utime(lock, (old, old))
    assert aot._acquire(lock)          # the stale lock is replaced by ours
    assert lock.read_text() == str(os.getpid())
    assert not aot._acquire(lock)      # and ours is respected


def test_the_module_key_changes_with_the_kernel_source(monkeypatch):
    name = aot.module_name()
    assert name.startswith("gpcf_kernels_") and len(name) == len("gpcf_kernels_") + 16
    monkeypatch.setattr(aot, "_version", lambda dist: "0.0.0")
    assert aot.module_name() != name
