"""The problem protocol: what contin needs to know about a system F(u, p) = 0.

contin never imports a concrete problem.  Anything with the attributes and methods of
:class:`Problem` can be continued; the optional methods are looked up with ``getattr``
and enable extra features (stability, symmetry-aware branch points, observables).

Parameters are passed as a plain ``dict[str, float]`` holding *every* parameter of the
problem; the continuation parameter is chosen by name (BifurcationKit's "lens").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

Params = Mapping[str, float]
Array = NDArray[np.float64]


@runtime_checkable
class Problem(Protocol):
    """Required interface of a continuation problem F(u, p) = 0, F: R^n x R^m -> R^n.

    Attributes
    ----------
    parameter_names : tuple of str
        Names of all scalar parameters, in a fixed order.

    Methods
    -------
    residual(u, p) -> (n,) array
        F(u, p).
    jacobian(u, p) -> (n, n) scipy.sparse matrix
        The exact dF/du (analytic or complex-step), sparse (CSC or CSR).
    dresidual_dp(u, p, name) -> (n,) array
        dF/dp for the parameter ``name`` (exact or complex-step).

    Optional methods (looked up with ``getattr``; absent means "not available")
    --------------------------------------------------------------------------
    dense_jacobian(u, p) -> (n, n) ndarray
        The same J as ``jacobian``, dense.  contin factorizes small systems densely
        (n + 1 <= ``contin.linalg.DENSE_LIMIT``) and then calls this instead of ``jacobian``
        in its Newton loops, which skips building a sparse matrix only to copy it into a
        dense one (at continuation sizes that construction costs more than the LU).  It may
        take a keyword ``out``: an earlier J (Fortran-ordered) that contin no longer needs and
        the hook may overwrite instead of allocating a new array (contin uses the returned
        array either way).
    mass_matrix(u, p) -> (n, n) sparse
        M in M du/dt = F(u, p); default eigenproblem is J x = omega M x.
    eigenproblem(u, p, **kwargs) -> (A, B)
        A generalized eigenproblem A x = omega B x whose eigenvalues decide linear
        stability (overrides jacobian/mass_matrix when the physical linearisation is not
        the Jacobian of the steady residual).  Rows of B that are zero give infinite
        eigenvalues, which contin discards.
    bp_eigen_auto : bool attribute
        False opts the problem out of the default eigenvalue-count BP detector
        (``DetectionOptions.bp_eigenvalues=None``, ``contin.bpdetect.bp_eigen_count``): for
        steady residuals with algebraic rows (boundary conditions, constraints) whose
        eigenvalues pair up and cross zero spuriously, so that the count re-steps and bisects
        on them (2-D disks: a steady-band trace 7.9 -> 18.3 s).  An explicit k still applies.
    order_parameter(u, p) -> float
        The scalar plotted on bifurcation diagrams (AUTO's L2-norm replacement).
    observables(u, p) -> dict[str, float]
        Extra scalars recorded at every point (BifurcationKit's record_from_solution).
    symmetry(u) -> (n,) array
        An involution S with F(S u, p) = S F(u, p) (and S S = identity).
    inner(a, b) -> float
        The inner product used for step lengths; default is the Euclidean dot / n.
    quadrature_weights(u, p) -> (n,) array
        Positive weights of the discrete L2 inner product of a discretized PDE's unknowns
        (quadrature weights per field).  The Hopf eigenvector is normalized with it for the
        first Lyapunov coefficient l1 (``contin.hopf``), which then converges with the grid;
        without it q^H q = 1 (exact for ODEs; for a PDE l1 then scales as 1/N).
    validate(p) -> None
        Raise ``ValueError`` with one clear sentence for an invalid parameter set.
    admissible(u, p) -> str | None
        None for a state inside the physical domain, else a one-line reason.  Newton
        backtracks to stay admissible; the tracer rejects (and retries with a smaller step)
        inadmissible points.
    under_resolved(u, p, tol) -> str | None
        None if the discretization resolves the converged state u to an estimated relative
        error ``tol`` (``ContinuationOptions.resolution_tol``), else a one-line reason (what
        is under-resolved, by how much, and what grid to try).  contin attaches no meaning to
        the estimate beyond "relative error of the state"; the problem chooses it (e.g. the
        relative size of the last spectral coefficients).  The tracer calls it on every
        converged candidate point before accepting it; an under-resolved point ends the run
        with status MX and message "under-resolved at <parameter> = <value>: <reason>",
        without being stored (a smaller step cannot help; the grid must be refined).

    Grid hooks (adaptive resolution, ``ContinuationOptions.adapt``; ``contin.adapt``)
    --------------------------------------------------------------------------------
    grid_size : int
        Size of the grid in force (e.g. the number of intervals N); what adaptation changes.
    error_estimate(u, p) -> float
        A-posteriori estimate of the relative discretization error of the converged state u
        (e.g. for Chebyshev collocation the relative size of the last coefficients, for finite
        differences a defect/Richardson estimate).  The tracer keeps it <= adapt.tol.
    with_grid(N) -> problem
        The same problem on the grid of size N (same method and model settings).
    transfer(u, other) -> (n_other,) array
        u carried onto ``other``'s grid by interpolation; must be linear in u, since it also
        carries the state part of tangents.
    vector_error(v) -> float  (optional)
        The estimate for a perturbation v (a null vector of J, a fold's tangent): a located BP
        or LP is located again on a finer grid when it exceeds adapt.tol, because the kernel,
        not only the state, fixes where the point lies.
    suggest_grid(u, p, tol) -> int  (optional)
        The grid size expected to bring the estimate below tol (refinement takes at least it).
    rounding_error(u, p) -> float  (optional)
        The part of error_estimate that no finer grid lowers (rounding of the computed state,
        e.g. next to a singularity of a closure): where it exceeds adapt.tol the branch ends
        at its precision limit (status EP, message "precision limit ...") instead of refining.
    precise_residual(u, p) -> array | None  (optional)
        The same residual F(u, p) evaluated in extended precision (e.g. ``numpy.longdouble``
        operators and arithmetic), returned as float64; None where the problem does not
        provide it for this model variant.  Where ``rounding_error`` of a state on the grid of
        the two-grid check is >= tol/100, ``contin.adapt.two_grid_error`` evaluates the fine
        residual with it and refines the correction twice (delta += -J^-1 F_precise(v + delta)),
        so the check measures the discretization error, not double-precision rounding in F;
        ``contin verify`` polishes its fine solves with it (two Newton steps) where present.
        Elsewhere it is never called (results bitwise as without it).  gPCF provides it.
    suggest_vector_grid(v, tol) -> int  (optional)
        The same for a perturbation v (``vector_error``): a refinement for an under-resolved
        BP's or LP's kernel takes at least it, so the point is located once on a grid that
        resolves it instead of on every grid of a growth chain.  Worth providing where the
        kernels at brackets are smooth modes whose decay rate extrapolates (demo BVPs); gPCF
        does not provide it: its banded branches bracket grid-scale artefact BPs whose slow
        envelopes asked for 2-2.5x the grid (main job: 1.8x the LU flops).
    solution_error(x, ref, p) -> float  (optional)
        Relative error of state x against a reference solution ref on the same grid, in the
        norm of error_estimate (``contin.verify`` re-solves stored points on a finer grid and
        measures them with it; default: the state's relative max-norm difference).
    convergence_order : float  (optional)
        The algebraic order q of the discretization error (finite differences: 2, 4, 6; inf
        for spectral methods; absent: unknown, taken as spectral).  A two-grid measurement is
        the difference e_c - e_f of the coarse and fine errors, e_f ~ e_c (N_c/N_f)^q; every
        two-grid check divides it by 1 - (N_c/N_f)^q (Richardson), so that an fd2 result is not
        passed at 3/4 of its error (``contin.adapt.richardson``).
    """

    parameter_names: tuple[str, ...]

    def residual(self, u: Array, p: Params) -> Array: ...

    def jacobian(self, u: Array, p: Params) -> sp.spmatrix: ...

    def dresidual_dp(self, u: Array, p: Params, name: str) -> Array: ...


#: The methods every problem must have (the attribute ``parameter_names`` too).
REQUIRED = ("residual", "jacobian", "dresidual_dp")


class ProtocolError(TypeError):
    """A problem lacks a method of the :class:`Problem` protocol (one sentence naming it)."""


def require_protocol(problem: Any) -> None:
    """Raise :class:`ProtocolError` naming the first missing required method or attribute.

    contin calls it where a run starts (``trace``, ``newton``), so a missing method is one
    clear sentence instead of an AttributeError deep inside the corrector.
    """
    kind = type(problem).__name__
    for method in REQUIRED:
        if not callable(getattr(problem, method, None)):
            raise ProtocolError(
                f"the problem ({kind}) has no method {method}(...), which contin needs "
                f"(required: {', '.join(m + '(u, p' + (', name)' if m == 'dresidual_dp' else ')') for m in REQUIRED)}"
                " and parameter_names); contin.from_functions(F, u0, params) builds them from F(u, p) alone")
    if not isinstance(getattr(problem, "parameter_names", None), tuple | list):
        raise ProtocolError(f"the problem ({kind}) has no parameter_names (a tuple of the parameter names), "
                            "which contin needs")


def has(problem: Any, method: str) -> bool:
    """True if ``problem`` provides the optional ``method``."""
    return callable(getattr(problem, method, None))


def complex_step_dp(problem: Any, u: Array, p: Params, name: str, h: float = 1e-30) -> Array:
    """dF/dp by the complex step, Im F(u, p + i h) / h (exact to rounding).

    Works for any residual written with numpy operations that accept complex input.
    """
    q = dict(p)
    q[name] = complex(p[name], h)
    return np.asarray(problem.residual(u.astype(complex), q)).imag / h


@dataclass(frozen=True)
class JacobianCheck:
    """Result of :func:`check_jacobian`: max abs and relative errors of J and dF/dp."""

    jacobian_error: float
    jacobian_scale: float
    dp_errors: dict[str, float]

    @property
    def relative_error(self) -> float:
        return self.jacobian_error / max(self.jacobian_scale, 1e-300)


def check_jacobian(
    problem: Any,
    u: Array,
    p: Params,
    *,
    parameters: tuple[str, ...] | None = None,
    step: float = 1e-7,
) -> JacobianCheck:
    """Compare the exact Jacobian and dF/dp with central finite differences.

    Central differences have O(step^2) truncation and O(eps/step) rounding error, so with
    the default step a correct Jacobian agrees to about 1e-7 relative.

    Returns
    -------
    JacobianCheck
        Max abs difference of J against finite differences, the max abs entry of J, and
        the max abs difference of dF/dp for each requested parameter.
    """
    u = np.asarray(u, dtype=float)
    n = u.size
    jac = sp.csc_matrix(problem.jacobian(u, p)).toarray()
    fd = np.empty((n, n))
    for j in range(n):
        h = step * max(1.0, abs(u[j]))
        up = u.copy()
        um = u.copy()
        up[j] += h
        um[j] -= h
        fd[:, j] = (problem.residual(up, p) - problem.residual(um, p)) / (2 * h)
    dp_errors: dict[str, float] = {}
    for name in parameters if parameters is not None else ():
        h = step * max(1.0, abs(p[name]))
        qp = dict(p)
        qm = dict(p)
        qp[name] += h
        qm[name] -= h
        fd_p = (problem.residual(u, qp) - problem.residual(u, qm)) / (2 * h)
        dp_errors[name] = float(np.max(np.abs(fd_p - problem.dresidual_dp(u, p, name))))
    return JacobianCheck(
        jacobian_error=float(np.max(np.abs(jac - fd))),
        jacobian_scale=float(np.max(np.abs(jac))),
        dp_errors=dp_errors,
    )
