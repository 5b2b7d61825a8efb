"""LAPACK's LU routines for contin's factorizations, without importing the scipy.linalg package.

:mod:`contin.linalg` and :mod:`contin.banded` call four routines of scipy's f2py wrapper of
LAPACK, the extension module ``scipy.linalg._flapack`` (``dgetrf``/``dgetrs``, ``dgbtrf``/
``dgbtrs``; ``scipy.linalg.lapack.dgetrf`` *is* that module's function).  Reaching them through
``scipy.linalg`` first executes the package's ``__init__``: ~40 modules (QZ, SVD, matrix
functions, Sylvester solvers, ...), 0.05-0.1 s of start-up before the first continuation step,
which needs none of them.  :func:`flapack` loads the extension file itself, under a private
module name (scipy's own ``scipy.linalg._flapack`` is left to scipy), and falls back to the
public ``scipy.linalg.lapack`` when that fails for any reason (another layout in another scipy
version) or when ``CONTIN_LAPACK_DIRECT=0``.  Either way the routines are the same compiled
wrappers around the same LAPACK library, so results are bitwise those of the public API
(``tests/test_startup.py`` compares them).
"""

from __future__ import annotations

import functools
import os
from typing import Any

#: Environment variable: "0" takes the routines from ``scipy.linalg.lapack`` (the public API).
ENV = "CONTIN_LAPACK_DIRECT"
#: The private module name the extension is loaded under (the last part selects its init function).
PRIVATE_NAME = "contin._scipy_lapack._flapack"


@functools.cache
def flapack() -> Any:
    """scipy's ``_flapack`` extension module (or ``scipy.linalg.lapack``, the fallback)."""
    if os.environ.get(ENV, "1").strip() != "0":
        try:
            return _load_direct()
        except Exception:  # noqa: BLE001 -- any surprise: the public API below is always right
            pass
    from scipy.linalg import lapack

    return lapack


def _load_direct() -> Any:
    import importlib.machinery
    import importlib.util

    import numpy  # noqa: F401  (the extension's init imports numpy's C API)

    spec = importlib.util.find_spec("scipy")  # imports scipy/__init__ only (light), not scipy.linalg
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("scipy not found")
    for root in spec.submodule_search_locations:
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = os.path.join(root, "linalg", "_flapack" + suffix)
            if os.path.isfile(path):
                loader = importlib.machinery.ExtensionFileLoader(PRIVATE_NAME, path)
                ext = importlib.util.spec_from_file_location(PRIVATE_NAME, path, loader=loader)
                assert ext is not None
                module = importlib.util.module_from_spec(ext)
                loader.exec_module(module)
                for name in ("dgetrf", "dgetrs", "dgbtrf", "dgbtrs"):
                    getattr(module, name)  # a wrapper without them: the fallback
                return module
    raise ImportError("scipy.linalg._flapack not found")
