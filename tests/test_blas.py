"""BLAS threads: the library limits them itself on small problems (contin.blas.small_matrices)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

# Runs in a fresh interpreter without the test session's global one-thread limit (conftest.py)
# and without OPENBLAS_NUM_THREADS: two BLAS threads outside, what trace and the stability pass
# see inside, and what is restored after.
_SCRIPT = """
import json
import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits
from contin.continuation import trace
from contin.options import ContinuationOptions, StepOptions
from contin.stability import stability_pass
from problems.demo import Bratu

def blas_threads():
    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

class Spy(Bratu):
    seen = []
    def jacobian(self, u, p):
        Spy.seen.append(blas_threads())
        return super().jacobian(u, p)

threadpool_limits(limits=2, user_api="blas")
before = blas_threads()
pb = Spy("cheb", 16)
br = trace(pb, np.zeros(pb.n), {"lam": 0.0}, "lam",
           ContinuationOptions(step=StepOptions(ds=0.2, ds_max=0.3), bounds={"lam": (0.0, 1.0)}, max_steps=5))
inside_trace = sorted({t for s in Spy.seen for t in s})
Spy.seen.clear()
stability_pass(pb, br, {})
inside_stability = sorted({t for s in Spy.seen for t in s})
print(json.dumps({"before": before, "trace": inside_trace, "stability": inside_stability, "after": blas_threads()}))
"""


def _run(**env):
    base = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "CONTIN_BLAS_THREADS",
                                                            "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, text=True, check=True,
                         env={**base, **env})
    return json.loads(out.stdout.splitlines()[-1])


def test_trace_and_stability_limit_blas_without_the_user_asking():
    r = _run()
    assert r["before"] == [2] and r["after"] == [2]  # the caller's setting is restored
    assert r["trace"] == [1] and r["stability"] == [1]


def test_limit_follows_the_environment():
    assert _run(CONTIN_BLAS_THREADS="0")["trace"] == [2]  # 0: leave BLAS alone
    assert _run(CONTIN_BLAS_SMALL="10")["trace"] == [2]  # 17 unknowns > 10: not a small problem


def test_nested_blocks_and_bad_values(monkeypatch):
    import pytest

    from contin.blas import small_matrices

    with small_matrices() as outer:
        with small_matrices() as inner:
            assert inner is None  # nested: the outer block already limits
    assert outer in (1, None)
    monkeypatch.setenv("CONTIN_BLAS_SMALL", "many")
    with pytest.raises(ValueError, match="CONTIN_BLAS_SMALL"):
        with small_matrices(10):
            pass
