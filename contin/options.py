"""Frozen, validated settings (BifurcationKit's ContinuationPar / NewtonPar, as dataclasses).

Change a setting with :func:`dataclasses.replace`; every constructor validates and raises
``ValueError`` with a message naming the offending field.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field, fields
from typing import Any


def real_number(value: Any, what: str) -> float:
    """``value`` as a float; TypeError naming ``what`` for anything that is not one real number
    (a str, None, a complex, a sequence): before session 14 such values met a deep comparison
    ('<' not supported between 'str' and 'int', bad operand type for abs())."""
    if isinstance(value, numbers.Real):
        return float(value)
    if (not isinstance(value, str | bytes | complex | numbers.Complex) and value is not None
            and hasattr(value, "__float__") and getattr(value, "shape", ()) == ()):  # 0-d numpy arrays
        return float(value)
    raise TypeError(f"{what} must be a real number, got {value!r} ({type(value).__name__})")


def whole_number(value: Any, what: str) -> int:
    """``value`` as an int (10.0 is 10); TypeError naming ``what`` otherwise (2.5, '10', None)."""
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value) and float(value).is_integer():
        return int(value)
    raise TypeError(f"{what} must be a whole number, got {value!r} ({type(value).__name__})")


def _check_field_types(obj: Any) -> None:
    """The numeric fields of a frozen options dataclass, checked and stored as float / int by their
    annotation (``float``, ``int``, ``float | None``, ``int | None``)."""
    owner = type(obj).__name__
    for f in fields(obj):
        value = getattr(obj, f.name)
        kind = str(f.type)
        if value is None and kind.endswith("| None"):
            continue
        if kind in ("float", "float | None"):
            object.__setattr__(obj, f.name, real_number(value, f"{owner}.{f.name}"))
        elif kind in ("int", "int | None"):
            object.__setattr__(obj, f.name, whole_number(value, f"{owner}.{f.name}"))


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
        _check_field_types(self)
        # finite: tol = inf accepted any residual, step_tol = NaN or -1 failed every step as
        # "no convergence" (qa15)
        for name in ("tol", "step_tol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"NewtonOptions.{name} must be a finite number > 0, got {v}")
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
        _check_field_types(self)
        if not (self.ds_max >= abs(self.ds) >= self.ds_min > 0):
            raise ValueError(
                f"need ds_max >= |ds| >= ds_min > 0, got ds_max={self.ds_max}, ds={self.ds}, ds_min={self.ds_min}"
            )
        # each a clear error, not a hang (ds = inf looped forever halving an infinite step) nor a
        # run that never grows its step or fails at the first one (qa15: the CLI checked ds, the
        # library did not)
        if not math.isfinite(self.ds):
            raise ValueError(f"StepOptions.ds must be finite, got {self.ds}")
        if not (math.isfinite(self.theta) and self.theta > 0):
            raise ValueError(f"StepOptions.theta (the parameter's weight in the arclength norm) must be a finite "
                             f"number > 0, got {self.theta}")
        if not self.grow >= 1 or not math.isfinite(self.grow):
            raise ValueError(f"StepOptions.grow must be a finite number >= 1, got {self.grow}")
        if not 0 < self.shrink < 1:
            raise ValueError(f"StepOptions.shrink must lie in (0, 1), got {self.shrink}")
        if self.newton_target < 1:
            raise ValueError(f"StepOptions.newton_target must be >= 1, got {self.newton_target}")
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
    retry_unconfirmed_bp : branch-jump protection (``contin.continuation``).  When a BP test
        function changes sign across a step but the location does not confirm a BP (the
        locator does not converge, the test function does not vanish at the located point, or
        that point lies off the step), the step is checked by two half steps: if they end
        elsewhere, the step jumped onto another branch and is retried with half the ds (down
        to ds_min, where it is kept with the BP marked unconfirmed); if they end at the same
        point the step is kept as it is.  Every such step is logged in ``Branch.audit``.
        False: no check (every corrected step is kept).
    bp_eigenvalues : the second BP detector (``contin.bpdetect``): the k eigenvalues of J
        nearest zero at every point, real ones crossing zero counted across each step and
        cross-checked with the determinant tests (which miss kernels of even dimension and two
        BPs in one step); a disagreement re-takes the step with half the ds.  Located BPs then
        carry ``kernel dimension d`` in their note.  k > 0 forces it on, 0 off; the default
        None is on (k = :data:`BP_EIGS_AUTO`) for problems with at most :data:`BP_AUTO_MAX`
        unknowns (dense eigenvalues there cost a few ms per point; at n = 200 .. 400 they cost
        more than the continuation itself: Swift-Hohenberg N = 200 0.5 -> 3.2 s, disks tests
        +10 s each), without their own ``eigenproblem`` and that are no augmented system
        (``point_tests``): problems with an
        ``eigenproblem`` (gPCF, disks, nonlocal flows) get the second witness from their
        stability pass instead, whose audit checks every change of ``n_unstable`` against the
        located LPs/BPs at no extra cost (``contin.stability.audit``; the count of J's own
        eigenvalues is not meaningful there: J is the steady residual's Jacobian with
        algebraic rows, not the linearised dynamics).
    detect_hopf : Hopf points (HB, ``contin.hopf``): a complex pair of eigenvalues of
        J x = omega M x crossing the imaginary axis.  The default None means on for problems
        without their own ``eigenproblem`` (whose stability is a family in kx, kz: locate
        their Hopf points with ``contin.stability.locate_hopf`` / ``contin.hopfscan``) that
        are no augmented systems (fold and Hopf curves, which have ``point_tests``), and that
        have at most :data:`HOPF_AUTO_MAX` unknowns or a ``mass_matrix`` (above that size,
        M = I would count a discretization's algebraic rows as dynamics); eigenvalues by dense
        QZ up to HOPF_AUTO_MAX unknowns, else the ``hopf_eigs`` nearest 0 by shift-invert
        ARPACK (a pair beyond the hopf_eigs-th eigenvalue magnitude is not seen).  True /
        False force it (dense up to ``hopf_dense_max``).
    hopf_eigs : eigenvalues nearest 0 computed per point when n > ``hopf_dense_max`` (shift-
        invert ARPACK); all of them (dense QZ) below.
    """

    detect_folds: bool = True
    detect_branch_points: bool = True
    locate: bool = True
    locate_tol: float = 1e-11
    max_bisections: int = 60
    retry_unconfirmed_bp: bool = True
    bp_eigenvalues: int | None = None
    detect_hopf: bool | None = None
    hopf_eigs: int = 12
    hopf_dense_max: int = 400

    def __post_init__(self) -> None:
        _check_field_types(self)
        if not (math.isfinite(self.locate_tol) and self.locate_tol > 0):  # inf located LPs 1e-10 off, silently
            raise ValueError(f"DetectionOptions.locate_tol must be a finite number > 0, got {self.locate_tol}")
        if self.max_bisections < 1:
            raise ValueError(f"DetectionOptions.max_bisections must be >= 1, got {self.max_bisections}")
        if self.hopf_eigs < 2 or self.hopf_dense_max < 2:
            raise ValueError(f"hopf_eigs and hopf_dense_max must be >= 2, got {self.hopf_eigs}, {self.hopf_dense_max}")
        if self.bp_eigenvalues is not None and self.bp_eigenvalues < 0:
            raise ValueError(f"bp_eigenvalues must be >= 0 (0 switches the eigenvalue count off), got {self.bp_eigenvalues}")


#: k of the eigenvalue-count BP detector when DetectionOptions.bp_eigenvalues is None (auto).
BP_EIGS_AUTO = 12
#: DetectionOptions.bp_eigenvalues=None: the eigenvalue count is on up to this many unknowns.
BP_AUTO_MAX = 100

#: DetectionOptions.detect_hopf=None: Hopf detection with M = I (no mass_matrix) up to this many
#: unknowns, and the size up to which its eigenvalues are dense (shift-invert ARPACK above).
HOPF_AUTO_MAX = 100


#: Special-point types that ``ContinuationOptions.stop_at`` counts.
STOP_KINDS = ("LP", "BP", "UZ", "HB")


@dataclass(frozen=True)
class AdaptOptions:
    """Adaptive resolution settings (``ContinuationOptions.adapt``).

    tol : largest estimated relative discretization error of an accepted point (the problem's
        ``error_estimate``); the grid is refined where it is exceeded.  Default 3e-5: the
        fixed-grid guard's ``ContinuationOptions.resolution_tol``, so an adaptive run accepts no
        point a fixed-grid run would have refused.
    max_grid : largest grid size; an estimate above tol there ends the run with MX.
    min_grid : smallest grid size coarsening may choose.
    coarsen_below : coarsen where the estimate falls below coarsen_below * tol (None: never).
    growth : factor between successive grid sizes (unless the problem suggests a grid).
    multiple : grid sizes are rounded up to a multiple of this.
    cooldown : accepted steps after a grid change before coarsening is tried again.
    special_tol : largest relative error of a located special point's position: estimated by the
        kernel that fixes it (a BP's null vector, an LP's tangent) and, for an LP, a Hopf point or
        a symmetry-breaking BP, measured by a two-grid check (``contin.specialcheck``, which decides
        where both exist); the point is located again on a finer grid above min(tol, special_tol).  Default 1e-10: the states of a branch may carry
        tol = 3e-5, but BPs and LPs keep the accuracy of a fine fixed grid (gPCF H_n^c to ~1e-13
        at a cheb 16-32 kernel instead of 1e-8 at cheb 12; the kernel converges spectrally).
    check_factor : two-grid check of the *solve* before a point is accepted
        (:func:`contin.adapt.two_grid_error`): one Newton correction of the transferred state on
        a grid ``check_factor`` times finer measures the point's achieved error, the quantity
        ``contin verify`` measures at its default factor 2; above tol the point is refused and
        the grid refined, as for an estimate above tol.  The estimate (a coefficient tail or a
        defect) measures how well the grid carries the state, not the error of the discrete
        solution, which is that truncation amplified by ||J^-1|| next to a BP or LP (issue 14:
        3-150x on coarse gPCF grids).  None switches the check off (CLI ``--no-solve-check``).
    solve_check : whether the two-grid check of ``check_factor`` judges each accepted state (and
        each point of a regridded fold curve) besides its estimate; False (CLI
        ``--no-solve-check``) accepts states by their estimate alone, as the fixed-grid guard does,
        and keeps the two-grid checks of located special points' positions
        (``contin.specialcheck``), which ``check_factor = None`` switches off as well.
    check_above : the check runs only where the estimate exceeds check_above * tol: a state whose
        estimate is lower would miss tol only through an amplification above 1 / check_above
        (the largest measured, error / estimate on the gPCF main job, was 3e2); states exact on
        their grid (estimate at rounding level, e.g. uniform shear) are not checked.  On grids of
        finite ``convergence_order`` (FD) every state is checked: their estimate need not see
        the scheme's truncation error (``contin.adapt.estimate_decides_check``).
    """

    tol: float = 3e-5
    max_grid: int = 512
    min_grid: int = 8
    coarsen_below: float | None = 1e-3
    growth: float = 1.5
    multiple: int = 4
    cooldown: int = 5
    special_tol: float = 1e-10
    check_factor: float | None = 2.0
    check_above: float = 1e-4
    solve_check: bool = True

    def __post_init__(self) -> None:
        _check_field_types(self)
        if not (math.isfinite(self.tol) and self.tol > 0):
            raise ValueError(f"AdaptOptions.tol must be a finite number > 0, got {self.tol}")
        if self.check_factor is not None and not (math.isfinite(self.check_factor) and self.check_factor > 1):
            raise ValueError(f"AdaptOptions.check_factor must be a finite number > 1 or None, got {self.check_factor}")
        if not (math.isfinite(self.check_above) and 0 <= self.check_above < 1):
            raise ValueError(f"AdaptOptions.check_above must lie in [0, 1), got {self.check_above}")
        if not (math.isfinite(self.special_tol) and self.special_tol > 0):
            raise ValueError(f"AdaptOptions.special_tol must be a finite number > 0, got {self.special_tol}")
        if not 1 <= self.min_grid <= self.max_grid:
            raise ValueError(f"need 1 <= min_grid <= max_grid, got min_grid={self.min_grid}, max_grid={self.max_grid}")
        if self.coarsen_below is not None and not 0 < self.coarsen_below < 1:
            raise ValueError(f"coarsen_below must lie in (0, 1) or be None, got {self.coarsen_below}")
        if not (self.growth > 1 and math.isfinite(self.growth)):  # inf was accepted (qa15)
            raise ValueError(f"growth must be a finite number > 1, got {self.growth}")
        from contin.limits import MAX_GRID

        if self.max_grid > MAX_GRID:  # the command line's limit; 1e9 was accepted (a memory bomb, qa15)
            raise ValueError(f"AdaptOptions.max_grid must be at most {MAX_GRID}, got {self.max_grid}")
        if self.multiple < 1 or self.cooldown < 0:
            raise ValueError(f"need multiple >= 1 and cooldown >= 0, got {self.multiple}, {self.cooldown}")


@dataclass(frozen=True)
class ContinuationOptions:
    """Everything a continuation run needs besides the problem and the start point.

    bounds : {name: (lo, hi)} bounds on parameters (the run ends with EP at a bound).
    max_steps : maximum number of continuation steps (EP when reached).
    detect_closed : stop with EP 'closed loop' when the branch returns to its start.
    save_every : keep every k-th state in Branch.states (special points always kept).
    resolution_tol : largest estimated relative discretization error of an accepted state,
        passed to the problem's optional ``under_resolved(u, p, tol)`` hook
        (``contin.problem``); a converged point above it ends the run with MX *before* it is
        stored, with the problem's reason in the message.  ``None`` switches the guard off
        (e.g. for convergence studies that want the coarse grids' answers as they are).  It
        is a run setting, like the Newton tolerance, not a property of the problem: the
        problem defines the estimate, the user how much error a run may accept.  The default
        3e-5 is calibrated on gPCF (``problems.couette.resolution``): above the 3e-7 of the
        densest results that are right (pitchfork scene at nu = 0.3 and 0.15, cheb 64) and
        below the 5e-5 where spurious unstable modes appear (nu = 0.5, H = 36.7, cheb 64).
    adapt : :class:`contin.adapt.AdaptOptions` or None.  Adaptive resolution: the problem's
        grid is chosen at the start and changed along the branch so that its a-posteriori
        error estimate stays <= adapt.tol (refined above it, coarsened far below it), up to
        adapt.max_grid, past which the run ends with MX.  Needs the problem's grid hooks
        (``contin.problem``); the fixed-grid guard ``resolution_tol`` is then not used.
        None (default): the problem's grid throughout.
    stop_at : AUTO's STOP: labels like ``"LP1"`` or ``"BP2"`` (type and count along this
        run); the run ends with EP right after the k-th point of that type is located,
        e.g. when only the first fold of a branch is wanted and what lies beyond it is not.
        ``"UZ<k>"`` (AUTO's UZSTOP) and ``"HB<k>"`` work the same way.
    user_zeros : {parameter: values}: a UZ point wherever the continuation parameter takes
        one of the values (AUTO's UZR), located like a fold, with its state stored.
    events : {name: g(u, p) -> float}: a UZ point (note = name) at every zero of g along the
        branch (BifurcationKit's event functions); p is the dict of all parameters.
    """

    newton: NewtonOptions = field(default_factory=NewtonOptions)
    step: StepOptions = field(default_factory=StepOptions)
    detection: DetectionOptions = field(default_factory=DetectionOptions)
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    max_steps: int = 500
    detect_closed: bool = True
    save_every: int = 1
    resolution_tol: float | None = 3e-5
    stop_at: tuple[str, ...] = ()
    adapt: AdaptOptions | None = None
    user_zeros: dict[str, tuple[float, ...]] = field(default_factory=dict)
    events: dict[str, Callable[..., float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _check_field_types(self)
        if isinstance(self.stop_at, str):  # stop_at=("LP1") is the string 'LP1': one label, not 'L', 'P', '1'
            object.__setattr__(self, "stop_at", (self.stop_at,))
        object.__setattr__(self, "stop_at", tuple(self.stop_at))
        for label in self.stop_at:
            kind, count = label[:2], label[2:]
            if kind not in STOP_KINDS or not count.isdigit() or int(count) < 1:
                raise ValueError(f"stop_at labels are {', '.join(k + '<k>' for k in STOP_KINDS)} with k >= 1, got {label!r}")
        zeros = {}
        for name, values in self.user_zeros.items():
            if isinstance(values, str | bytes):  # '12' was iterated: UZ points at 1 and 2
                raise TypeError(f"user_zeros for {name!r} must be numbers, got the string {values!r}")
            if isinstance(values, numbers.Real):
                values = [values]
            vals = tuple(real_number(v, f"user_zeros for {name!r}") for v in values)
            if not all(math.isfinite(v) for v in vals):
                raise ValueError(f"user_zeros for {name!r} must be finite numbers, got {values!r}")
            zeros[str(name)] = tuple(dict.fromkeys(vals))  # '--uz lam=1,1,1' located each crossing 3 times
        object.__setattr__(self, "user_zeros", zeros)
        for name, fn in self.events.items():
            if not callable(fn):
                raise ValueError(f"event {name!r} must be a callable g(u, p) -> float")
        if self.max_steps < 1:
            raise ValueError(f"max_steps must be >= 1, got {self.max_steps}")
        if self.resolution_tol is not None and not (math.isfinite(self.resolution_tol) and self.resolution_tol > 0):
            raise ValueError(f"resolution_tol must be > 0 and finite (or None to switch the guard off), "
                             f"got {self.resolution_tol}")
        if self.save_every < 1:
            raise ValueError(f"save_every must be >= 1, got {self.save_every}")
        if not isinstance(self.bounds, dict):
            raise TypeError(f"bounds must be a dict {{name: (lo, hi)}}, got {type(self.bounds).__name__}")
        pairs = {}
        for name, pair in self.bounds.items():
            if isinstance(pair, str | bytes) or not hasattr(pair, "__len__") or len(pair) != 2:
                raise TypeError(f"bounds for {name!r} must be a pair (lo, hi) of numbers, got {pair!r}")
            lo, hi = (real_number(v, f"bounds for {name!r}") for v in pair)
            if not lo < hi:
                raise ValueError(f"bounds for {name!r} must satisfy lo < hi, got ({lo}, {hi})")
            pairs[name] = (lo, hi)
        object.__setattr__(self, "bounds", pairs)

    def __hash__(self) -> int:  # bounds is a dict; hash its items so options stay usable as keys
        return hash((self.newton, self.step, self.detection, tuple(sorted(self.bounds.items())),
                     self.max_steps, self.detect_closed, self.save_every, self.resolution_tol, self.stop_at,
                     tuple(sorted(self.user_zeros.items())), tuple(sorted(self.events.items(), key=lambda kv: kv[0])),
                     self.adapt))


#: (tol,) while a :func:`resolution_override` block is active, else None.
_RESOLUTION_OVERRIDE: ContextVar[tuple[float | None] | None] = ContextVar("resolution_override", default=None)


def check_resolution_tol(tol: float | None) -> float | None:
    """``tol`` as a float (None stays None); ValueError unless it is a finite number > 0."""
    if tol is None:
        return None
    value = float(tol)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"resolution_tol must be a finite number > 0 (or None to switch the guard off), got {tol}")
    return value


@contextmanager
def resolution_override(tol: float | None) -> Iterator[None]:
    """Within the block every trace uses ``tol`` as its resolution_tol (None: guard off),
    whatever its :class:`ContinuationOptions` say.

    For the command line's ``--resolution-tol``: scenes build their options internally (one
    per branch, fold curve or homotopy), so a run setting that must reach all of them is set
    for the run, not threaded through every scene.  Scoped (a context variable), so it ends
    with the block and does not leak into other threads' runs.
    """
    token = _RESOLUTION_OVERRIDE.set((check_resolution_tol(tol),))
    try:
        yield
    finally:
        _RESOLUTION_OVERRIDE.reset(token)


def effective_resolution_tol(options: ContinuationOptions) -> float | None:
    """The resolution_tol a trace uses: a :func:`resolution_override` if one is active, else
    ``options.resolution_tol``."""
    override = _RESOLUTION_OVERRIDE.get()
    return options.resolution_tol if override is None else override[0]
