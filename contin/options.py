"""Frozen, validated settings (BifurcationKit's ContinuationPar / NewtonPar, as dataclasses).

Change a setting with :func:`dataclasses.replace`; every constructor validates and raises
``ValueError`` with a message naming the offending field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass(frozen=True)
class NewtonOptions:
    """Newton corrector settings.

    tol : residual max-norm for convergence (also requires the Newton update below
        ``step_tol`` relative to the solution size).  On fine grids where rounding alone
        leaves a larger residual, eps * ||J||_inf * max(1, ||u||_inf) is used instead.
    max_iterations : iterations before the corrector gives up (the step is then retried
        with a smaller ds; it never raises out of the tracer).
    """

    tol: float = 1e-10
    step_tol: float = 1e-8
    max_iterations: int = 12

    def __post_init__(self) -> None:
        if not self.tol > 0:
            raise ValueError(f"NewtonOptions.tol must be > 0, got {self.tol}")
        if self.max_iterations < 1:
            raise ValueError(f"NewtonOptions.max_iterations must be >= 1, got {self.max_iterations}")


@dataclass(frozen=True)
class StepOptions:
    """Pseudo-arclength step-size control.

    ds : initial step (signed: its sign sets the initial direction of the parameter).
    ds_min, ds_max : bounds on |ds|; a step that fails at ds_min ends the run with MX.
    newton_target : Newton iterations aimed for; ds is scaled by newton_target/iterations
        (bounded by grow / shrink factors).
    max_angle : largest angle (radians) allowed between successive tangents.
    theta : weight of the parameter in the arclength norm (1 = equal weight).
    """

    ds: float = 0.01
    ds_min: float = 1e-8
    ds_max: float = 0.5
    newton_target: int = 4
    grow: float = 1.5
    shrink: float = 0.5
    max_angle: float = 0.3
    theta: float = 1.0
    predictor: str = "tangent"  # or "secant"

    def __post_init__(self) -> None:
        if not (self.ds_max >= abs(self.ds) >= self.ds_min > 0):
            raise ValueError(
                f"need ds_max >= |ds| >= ds_min > 0, got ds_max={self.ds_max}, ds={self.ds}, ds_min={self.ds_min}"
            )
        if self.predictor not in ("tangent", "secant"):
            raise ValueError(f"predictor must be 'tangent' or 'secant', got {self.predictor!r}")
        if not 0 < self.max_angle < math.pi / 2:
            raise ValueError(f"max_angle must be in (0, pi/2), got {self.max_angle}")


@dataclass(frozen=True)
class DetectionOptions:
    """Special-point detection and location.

    detect_folds, detect_branch_points : switch the LP / BP test functions on.
    locate_tol : tolerance on the continuation parameter for located points
        (relative to max(1, |p|)).
    max_bisections : iterations of the locator before it gives up (converged=False).
    """

    detect_folds: bool = True
    detect_branch_points: bool = True
    locate: bool = True
    locate_tol: float = 1e-11
    max_bisections: int = 60


@dataclass(frozen=True)
class ContinuationOptions:
    """Everything a continuation run needs besides the problem and the start point.

    bounds : {name: (lo, hi)} bounds on parameters (the run ends with EP at a bound).
    max_steps : maximum number of continuation steps (EP when reached).
    detect_closed : stop with EP 'closed loop' when the branch returns to its start.
    save_every : keep every k-th state in Branch.states (special points always kept).
    """

    newton: NewtonOptions = field(default_factory=NewtonOptions)
    step: StepOptions = field(default_factory=StepOptions)
    detection: DetectionOptions = field(default_factory=DetectionOptions)
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    max_steps: int = 500
    detect_closed: bool = True
    save_every: int = 1

    def __post_init__(self) -> None:
        if self.max_steps < 1:
            raise ValueError(f"max_steps must be >= 1, got {self.max_steps}")
        for name, (lo, hi) in self.bounds.items():
            if not lo < hi:
                raise ValueError(f"bounds for {name!r} must satisfy lo < hi, got ({lo}, {hi})")

    def __hash__(self) -> int:  # bounds is a dict; hash its items so options stay usable as keys
        return hash((self.newton, self.step, self.detection, tuple(sorted(self.bounds.items())),
                     self.max_steps, self.detect_closed, self.save_every))
