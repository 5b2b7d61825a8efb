"""BLAS threading for continuation-sized problems.

Continuation factorizes and diagonalizes many *small* matrices (a few hundred unknowns).
Multithreaded OpenBLAS loses on those: thread start-up and spinning cost more than the work,
and on a shared 2-core machine they fight the other processes.  Measured on the gPCF
``pitchfork`` scene (Chebyshev N = 64, k_x = 0 stability by dense QZ on 325 x 325 pencils):
31 s CPU / 88 s wall with the default threads, 4.8 s CPU with one BLAS thread.

:func:`limit_blas_threads` caps every loaded BLAS (numpy's and scipy's OpenBLAS are two
separate libraries) through ``threadpoolctl``.  The CLI calls it at start-up with
``CONTIN_BLAS_THREADS`` (default 1); library users decide themselves.
"""

from __future__ import annotations

import logging
import os

log = logging.getLogger("contin")

#: Environment variable read by :func:`limit_blas_threads` when ``n`` is None.
ENV = "CONTIN_BLAS_THREADS"


def limit_blas_threads(n: int | None = None) -> int | None:
    """Limit BLAS to ``n`` threads (None: ``$CONTIN_BLAS_THREADS``, default 1; 0 = leave alone).

    Returns the limit applied, or None when nothing was changed (n = 0, or threadpoolctl is
    not installed).  scipy.linalg is imported first so that scipy's own BLAS is loaded and
    limited too.
    """
    if n is None:
        text = os.environ.get(ENV, "1").strip()
        try:
            n = int(text)
        except ValueError:
            raise ValueError(f"{ENV} must be a whole number of threads, got {text!r}") from None
    if n < 0:
        raise ValueError(f"the BLAS thread limit must be >= 0, got {n}")
    if n == 0:
        return None
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: without it BLAS keeps its default threads
        log.debug("threadpoolctl not installed; BLAS threads not limited")
        return None
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401
    import scipy.sparse.linalg  # noqa: F401

    threadpool_limits(limits=n, user_api="blas")
    return n
