"""contin: pseudo-arclength continuation and bifurcation tracking for large sparse systems.

The core is import-light: plotting (``contin.plot``), HDF5 (``contin.io``) and the CLI
(``contin.cli``) are imported only when used, and the names below are resolved on first
access (PEP 562 ``__getattr__``), so ``import contin.cli`` (``contin --help``, ``--version``)
does not pay for numpy and scipy.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

#: public name -> defining module, imported on first access
_LAZY = {
    "Branch": "contin.branch",
    "SpecialPoint": "contin.branch",
    "ContinuationOptions": "contin.options",
    "DetectionOptions": "contin.options",
    "NewtonOptions": "contin.options",
    "StepOptions": "contin.options",
    "Problem": "contin.problem",
    "check_jacobian": "contin.problem",
    "from_functions": "contin.fromfunctions",
    "DiagramSettings": "contin.diagram",
    "bifurcation_diagram": "contin.diagram",
}

__all__ = [
    "Branch",
    "ContinuationOptions",
    "DetectionOptions",
    "DiagramSettings",
    "NewtonOptions",
    "Problem",
    "SpecialPoint",
    "StepOptions",
    "__version__",
    "bifurcation_diagram",
    "check_jacobian",
    "from_functions",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'contin' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
