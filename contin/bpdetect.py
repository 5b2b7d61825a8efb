"""A second branch-point detector: real eigenvalues of J crossing zero, cross-checked with the
determinant test functions (issue 12 sec. 3, "branch points that are never missed").

The determinant tests of ``contin.testfunctions`` see the *parity* of the number of real
eigenvalues of J = F_u that cross zero in a step: a kernel of even dimension (two eigenvalues
through zero together) and two simple branch points inside one step leave the sign unchanged
and are missed.  This module counts the crossings instead (BifurcationKit's eigenvalue-based
detection, ``detect_bifurcation = 3``; Govaerts 2000, sec. 3.3):

1. at every accepted point the ``k`` eigenvalues of J nearest zero (dense ``eigvals`` for
   n <= :data:`DENSE_EIG_LIMIT`, shift-invert ARPACK ``eigs(J, k, sigma=0)`` above, Lehoucq,
   Sorensen & Yang 1998, sec. 4.3);
2. across a step, the numbers of positive (p) and negative (m) real eigenvalues in the disc
   that both ends cover (all eigenvalues for dense spectra; else r = the smaller of the two
   k-th magnitudes): p_b - p_a = m_a - m_b = c, the net number of crossings (*conclusive*);
   unequal changes mean a collision into a complex pair or an eigenvalue crossing the rim of
   the disc, which a shorter step separates from a crossing;
3. the count is compared with the number of determinant tests that changed sign.  Agreement,
   or a single point where all counted eigenvalues vanish together (a BP of kernel dimension
   c: located by bisection on the count, the kernel dimension is the number of eigenvalues
   below :data:`KERNEL_GAP` times the next one), accepts the step; otherwise the step is
   re-taken with half the ds, up to :data:`MAX_HALVINGS` times, after which it is kept with an
   audit line and a note that says why the detectors still disagree.

Every BP located on a step the detector examined carries ``kernel dimension d`` in its note
(:func:`kernel_dimension` reads it back).  Net counting cannot see one eigenvalue going up
while another goes down inside one step; neither can the determinant (the step-size bound
ds_max is the user's control over that).
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from contin.branch import MAX_AUDIT, SpecialPoint
from contin.options import BP_AUTO_MAX, BP_EIGS_AUTO, DetectionOptions
from contin.problem import Array, has

if TYPE_CHECKING:
    from contin.continuation import _Point, _Tracer

log = logging.getLogger("contin")

#: Largest n for which all eigenvalues are computed densely.
DENSE_EIG_LIMIT = 400
#: An eigenvalue is real when |Im| <= REAL_TOL * max(1, |lambda|).
REAL_TOL = 1e-8
#: Kernel dimension at a located point: eigenvalues smaller than KERNEL_GAP times the next one.
KERNEL_GAP = 1e-4
#: Halvings of ds on one step while the detectors disagree, before the step is kept as it is.
MAX_HALVINGS = 8


def bp_eigen_count(problem: Any, detection: DetectionOptions, n: int) -> int:
    """k of the eigenvalue count on ``problem`` with n unknowns (0: off):
    ``detection.bp_eigenvalues`` if set, else :data:`contin.options.BP_EIGS_AUTO` for problems
    with at most :data:`contin.options.BP_AUTO_MAX` unknowns, without their own
    ``eigenproblem`` (whose stability pass is the second witness, ``contin.stability.audit``)
    and that are no augmented systems (``point_tests``: fold, BP and Hopf curves) nor opt
    out (``bp_eigen_auto = False``)."""
    if detection.bp_eigenvalues is not None:
        return int(detection.bp_eigenvalues)
    if n > BP_AUTO_MAX or has(problem, "eigenproblem") or has(problem, "point_tests"):
        return 0
    if getattr(problem, "bp_eigen_auto", True) is False:  # the problem opts out (contin.problem)
        return 0
    return BP_EIGS_AUTO


@dataclass(frozen=True)
class Spectrum:
    """The eigenvalues of J nearest zero at one point and the radius they cover (inf: all)."""

    values: np.ndarray
    radius: float

    def real_counts(self, r: float) -> tuple[int, int]:
        """(positive, negative) real eigenvalues with |lambda| < r."""
        w = self.values
        inside = np.abs(w) < r
        real = np.abs(w.imag) <= REAL_TOL * np.maximum(1.0, np.abs(w))
        sel = w.real[inside & real]
        return int(np.count_nonzero(sel > 0)), int(np.count_nonzero(sel < 0))


def spectrum(jac: Any, k: int) -> Spectrum:
    """Eigenvalues of J sorted by magnitude and the radius within which every eigenvalue is
    listed: all of them (radius inf) for n <= :data:`DENSE_EIG_LIMIT`, else the k - 1 nearest
    zero by shift-invert ARPACK, the k-th magnitude being the radius."""
    n = jac.shape[0]
    if n <= DENSE_EIG_LIMIT or k >= n - 1:
        a = jac.toarray() if sp.issparse(jac) else np.asarray(jac, dtype=float)
        import scipy.linalg as la  # lazy: the package is off the path to the first step (contin.lapack)

        w = la.eigvals(a)
        return Spectrum(w[np.argsort(np.abs(w))], math.inf)
    import scipy.sparse.linalg as spla  # lazy: off the main path (start-up)

    from contin.arpack import start_vector

    w = spla.eigs(sp.csc_matrix(jac), k=k, sigma=0.0, which="LM", return_eigenvectors=False, tol=1e-10,
                  v0=start_vector(n))
    w = np.asarray(w)[np.argsort(np.abs(w))]
    return Spectrum(w[:-1], float(abs(w[-1])))


def without_fixed(sa: Spectrum, sb: Spectrum) -> tuple[Spectrum, Spectrum, int]:
    """Both spectra without the eigenvalues that did not move in the step, and how many values
    were set aside.

    A Krylov method (ARPACK) returns the copies of a multiple eigenvalue unreliably: from one
    start vector the Krylov space holds one vector of each eigenspace, the others enter by
    rounding only (the Brusselator's four boundary rows, eigenvalue 1, came back three or four
    times, and the count of the disc changed by one with nothing crossing zero: an endless
    "inconclusive" and a branch that crawled to its step cap short of its Hopf point).  An
    eigenvalue whose value is the same at both ends (to :data:`REAL_TOL` relative) has crossed
    zero a net zero times, and so have all its copies: they are set aside at both ends.
    """
    a, b = sa.values, sb.values
    fixed_a, fixed_b = _found_in(a, b), _found_in(b, a)
    return (Spectrum(a[~fixed_a], sa.radius), Spectrum(b[~fixed_b], sb.radius),
            int(np.count_nonzero(fixed_a) + np.count_nonzero(fixed_b)))


def _found_in(w: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Which nonzero values of w are in ``other`` (to REAL_TOL relative); every copy counts."""
    if w.size == 0 or other.size == 0:
        return np.zeros(w.size, dtype=bool)
    close = np.abs(w[:, None] - other[None, :]) <= REAL_TOL * np.abs(w)[:, None]
    return (w != 0) & close.any(axis=1)


def disc_radius(sa: Spectrum, sb: Spectrum, k: int, moved: float = 0.0) -> float:
    """Radius of the disc in which crossings are counted.

    Far from zero, discretized operators have many eigenvalues that meet and turn complex, and
    a disc whose rim an eigenvalue crosses during the step miscounts.  The radius is therefore
    put in a gap between consecutive magnitudes of both ends' eigenvalues (the 2k smallest)
    where both ends have the same number of eigenvalues inside (nothing crossed the rim), above
    the smallest magnitude of each end and above ``moved`` (a bound on how far an eigenvalue
    moved in the step, ||J_b - J_a||_F: an eigenvalue that crossed zero is then inside at both
    ends; Bauer-Fike for normal J), choosing the widest such gap by ratio; the whole common
    range if there is none.  Equal counts inside do not prove that nothing crossed the rim: one
    eigenvalue may leave while another enters (AUTO's ``enz``: the real pair +-1.417 swapping
    magnitudes counted as a crossing, a spurious BP "not located (eigenvalue count only)"), so a
    cut must also lie farther than ``moved`` from every magnitude of both ends, which no
    eigenvalue can then have passed.
    """
    r = min(sa.radius, sb.radius)
    ma, mb = np.abs(sa.values), np.abs(sb.values)
    m = np.sort(np.concatenate([ma, mb]))
    m = m[m < r][: 2 * k]
    floor = max(float(np.min(ma, initial=0.0)), float(np.min(mb, initial=0.0)), moved)
    best, radius = 1.0, r
    for j in range(m.size - 1):
        if m[j] < floor or m[j] <= 0 or m[j + 1] / m[j] <= best:
            continue
        cut = math.sqrt(m[j] * m[j + 1])
        if min(cut - m[j], m[j + 1] - cut) <= moved:
            continue
        if np.count_nonzero(ma < cut) == np.count_nonzero(mb < cut):
            best, radius = m[j + 1] / m[j], cut
    return radius


def crossings(sa: Spectrum, sb: Spectrum, k: int = 12, moved: float = 0.0) -> tuple[int, bool, str]:
    """(number of real eigenvalues that crossed zero from a to b, conclusive, detail).

    In the disc |lambda| < r of :func:`disc_radius`, p = number of positive and m = number of
    negative real eigenvalues.  A real eigenvalue through zero moves one from one side to the
    other: p_b - p_a = m_a - m_b = the net number of crossings (the count is *conclusive*).  Two
    real eigenvalues meeting and turning complex (or the reverse) change one side by two and
    the other not at all: no crossing, also conclusive.  Anything else (an eigenvalue crossing
    the rim of the disc, or a crossing and a collision together) is inconclusive; a shorter
    step separates the events.  An inconclusive count is made again without the eigenvalues that
    did not move (:func:`without_fixed`: copies of a multiple eigenvalue that ARPACK returned at
    one end and not the other).
    """
    c, conclusive, detail = _count(sa, sb, k, moved)
    if not conclusive:
        ra, rb, n_fixed = without_fixed(sa, sb)
        if n_fixed:
            c2, conclusive2, detail2 = _count(ra, rb, k, moved)
            if conclusive2:
                return c2, True, f"{detail2} ({n_fixed} eigenvalues that did not move set aside)"
    return c, conclusive, detail


def _count(sa: Spectrum, sb: Spectrum, k: int, moved: float) -> tuple[int, bool, str]:
    r = disc_radius(sa, sb, k, moved)
    pa, ma = sa.real_counts(r)
    pb, mb = sb.real_counts(r)
    up, down = pb - pa, ma - mb
    rim = f"|lambda| < {r:.3g}" if math.isfinite(r) else "all eigenvalues"
    detail = f"real eigenvalues (+, -) {rim}: ({pa}, {ma}) -> ({pb}, {mb})"
    if up == down:
        return abs(up), True, detail
    if (up == 0 and down % 2 == 0) or (down == 0 and up % 2 == 0):
        return 0, True, detail + " (a collision into or out of a complex pair)"
    return abs(up), False, detail


def kernel_dimension_of(spec: Spectrum, scale: float = 0.0) -> int:
    """Size of the leading cluster of eigenvalues that is KERNEL_GAP below the next one (0 if
    the smallest eigenvalue is not separated from the rest like that).  ``scale`` (the largest
    eigenvalue magnitude at the step's ends) closes the list when every eigenvalue is in the
    cluster: n = 1, or a kernel as large as the matrix, has no "next" eigenvalue of its own
    (a scalar fold had kernel dimension 0 and the detectors disagreed at every fold)."""
    m = np.abs(spec.values)
    if math.isfinite(spec.radius):
        m = np.append(m, spec.radius)
    if scale > 0:
        m = np.append(m, scale)
    for j in range(m.size - 1):
        if m[j] < KERNEL_GAP * m[j + 1]:
            return j + 1
    return 0


_DIM = re.compile(r"kernel dimension (\d+)")


def kernel_dimension(point: SpecialPoint) -> int | None:
    """The kernel dimension recorded on a BP (None if it was not determined)."""
    m = _DIM.search(point.note)
    return int(m.group(1)) if m else None


def _audit(tracer: _Tracer, line: str) -> None:
    if len(tracer.audit) < MAX_AUDIT:
        tracer.audit.append(line)


def _with_note(sp_: SpecialPoint, text: str) -> SpecialPoint:
    return replace(sp_, note=(sp_.note + "; " if sp_.note else "") + text)


class EigenCounter:
    """The eigenvalue-count detector of one trace (module docstring)."""

    def __init__(self, k: int) -> None:
        self.k = int(k)
        self._cache: dict[int, tuple[Any, Spectrum, Any]] = {}
        self._halvings: dict[int, int] = {}

    def spectrum_at(self, tracer: _Tracer, pt: _Point) -> Spectrum:
        return self._at(tracer, pt)[0]

    def _at(self, tracer: _Tracer, pt: _Point) -> tuple[Spectrum, Any]:
        key = id(pt)
        hit = self._cache.get(key)
        if hit is not None and hit[0] is pt:
            return hit[1], hit[2]
        jac = tracer.system.state_jacobian(pt.x)
        spec = spectrum(jac, self.k)
        if len(self._cache) > 8:
            self._cache.clear()
        self._cache[key] = (pt, spec, jac)
        return spec, jac

    def moved(self, ja: Any, jb: Any) -> float:
        """||J_b - J_a||_F: bounds how far an eigenvalue of (normal) J moved in the step."""
        d = jb - ja
        if sp.issparse(d):
            import scipy.sparse.linalg as spla  # lazy: off the main path (start-up)

            return float(spla.norm(d))
        return float(np.linalg.norm(d))

    def dimension_at(self, tracer: _Tracer, x: Array, scale: float = 0.0) -> int:
        return kernel_dimension_of(spectrum(tracer.system.state_jacobian(x), self.k), scale)

    def check(self, tracer: _Tracer, cur: _Point, new: _Point, found: list[SpecialPoint], ds: float,
              can_halve: bool) -> list[SpecialPoint] | None:
        """The special points of the step cur -> new after the cross-check, or None: re-take the
        step with half the ds (``can_halve``: ds is above ds_min)."""
        sys = tracer.system

        def evaluate(s: float) -> _Point | None:
            corr = tracer.correct_at(cur.x + s * cur.t, cur.t)
            if not corr.converged or corr.factorization is None or sys.admissible(corr.x) is not None:
                return None
            return tracer.finish_point(corr, cur.t)

        s_new = sys.dot(cur.t, new.x - cur.x)
        (sa, ja), (sb, jb) = self._at(tracer, cur), self._at(tracer, new)
        c, conclusive, detail = crossings(sa, sb, self.k, self.moved(ja, jb))
        # a fold is a real eigenvalue through zero as well
        n_det = sum(sp_.type in ("BP", "LP") for sp_ in found)
        head = f"{sys.parameter}={cur.x[-1]:.10g} ds={ds:.3g}"
        halvings = self._halvings.get(id(cur), 0)
        retry_ok = can_halve and halvings < MAX_HALVINGS

        def retry(why: str) -> None:
            self._halvings[id(cur)] = halvings + 1
            _audit(tracer, f"{head} re-stepped with half ds: {why}")

        if not conclusive:
            if retry_ok:
                retry(f"eigenvalue count inconclusive ({detail})")
                return None
            if c == 0 and n_det == 0:
                return found
            _audit(tracer, f"{head} kept: eigenvalue count inconclusive after {halvings} halvings ({detail})")
            return [_with_note(s, "eigenvalue count inconclusive") if s.type == "BP" else s for s in found]
        if c == 0 and n_det == 0:
            return found
        bps = [s for s in found if s.type in ("BP", "LP")]
        scale = float(max(np.max(np.abs(sa.values), initial=0.0), np.max(np.abs(sb.values), initial=0.0)))
        dims = [self.dimension_at(tracer, sys.pack(s.state, s.params[sys.parameter]), scale) for s in bps]
        if n_det and sum(dims) == c and all(d >= 1 for d in dims):
            it = iter(dims)
            out = []
            for s in found:
                d = next(it) if s.type in ("BP", "LP") else 0
                if s.type == "BP" and not s.converged and d >= 2 and n_det == 1:
                    # the determinant's locator stalls next to a kernel of dimension > 1 (the
                    # bordered matrix is singular to order d there); bisection on the count does not
                    located = self._locate_first(tracer, cur, evaluate, s_new)
                    if located is not None and self.dimension_at(tracer, located[0], scale) == d:
                        x_bp, ok = located
                        s = replace(s, params=sys.params_at(x_bp[-1]), order_parameter=sys.order_parameter(x_bp),
                                    state=x_bp[:-1].copy(), converged=ok,
                                    note=s.note.replace("location did not converge", "located by the eigenvalue count"))
                out.append(_with_note(s, f"kernel dimension {d}") if s.type == "BP" else s)
            return out
        if n_det == 0 and c >= 2 and c % 2 == 0:
            # even crossing count, no determinant sign change: one BP of even kernel dimension,
            # or several BPs inside the step; locate the first crossing and look at its kernel
            located = self._locate_first(tracer, cur, evaluate, s_new)
            if located is not None:
                x_bp, bracket = located
                dim = self.dimension_at(tracer, x_bp, scale)
                if dim == c:
                    sp_ = SpecialPoint(
                        type="BP", index=len(tracer.points) - 1, params=sys.params_at(x_bp[-1]),
                        order_parameter=sys.order_parameter(x_bp), state=x_bp[:-1].copy(),
                        tangent=sys.unit(cur.t + new.t), bracket=(float(cur.x[-1]), float(new.x[-1])),
                        converged=bracket, note=f"kernel dimension {dim}; found by the eigenvalue count")
                    log.info("BP (kernel dimension %d) at %s=%.12g", dim, sys.parameter, x_bp[-1])
                    return sorted(found + [sp_], key=lambda s: sys.dot(cur.t, sys.pack(s.state, s.params[sys.parameter]) - cur.x))
        why = (f"{c} real eigenvalue(s) crossed zero but {n_det} determinant test(s) changed sign"
               f"{' (kernel dimensions at the located points: ' + ', '.join(map(str, dims)) + ')' if dims else ''}; {detail}")
        if retry_ok:
            retry(why)
            return None
        _audit(tracer, f"{head} kept after {halvings} halvings, detectors disagree: {why}")
        note = f"detectors disagree: {c} eigenvalue crossing(s) in the step"
        out = [_with_note(s, note) if s.type == "BP" else s for s in found]
        if n_det == 0:
            # never silent: a BP the determinant missed is stored, unlocated, at the step's end
            out.append(SpecialPoint(
                type="BP", index=len(tracer.points) - 1, params=sys.params_at(new.x[-1]),
                order_parameter=sys.order_parameter(new.x), state=new.x[:-1].copy(),
                tangent=sys.unit(cur.t + new.t), bracket=(float(cur.x[-1]), float(new.x[-1])),
                converged=False, note=f"{note}; not located (eigenvalue count only)"))
        return out

    def _locate_first(self, tracer: _Tracer, cur: _Point, evaluate: Callable[[float], _Point | None],
                      s_new: float) -> tuple[Array, bool] | None:
        """Bisection on the count for the first crossing after cur; (x, converged) or None."""
        sa, ja = self._at(tracer, cur)
        lo, hi = 0.0, s_new
        x_hi = None
        tol = tracer.options.detection.locate_tol * max(1.0, abs(cur.x[-1]))
        for _ in range(tracer.options.detection.max_bisections):
            if abs(hi - lo) <= tol:
                break
            for mid in (0.5 * (lo + hi), lo + 0.3 * (hi - lo), lo + 0.7 * (hi - lo)):
                pt = evaluate(mid)  # next to a singular point the corrector may fail: try aside
                if pt is not None:
                    break
            if pt is None:
                return None if x_hi is None else (x_hi, False)
            jm = tracer.system.state_jacobian(pt.x)
            c, conclusive, _ = crossings(sa, spectrum(jm, self.k), self.k, self.moved(ja, jm))
            if not conclusive:
                return None if x_hi is None else (x_hi, False)
            if c >= 1:
                hi, x_hi = mid, pt.x
            else:
                lo = mid
        if x_hi is None:
            pt = evaluate(hi)
            if pt is None:
                return None
            x_hi = pt.x
        return x_hi, abs(hi - lo) <= tol
