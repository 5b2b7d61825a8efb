"""Two-parameter continuation of a located special point (AUTO's restart at a label with two
free parameters, ``ICP=[p1, p2]``).

:func:`continue_point` dispatches on the point's type through :data:`CURVES`:

- ``LP`` -- the fold curve through the Moore-Spence system F = 0, J phi = 0, c.phi = 1
  (:class:`contin.foldcurve.FoldProblem`, as in :func:`contin.foldcurve.trace_fold_curve`);
- ``BP`` -- the same system.  At a simple symmetry-breaking pitchfork it is regular (Werner &
  Spence, SIAM J. Numer. Anal. 21, 1984): with a symmetry-preserving second parameter the
  curve is the curve of pitchforks; with a symmetry-breaking one it is the fold curve of the
  imperfect pitchfork, whose projection on (p1, p2) has its cusp at the BP.  At a
  transcritical BP unfolded by the second parameter it is the fold curve through the BP
  (lam x - x^2 + mu: x = lam/2, mu = -lam^2/4).  Where it is singular (a second parameter
  that keeps a transcritical BP) the corrector fails and the error says so;
- ``HB`` -- Hopf curves: registered by a Hopf module with :func:`register_curve`; until one
  is, asking for one is a clear error (:class:`NotAvailable`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

from contin.branch import Branch, SpecialPoint
from contin.continuation import join, trace
from contin.foldcurve import as_fold_curve, fold_start
from contin.options import ContinuationOptions

#: curve(problem, point, second, options, parameter=..., branch_id=...) -> Branch
CurveTracer = Callable[..., Branch]


class NotAvailable(ValueError):
    """Two-parameter continuation of this point type is not implemented (yet)."""


def _fold_or_pitchfork(problem: Any, point: SpecialPoint, second: str, options: ContinuationOptions, *,
                       parameter: str, branch_id: str) -> Branch:
    """Both halves of the Moore-Spence curve through ``point``.

    Unlike :func:`contin.foldcurve.trace_fold_curve` (halves chosen by the sign of d parameter/ds)
    the second half starts with minus the first half's start tangent: at a pitchfork unfolded by
    ``second`` the curve has a cusp in (p1, p2), p1 is extremal there (d p1/ds = 0) and the sign
    of d p1/ds cannot tell the halves apart.
    """
    fold, start = fold_start(problem, point, second)
    opts = replace(options, detection=replace(options.detection, detect_branch_points=False))
    common = dict(branch_id=branch_id, kind="fold-curve", parent=point.name)
    forward = trace(fold, start, dict(point.params), parameter, opts, direction=+1, **common)
    if forward.closed or len(forward) < 2:
        return as_fold_curve(forward, fold, opts)
    backward = trace(fold, start, dict(point.params), parameter, opts, direction=-1, tangent=forward.tangents[0],
                     **common)
    return as_fold_curve(join(backward, forward), fold, opts)


#: Point type -> tracer of its two-parameter curve.  A module that adds one (e.g. Hopf curves)
#: calls register_curve('HB', fn) on import.
CURVES: dict[str, CurveTracer] = {"LP": _fold_or_pitchfork, "BP": _fold_or_pitchfork}


def register_curve(point_type: str, tracer: CurveTracer) -> None:
    """Make :func:`continue_point` trace ``point_type`` points (e.g. 'HB') with ``tracer``."""
    CURVES[point_type] = tracer


def continue_point(problem: Any, branch: Branch, point: SpecialPoint, second: str,
                   options: ContinuationOptions, *, branch_id: str | None = None) -> Branch:
    """The curve of ``point`` (a located LP, BP or HB of ``branch``) in (branch.parameter, ``second``).

    Raises
    ------
    NotAvailable
        For a point type without a registered curve tracer (HB until Hopf curves exist; EP, MX...).
    ValueError
        For a bad second parameter, a point without a state, or a start the corrector cannot
        converge (e.g. a transcritical BP, where the fold system is singular).
    """
    first = branch.parameter
    names = tuple(getattr(problem, "parameter_names", ()))
    if second == first:
        raise ValueError(f"the second parameter must differ from the branch's parameter {first!r}")
    if names and second not in names:
        raise ValueError(f"unknown parameter {second!r}; the problem's parameters are {', '.join(names)}")
    if second not in point.params:
        raise ValueError(f"point {point.name} has no value of {second!r}")
    tracer = CURVES.get(point.type)
    if tracer is None:
        if point.type == "HB":
            raise NotAvailable(f"{point.name}: two-parameter continuation of Hopf points is not available yet "
                               "(no Hopf-curve tracer registered; contin.twoparam.register_curve('HB', ...))")
        raise NotAvailable(f"{point.name}: only {', '.join(sorted(CURVES))} points can be continued in two parameters, "
                           f"not {point.type}")
    if point.state is None:
        raise ValueError(f"{point.name} has no stored state")
    curve = tracer(problem, point, second, options, parameter=first,
                   branch_id=branch_id if branch_id is not None else f"{point.name}.{second}")
    if len(curve) <= 1:
        hint = (f" (the fold system is singular at a BP that {second!r} does not unfold)"
                if point.type == "BP" else "")
        raise ValueError(f"the {point.type} curve from {point.name} did not start: {curve.message}{hint}")
    return curve
