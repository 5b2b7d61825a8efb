"""contin: pseudo-arclength continuation and bifurcation tracking for large sparse systems.

The core is import-light: plotting (``contin.plot``), HDF5 (``contin.io``) and the CLI
(``contin.cli``) are imported only when used.
"""

from contin.branch import Branch, SpecialPoint
from contin.options import ContinuationOptions, DetectionOptions, NewtonOptions, StepOptions
from contin.fromfunctions import from_functions
from contin.problem import Problem, check_jacobian

__version__ = "0.1.0"

__all__ = [
    "Branch",
    "ContinuationOptions",
    "DetectionOptions",
    "NewtonOptions",
    "Problem",
    "SpecialPoint",
    "StepOptions",
    "__version__",
    "check_jacobian",
    "from_functions",
]
