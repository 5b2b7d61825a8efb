"""Two-grid checks of located special points: how far an LP, a BP or a Hopf point lies from
where a finer grid puts it, measured instead of inferred from the tail of its kernel.

Adaptive resolution (``contin.adapt``) locates LPs and BPs on the grid in force and, where the
kernel that fixes a point's position (an LP's tangent, a BP's null vector) has a coefficient
tail above ``special_tol``, locates it again on a finer grid.  The tail over-states the error of
the position: a BP is the eigenvalue-like quantity of its kernel, and its position converges
faster than the kernel (gPCF's H_1^c on Chebyshev 8: kernel tail 3.9e-3, position error 4e-6
relative).  The functions here measure the position's error directly, as
:func:`contin.adapt.two_grid_error` measures a state's: the located point (state, kernel,
parameter) is carried onto a grid ``check_factor`` times finer and one Newton step of the
point's defining system is solved there; the step is the difference between the coarse point
and the fine one to first order (the fine grid's own error subtracted: the error itself for
spectral grids, 1 - factor^-q of it for FD of order q).

- LP: one pseudo-arclength Newton step of the branch itself on the fine grid, bordered by the
  located tangent (regular at a quadratic fold); p is stationary at the LP, so the step's dp is
  the fold's parameter error to first order (:func:`fold_point_error`).  (The Moore-Spence fold
  system would give the same to first order at several times the cost: a 2n + 1 system with
  second derivatives.)
- BP on an S-invariant branch (symmetry-breaking): along the branch x(alpha) (alpha the
  arclength of the located tangent t), the system H(phi, alpha) = (J(x(alpha)) phi,
  c.phi - 1) = 0 with Jacobian M = [[J, m], [c^T, 0]], m = d/dalpha (J phi) (a central
  difference of J along t), is regular where the critical eigenvalue crosses zero with
  non-zero speed.  The branch state at the BP's parameter is first corrected on the fine grid
  with the same M (the correction orthogonal to c; the symmetric residual has no component
  along the antisymmetric left kernel, so the border's multiplier vanishes).  Other BPs
  (transcritical, or on branches without a symmetry) have no check: a fixed-parameter
  correction next to them is ambiguous between the crossing branches, and they keep the
  kernel-tail rule.
- HB (Hopf point): one Newton step of the Hopf defining system F = 0, J q = i omega M q,
  c^H q = 1 in (u, q, omega, p), in the real form of ``contin.hopfsystem``, from the carried
  state and critical eigenvector (:func:`hopf_point_error`).  A Hopf point has no kernel of J
  whose tail could be estimated: without this check only its state's estimate judged it, and an
  HB located on a coarse FD grid kept the scheme's O(h^2) error (Brusselator fd2 8: b_H 5e-4
  off) without a note, whatever special_tol asked for.

The error of the position is the parameter's relative change |dp| / max(|p|,
PARAM_SCALE_FLOOR); the state's relative change (the problem's ``solution_error`` norm,
``contin.adapt.solution_error``) is reported beside it (the branch's states are checked
against tol by the tracer's own two-grid checks).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contin.options import AdaptOptions
from contin.problem import Array

#: A position check whose error is at most this (relative) is not acted on where the kernel's
#: estimate met special_tol: below it the check's own rounding (its step solves a bordered
#: system with condition ~ 1/distance next to the point) can exceed the discretization's part.
POSITION_FLOOR = 1e-9

#: Relative step of the central difference of J phi along the branch tangent.
DIFFERENCE_STEP = 1e-6

#: The BP check is conclusive only where the multiplier of the fine state's bordered correction
#: (the residual's component along the left kernel, which the symmetric structure makes zero)
#: is at most this fraction of the residual's size: otherwise the structure is not there.
MULTIPLIER_SHARE = 1e-6
#: ... or of ROUNDING_TERMS x eps x ||J|| ||u|| where the residual itself is at rounding level.
ROUNDING_TERMS = 100.0


@dataclass(frozen=True)
class PointCheck:
    """Result of a special point's two-grid check on the grid ``grid``: ``error``, the relative
    error of the point's parameter (its position: |dp| / max(|p|, PARAM_SCALE_FLOOR), divided by
    1 - (N/N_f)^q for a discretization of order q, ``contin.adapt.richardson``);
    ``parameter_shift`` dp; ``state_error``: the state's relative change (the solve's error,
    which the branch's own two-grid checks bound by tol)."""

    error: float
    grid: int
    parameter_shift: float
    state_error: float = math.nan


def _relative_shift(dp: float, p: float) -> float:
    """|dp| / max(|p|, PARAM_SCALE_FLOOR) (``contin.adapt``)."""
    from contin.adapt import PARAM_SCALE_FLOOR

    return abs(dp) / max(abs(p), PARAM_SCALE_FLOOR)


def _carried(problem: Any, state: Array, tangent: Array, opts: AdaptOptions) -> tuple[int, Any, Array, Array] | None:
    """(check grid, the problem on it, the state and the tangent's state part carried there) for
    a point's two-grid check; None without ``check_factor`` or where the check grid rounds to
    the point's (``contin.adapt.check_grid``)."""
    from contin.adapt import check_grid, on_grid

    if opts.check_factor is None:
        return None
    n_f = check_grid(problem, opts.check_factor, opts)
    if n_f is None:
        return None
    fine = on_grid(problem, n_f)
    u = np.asarray(problem.transfer(np.asarray(state, dtype=float), fine), dtype=float)
    t_u = np.asarray(problem.transfer(np.asarray(tangent, dtype=float)[:-1], fine), dtype=float)
    return n_f, fine, u, t_u


def _point_check(problem: Any, fine: Any, n_f: int, parameter: str, q: dict[str, float], dp: float,
                 u: Array, u_fine: Array) -> PointCheck:
    """The PointCheck of a check's Newton step: the parameter's shift dp from q[parameter] (q is
    moved to p + dp) and the state's change u -> u_fine on the check grid ``fine``, both divided
    by 1 - (N/N_f)^q for a scheme of order q (:func:`contin.adapt.richardson`)."""
    from contin.adapt import richardson, solution_error

    p = float(q[parameter])
    q[parameter] = p + dp
    scale = richardson(problem, n_f)
    e = scale * _relative_shift(dp, p + dp)
    return PointCheck(e if math.isfinite(e) else math.inf, n_f, dp, scale * solution_error(fine, u, u_fine, q))


def fold_point_error(problem: Any, state: Array, params: Mapping[str, float], parameter: str,
                     tangent: Array, opts: AdaptOptions) -> PointCheck | None:
    """Two-grid error of a located LP (state u, the branch's unit tangent (du, dp) there, dp ~ 0):
    one Newton step of the extended system on the check grid, bordered by the pseudo-arclength
    row of the carried tangent,

        [J_f  F_p] [du]   [-F_f(u, p)]
        [ t_u t_p] [dp] = [     0    ],

    regular at a quadratic fold.  It lands on the fine branch at the point whose arclength
    coordinate along t is the LP's; as p is stationary at the LP, the fine LP's parameter
    differs from that point's by O(alpha^2) (alpha the two LPs' distance along the branch),
    so dp is the LP's parameter error to first order (module docstring).  None without
    ``check_factor`` or when the check grid rounds to the point's; error inf where the bordered
    matrix is singular there or the step is not finite."""
    from contin.adapt import factorizable_jacobian
    from contin.linalg import factorize_bordered

    carried = _carried(problem, state, tangent, opts)
    if carried is None:
        return None
    n_f, fine, u, t_u = carried
    t = np.asarray(tangent, dtype=float)
    q = {k: float(v) for k, v in params.items()}
    with np.errstate(all="ignore"):
        fact = factorize_bordered(factorizable_jacobian(fine, u, q),
                                  np.asarray(fine.dresidual_dp(u, q, parameter), dtype=float).ravel(),
                                  np.append(t_u, float(t[-1])))
        if fact is None:
            return PointCheck(math.inf, n_f, math.inf)
        delta = fact.solve(np.append(-np.asarray(fine.residual(u, q), dtype=float), 0.0))
    if not np.all(np.isfinite(delta)):
        return PointCheck(math.inf, n_f, math.inf)
    return _point_check(problem, fine, n_f, parameter, q, float(delta[-1]), u, u + delta[:-1])


def symmetric_bp_error(problem: Any, state: Array, params: Mapping[str, float], parameter: str,
                       tangent: Array, kernel: Array, opts: AdaptOptions) -> PointCheck | None:
    """Two-grid error of a located symmetry-breaking BP (state u on an S-invariant branch, the
    branch's unit tangent (du, dp), J's antisymmetric null vector ``kernel``): the fine state
    corrected with the bordered matrix M, then one Newton step of H(phi, alpha) (module
    docstring).  None without ``check_factor``, when the check grid rounds to the point's, or
    when the check is not conclusive (the bordered correction needs a multiplier: the point is
    not on a symmetric branch as assumed); error inf where M is singular or a step not finite."""
    from contin.adapt import factorizable_jacobian
    from contin.linalg import factorize_bordered, inf_norm

    carried = _carried(problem, state, tangent, opts)
    if carried is None:
        return None
    n_f, fine, u, t_u = carried
    phi = np.asarray(problem.transfer(np.asarray(kernel, dtype=float), fine), dtype=float)
    t_p = float(np.asarray(tangent, dtype=float)[-1])
    norm2 = float(phi @ phi)
    if not norm2 > 0:
        return None
    c = phi / norm2
    p = float(params[parameter])
    q = {k: float(v) for k, v in params.items()}

    def jac(v: Array, at: float) -> Any:
        return factorizable_jacobian(fine, v, {**q, parameter: at})

    # the step along the tangent: relative to the state's and the parameter's size
    h = DIFFERENCE_STEP * max(1.0, float(np.max(np.abs(u))), abs(p)) / max(float(np.max(np.abs(t_u))), abs(t_p), 1e-300)
    with np.errstate(all="ignore"):
        m = (jac(u + h * t_u, p + h * t_p) @ phi - jac(u - h * t_u, p - h * t_p) @ phi) / (2.0 * h)
        j0 = jac(u, p)
        fact = factorize_bordered(j0, np.asarray(m, dtype=float).ravel(), np.append(c, 0.0))
        if fact is None:
            return PointCheck(math.inf, n_f, math.inf)
        f = np.asarray(fine.residual(u, q), dtype=float)
        corr = fact.solve(np.append(-f, 0.0))
        if not np.all(np.isfinite(corr)):
            return PointCheck(math.inf, n_f, math.inf)
        # the multiplier's residual share, against the residual and, where that is at rounding
        # level (an exact state: uniform shear), against the rounding of its terms ||J|| ||u||
        f_size = float(np.max(np.abs(f), initial=0.0))
        floor = ROUNDING_TERMS * float(np.finfo(float).eps) * inf_norm(j0) * float(np.max(np.abs(u), initial=0.0))
        if abs(float(corr[-1])) * float(np.max(np.abs(m), initial=0.0)) > max(MULTIPLIER_SHARE * f_size, floor):
            return None  # the residual has a component along the left kernel: not the symmetric case
        u_f = u + corr[:-1]
        r = np.asarray(jac(u_f, p) @ phi, dtype=float).ravel()
        step = fact.solve(np.append(-r, 1.0 - float(c @ phi)))
    if not np.all(np.isfinite(step)):
        return PointCheck(math.inf, n_f, math.inf)
    alpha = float(step[-1])
    return _point_check(problem, fine, n_f, parameter, q, alpha * t_p, u, u_f + alpha * t_u)


def hopf_point_error(problem: Any, state: Array, params: Mapping[str, float], parameter: str,
                     tangent: Array, omega: float, eigenvector: Array | None, opts: AdaptOptions) -> PointCheck | None:
    """Two-grid error of a located Hopf point (state u, parameter p, frequency omega, the critical
    eigenvector q with J q = i omega M q; M the problem's ``mass_matrix``, else I): u and q are
    carried onto the check grid (the problem's linear ``transfer`` of Re q and Im q) and one
    Newton step of the Hopf defining system in (u, q, omega, p) is solved there,

        F(u, p) = 0,   J(u, p) q - i omega M q = 0,   c^H q = 1   (c: the carried q),

    in the real form of :class:`contin.hopfsystem.HopfCurveProblem` (Govaerts, *Numerical
    Methods for Bifurcations of Dynamical Equilibria*, SIAM 2000, sec. 4.4.2; Kuznetsov,
    *Elements of Applied Bifurcation Theory*, 3rd ed., sec. 10.2): with q scaled so that
    v = Re q has |v| = 1 and v . Im q = 0 (:func:`contin.hopfsystem.hopf_basis`) and w = M^-1 J v
    = -omega Im q, the unknowns (u, v, w, kappa = omega^2, p) solve

        F = 0,   J v - M w = 0,   J w + kappa M v = 0,   c . v = 1,   d . v = 0,

    c = v_f / |v_f|^2 and d the carried w made orthogonal to v_f (v_f: the carried v), so the
    two rows hold at the carried point (the real and imaginary part of c^H q = 1 up to the
    phase, which d fixes).  Its Jacobian is regular at a Hopf point whose pair crosses with
    non-zero speed (the derivatives of J q in u and p: central differences of J, as
    :func:`symmetric_bp_error`'s m).  The step's dp is the Hopf parameter's error to first
    order (the carried q is not the fine eigenvector: O(dp^2) remains).  ``eigenvector``: q on
    the point's grid, or None (computed here by inverse iteration from J - i omega M,
    :func:`contin.hopf.hopf_vectors`).  None without ``check_factor``, when the check grid rounds
    to the point's, without a positive finite omega, for problems with their own
    ``eigenproblem`` (their pencil is not (J, M)), or when no eigenvector is found; error inf
    where the augmented Jacobian is singular or the step not finite."""
    from contin.hopfsystem import HopfCurveProblem, hopf_basis
    from contin.linalg import factorize
    from contin.problem import has

    if not (math.isfinite(omega) and omega > 0) or has(problem, "eigenproblem"):
        return None
    carried = _carried(problem, state, tangent, opts)
    if carried is None:
        return None
    n_f, fine, u, _ = carried
    p = float(params[parameter])
    q = {k: float(v) for k, v in params.items()}
    try:
        with np.errstate(all="ignore"):
            v, w, _ = hopf_basis(problem, np.asarray(state, dtype=float), q, omega,
                                 None if eigenvector is None else np.asarray(eigenvector, dtype=complex))
    except (np.linalg.LinAlgError, RuntimeError, ValueError, ZeroDivisionError):
        return None
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(w))):
        return None
    v_f = np.asarray(problem.transfer(v, fine), dtype=float)
    w_f = np.asarray(problem.transfer(w, fine), dtype=float)
    vv = float(v_f @ v_f)
    d = w_f - (float(w_f @ v_f) / vv) * v_f if vv > 0 else w_f
    dd = float(np.linalg.norm(d))
    if not (vv > 0 and dd > 0):
        return None
    curve = HopfCurveProblem(fine, parameter, v_f / vv, d / dd)
    x = np.concatenate([u, v_f, w_f, [omega * omega, p]])
    with np.errstate(all="ignore"):
        fact = factorize(curve.jacobian(x, q))
        if fact is None:
            return PointCheck(math.inf, n_f, math.inf)
        delta = fact.solve(-np.asarray(curve.residual(x, q), dtype=float))
    if not np.all(np.isfinite(delta)):
        return PointCheck(math.inf, n_f, math.inf)
    return _point_check(problem, fine, n_f, parameter, q, float(delta[-1]), u, u + delta[:u.size])


def has_position_check(kind: str, symmetric: bool) -> bool:
    """Whether a located point of ``kind`` gets :func:`check_located`'s check: an LP, a Hopf
    point (HB), or a BP on an S-invariant branch (``symmetric``; the tracer's symmetry-breaking
    test)."""
    return kind in ("LP", "HB") or (kind == "BP" and symmetric)


def check_located(adaptor: Any, system: Any, points: list[Any], symmetric: bool,
                  kernels: list[Array | None] | None = None) -> float | None:
    """The measured error of where the located special points of one step lie (the worst over
    ``points``), for the tracer's adaptive resolution (``adaptor``: its
    ``contin.adapt.Adaptor``; ``system``: the extended system on the grid in force): each
    point's two-grid check (an LP's parameter, :func:`fold_point_error`; a Hopf point's,
    :func:`hopf_point_error`; a symmetry-breaking BP's on an S-invariant branch,
    ``symmetric``, :func:`symmetric_bp_error`), combined with its
    state's estimate.  None when some point has no check (:func:`has_position_check`, an
    inconclusive check, no ``check_factor``): the kernel estimate then decides.  ``kernels``:
    each point's BP null vector where the tracer already has it (``Adaptor.special_error``),
    else None (computed here).

    The tracer calls it on every located point: where the kernel estimate exceeds special_tol,
    which over-states the position's error (module docstring), the check spares a refinement
    and a second location where the position already meets it; where the estimate meets
    special_tol, it catches a position the estimate does not see (an FD scheme's error)."""
    from contin.adapt import DENSE_KERNEL_MAX, null_vector, richardson

    opts = adaptor.opts
    if opts.check_factor is None:
        return None
    worst, checked = 0.0, False
    for i, sp_ in enumerate(points):
        if sp_.type == "UZ":
            # A user zero lies on its value (or its event's zero) by construction: no position to
            # check, and its state is judged by the tracer's estimate.  It used to make the whole
            # step unchecked: `contin trace brusselator --uz b=5.2` kept the HB of the same step
            # 2.6e-9 off on cheb 8 (special_tol 1e-10) without a note, l1 50% off (session 14).
            continue
        if sp_.tangent is None or not has_position_check(sp_.type, symmetric):
            return None
        checked = True
        x = system.pack(sp_.state, sp_.params[system.parameter])
        if sp_.type == "LP":
            def measure(o: AdaptOptions, sp_: Any = sp_) -> PointCheck | None:
                return fold_point_error(system.problem, sp_.state, sp_.params, system.parameter, sp_.tangent, o)
        elif sp_.type == "HB":
            # the HB's omega is the point test's (contin.hopf); its eigenvector is not stored, so
            # hopf_point_error recomputes it on the point's grid (one LU of J - i omega M)
            def measure(o: AdaptOptions, sp_: Any = sp_) -> PointCheck | None:
                return hopf_point_error(system.problem, sp_.state, sp_.params, system.parameter, sp_.tangent,
                                        float(sp_.data.get("omega", math.nan)), None, o)
        else:
            kernel = None if kernels is None else kernels[i]
            if kernel is None:
                kernel = null_vector(system.state_jacobian(x, dense_ok=x.size - 1 <= DENSE_KERNEL_MAX))

            def measure(o: AdaptOptions, sp_: Any = sp_, kernel: Array = kernel) -> PointCheck | None:
                return symmetric_bp_error(system.problem, sp_.state, sp_.params, system.parameter, sp_.tangent,
                                          kernel, o)
        check = measure(opts)
        if check is None:
            return None
        if (math.isfinite(check.error) and check.error <= min(opts.tol, opts.special_tol)
                and check.error > POSITION_FLOOR and richardson(system.problem, check.grid) > 1.0):
            # a scheme of finite order passes on its nominal order only in the asymptotic range:
            # confirm it on a third grid (three_grid_error)
            wider = measure(replace(opts, check_factor=2.0 * opts.check_factor))
            if wider is not None and wider.grid > check.grid:
                p = float(sp_.params[system.parameter])
                check = replace(check, error=max(check.error, three_grid_error(
                    p, int(system.problem.grid_size), check, wider,
                    float(getattr(system.problem, "convergence_order")))))
        worst = max(worst, adaptor.error(system, x), check.error)
    return worst if checked else None


def three_grid_error(p: float, n: int, near: PointCheck, far: PointCheck, order: float) -> float:
    """The relative error of a special point's parameter p located on grid n, from its two-grid
    shifts to the grids ``near.grid`` and ``far.grid`` (one check each): with p(M) = p* + C M^-r
    through the three grids, the observed order r (Richardson's extrapolation with the order
    estimated, as in a grid-convergence study: Roache, *Verification and Validation in
    Computational Science and Engineering*, 1998, ch. 5) gives |p* - p| = |s_near| / (1 -
    (n / n_near)^r).  An FD scheme is pre-asymptotic on coarse grids (gPCF fd4 16 -> 32: H_1^c's
    error falls 1.2x, not 16x), where the nominal order's estimate under-states the error;
    there r < order and this estimate is the larger.  Where the shifts are not monotone (no
    observed order), the far shift scaled with the nominal order is returned.  inf for a
    non-finite shift."""
    s1, s2 = near.parameter_shift, far.parameter_shift
    if not (math.isfinite(s1) and math.isfinite(s2)):
        return math.inf
    d1, d2 = s1, s2 - s1  # p(near) - p(n), p(far) - p(near)
    a, b = n / near.grid, near.grid / far.grid
    if d1 * d2 <= 0 or abs(d2) >= abs(d1):
        # not (yet) converging monotonically: the point is at least the far shift off
        return _relative_shift(s2 / (1.0 - (n / far.grid) ** order), p)
    # d1 / d2 = (1 - a^r) / (a^r (1 - b^r)) (n^-r - near^-r over near^-r - far^-r), increasing in r
    target = d1 / d2

    def ratio(r: float) -> float:
        return (1.0 - a**r) / (a**r * (1.0 - b**r))

    lo, hi = 1e-3, 4.0 * order
    if ratio(hi) < target:  # faster than four times the nominal order: the nominal estimate
        return _relative_shift(d1 / (1.0 - a**order), p)
    for _ in range(100):  # bisection in r (ratio is monotone); 2^-100 of the bracket
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ratio(mid) < target else (lo, mid)
    return _relative_shift(d1 / (1.0 - a ** (0.5 * (lo + hi))), p)
