"""The baseline a user would otherwise write: ``scipy.integrate.solve_bvp`` on the gPCF BVP.

Steady granular plane Couette flow, no-slip / zero-flux walls, no gravity (physics.md
section 3(a)), Alam scaling.  State Y = (u, T, Q, nu, M), unknown shear stress S::

    u'  = S / (f2 sqrt T)
    T'  = -H^2 Q / (f4 sqrt T)
    Q'  = S^2 / (f2 sqrt T) - f5 T^{3/2}
    nu' = -f1 T' / (f1'(nu) T)              (g = 0: f1 T = const)
    M'  = nu

    u(-1/2) = -1/2, u(1/2) = 1/2, Q(-1/2) = Q(1/2) = 0, M(-1/2) = 0, M(1/2) = nubar.

Two things a careful user would write with it, both implemented here:

(a) :func:`natural_continuation` -- natural-parameter continuation in H: step H, reuse the
    previous solution (mesh, profiles, S) as the initial guess, halve the step on failure.
    By construction it cannot go round a fold (limit point): at ``nubar = 0.16`` (subcritical
    pitchfork, e = 0.8) it either stalls or jumps to another solution there, and
    :class:`NaturalResult` says which.
(b) :func:`critical_gap_by_pinning` -- the delta-pinning trick of physics.md section 7: H
    becomes a second unknown parameter fixed by the extra condition nu(1/2) = nubar + delta.
    Along the mode-1 branch H(delta) = H_1^c + a delta^2 + O(delta^4) (the branch is even in
    delta by the y -> -y symmetry), so Richardson extrapolation in delta^2 of H(delta),
    H(delta/2) estimates H_1^c, which is compared with the analytic n pi psi(nubar, e).

The Jacobians passed to solve_bvp are exact (complex step through the vectorized right-hand
side, 5 + k evaluations), which is the strongest version of this baseline: without them
solve_bvp falls back to forward differences (``exact_jacobian=False``).

References: J. Kierzenka & L. F. Shampine, ACM TOMS 27 (2001) 299 (the solve_bvp algorithm);
M. Alam et al., J. Fluid Mech. 523 (2005) 277 (the model).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_bvp

from problems.couette.closures import coefficients, critical_gap_factor, packing_limit, uniform_shear

Array = NDArray[np.float64]

#: Components of the state vector Y.
U, T, Q, NU, M = range(5)
_CS_STEP = 1e-30


@dataclass(frozen=True)
class GPCF:
    """Material and flow parameters of the gravity-free gPCF BVP (physics.md sections 1-3).

    nubar : mean volume fraction; e : particle restitution coefficient; chi, nu_max : radial
    distribution model and its packing limit (closures.radial_distribution).
    """

    nubar: float
    e: float = 0.8
    chi: str = "jj"
    nu_max: float = 0.65

    def __post_init__(self) -> None:
        limit = packing_limit(self.chi, self.nu_max)
        if not 0.0 < self.nubar < limit:
            raise ValueError(f"nubar must lie in (0, {limit}), got {self.nubar}")
        if not 0.0 < self.e <= 1.0:
            raise ValueError(f"e must lie in (0, 1], got {self.e}")

    def critical_gap(self, n: int = 1) -> float:
        """Analytic H_n^c = n pi psi(nubar, e) (physics.md section 4); nan if none exists."""
        return float(n * np.pi * critical_gap_factor(self.nubar, self.e, self.chi, self.nu_max))

    def rhs(self, x: Array, y: Array, s, h) -> Array:
        """dY/dy of the first-order system above; vectorized over nodes, complex-safe."""
        c = coefficients(y[NU], self.e, self.chi, self.nu_max)
        sqrt_t = np.sqrt(y[T])
        dt = -h * h * y[Q] / (c.f4 * sqrt_t)
        return np.array(
            [
                s / (c.f2 * sqrt_t),
                dt,
                s * s / (c.f2 * sqrt_t) - c.f5 * y[T] * sqrt_t,
                -c.f1 * dt / (c.f1_nu * y[T]),
                y[NU] + 0.0 * dt,
            ]
        )

    def uniform(self, x: Array) -> tuple[Array, float]:
        """Uniform shear (u = y, T = f2/f5, Q = 0, nu = nubar, M = nubar (y + 1/2)) and S0."""
        t0, s0, _ = uniform_shear(self.nubar, self.e, self.chi, self.nu_max)
        y = np.vstack([x, np.full_like(x, t0), 0.0 * x, np.full_like(x, self.nubar), self.nubar * (x + 0.5)])
        return y, float(s0)

    def mode(self, x: Array, h: float, n: int = 1) -> Array:
        """Neutral k_x = 0 mode n of uniform shear with nu-amplitude 1 (physics.md sections 4, 7).

        nu^ = cos k yt, T^ = -(p_nu / p_T) cos k yt, u^ = -(mu_nu + mu_T T^/nu^)/(mu0 k) sin k yt,
        Q^ = -(f4 sqrt T0 / H^2) T^', M^ = sin(k yt)/k; k = n pi, yt = y + 1/2.  nu(1/2) = nubar
        + (-1)^n times the amplitude.
        """
        c = coefficients(self.nubar, self.e, self.chi, self.nu_max)
        t0, _, _ = uniform_shear(self.nubar, self.e, self.chi, self.nu_max)
        k = n * np.pi
        yt = x + 0.5
        theta = -(c.f1_nu * t0) / c.f1
        mu0, mu_nu, mu_t = c.f2 * np.sqrt(t0), c.f2_nu * np.sqrt(t0), c.f2 / (2.0 * np.sqrt(t0))
        u_amp = -(mu_nu + mu_t * theta) / (mu0 * k)
        q_amp = c.f4 * np.sqrt(t0) / h**2 * theta * k
        return np.vstack(
            [u_amp * np.sin(k * yt), theta * np.cos(k * yt), q_amp * np.sin(k * yt), np.cos(k * yt), np.sin(k * yt) / k]
        )

    def admissible(self, y: Array) -> bool:
        """True if every node has finite values, T > 0 and 0 < nu < nu_max."""
        limit = packing_limit(self.chi, self.nu_max)
        return bool(np.all(np.isfinite(y)) and np.all(y[T] > 0) and np.all((y[NU] > 0) & (y[NU] < limit)))


# ---------------------------------------------------------------------------------------------
# solve_bvp callbacks.  p = [S] at fixed H, p = [S, H] with the pinning condition.


PINS = ("odd", "top")


def _callbacks(model: GPCF, h: float | None, delta: float | None, pin: str, exact_jacobian: bool):
    """fun, bc, fun_jac, bc_jac for solve_bvp (H fixed if ``delta`` is None, else pinned).

    pin = 'top': nu(1/2) - nubar = delta (physics.md section 7).  pin = 'odd':
    (nu(1/2) - nu(-1/2)) / 2 = delta, the part of the top-wall density that is odd under the
    reflection y -> -y, so that H(delta) is exactly even in delta (with 'top' the branch has
    H = H_c + a delta^2 + b delta^3 + ..., because nu(1/2) - nubar carries an O(A^2) even part).
    """
    pinned = delta is not None
    if pin not in PINS:
        raise ValueError(f"unknown pinning condition {pin!r}; choose one of {', '.join(PINS)}")
    odd = pin == "odd"

    def fun(x, y, p):
        return model.rhs(x, y, p[0], p[1] if pinned else h)

    def bc(ya, yb, p):
        res = [ya[U] + 0.5, yb[U] - 0.5, ya[Q], yb[Q], ya[M], yb[M] - model.nubar]
        if pinned:
            res.append(0.5 * (yb[NU] - ya[NU]) - delta if odd else yb[NU] - model.nubar - delta)
        return np.array(res)

    def fun_jac(x, y, p):
        n, m = y.shape
        k = p.size
        df_dy = np.empty((n, n, m))
        df_dp = np.empty((n, k, m))
        yc = y.astype(complex)
        for j in range(n):
            yc[j] += 1j * _CS_STEP
            df_dy[:, j, :] = fun(x, yc, p).imag / _CS_STEP
            yc[j] = y[j]
        for j in range(k):
            pc = p.astype(complex)
            pc[j] += 1j * _CS_STEP
            df_dp[:, j, :] = fun(x, y.astype(complex), pc).imag / _CS_STEP
        return df_dy, df_dp

    def bc_jac(ya, yb, p):
        k = p.size
        rows = 7 if pinned else 6
        dya, dyb, dp = np.zeros((rows, 5)), np.zeros((rows, 5)), np.zeros((rows, k))
        dya[0, U] = dyb[1, U] = dya[2, Q] = dyb[3, Q] = dya[4, M] = dyb[5, M] = 1.0
        if pinned:
            dyb[6, NU] = 0.5 if odd else 1.0
            dya[6, NU] = -0.5 if odd else 0.0
        return dya, dyb, dp

    if exact_jacobian:
        return fun, bc, fun_jac, bc_jac
    return fun, bc, None, None


@dataclass
class PointResult:
    """One solve_bvp call: the converged point (if any) and what it cost."""

    H: float
    S: float
    phi: float  # order parameter nu(1/2)
    success: bool
    status: int
    message: str
    seconds: float
    nodes: int
    iterations: int
    sol: object = field(default=None, repr=False)


def solve_point(
    model: GPCF,
    x: Array,
    y: Array,
    p: Array,
    *,
    h: float | None = None,
    delta: float | None = None,
    pin: str = "odd",
    tol: float = 1e-6,
    max_nodes: int = 20000,
    exact_jacobian: bool = True,
) -> PointResult:
    """One solve_bvp solve from the guess (x, y, p); H fixed (``h``) or pinned (``delta``).

    A result that solve_bvp reports as converged but that leaves the physical domain
    (non-finite, T <= 0 or nu outside (0, nu_max)) is marked unsuccessful.
    """
    if (h is None) == (delta is None):
        raise ValueError("give exactly one of h (fixed gap) or delta (pinned amplitude)")
    fun, bc, fun_jac, bc_jac = _callbacks(model, h, delta, pin, exact_jacobian)
    start = time.perf_counter()
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            sol = solve_bvp(fun, bc, x, y, p=np.asarray(p, float), fun_jac=fun_jac, bc_jac=bc_jac,
                            tol=tol, max_nodes=max_nodes)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError) as exc:
            return PointResult(float(h if h is not None else p[1]), float(p[0]), float("nan"), False, -1,
                               f"solve_bvp raised: {exc}", time.perf_counter() - start, x.size, 0)
    seconds = time.perf_counter() - start
    ok = bool(sol.success) and model.admissible(sol.y)
    message = sol.message if sol.success == ok else "left the physical domain (T <= 0, nu outside (0, nu_max) or nan)"
    return PointResult(
        H=float(sol.p[1] if delta is not None else h),
        S=float(sol.p[0]),
        phi=float(sol.y[NU, -1]),
        success=ok,
        status=int(sol.status),
        message=message,
        seconds=seconds,
        nodes=int(sol.x.size),
        iterations=int(sol.niter),
        sol=sol,
    )


def banded_guess(model: GPCF, h: float, amplitude: float, n: int = 1, nodes: int = 101):
    """Uniform shear plus ``amplitude`` times mode n: the guess (x, y, p=[S0]) near H_n^c."""
    x = np.linspace(-0.5, 0.5, nodes)
    y0, s0 = model.uniform(x)
    return x, y0 + amplitude * model.mode(x, h, n), np.array([s0])


# ---------------------------------------------------------------------------------------------
# (b) H_1^c by delta-pinning


@dataclass
class PinningResult:
    """H(delta) at the pinning amplitudes and the Richardson estimate of H_n^c."""

    deltas: tuple[float, ...]
    points: list[PointResult]
    estimate: float
    exact: float

    @property
    def success(self) -> bool:
        return all(pt.success for pt in self.points)

    @property
    def relative_error(self) -> float:
        return abs(self.estimate - self.exact) / self.exact

    @property
    def seconds(self) -> float:
        return sum(pt.seconds for pt in self.points)


def pinned_branch(
    model: GPCF,
    deltas,
    *,
    n: int = 1,
    pin: str = "odd",
    tol: float = 1e-6,
    nodes: int = 101,
    exact_jacobian: bool = True,
) -> list[PointResult]:
    """H(delta) along the mode-n branch by amplitude continuation in delta.

    The first delta starts from uniform shear + mode n at H = H_n^c (or H = 10 n if no finite
    H_n^c exists); each further delta starts from the previous solution.  pin = 'odd' needs an
    odd mode number (even modes leave nu(1/2) - nu(-1/2) = 0).
    """
    if pin == "odd" and n % 2 == 0:
        raise ValueError(f"pin='odd' cannot select the even mode n={n}; use pin='top'")
    hc = model.critical_gap(n)
    h0 = hc if np.isfinite(hc) else 10.0 * n
    deltas = list(deltas)
    sign = (-1) ** n
    x, y, p = banded_guess(model, h0, sign * deltas[0], n, nodes)
    p = np.array([p[0], h0])
    out = []
    for d in deltas:
        pt = solve_point(model, x, y, p, delta=d, pin=pin, tol=tol, exact_jacobian=exact_jacobian)
        out.append(pt)
        if not pt.success:
            break
        x, y, p = pt.sol.x, pt.sol.y, pt.sol.p
    return out


def richardson_delta2(deltas, heights) -> float:
    """Polynomial extrapolation of H(delta) = H_c + a delta^2 + b delta^4 + ... to delta = 0.

    With len(deltas) = m the first m - 1 even powers are eliminated (Lagrange interpolation in
    delta^2 evaluated at 0).
    """
    z = np.asarray(deltas, float) ** 2
    h = np.asarray(heights, float)
    total = 0.0
    for i in range(z.size):
        others = np.delete(z, i)
        total += h[i] * np.prod(others / (others - z[i]))
    return float(total)


def critical_gap_by_pinning(
    model: GPCF,
    *,
    n: int = 1,
    delta: float = 0.01,
    levels: int = 3,
    pin: str = "odd",
    tol: float = 1e-6,
    nodes: int = 101,
    exact_jacobian: bool = True,
) -> PinningResult:
    """H_n^c from H(delta / 2^(levels-1)), ..., H(delta/2), H(delta) by Richardson in delta^2.

    Error: O(delta^(2 levels)) truncation plus the solve_bvp error in H(delta), which scales
    like tol (its relative collocation residual) amplified by the O(1/delta) conditioning of
    the pinned problem (dF/dH vanishes on uniform shear).
    """
    if not np.isfinite(model.critical_gap(n)):
        raise ValueError(f"no finite H_{n}^c at nubar={model.nubar}, e={model.e} (no shear-banding instability)")
    # Smallest amplitude first: solve_bvp only ever inserts mesh nodes, so going down in delta
    # from a resolved large-amplitude mesh accumulates nodes (and can hit max_nodes).
    deltas = tuple(delta / 2**i for i in reversed(range(levels)))
    points = pinned_branch(model, deltas, n=n, pin=pin, tol=tol, nodes=nodes, exact_jacobian=exact_jacobian)
    ok = len(points) == levels and all(pt.success for pt in points)
    estimate = richardson_delta2(deltas, [pt.H for pt in points]) if ok else float("nan")
    return PinningResult(deltas, points, estimate, model.critical_gap(n))


# ---------------------------------------------------------------------------------------------
# (a) natural-parameter continuation in H


@dataclass
class NaturalResult:
    """Outcome of :func:`natural_continuation`.

    status : 'reached' (got to h_stop), 'failed' (step halved below dh_min without
        converging: stalled, typically at a fold), or 'jumped' (converged, but onto another
        solution: the order parameter moved far off the branch's extrapolation).
    points : the accepted converged points, in order.
    failed_solves : solve_bvp calls that did not converge (their time counts in ``seconds``).
    """

    status: str
    message: str
    points: list[PointResult]
    failed_solves: int
    seconds: float
    jump: PointResult | None = None

    @property
    def passed(self) -> bool:
        return self.status == "reached"

    @property
    def H(self) -> Array:
        return np.array([pt.H for pt in self.points])

    @property
    def phi(self) -> Array:
        return np.array([pt.phi for pt in self.points])

    @property
    def seconds_per_point(self) -> float:
        return self.seconds / max(len(self.points), 1)


def natural_continuation(
    model: GPCF,
    start: PointResult,
    h_stop: float,
    dh: float,
    *,
    dh_min: float | None = None,
    tol: float = 1e-6,
    jump_factor: float = 1.0,
    max_points: int = 10000,
    max_nodes: int = 20000,
    exact_jacobian: bool = True,
) -> NaturalResult:
    """Step H from ``start.H`` towards ``h_stop`` with step |dh|, halved on failure.

    The guess for each step is the previous solution (previous-point predictor: what a user
    writes around solve_bvp); after a success the step doubles back towards |dh|.  From the
    second step on, a converged point is rejected as a jump if its order parameter
    phi = nu(1/2) differs from the secant extrapolation of the last two points by more than
    ``jump_factor`` times the extrapolated change (a Newton correction larger than the
    predicted increment means another solution was found, e.g. the other side of a fold
    or the uniform state); the step is then halved as for a failure.  When the step falls
    below ``dh_min`` the run ends with 'jumped' if the last rejection was a jump, else
    'failed'.
    """
    if start.sol is None or not start.success:
        raise ValueError("natural_continuation needs a converged starting point")
    direction = np.sign(h_stop - start.H)
    dh = abs(dh) * direction
    dh_min = abs(dh) / 1024 if dh_min is None else abs(dh_min)
    points = [start]
    failed = 0
    seconds = 0.0
    step = dh
    last_jump: PointResult | None = None
    while len(points) < max_points:
        prev = points[-1]
        if (h_stop - prev.H) * direction <= 1e-12 * abs(h_stop):
            return NaturalResult("reached", f"reached H = {h_stop}", points, failed, seconds)
        h = prev.H + step
        if (h_stop - h) * direction < 0:
            h = h_stop
        pt = solve_point(model, prev.sol.x, prev.sol.y, prev.sol.p[:1], h=h, tol=tol, max_nodes=max_nodes,
                         exact_jacobian=exact_jacobian)
        seconds += pt.seconds
        jumped = False
        if pt.success and len(points) >= 2:
            p0 = points[-2]
            increment = (prev.phi - p0.phi) * (h - prev.H) / (prev.H - p0.H)
            jumped = abs(pt.phi - prev.phi - increment) > jump_factor * abs(increment) + 10 * tol * abs(prev.phi)
        if pt.success and not jumped:
            points.append(pt)
            last_jump = None
            step = dh if abs(2 * step) >= abs(dh) else 2 * step
            continue
        if pt.success:
            last_jump = pt
        else:
            failed += 1
        step /= 2
        if abs(step) < dh_min:
            if last_jump is not None:
                return NaturalResult(
                    "jumped",
                    f"beyond H = {prev.H:.6g} solve_bvp only converged onto another solution "
                    f"(phi = {last_jump.phi:.6g} at H = {last_jump.H:.6g}, branch had phi = {prev.phi:.6g})",
                    points, failed, seconds, last_jump,
                )
            return NaturalResult(
                "failed",
                f"no convergence beyond H = {prev.H:.6g} (step below {dh_min:.3g}): {pt.message}",
                points, failed, seconds,
            )
    return NaturalResult("failed", f"stopped after max_points = {max_points}", points, failed, seconds)


def banded_start(
    model: GPCF,
    delta: float,
    *,
    n: int = 1,
    pin: str = "odd",
    tol: float = 1e-6,
    steps: int = 8,
    nodes: int = 101,
    exact_jacobian: bool = True,
) -> PointResult:
    """A converged point on the mode-n branch with nu(1/2) - nubar = (-1)^n ... = ``delta``.

    Reached by amplitude (delta) continuation from a small amplitude in ``steps`` steps.
    """
    deltas = np.linspace(delta / steps, delta, steps)
    pts = pinned_branch(model, deltas, n=n, pin=pin, tol=tol, nodes=nodes, exact_jacobian=exact_jacobian)
    if len(pts) != steps or not pts[-1].success:
        raise RuntimeError(f"could not reach the mode-{n} branch at delta = {delta}: {pts[-1].message}")
    return pts[-1]


def fixed_h_point(model: GPCF, pinned: PointResult, *, tol: float = 1e-6, exact_jacobian: bool = True) -> PointResult:
    """Re-solve a pinned solution as an ordinary fixed-H point (p = [S]), for natural continuation."""
    sol = pinned.sol
    return solve_point(model, sol.x, sol.y, sol.p[:1], h=float(sol.p[1]), tol=tol, exact_jacobian=exact_jacobian)


def start_near_critical(
    model: GPCF, h: float, amplitude: float, *, n: int = 1, tol: float = 1e-6, nodes: int = 101,
    exact_jacobian: bool = True,
) -> PointResult:
    """Solve at fixed H just past H_n^c from uniform shear + ``amplitude`` times mode n.

    A result that fell back onto uniform shear (|phi - nubar| below 1e-3 |amplitude|) is marked
    unsuccessful: the guessed amplitude was too small (or H on the wrong side of H_n^c).
    """
    x, y, p = banded_guess(model, h, (-1) ** n * amplitude, n, nodes)
    pt = solve_point(model, x, y, p, h=h, tol=tol, exact_jacobian=exact_jacobian)
    if pt.success and abs(pt.phi - model.nubar) < 1e-3 * abs(amplitude):
        pt.success = False
        pt.message = f"converged onto uniform shear (phi - nubar = {pt.phi - model.nubar:.3g}); not on the banded branch"
    return pt


@dataclass
class FoldEstimate:
    """A fold (limit point) in H of the mode-n branch found by a delta-pinning scan."""

    H: float
    delta: float
    phi: float
    points: list[PointResult]


def fold_by_pinning(model: GPCF, deltas, *, n: int = 1, tol: float = 1e-8) -> FoldEstimate:
    """Locate min H(delta) on a scan of pinned amplitudes ``deltas`` (parabola through the
    smallest sample and its neighbours); the fold of the branch in H (a limit point, LP).

    Raises ValueError if the minimum lies at an end of the scan (no interior fold).
    """
    pts = pinned_branch(model, deltas, n=n, tol=tol)
    if len(pts) != len(deltas) or not all(pt.success for pt in pts):
        raise RuntimeError(f"pinning scan failed at delta = {deltas[len(pts) - 1]}: {pts[-1].message}")
    d = np.asarray(deltas, float)
    h = np.array([pt.H for pt in pts])
    phi = np.array([pt.phi for pt in pts])
    i = int(np.argmin(h))
    if i in (0, d.size - 1):
        raise ValueError("H(delta) has no interior minimum on this scan; widen the delta range")
    sl = slice(i - 1, i + 2)
    a, b, c = np.polyfit(d[sl], h[sl], 2)
    d_star = -b / (2 * a)
    return FoldEstimate(float(np.polyval([a, b, c], d_star)), float(d_star),
                        float(np.polyval(np.polyfit(d[sl], phi[sl], 2), d_star)), pts)
