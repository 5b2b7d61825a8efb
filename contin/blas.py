"""BLAS threading for continuation-sized problems.

Continuation factorizes and diagonalizes many *small* matrices (a few hundred unknowns).
Multithreaded OpenBLAS loses on those: thread start-up and spinning cost more than the work,
and on a shared 2-core machine they fight the other processes.  Measured on the gPCF
``pitchfork`` scene (Chebyshev N = 64, k_x = 0 stability by dense QZ on 325 x 325 pencils):
31 s CPU / 88 s wall with the default threads, 4.8 s CPU with one BLAS thread.

:func:`limit_blas_threads` caps every loaded BLAS (numpy's and scipy's OpenBLAS are two
separate libraries) through ``threadpoolctl``.  The CLI calls it at start-up with
``CONTIN_BLAS_THREADS`` (default 1).

Library users need not: :func:`small_matrices` (a context manager and decorator) applies the
same limit for the duration of a call on problems of at most ``CONTIN_BLAS_SMALL`` unknowns
(default 5000) and restores the caller's setting afterwards.  :func:`contin.continuation.trace`
and the passes of :mod:`contin.stability` run inside it, so a plain
``from contin.continuation import trace`` gets one BLAS thread on small problems (measured: a
dense LU of a few hundred unknowns takes 11 ms with two fighting OpenBLAS threads on the shared
2-core machine, 0.5 ms with one).  ``CONTIN_BLAS_THREADS=0`` switches both off.
"""

from __future__ import annotations

import functools
import logging
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, TypeVar

log = logging.getLogger("contin")

#: Environment variable read by :func:`limit_blas_threads` when ``n`` is None.
ENV = "CONTIN_BLAS_THREADS"
#: Environment variable: the largest problem (unknowns) :func:`small_matrices` limits BLAS for.
ENV_SMALL = "CONTIN_BLAS_SMALL"
#: Default of ``CONTIN_BLAS_SMALL``: dense factorizations of up to a few thousand unknowns are
#: faster on one thread than on two competing ones (above that, threads start to pay).
SMALL_DEFAULT = 5000

_inside: ContextVar[bool] = ContextVar("contin_blas_limited", default=False)
F = TypeVar("F", bound=Callable[..., Any])


def limit_blas_threads(n: int | None = None) -> int | None:
    """Limit BLAS to ``n`` threads (None: ``$CONTIN_BLAS_THREADS``, default 1; 0 = leave alone).

    Returns the limit applied, or None when nothing was changed (n = 0, or threadpoolctl is
    not installed).  scipy's LAPACK extension is loaded first (:func:`contin.lapack.flapack`) so
    that scipy's own BLAS library is loaded and limited too.
    """
    if n is None:
        n = _env_threads()
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

    from contin.lapack import flapack

    flapack()  # scipy's BLAS/LAPACK library (scipy.linalg's and scipy.sparse.linalg's), without scipy.linalg
    threadpool_limits(limits=n, user_api="blas")
    return n


def _env_threads() -> int:
    text = os.environ.get(ENV, "1").strip()
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"{ENV} must be a whole number of threads, got {text!r}") from None


def _small_limit() -> int:
    text = os.environ.get(ENV_SMALL, str(SMALL_DEFAULT)).strip()
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"{ENV_SMALL} must be a whole number of unknowns, got {text!r}") from None


@contextmanager
def small_matrices(size: int | None = None) -> Iterator[int | None]:
    """Limit BLAS to ``CONTIN_BLAS_THREADS`` threads (default 1) inside the block, then restore.

    ``size``: the number of unknowns of the problem (None: assume small); nothing is changed
    above ``CONTIN_BLAS_SMALL`` unknowns, with ``CONTIN_BLAS_THREADS=0``, without threadpoolctl,
    or inside another ``small_matrices`` block (nesting costs nothing).  Yields the limit in
    force, or None.
    """
    if _inside.get() or (size is not None and size > _small_limit()):
        yield None
        return
    n = _env_threads()
    controller = _controller() if n > 0 else None
    if controller is None:
        yield None
        return
    token = _inside.set(True)
    try:
        with controller.limit(limits=n, user_api="blas"):
            yield n
    finally:
        _inside.reset(token)


@functools.lru_cache(maxsize=1)
def _controller() -> Any:
    """threadpoolctl's view of the loaded BLAS libraries, built once (scanning them costs ~5-10 ms;
    limiting through the cached controller ~0.03 ms).  None without threadpoolctl."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # optional: without it BLAS keeps its default threads
        log.debug("threadpoolctl not installed; BLAS threads not limited")
        return None
    import numpy  # noqa: F401

    from contin.lapack import flapack

    flapack()  # scipy's own BLAS (scipy.linalg's, scipy.sparse.linalg's): loaded first so that it is limited too

    return ThreadpoolController()


def limited(size_of: Callable[..., int | None] | None = None) -> Callable[[F], F]:
    """Decorator: run the function inside :func:`small_matrices` (``size_of(*args, **kwargs)``
    gives the problem size; default: assume small)."""

    def wrap(fn: F) -> F:
        @functools.wraps(fn)
        def inner(*args: Any, **kwargs: Any) -> Any:
            size = None
            if size_of is not None:
                try:
                    size = size_of(*args, **kwargs)
                except Exception:  # noqa: BLE001 -- a size we cannot tell is treated as small
                    size = None
            with small_matrices(size):
                return fn(*args, **kwargs)

        return inner  # type: ignore[return-value]

    return wrap
