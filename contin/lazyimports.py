"""Start-up: numpy's developer tools (``numpy.f2py``, ``numpy.testing``) loaded only when used.

scipy >= 1.15 imports its vendored ``array_api_compat``, which clones numpy's namespace with
``hasattr(numpy, name)`` for every name in ``dir(numpy)``.  numpy loads its submodules on first
attribute access (PEP 562), so that clone imports ``numpy.f2py`` (a Fortran wrapper generator
that compiles ~200 regular expressions at import) and ``numpy.testing`` (with ``unittest``,
``email``, ``subprocess``): 40-60 % of ``import scipy.sparse`` on top of numpy, in every process
that touches scipy, for modules a continuation run never calls.

:func:`defer_numpy_tools` registers those two as lazy modules (the standard library's
:class:`importlib.util.LazyLoader`, the recipe of the importlib documentation) before scipy is
imported: the clone then finds the attribute without executing the module, and the first
attribute access anywhere (a test's ``numpy.testing.assert_allclose``) executes it in full, so
nothing a caller can observe changes but the time.  The CLI calls it before a command runs
(:class:`contin.cli._base.ContinCommand`); library users may call it before importing scipy.
``CONTIN_LAZY_NUMPY=0`` switches it off.
"""

from __future__ import annotations

import os
import sys

#: numpy submodules that no contin code path uses at run time (tests import them themselves)
TOOLS = ("f2py", "testing")
#: Environment variable: "0" leaves numpy's import alone.
ENV = "CONTIN_LAZY_NUMPY"


def defer_numpy_tools(names: tuple[str, ...] = TOOLS) -> list[str]:
    """Make ``numpy.<name>`` lazy for each name not imported yet; returns the modules deferred.

    A no-op (returns []) with ``CONTIN_LAZY_NUMPY=0``, for a module already imported, or when the
    module's loader cannot be made lazy (then numpy imports it as usual when asked).
    """
    if os.environ.get(ENV, "1").strip() == "0":
        return []
    import importlib.util

    import numpy

    deferred = []
    for short in names:
        name = f"numpy.{short}"
        if name in sys.modules:
            continue
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            continue
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            continue
        loader = importlib.util.LazyLoader(spec.loader)
        spec.loader = loader
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        loader.exec_module(module)  # executes nothing yet: the first attribute access does
        setattr(numpy, short, module)  # as the import system does for a loaded submodule
        deferred.append(name)
    return deferred
