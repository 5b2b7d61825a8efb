"""Linear stability of steady states: the generalized eigenproblem A x = omega B x.

A steady state u* of  M du/dt = F(u, p)  is linearly stable when every finite eigenvalue
omega of  J x = omega M x  (J = dF/du at u*) has Re omega < 0.  Problems whose physical
linearisation is not the Jacobian of their steady residual (e.g. perturbations with
wavenumbers k_x, k_z, or steady formulations with auxiliary unknowns) provide
``eigenproblem(u, p, kx=..., kz=...) -> (A, B)`` instead (see :mod:`contin.problem`).

Singular B
    Rows of B that are zero (boundary conditions, algebraic constraints) give infinite
    eigenvalues.  QZ returns them as pairs (alpha, beta) with beta ~ eps ||B||, i.e.
    |omega| ~ ||A|| / (eps ||B||); they are discarded when |omega| exceeds
    ``inf_cutoff * ||A|| / ||B||`` (max-abs entry norms).  Physical eigenvalues of a
    discretised operator are bounded by about ||A|| ||B_reg^{-1}||, many orders of magnitude
    below the cutoff.

Counting unstable eigenvalues
    An eigenvalue counts as unstable when  Re omega > tol * max(1, |omega|):  relative to
    |omega| for eigenvalues larger than one time unit of the problem, absolute (tol) below.
    The absolute floor keeps rounding noise on exactly neutral eigenvalues (Re omega ~
    1e-14) out of ``n_unstable``; choose ``tol`` above the noise of your discretisation
    and below the growth rates you want to resolve.

Audit
    Along a branch, each fold (LP) or simple branch point (BP) is a real eigenvalue
    crossing zero and each Hopf point (HB, ``contin.hopf``) a complex pair crossing the
    imaginary axis, so ``n_unstable`` must change across it, and every change of
    ``n_unstable`` must be explained by such a point (a complex pair crossing where the tracer
    did not detect Hopf points is reported as unexplained; :func:`locate_hopf` locates it).
    This is the branch invariant of BifurcationKit's ``test_bif_detection.jl``.

References
----------
C. B. Moler & G. W. Stewart, "An algorithm for generalized matrix eigenvalue problems",
SIAM J. Numer. Anal. 10 (1973) 241 (QZ).  R. B. Lehoucq, D. C. Sorensen & C. Yang,
*ARPACK Users' Guide*, SIAM 1998, section 4.3 (shift-invert spectral transformation).
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from contin.blas import limited
from contin.branch import Branch
from contin.problem import has

log = logging.getLogger("contin")

#: Default tolerance of the unstable count (see the module docstring).
DEFAULT_TOL = 1e-8
#: Default number of eigenvalues computed by the sparse (ARPACK) path.
DEFAULT_SPARSE_K = 12

CArray = NDArray[np.complex128]


def _max_abs(m: Any) -> float:
    if sp.issparse(m):
        data = sp.csr_matrix(m).data
        return float(np.max(np.abs(data))) if data.size else 0.0
    return float(np.max(np.abs(m))) if np.size(m) else 0.0


def _sort(w: CArray, v: CArray | None) -> tuple[CArray, CArray | None]:
    """Real part descending; ties (conjugate pairs) with positive imaginary part first."""
    order = np.lexsort((-w.imag, -w.real))
    return w[order], None if v is None else v[:, order]


def eigenpairs(
    A: Any,
    B: Any,
    *,
    k: int | None = None,
    sigma: complex | None = None,
    dense_max: int = 600,
    inf_cutoff: float = 1e8,
    vectors: bool = True,
) -> tuple[CArray, CArray | None]:
    """Finite eigenvalues (and right eigenvectors) of A x = omega B x, sorted by Re descending.

    Parameters
    ----------
    A, B : (n, n) dense arrays or scipy.sparse matrices (real or complex); B may be singular.
    k : int, optional
        Number of eigenvalues returned.  Dense path: the k with the largest real part (all
        finite ones when None).  Sparse path: the k nearest ``sigma`` (default
        ``DEFAULT_SPARSE_K``), then sorted by real part.
    sigma : complex, optional
        Shift of the sparse path (default 0: for dissipative problems the least-stable
        eigenvalues are the ones nearest the origin).  Ignored by the dense path.
    dense_max : int
        Dense QZ (``scipy.linalg.eig(A, B)``) when n <= dense_max, else shift-invert ARPACK.
    inf_cutoff : float
        Eigenvalues with |omega| > inf_cutoff * max|A| / max|B| are infinite (singular B).
    vectors : bool
        Also return the eigenvectors as columns (None otherwise).

    Notes
    -----
    The sparse path does the spectral transformation itself: ARPACK finds the eigenvalues mu
    of largest modulus of OP = (A - sigma B)^{-1} B (one sparse LU of A - sigma B), and
    omega = sigma + 1/mu.  Infinite eigenvalues map to mu = 0, so they are never selected and
    B need not be symmetric or definite (scipy's ``eigs(A, M=B, sigma=...)`` requires that).

    Raises
    ------
    ValueError
        Shapes that do not match, or an empty matrix.
    """
    n = A.shape[0]
    if A.shape != (n, n) or B.shape != (n, n) or n == 0:
        raise ValueError(f"A and B must be square of the same size, got {A.shape} and {B.shape}")
    if n <= dense_max:
        return _dense_eigenpairs(A, B, k, inf_cutoff, vectors)
    return _sparse_eigenpairs(A, B, k, 0.0 if sigma is None else sigma, vectors)


def eigenvalues(
    A: Any,
    B: Any,
    *,
    k: int | None = None,
    sigma: complex | None = None,
    dense_max: int = 600,
    inf_cutoff: float = 1e8,
) -> CArray:
    """Finite eigenvalues of A x = omega B x sorted by real part descending.

    See :func:`eigenpairs` for the parameters (this is ``eigenpairs(..., vectors=False)[0]``).
    """
    return eigenpairs(A, B, k=k, sigma=sigma, dense_max=dense_max, inf_cutoff=inf_cutoff, vectors=False)[0]


def _dense_eigenpairs(A: Any, B: Any, k: int | None, inf_cutoff: float, vectors: bool) -> tuple[CArray, CArray | None]:
    a = A.toarray() if sp.issparse(A) else np.asarray(A)
    b = B.toarray() if sp.issparse(B) else np.asarray(B)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("the eigenproblem matrices contain NaN or inf entries")
    import scipy.linalg as la  # lazy: the package is off the path to the first step (contin.lapack)

    if vectors:
        ab, v = la.eig(a, b, right=True, homogeneous_eigvals=True)
    else:
        ab, v = la.eig(a, b, right=False, homogeneous_eigvals=True), None
    alpha, beta = ab
    scale_b = _max_abs(b)
    if scale_b == 0.0:
        raise ValueError("B is zero: the eigenproblem has no finite eigenvalues")
    cutoff = inf_cutoff * max(_max_abs(a), 1e-300) / scale_b
    finite = np.abs(alpha) < cutoff * np.abs(beta)
    w = (alpha[finite] / beta[finite]).astype(complex)
    w, v = _sort(w, None if v is None else v[:, finite].astype(complex))
    if k is not None:
        w = w[:k]
        v = None if v is None else v[:, :k]
    return w, v


def _sparse_eigenpairs(A: Any, B: Any, k: int | None, sigma: complex, vectors: bool) -> tuple[CArray, CArray | None]:
    n = A.shape[0]
    k = DEFAULT_SPARSE_K if k is None else k
    if not 0 < k < n - 1:
        raise ValueError(f"the sparse eigensolver needs 0 < k < n - 1, got k={k}, n={n}")
    a = sp.csc_matrix(A)
    b = sp.csc_matrix(B)
    dtype = np.result_type(a.dtype, b.dtype, np.asarray(sigma).dtype)
    import scipy.sparse.linalg as spla  # lazy: off the main path (start-up)

    lu = spla.splu(sp.csc_matrix(a - sigma * b, dtype=dtype))
    op = spla.LinearOperator((n, n), matvec=lambda x: lu.solve(np.asarray(b @ x, dtype=dtype)), dtype=dtype)
    ncv = min(n, max(2 * k + 1, 40))
    from contin.arpack import start_vector

    v0 = start_vector(n, dtype)
    if vectors:
        mu, v = spla.eigs(op, k=k, which="LM", ncv=ncv, v0=v0)
    else:
        mu, v = spla.eigs(op, k=k, which="LM", ncv=ncv, return_eigenvectors=False, v0=v0), None
    keep = np.abs(mu) > 1e-12 * np.max(np.abs(mu))
    w = sigma + 1.0 / mu[keep]
    return _sort(w.astype(complex), None if v is None else v[:, keep].astype(complex))


def count_unstable(w: CArray, tol: float = DEFAULT_TOL) -> int:
    """Number of eigenvalues with Re omega > tol * max(1, |omega|) (module docstring)."""
    w = np.asarray(w)
    return int(np.count_nonzero(w.real > tol * np.maximum(1.0, np.abs(w))))


@dataclass(frozen=True)
class StabilityResult:
    """Linear stability of one steady state.

    Attributes
    ----------
    eigenvalues : (n_eigs,) complex
        Leading finite eigenvalues, real part descending (padded with nan if fewer exist).
    n_unstable : int
        Unstable eigenvalues among all finite ones computed (:func:`count_unstable`).
    stable : bool
        ``n_unstable == 0``.
    tol : float
        Tolerance used for the count.
    kx, kz : float
        Wavenumbers of the perturbation (0 for the plain Jacobian).
    n_finite : int
        Number of finite eigenvalues the count looked at (all of them on the dense path).
    """

    eigenvalues: CArray
    n_unstable: int
    stable: bool
    tol: float
    kx: float = 0.0
    kz: float = 0.0
    n_finite: int = 0

    @property
    def leading(self) -> complex:
        """The least-stable eigenvalue."""
        return complex(self.eigenvalues[0])


def operator_pair(problem: Any, u: NDArray[np.float64], params: Mapping[str, float], *,
                  kx: float = 0.0, kz: float = 0.0) -> tuple[Any, Any]:
    """(A, B) of the stability problem of ``problem`` at (u, p).

    ``problem.eigenproblem(u, p, kx=kx, kz=kz)`` when the problem has it, else the Jacobian
    and ``problem.mass_matrix(u, p)`` (identity when absent).

    Raises
    ------
    ValueError
        kx or kz nonzero for a problem without ``eigenproblem``.
    """
    if has(problem, "eigenproblem"):
        return problem.eigenproblem(u, params, kx=kx, kz=kz)
    if kx != 0.0 or kz != 0.0:
        raise ValueError("this problem has no eigenproblem(u, p, kx, kz) method, so only kx = kz = 0 is available")
    A = problem.jacobian(u, params)
    B = problem.mass_matrix(u, params) if has(problem, "mass_matrix") else sp.identity(A.shape[0], format="csr")
    return A, B


def finite_spectrum(
    problem: Any,
    u: NDArray[np.float64],
    params: Mapping[str, float],
    *,
    kx: float = 0.0,
    kz: float = 0.0,
    n_eigs: int = 6,
    dense_max: int = 600,
    sigma: complex | None = None,
) -> CArray:
    """The finite eigenvalues :func:`stability_of_state` counts, real part descending.

    A x = omega B x from :func:`operator_pair`, solved by :func:`eigenvalues`: every finite
    eigenvalue on the dense path, the ``max(n_eigs, DEFAULT_SPARSE_K)`` nearest ``sigma`` on the
    sparse path (n > dense_max).
    """
    A, B = operator_pair(problem, u, params, kx=kx, kz=kz)
    k = None if A.shape[0] <= dense_max else max(n_eigs, DEFAULT_SPARSE_K)
    return eigenvalues(A, B, k=k, sigma=sigma, dense_max=dense_max)


def stability_of_state(
    problem: Any,
    u: NDArray[np.float64],
    params: Mapping[str, float],
    *,
    kx: float = 0.0,
    kz: float = 0.0,
    n_eigs: int = 6,
    tol: float = DEFAULT_TOL,
    dense_max: int = 600,
    sigma: complex | None = None,
) -> StabilityResult:
    """Leading eigenvalues and unstable count of the steady state ``u`` at ``params``.

    Solves A x = omega B x from :func:`operator_pair` with :func:`eigenvalues`
    (:func:`finite_spectrum`).  On the dense path every finite eigenvalue is counted; on the
    sparse path (n > dense_max) only the ``max(n_eigs, DEFAULT_SPARSE_K)`` eigenvalues nearest
    ``sigma``.
    """
    _check_n_eigs(n_eigs)
    w = finite_spectrum(problem, u, params, kx=kx, kz=kz, n_eigs=n_eigs, dense_max=dense_max, sigma=sigma)
    n_unst = count_unstable(w, tol)
    return StabilityResult(_leading(w, n_eigs), n_unst, n_unst == 0, tol, float(kx), float(kz), int(w.size))


def _check_n_eigs(n_eigs: int) -> None:
    if n_eigs < 1:
        raise ValueError(f"n_eigs must be >= 1, got {n_eigs}")


def _leading(w: CArray, n_eigs: int) -> CArray:
    """The first n_eigs of ``w``, padded with nan."""
    lead = np.full(n_eigs, np.nan + 0j)
    lead[: min(n_eigs, w.size)] = w[:n_eigs]
    return lead


#: Failures of one point's eigenproblem that leave its stability unknown while the pass goes on
#: (a singular shift, ARPACK not converging: RuntimeError includes ARPACK's ArpackError).
EIGENPROBLEM_ERRORS: tuple[type[BaseException], ...] = (np.linalg.LinAlgError, RuntimeError)


def stability_columns(
    branch: Branch,
    params_fixed: Mapping[str, float] | None,
    spectrum: Callable[[int, NDArray[np.float64], dict[str, float]], CArray],
    *,
    n_eigs: int = 6,
    tol: float = DEFAULT_TOL,
    errors: tuple[type[BaseException], ...] = EIGENPROBLEM_ERRORS,
    what: str = "stability",
) -> tuple[NDArray[np.bool_], NDArray[np.int64], CArray] | None:
    """(stable, n_unstable, eigenvalues (S x n_eigs)) of every stored point of ``branch``.

    The one per-point loop of every stability pass (:func:`stability_pass`,
    :func:`growth_columns`, problems with their own eigensolver).  ``spectrum(i, u, p)``
    returns the finite eigenvalues of point i (state u, parameters p: ``params_fixed`` updated
    with ``branch.params[name][i]``), real part descending; the point is unstable with
    ``count_unstable(w, tol)`` eigenvalues (all of ``w``), its ``n_eigs`` leading ones are stored
    (nan-padded).  A point whose state was not saved (``save_every > 1``) or whose ``spectrum``
    raised one of ``errors`` (logged as "<what> failed at point i of branch ...") keeps
    ``n_unstable = -1``, ``stable = False``, eigenvalues nan: unknown, not guessed.  A stop
    request (:func:`contin.cancel.stop_requested`, the first Ctrl-C/SIGTERM), asked between
    points, returns None: no wait for the rest of the pass (35 s on a gravity branch, qa17).
    """
    from contin.cancel import stop_requested

    _check_n_eigs(n_eigs)
    s = len(branch)
    stable = np.zeros(s, dtype=bool)
    n_unstable = np.full(s, -1, dtype=np.int64)
    eigs = np.full((s, n_eigs), np.nan + 0j)
    base = dict(params_fixed or {})
    for i in range(s):
        if stop_requested():
            return None
        p = {**base, **{name: float(values[i]) for name, values in branch.params.items()}}
        try:
            u = branch.state(i)
        except KeyError:  # save_every > 1 dropped this state: stability stays unknown
            continue
        try:
            w = spectrum(i, u, p)
        except errors as exc:
            log.warning("%s failed at point %d of branch %s: %s", what, i, branch.id, exc)
            continue
        n_unstable[i] = count_unstable(w, tol)
        stable[i] = n_unstable[i] == 0
        eigs[i] = _leading(w, n_eigs)
    return stable, n_unstable, eigs


def _warn_identity_mass(problem: Any, branch: Branch) -> None:
    """The UserWarning of a pass on a problem with neither mass_matrix nor eigenproblem (M = I),
    attributed to the caller of the pass."""
    if not has(problem, "mass_matrix") and not has(problem, "eigenproblem"):
        warnings.warn(f"stability of branch {branch.id}: the problem has no mass_matrix (M du/dt = F), so M = I and "
                      "algebraic rows (boundary conditions, constraints) count as dynamic equations and may count "
                      "as unstable; give the problem mass_matrix(u, p) with zero rows for them", UserWarning,
                      stacklevel=3)


def _point_spectrum(problem: Any, branch: Branch, *, kx: float, kz: float, n_eigs: int, dense_max: int,
                    sigma: complex | None) -> Callable[[int, NDArray[np.float64], dict[str, float]], CArray]:
    """:func:`finite_spectrum` of point i, each point on its own grid (adaptive runs,
    :func:`contin.adapt.point_problem`)."""
    from contin.adapt import point_problem

    def spectrum(i: int, u: NDArray[np.float64], p: dict[str, float]) -> CArray:
        return finite_spectrum(point_problem(problem, branch, i), u, p, kx=kx, kz=kz, n_eigs=n_eigs,
                               dense_max=dense_max, sigma=sigma)

    return spectrum


@limited()  # one BLAS thread for the small dense eigenproblems (contin.blas)
def stability_pass(
    problem: Any,
    branch: Branch,
    params_fixed: Mapping[str, float] | None = None,
    *,
    n_eigs: int = 6,
    tol: float = DEFAULT_TOL,
    kx: float = 0.0,
    kz: float = 0.0,
    dense_max: int = 600,
    shift: complex | None = None,
) -> None:
    """Fill ``branch.stable``, ``branch.n_unstable`` and ``branch.eigenvalues`` (S x n_eigs).

    ``shift`` is the shift sigma of the sparse (shift-invert) path (n > dense_max): the
    eigenvalues nearest it are computed (default 0).  A problem with neither ``mass_matrix``
    nor ``eigenproblem`` is solved with M = I, so its algebraic rows (boundary conditions such
    as u_0 = 0) act as dynamic equations and may count as unstable: a UserWarning says so.

    The parameters at point i are ``params_fixed`` updated with ``branch.params[name][i]``
    for every name the branch records.  A point whose eigenproblem fails (singular shift,
    ARPACK not converging) is logged and marked ``n_unstable = -1``, ``stable = False``,
    eigenvalues nan; :func:`audit` reports such points instead of guessing.  A stop request
    (:func:`contin.cancel.stop_requested`, asked between points) ends the pass with the branch
    left without stability columns.
    """
    s = len(branch)
    for name, values in branch.params.items():
        if len(values) != s:
            raise ValueError(f"branch parameter {name!r} has {len(values)} values but the branch has {s} states")
    _warn_identity_mass(problem, branch)
    columns = stability_columns(branch, params_fixed, _point_spectrum(problem, branch, kx=kx, kz=kz, n_eigs=n_eigs,
                                                                      dense_max=dense_max, sigma=shift),
                                n_eigs=n_eigs, tol=tol)
    if columns is None:  # stopped: the branch stays without stability (--resume fills it)
        return
    branch.stable, branch.n_unstable, branch.eigenvalues = columns
    branch.stability_k = (float(kx), float(kz))


@limited()
def growth_columns(
    problem: Any,
    branch: Branch,
    params_fixed: Mapping[str, float] | None = None,
    *,
    kx: float,
    kz: float = 0.0,
    tol: float = DEFAULT_TOL,
    dense_max: int = 600,
) -> dict[str, NDArray[np.float64]]:
    """Stability along a branch at extra wavenumbers, as observable columns.

    Returns ``{"growth_rate_kx<kx>": max Re omega, "n_unstable_kx<kx>": unstable count}``
    (``<kx>`` formatted with ``:g``; ``_kz<kz>`` appended when kz != 0), shape (S,); nan
    where the state was not saved or the eigenproblem failed.
    """
    _warn_identity_mass(problem, branch)
    columns = stability_columns(branch, params_fixed, _point_spectrum(problem, branch, kx=kx, kz=kz, n_eigs=1,
                                                                      dense_max=dense_max, sigma=None),
                                n_eigs=1, tol=tol, what=f"stability at kx={kx:g}")
    if columns is None:  # the first Ctrl-C/SIGTERM: no columns rather than a wait for the whole pass
        return {}
    _, n_unstable, eigs = columns
    suffix = f"_kx{kx:g}" + (f"_kz{kz:g}" if kz != 0.0 else "")
    return {"growth_rate" + suffix: eigs[:, 0].real.copy(),
            "n_unstable" + suffix: np.where(n_unstable >= 0, n_unstable, np.nan)}


def _crossing_counts(points: list[Any]) -> list[int] | None:
    """Eigenvalues through the imaginary axis at each point (LP 1, HB 2, BP its kernel dimension),
    or None unless some BP has a recorded kernel dimension (``contin.bpdetect``) and all are known."""
    from contin.bpdetect import kernel_dimension

    out, known = [], False
    for p in points:
        d = {"LP": 1, "HB": 2}.get(p.type) if p.type != "BP" else kernel_dimension(p)
        if d is None:
            return None
        known = known or p.type == "BP"
        out.append(d)
    return out if known else None


def audit(branch: Branch) -> list[str]:
    """Check special points against changes of ``n_unstable``; store and return disagreements.

    Each BP/LP with ``index = i`` lies between stored points i and i + 1 (if its parameter
    coincides with a stored point's, the interval on the other side of that point is
    accepted too).  An interval holding an odd number of BP/LP must show a change of
    ``n_unstable``; an interval whose ``n_unstable`` changes must hold at least one BP/LP
    (two points in one interval may cancel, so an even number with no change is accepted).
    Where the BPs carry their kernel dimension (``contin.bpdetect``; LP counts 1, HB 2) the
    change must equal the sum of the dimensions up to cancelling pairs: a BP of kernel
    dimension 2 changes ``n_unstable`` by 2 (or 0), one of dimension 3 by 3 or 1.
    Messages are human readable, one per disagreement; they replace the messages of any
    earlier stability audit in ``branch.audit`` (:func:`is_stability_message`) and follow every
    other line there (the tracer's: rejected steps, grid changes and two-grid checks of adaptive
    resolution, located points' checks), which are kept.  An empty list means consistent.

    Point 0 of a switched branch (its parent's BP) counts with point 1's ``n_unstable``.

    Raises
    ------
    ValueError
        If the stability columns have not been filled (run :func:`stability_pass` first).
    """
    if branch.n_unstable is None:
        raise ValueError(f"branch {branch.id} has no stability data; run stability_pass first")
    nu = np.asarray(branch.n_unstable)
    if "@" in branch.parent and len(nu) > 1 and nu[0] >= 0:
        # Point 0 of a switched branch (contin.continuation.switch: parent "BPk@id") is the
        # parent's BP itself: one eigenvalue is exactly zero there, its computed sign is rounding
        # noise, and the BP is a special point of the parent, not of this branch; it is audited
        # with the count of point 1 (the stored column keeps the computed value).
        nu = np.concatenate([nu[1:2], nu[1:]])
    s = len(nu)
    par = branch.parameter
    pv = branch.params.get(par, np.full(s, np.nan))
    messages: list[str] = []
    per_interval: dict[int, list[Any]] = {}
    for spt in branch.special_points:
        if spt.type not in ("BP", "LP", "HB"):
            continue
        if spt.type == "HB" and (spt.data.get("kx", 0.0), spt.data.get("kz", 0.0)) != (branch.stability_k or (0.0, 0.0)):
            continue  # a Hopf point of another wavenumber's stability problem
        i = spt.index
        p_sp = spt.params.get(par, np.nan)
        candidates = [i]
        if 0 <= i < s and np.isclose(p_sp, pv[i], rtol=1e-12, atol=1e-14):
            candidates.append(i - 1)
        if 0 <= i + 1 < s and np.isclose(p_sp, pv[i + 1], rtol=1e-12, atol=1e-14):
            candidates.append(i + 1)
        candidates = [c for c in candidates if 0 <= c < s - 1]
        if not candidates:
            messages.append(f"{spt.name} at {par}={p_sp:.6g} (index {i}) has no neighbouring points on the branch")
            continue
        unknown = [c for c in candidates if nu[c] < 0 or nu[c + 1] < 0]
        if unknown and len(unknown) == len(candidates):
            messages.append(f"{spt.name} at {par}={p_sp:.6g}: stability unknown at points "
                            f"{candidates[0]}..{candidates[0] + 1} (eigenproblem failed)")
            continue
        changing = [c for c in candidates if c not in unknown and nu[c] != nu[c + 1]]
        per_interval.setdefault(changing[0] if changing else candidates[0], []).append(spt)
    for c, pts in sorted(per_interval.items()):
        names = ", ".join(f"{p.name} at {par}={p.params.get(par, np.nan):.6g}" for p in pts)
        crossing = _crossing_counts(pts)
        if crossing is not None:
            # kernel dimensions known (contin.bpdetect): the count must change by their sum,
            # less pairs that cancel (eigenvalues crossing in opposite directions)
            total, delta = sum(crossing), abs(int(nu[c + 1]) - int(nu[c]))
            if delta > total or (total - delta) % 2:
                messages.append(f"{names}: n_unstable changes by {delta} between points {c} and {c + 1}, but "
                                f"their kernel dimensions add up to {total}")
        elif nu[c] == nu[c + 1] and len(pts) % 2 == 1:
            messages.append(f"{names}: n_unstable does not change between points {c} and {c + 1} "
                            f"(stays {nu[c]})")
    for c in range(s - 1):
        if nu[c] < 0 or nu[c + 1] < 0 or nu[c] == nu[c + 1] or c in per_interval:
            continue
        kind = ""
        if branch.eigenvalues is not None:
            lead = branch.eigenvalues[c + 1 if nu[c + 1] > nu[c] else c, 0]
            if np.isfinite(lead) and abs(lead.imag) > 1e-8 * max(1.0, abs(lead)):
                kind = " (complex pair: possible Hopf point, not located: run contin.stability.locate_hopf)"
        messages.append(f"n_unstable changes {nu[c]} -> {nu[c + 1]} between points {c} and {c + 1} "
                        f"({par} = {pv[c]:.6g} .. {pv[c + 1]:.6g}) with no BP/LP in between{kind}")
    for c in np.flatnonzero(nu < 0):
        messages.append(f"stability unknown at point {c} ({par} = {pv[c]:.6g}): the eigenproblem failed")
    branch.audit = [m for m in branch.audit if not is_stability_message(m)] + messages
    return messages


def is_stability_message(line: str) -> bool:
    """Whether an audit line is one of :func:`audit`'s messages (the forms it writes: an
    ``n_unstable`` disagreement, an unknown stability, a special point without neighbours), so
    that a repeated audit replaces them and keeps the tracer's lines (grid changes, checks: a
    replacement that kept only the rejected-step lines dropped them from every file written
    with a stability pass).  A ``"stability audit: "`` prefix (scenes that tag them) is allowed."""
    line = line.removeprefix("stability audit: ")
    return ("n_unstable " in line or line.startswith("stability unknown at point")
            or ": stability unknown at points " in line or line.endswith("has no neighbouring points on the branch"))
