"""Steady, fully developed granular plane Couette flow as a continuation problem.

Alam scaling (physics.md sections 2-3): y in [-1/2, 1/2], walls moving with u = -+1/2,
T = T~ / (gamma_dot d_p)^2, stresses by rho_p (gamma_dot d_p)^2.  With a = f2 sqrt(T) (viscosity),
k = f4 sqrt(T) (conductivity), D = f5 T^{3/2} (dissipation) the steady equations are

    (a u')' = 0                                               x-momentum, S = a u' constant
    (1/H^2) (k T' + k_h nu')' + a u'^2 - D = 0               energy, k_h = f_h T^{3/2} (Dufour)
    f1(nu) T - P + H^3 G M = 0                                y-momentum, integrated
    integral of nu dy = nu_bar                                mass constraint (fixes P)
    M' = nu, M(-1/2) + M(1/2) = 0                             centred cumulative mass (gravity)

i.e. d(f1 T)/dy = -H^3 G nu with G = Fr^-2; M(y) = int_{-1/2}^y nu dy' - nu_bar/2 is the
cumulative mass centred so that it is odd under reflection (P is then the pressure where half
of the mass lies below).  Unknowns on the grid y_0 = -1/2 .. y_N = 1/2:

    x = [nu (N+1), u (N+1), T (N+1), P (1)]  (+ [M (N+1)] only for ``gravity=True``)

and the residual rows come in the same blocks: y-momentum at every node (algebraic),
x-momentum and energy at interior nodes with wall conditions in rows 0 and N, the mass
constraint, and (rows of M) the N cell equations M_j - M_j-1 = (integral of the interpolant of
nu over [y_j-1, y_j]) plus the centring M_0 + M_N = 0.
The divergences are collocated in expanded form, (a u')' = a u'' + a' u' with a' = D1 a.

Walls (n = outward normal, sigma = -1 at the bottom and +1 at the top, u_w = sigma/2;
Q = -(1/H^2)(k T' + k_h nu') is the wall-normal heat flux):

- ``noslip``: u = u_w, zero heat flux (sigma T' = 0; sigma (k T' + k_h nu') = 0 with Dufour).
- ``jj`` (Johnson & Jackson 1987; physics.md section 3b; A13 slide "Boundary Conditions"):
  -sigma S = H s_w (u - u_w)       (wall friction balances the shear stress)
  -sigma Q = H s_w (u - u_w)^2 - d_w / H   (heat into the material = slip work - wall loss)
  s_w = phi_w pi nu chi sqrt(T) / (2 sqrt(3) nu_m), d_w = sqrt(3) pi nu chi (1 - ew^2) T^{3/2} / (4 nu_m).

Symmetry.  S: (nu, T)(y) -> (nu, T)(-y), u(y) -> -u(-y), P -> P, M(y) -> -M(-y) (a signed
permutation) satisfies F(Sx, p) = S F(x, p') with p' = p except G -> -G, for every x, with the
SAME matrix S on unknowns and residual rows.  For this every wall row is written in the wall's
outward orientation, and the rows of M are laid out so that S maps them like the unknowns:
slot i < N/2 holds the cell to the right of node i, slot i > N/2 minus the cell to the left of
node i, and the middle slot(s) the centring row (for odd N combined with the middle cell).

References: M. Alam, YITP 2013 slides (seeds/001); Alam, Arakeri, Nott, Goddard & Herrmann,
J. Fluid Mech. 523 (2005) 277; Lun, Savage, Jeffrey & Chepurniy, J. Fluid Mech. 140 (1984) 223.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from contin.problem import complex_step_dp
from problems.couette import compiled
from problems.couette.closures import CHI_MODELS, coefficients, packing_limit, real_coefficients, wall_prefactors
from problems.couette.params import PARAMETER_NAMES, build_params, validate_params
from problems.discretization import cell_integration_matrix, make_grid
from problems.gridhooks import ResolutionHooks

Array = NDArray[np.float64]
WALLS = ("noslip", "jj")
#: Implementations of residual, Jacobian and dF/dH: numpy (default), or compiled by numba
#: (problems.couette.compiled; the ``fast`` extra).  ``engine="auto"`` takes numba where it is
#: installed and covers the problem (compiled.supports), numpy elsewhere.
ENGINES = ("numpy", "numba")

#: Parameter value types for which the residual is real double (see CouetteProblem.residual).
_REAL_TYPES = frozenset({float, int, np.float64})
#: Types of e for which closures.real_coefficients applies (it caches its matrix per e).
_FLOAT_TYPES = frozenset({float, np.float64})
#: Grids up to this many nodes differentiate with dense operators (see CouetteProblem.__init__).
DENSE_DERIVATIVES = 160
#: _Layout.assemble_dense adds dense operator blocks term by term from this many entries in
#: them on (below, one bincount scatter has less call overhead) ...
BLOCKWISE_MIN = 40000
#: ... an operator being a dense block when at least this fraction of its bounding box is set.
BLOCKWISE_FILL = 0.5


class _Fields(NamedTuple):
    """Everything the residual and the Jacobian share at one state (a NamedTuple: built at every
    residual evaluation, where a 20-field frozen dataclass costs ~5 us, a tuple ~1 us)."""

    nu: Any
    u: Any
    T: Any
    P: Any
    M: Any
    c: Any  # closures.Coefficients
    sT: Any
    a: Any
    k: Any
    D: Any
    up: Any
    upp: Any
    Tp: Any
    Tpp: Any
    ap: Any
    kp: Any
    kh: Any
    nup: Any
    nupp: Any
    khp: Any
    cond: Any  # k T'' + k' T' (energy rows of the residual and of dF/dH)
    up2: Any  # u'^2 (energy rows of the residual and of the Jacobian)


def rebuilt_engine(stored: Any) -> str:
    """The engine to rebuild a stored run's problem with: numba where the run used it and it is
    available here ('auto'), else numpy (the two agree to rounding)."""
    return "auto" if stored == "numba" else "numpy"


class CouetteProblem(ResolutionHooks):
    """Steady granular plane Couette flow F(x, p) = 0 (see the module docstring).

    Parameters
    ----------
    method : 'cheb', 'fd2', 'fd4' or 'fd6' (problems.discretization)
    N : number of grid intervals (N + 1 nodes)
    walls : 'noslip' (no slip, zero heat flux) or 'jj' (Johnson-Jackson slip and energy flux)
    chi : radial distribution 'jj', 'cs' or 'ls' (closures.radial_distribution)
    gravity : include the wall-normal gravity term and the cumulative mass M (needed for G != 0)
    dufour : include the Dufour-like flux -k_h nu' (off by default, physics.md 1.2)
    engine : 'numpy' (default), 'numba' (compiled residual, Jacobian and dF/dH:
        problems.couette.compiled, ~8x less time per Newton iteration at N = 12..48; needs the
        ``fast`` extra) or 'auto' (numba where installed and applicable, else numpy)

    Continuation parameters are those of :data:`problems.couette.params.PARAMETER_NAMES`.
    """

    parameter_names: tuple[str, ...] = PARAMETER_NAMES
    #: Parameters whose nonzero values break the reflection symmetry (F(Sx, G) = S F(x, -G)):
    #: a symmetric start state must not be treated as lying on an S-invariant branch when
    #: continuing in these (pass ``symmetric=False`` to contin.continuation.trace).
    symmetry_breaking_parameters: tuple[str, ...] = ("G",)

    def __init__(
        self,
        method: str = "cheb",
        N: int = 48,
        *,
        walls: str = "noslip",
        chi: str = "jj",
        gravity: bool = False,
        dufour: bool = False,
        engine: str = "numpy",
    ) -> None:
        if walls not in WALLS:
            raise ValueError(f"unknown wall model walls = {walls!r}; choose one of {', '.join(WALLS)}")
        if chi not in CHI_MODELS:
            raise ValueError(f"unknown radial distribution chi = {chi!r}; choose one of {', '.join(CHI_MODELS)}")
        self.grid = make_grid(method, int(N))
        self.method = method
        self.N = int(N)
        self.walls = walls
        self.chi = chi
        self.gravity = bool(gravity)
        self.dufour = bool(dufour)

        n = self.grid.size
        self.n = n
        self.size = 3 * n + 1 + (n if self.gravity else 0)
        self.i_nu = slice(0, n)
        self.i_u = slice(n, 2 * n)
        self.i_T = slice(2 * n, 3 * n)
        self.i_P = 3 * n
        self.i_M = slice(3 * n + 1, 4 * n + 1) if self.gravity else None

        setup = _grid_setup(method, int(N), self.gravity)
        self._d1, self._d2, self._d1t, self._d2t = setup.d1, setup.d2, setup.d1t, setup.d2t
        if self.gravity:
            self._mass_M, self._mass_nu = setup.mass_M, setup.mass_nu
        self._walls_idx = np.array([0, n - 1])
        self._sigma = np.array([-1.0, 1.0])  # outward normal at bottom, top
        self._uw = 0.5 * self._sigma  # wall velocities
        self._ops = setup.ops
        self._shared_layouts = setup.layouts
        self._layouts: dict[tuple, _Layout] = {}
        self._cache: tuple | None = None  # (x, (e, num), _Fields) of the last real evaluation
        self._mid_weights: Array | None = None
        self._symmetry_matrix: sp.csr_matrix | None = None
        self._extended: CouetteProblem | None = None  # the longdouble copy of precise_residual
        if engine not in ENGINES + ("auto",):
            raise ValueError(f"unknown engine {engine!r}; choose one of {', '.join(ENGINES)} or auto")
        if engine == "auto":
            engine = "numba" if compiled.supports(self) is None else "numpy"
        self.engine = engine
        self._compiled = compiled.CompiledKernels(self) if engine == "numba" else None

    # ------------------------------------------------------------------ bookkeeping
    def __repr__(self) -> str:
        return (
            f"CouetteProblem(method={self.method!r}, N={self.N}, walls={self.walls!r}, chi={self.chi!r}, "
            f"gravity={self.gravity}, dufour={self.dufour}, engine={self.engine!r})"
        )

    @property
    def options(self) -> dict[str, Any]:
        """Constructor options (discretization and model switches), e.g. for provenance."""
        return {
            "method": self.method,
            "N": self.N,
            "walls": self.walls,
            "chi": self.chi,
            "gravity": self.gravity,
            "dufour": self.dufour,
            "engine": self.engine,
        }

    def params(self, values: Mapping[str, Any] | None = None) -> dict[str, float]:
        """Full validated parameter dict (defaults merged with ``values``; accepts ``Fr``)."""
        p = build_params(values, chi=self.chi)
        self._check_gravity(p)
        return p

    def validate(self, p: Mapping[str, Any]) -> None:
        """Raise ``ValueError`` with one sentence if ``p`` is not valid for this instance."""
        validate_params(p, chi=self.chi)
        self._check_gravity(p)

    def _check_gravity(self, p: Mapping[str, Any]) -> None:
        if not self.gravity and p["G"] != 0:
            raise ValueError(
                f"gravity G = {p['G']} needs a problem built with gravity=True (this one has G = 0 only)"
            )

    def unpack(self, x: NDArray) -> tuple[NDArray, NDArray, NDArray, Any, NDArray | None]:
        """(nu, u, T, P, M) views of the state vector (M is None without gravity)."""
        m = x[self.i_M] if self.gravity else None
        return x[self.i_nu], x[self.i_u], x[self.i_T], x[self.i_P], m

    def pack(self, nu: NDArray, u: NDArray, T: NDArray, P: float, M: NDArray | None = None) -> NDArray:
        """Inverse of :meth:`unpack`; M defaults to :meth:`cumulative_mass` of nu."""
        parts = [np.asarray(nu), np.asarray(u), np.asarray(T), np.atleast_1d(P)]
        if self.gravity:
            parts.append(self.cumulative_mass(nu) if M is None else np.asarray(M))
        return np.concatenate(parts)

    def cumulative_mass(self, nu: NDArray) -> NDArray:
        """Centred cumulative mass M_j = int_{-1/2}^{y_j} nu dy - (1/2) int nu dy (interpolant of nu)."""
        cells = cell_integration_matrix(self.grid)
        cum = np.concatenate([[0.0], np.cumsum(cells @ nu)])
        return cum - 0.5 * cum[-1]

    # ------------------------------------------------------------------ residual
    def _fields(self, x: NDArray, p: Mapping[str, Any]) -> _Fields:
        """Fields, closures and derivatives at x (depend on p only through e and num).

        The last real evaluation is cached: within a Newton iteration the residual at an
        iterate is followed by the Jacobian (and the observables) at the same iterate.
        """
        key = (p["e"], p["num"])
        real = x.dtype == np.float64 and not isinstance(key[0], complex) and not isinstance(key[1], complex)
        if not real:
            return self._compute_fields(x, p)
        # The bytes of x as the key: one cheap comparison (np.array_equal costs ~4 us, called
        # ~3 times per Newton iteration); bitwise equality is what the cache needs anyway.
        raw = x.tobytes()
        cached = self._cache
        if cached is not None and cached[1] == key and cached[0] == raw:
            return cached[2]  # type: ignore[no-any-return]
        f = self._compute_fields(x, p)
        self._cache = (raw, key, f)
        return f

    def _compute_fields(self, x: NDArray, p: Mapping[str, Any]) -> _Fields:
        nu, u, T, P, M = self.unpack(x)
        e, num = p["e"], p["num"]
        if not self.dufour and x.dtype == np.float64 and type(e) in _FLOAT_TYPES and type(num) in _REAL_TYPES:
            c = real_coefficients(nu, e, self.chi, num)  # one stacked product (the Newton hot path)
        else:
            c = coefficients(nu, e, self.chi, num, self.dufour)
        sT = np.sqrt(T)
        a = c.f2 * sT
        k = c.f4 * sT
        # Differentiate after removing the parts D1, D2 map exactly to 0 or 1 (constants,
        # u = y): the same operators in exact arithmetic, but the cheb D2 has entries ~N^4
        # whose rounding would otherwise leave ~1e-10 in the residual of uniform shear.
        # Rows: [u - y, T - T0, (nu - nu0,)] get D1 and D2, then [a - a0, k - k0, (kh - kh0)] D1.
        nd = 3 if self.dufour else 2
        dtype = np.float64 if x.dtype == np.float64 and c.f2.dtype == np.float64 else np.result_type(x, c.f2)
        v = np.empty((2 * nd, self.n), dtype=dtype)
        v[0] = u - self.grid.y
        v[1] = T - T[0]
        v[nd] = a - a[0]
        v[nd + 1] = k - k[0]
        if self.dufour:
            kh = c.fh * T * sT
            v[2] = nu - nu[0]
            v[5] = kh - kh[0]
        d1v = v @ self._d1t
        d2v = v[:nd] @ self._d2t
        if self.dufour:
            nup, nupp, khp = d1v[2], d2v[2], d1v[5]
        else:
            kh = nup = nupp = khp = None
        up, Tp, Tpp, kp = d1v[0] + 1.0, d1v[1], d2v[1], d1v[nd + 1]
        return _Fields(
            nu, u, T, P, M, c, sT, a, k, c.f5 * T * sT,
            up, d2v[0], Tp, Tpp, d1v[nd], kp, kh, nup, nupp, khp, k * Tpp + kp * Tp, up**2,
        )

    def _wall_flux(self, f: _Fields) -> Any:
        """k T' (+ k_h nu' with the Dufour flux) at the bottom and top wall: -H^2 Q there."""
        w = self._walls_idx
        flux = f.k[w] * f.Tp[w]
        return flux + f.kh[w] * f.nup[w] if self.dufour else flux

    def _wall_coefficients(self, f: _Fields, p: Mapping[str, Any]):
        """s_w, d_w of the Johnson-Jackson conditions at both walls (and their nu-, T-derivatives)."""
        w = self._walls_idx
        nu, T, sT = f.nu[w], f.T[w], f.sT[w]
        chi, chi_nu = f.c.chi[w], f.c.chi_nu[w]
        g, g_nu = nu * chi, chi + nu * chi_nu
        cs, cd = wall_prefactors(p["phi_w"], p["ew"], p["num"])
        sw, dw = cs * g * sT, cd * g * T * sT
        return sw, dw, cs * g_nu * sT, sw / (2.0 * T), cd * g_nu * T * sT, 1.5 * cd * g * sT

    def residual(self, x: NDArray, p: Mapping[str, Any]) -> NDArray:
        """F(x, p); accepts complex x and p (complex-step derivatives)."""
        self._check_gravity(p)
        real = x.dtype == np.float64 and _REAL_TYPES.issuperset(map(type, p.values()))
        if real and self._compiled is not None:
            return self._compiled.residual(x, p)  # type: ignore[no-any-return]
        f = self._fields(x, p)
        H = p["H"]
        if real:
            dtype = np.float64  # the common case, without np.result_type over every parameter
        else:
            dtype = np.result_type(x, *(p[q] for q in self.parameter_names))
        F = np.empty(self.size, dtype=dtype)
        w, sig = self._walls_idx, self._sigma

        ry = f.c.f1 * f.T - f.P
        if self.gravity:
            ry = ry + H**3 * p["G"] * f.M
        F[self.i_nu] = ry

        ru = f.a * f.upp + f.ap * f.up
        rT = f.cond / H**2 + f.a * f.up2 - f.D
        if self.dufour:
            rT = rT + (f.kh * f.nupp + f.khp * f.nup) / H**2
        if self.dufour or self.walls != "noslip":
            flux = self._wall_flux(f)
        uw = self._uw
        if self.walls == "noslip":
            ru[w] = f.u[w] - uw
            rT[w] = sig * (flux if self.dufour else f.Tp[w])
        else:
            sw, dw = self._wall_coefficients(f, p)[:2]
            slip = f.u[w] - uw
            ru[w] = -sig * f.a[w] * f.up[w] - H * sw * slip
            rT[w] = sig * flux / H**2 - H * sw * slip**2 + dw / H
        F[self.i_u] = ru
        F[self.i_T] = rT
        F[self.i_P] = self.grid.weights @ f.nu - p["nu"]
        if self.gravity:
            F[self.i_M] = self._mass_M @ f.M - self._mass_nu @ f.nu
        return F

    def precise_residual(self, x: Array, p: Mapping[str, Any]) -> Array | None:
        """F(x, p) evaluated in extended precision (``np.longdouble``), returned as float64: the
        optional hook of ``contin.problem`` (the two-grid check of ``contin.adapt`` and the polish
        of ``contin verify`` use it where ``rounding_error`` matters for tol).

        The same code as :meth:`residual` (numpy path, whatever the engine) on the grid of
        :func:`problems.couette.extended_precision.extended` (nodes, weights and differentiation
        matrices in longdouble, dense products), with x and the real parameters cast to
        longdouble; the closures are numpy-generic (problems.couette.closures), so the whole
        evaluation is in longdouble.  Its rounding is ~2000x below the double residual's, whose
        cheb D2 rows (entries ~N^4) leave a floor next to packing.  None with ``gravity=True``
        (the cumulative-mass rows are not converted: the caller then uses :meth:`residual`)."""
        if self.gravity:
            return None
        from problems.couette.extended_precision import LD, extended

        ext = self._extended
        if ext is None:
            ext = self._extended = extended(self)
        pl = {k: LD(v) if isinstance(v, (float, np.floating)) else v for k, v in p.items()}
        return np.asarray(ext.residual(np.asarray(x, dtype=float).astype(LD), pl), dtype=float)

    # ------------------------------------------------------------------ Jacobian
    def jacobian(self, x: Array, p: Mapping[str, Any]) -> sp.csr_matrix:
        """Exact dF/dx (analytic), CSR.

        Notes
        -----
        Linearizing a u'' + a' u' gives (diag(u'') + diag(u') D1) da + diag(a) D2 du + diag(a') D1 du
        with da = a_nu dnu + a_T dT; the energy and wall rows follow the same pattern.  The
        nu-derivatives of f1..f5 come from closures.coefficients (analytic); that of f_h (Dufour
        only) by a complex step.
        """
        if self._compiled is not None:
            self._check_gravity(p)
            return sp.csr_matrix(self._compiled.jacobian(np.asarray(x, dtype=float), p))
        layout, rows, cols = self._jacobian_terms(x, p)
        return layout.assemble(rows, cols)

    def dense_jacobian(self, x: Array, p: Mapping[str, Any], out: Array | None = None) -> Array:
        """The same dF/dx as :meth:`jacobian`, as a dense Fortran-ordered array.

        The optional contin hook (``contin.problem``): contin factorizes small systems densely,
        and scattering the entries straight into a dense array skips building a CSR matrix
        only to copy it into one (scipy's CSR constructor alone costs ~15 us at N = 12).
        ``out``: an earlier J the caller no longer needs, overwritten by the term-by-term
        assembly of large grids (:class:`_Layout`) instead of a new array; use the return value.
        """
        if self._compiled is not None:
            self._check_gravity(p)
            return self._compiled.jacobian(np.asarray(x, dtype=float), p)  # type: ignore[no-any-return]
        layout, rows, cols = self._jacobian_terms(x, p)
        return layout.assemble_dense(rows, cols, out=out)

    def _jacobian_terms(self, x: Array, p: Mapping[str, Any]) -> tuple[_Layout, list, list]:
        """The cached layout of J and the row and column factors of its terms at (x, p)."""
        self._check_gravity(p)
        x = np.asarray(x, dtype=float)
        f = self._fields(x, p)
        c, H, n = f.c, p["H"], self.n
        h2 = 1.0 / H**2
        w, sig = self._walls_idx, self._sigma

        # (each factor is written exactly as the masked version before it, so J is bitwise the same)
        two_sT = 2.0 * f.sT
        a_nu, a_T = c.f2_nu * f.sT, c.f2 / two_sT
        k_nu, k_T = c.f4_nu * f.sT, c.f4 / two_sT
        D_nu, D_T = c.f5_nu * f.T * f.sT, 1.5 * c.f5 * f.sT
        up2 = f.up2
        tp_h2 = f.Tp * h2

        # Terms (operator, row factor, column factor): entry = row[i] * op[i, j] * col[j].  The
        # "...i" operators act on the interior rows, the "...w" ones on the two wall rows (their
        # row factors hold the bottom and top values).
        # x-momentum, interior: da (u'' + u' D1) + (a D2 + a' D1) du, da = a_nu dnu + a_T dT
        ju_u = [("d2i", f.a, None), ("d1i", f.ap, None)]
        ju_nu = [("Ii", f.upp * a_nu, None), ("d1i", f.up, a_nu)]
        ju_T = [("Ii", f.upp * a_T, None), ("d1i", f.up, a_T)]
        # energy, interior: (dk (T'' + T' D1) + k D2 dT + k' D1 dT) / H^2 + da u'^2 + 2 a u' D1 du - dD
        jt_T = [
            ("Ii", f.Tpp * k_T * h2 + up2 * a_T - D_T, None),
            ("d1i", tp_h2, k_T),
            ("d2i", f.k * h2, None),
            ("d1i", f.kp * h2, None),
        ]
        jt_nu = [("Ii", f.Tpp * k_nu * h2 + up2 * a_nu - D_nu, None), ("d1i", tp_h2, k_nu)]
        jt_u = [("d1i", 2.0 * f.a * f.up, None)]
        # wall heat flux k T' (+ k_h nu'): its T- and nu-derivatives at the walls (not needed by
        # no-slip walls without the Dufour flux, whose wall row is sigma T')
        if self.dufour or self.walls != "noslip":
            flux_T_diag = k_T[w] * f.Tp[w]
            flux_nu_diag = k_nu[w] * f.Tp[w]
        if self.dufour:
            fh_nu = _dufour_nu_derivative(f.nu, p, self.chi)
            kh_T, kh_nu = 1.5 * c.fh * f.sT, fh_nu * f.T * f.sT
            jt_T += [("Ii", f.nupp * kh_T * h2, None), ("d1i", f.nup * h2, kh_T)]
            jt_nu += [
                ("Ii", f.nupp * kh_nu * h2, None),
                ("d1i", f.nup * h2, kh_nu),
                ("d2i", f.kh * h2, None),
                ("d1i", f.khp * h2, None),
            ]
            flux_T_diag = flux_T_diag + kh_T[w] * f.nup[w]
            flux_nu_diag = flux_nu_diag + kh_nu[w] * f.nup[w]

        # wall rows
        if self.walls == "noslip":
            ju_u.append(("Iw", None, None))
            if self.dufour:
                jt_T += [("d1w", sig * f.k[w], None), ("Iw", sig * flux_T_diag, None)]
                jt_nu += [("d1w", sig * f.kh[w], None), ("Iw", sig * flux_nu_diag, None)]
            else:
                jt_T.append(("d1w_sig", None, None))
        else:
            sw, dw, sw_nu, sw_T, dw_nu, dw_T = self._wall_coefficients(f, p)
            slip = f.u[w] - 0.5 * sig
            upw = f.up[w]
            ju_u += [("d1w", -sig * f.a[w], None), ("Iw", -H * sw, None)]
            ju_nu.append(("Iw", -sig * a_nu[w] * upw - H * sw_nu * slip, None))
            ju_T.append(("Iw", -sig * a_T[w] * upw - H * sw_T * slip, None))
            jt_T += [
                ("d1w", sig * f.k[w] * h2, None),
                ("Iw", sig * flux_T_diag * h2 - H * sw_T * slip**2 + dw_T / H, None),
            ]
            jt_nu.append(("Iw", sig * flux_nu_diag * h2 - H * sw_nu * slip**2 + dw_nu / H, None))
            if self.dufour:
                jt_nu.append(("d1w", sig * f.kh[w] * h2, None))
            jt_u.append(("Iw", -2.0 * H * sw * slip, None))

        iu, iT, iP = self.i_u.start, self.i_T.start, self.i_P
        first: list[tuple[int, int, str, Array | None, Array | None]] = [
            (0, 0, "I", c.f1_nu * f.T, None),
            (0, iT, "I", c.f1, None),
            (0, iP, "ones_col", None, None),
            (iP, 0, "weights", None, None),
        ]
        blocks = ((iu, 0, ju_nu), (iu, iu, ju_u), (iu, iT, ju_T), (iT, 0, jt_nu), (iT, iu, jt_u), (iT, iT, jt_T))
        last: list[tuple[int, int, str, Array | None, Array | None]] = []
        with_g = False
        if self.gravity:
            iM = self.i_M.start
            hg = H**3 * p["G"]
            with_g = hg != 0
            if with_g:
                last.append((0, iM, "I", np.full(n, hg), None))
            last += [(iM, 0, "mass_nu", None, None), (iM, iM, "mass_M", None, None)]
        # The factors in term order (plain loops: this runs at every Newton iteration).
        rows, cols = [c.f1_nu * f.T, c.f1], []
        for _, _, block in blocks:
            for _, row, col in block:
                if row is not None:
                    rows.append(row)
                if col is not None:
                    cols.append(col)
        for term in last:
            if term[3] is not None:
                rows.append(term[3])
        # The term structure depends on the instance's switches and on whether H^3 G != 0 only.
        layout = self._layouts.get(with_g)
        if layout is None:
            terms = first + [(r0, c0, *t) for r0, c0, block in blocks for t in block] + last
            key = tuple((r0, c0, name, row is None, col is None) for r0, c0, name, row, col in terms)
            # shared by every instance on this grid with the same term structure (_grid_setup)
            layout = self._shared_layouts.get(key)
            if layout is None:
                layout = self._shared_layouts[key] = _Layout(self.size, self._ops, key)
            self._layouts[with_g] = layout
        return layout, rows, cols

    def dresidual_dp(self, x: Array, p: Mapping[str, Any], name: str) -> Array:
        """dF/dp for the parameter ``name`` by the complex step (exact to rounding)."""
        if name not in self.parameter_names:
            raise ValueError(f"unknown parameter {name!r}; known parameters are {', '.join(self.parameter_names)}")
        if name == "G" and not self.gravity:
            raise ValueError("continuation in G needs a problem built with gravity=True")
        if name == "H":
            return self._residual_dH(np.asarray(x, dtype=float), p)
        return complex_step_dp(self, np.asarray(x, dtype=float), p, name)

    def _residual_dH(self, x: Array, p: Mapping[str, Any]) -> Array:
        """dF/dH, analytic (H, the usual continuation parameter, enters F explicitly only).

        Energy rows: -2 (k T'' + k' T' [+ k_h nu'' + k_h' nu']) / H^3; JJ wall rows:
        -sigma S = H s_w slip gives -s_w slip, the heat-flux row -2 sigma H^2 Q / H^3
        - s_w slip^2 - d_w / H^2; gravity: 3 H^2 G M.  Equal to the complex step (tested).
        """
        self._check_gravity(p)
        if self._compiled is not None and _REAL_TYPES.issuperset(map(type, p.values())):
            return self._compiled.residual_dh(x, p)  # type: ignore[no-any-return]
        f = self._fields(x, p)
        H = p["H"]
        w, sig = self._walls_idx, self._sigma
        out = np.zeros(self.size)
        cond = f.cond
        if self.dufour:
            cond = cond + f.kh * f.nupp + f.khp * f.nup
        dT = (-2.0 / H**3) * cond
        if self.walls == "noslip":
            dT[w] = 0.0
        else:
            flux = self._wall_flux(f)
            sw, dw = self._wall_coefficients(f, p)[:2]
            slip = f.u[w] - 0.5 * sig
            out[self.i_u.start + w] = -sw * slip
            dT[w] = -2.0 * sig * flux / H**3 - sw * slip**2 - dw / H**2
        out[self.i_T] = dT
        if self.gravity:
            out[self.i_nu] = 3.0 * H**2 * p["G"] * f.M
        return out

    # ------------------------------------------------------------------ states
    def uniform_state(self, p: Mapping[str, Any]) -> Array:
        """Uniform shear (physics.md section 4): nu = nu_bar, u = y, T = f2/f5, P = f1 T.

        An exact solution of the discrete no-slip problem at G = 0 (D1 and D2 are exact on
        constants and linear functions); with gravity M = nu_bar (y + 1/2) - nu_bar/2.

        Raises
        ------
        ValueError
            At e = 1 (no dissipation, so no steady uniform temperature).
        """
        if p["e"] == 1:
            raise ValueError("uniform shear has no steady temperature at e = 1 (no collisional dissipation)")
        c = coefficients(np.float64(p["nu"]), p["e"], self.chi, p["num"])
        t0 = c.f2 / c.f5
        nu = np.full(self.n, float(p["nu"]))
        return self.pack(nu, self.grid.y.copy(), np.full(self.n, t0), c.f1 * t0)

    def initial_guess(self, p: Mapping[str, Any]) -> Array:
        """A starting point for Newton.

        No-slip walls: uniform shear.  Johnson-Jackson walls: uniform nu and T with a slipping
        linear profile u = gamma y, where gamma balances bulk and wall shear stress,
        f2 sqrt(T) gamma = H s_w (1 - gamma)/2, and T the integrated energy balance,
        f2 sqrt(T) gamma^2 - f5 T^{3/2} = 2 [H s_w ((1 - gamma)/2)^2 - d_w / H]; both are explicit
        because s_w ~ sqrt(T) and d_w ~ T^{3/2}.
        """
        if self.walls == "noslip":
            return self.uniform_state(p)
        c = coefficients(np.float64(p["nu"]), p["e"], self.chi, p["num"])
        g = p["nu"] * c.chi
        H = p["H"]
        cs, cd = (c * g for c in wall_prefactors(p["phi_w"], p["ew"], p["num"]))
        gamma = H * cs / (2.0 * c.f2 + H * cs)
        slip = 0.5 * (1.0 - gamma)
        t0 = (c.f2 * gamma**2 + 2.0 * H * cs * slip**2) / (c.f5 + 2.0 * cd / H)
        nu = np.full(self.n, float(p["nu"]))
        return self.pack(nu, gamma * self.grid.y, np.full(self.n, t0), c.f1 * t0)

    def profiles(self, x: Array) -> dict[str, Array]:
        """{'nu', 'u', 'T'} (plus the centred cumulative mass 'M' with gravity) on ``self.grid.y``."""
        nu, u, T, _, M = self.unpack(np.asarray(x))
        out = {"nu": nu.copy(), "u": u.copy(), "T": T.copy()}
        if M is not None:
            out["M"] = M.copy()
        return out

    def admissible(self, x: Array, p: Mapping[str, Any]) -> str | None:
        """None for a physical state, else the reason (non-finite, T <= 0, nu outside (0, limit))."""
        x = np.asarray(x)
        nu, T = x[self.i_nu], x[self.i_T]
        limit = packing_limit(self.chi, p["num"])
        # Fast path (called for every Newton iterate): the extremes of nu, T and x decide a
        # physical state (x is finite iff its largest and smallest entries are); anything else
        # gets the detailed checks below.  argmin/argmax (C methods; they return the first NaN)
        # instead of ufunc reductions, whose set-up costs ~2.5 us each at continuation sizes.
        if (nu[nu.argmin()] > 0 and nu[nu.argmax()] < limit and T[T.argmin()] > 0
                and math.isfinite(x[x.argmax()]) and math.isfinite(x[x.argmin()])):
            return None
        if not np.all(np.isfinite(x)):
            return "state has non-finite entries"
        if np.min(T) <= 0:
            return f"temperature not positive (min T = {np.min(T):.3g})"
        if np.min(nu) <= 0:
            return f"volume fraction not positive (min nu = {np.min(nu):.3g})"
        if np.max(nu) >= limit:
            return f"volume fraction reached the packing limit {limit:g} (max nu = {np.max(nu):.6g})"
        return None

    # ------------------------------------------------------------------ diagnostics
    def order_parameter(self, x: Array, p: Mapping[str, Any] | None = None) -> float:
        """Phi = nu(y = 1/2), the density at the top wall (A13)."""
        return float(np.real(x[self.i_nu][-1]))

    def shear_stress(self, x: Array, p: Mapping[str, Any]) -> Array:
        """S(y) = f2 sqrt(T) u' (constant for a steady state)."""
        f = self._fields(np.asarray(x, dtype=float), p)
        return f.a * f.up

    def heat_flux(self, x: Array, p: Mapping[str, Any]) -> Array:
        """Q(y) = -(1/H^2)(k T' + k_h nu'), the wall-normal heat flux (positive towards +y)."""
        f = self._fields(np.asarray(x, dtype=float), p)
        flux = f.k * f.Tp
        if self.dufour:
            flux = flux + f.kh * f.nup
        return -flux / p["H"] ** 2

    def observables(self, x: Array, p: Mapping[str, Any]) -> dict[str, float]:
        """Scalars recorded along a branch.

        phi = nu(1/2); delta = phi - nu_bar; shear_stress = S at the top wall; pressure =
        f1 T at the bottom wall; nu_bottom, nu_top; T_bottom, T_mid (T at y = 0), T_top.
        """
        x = np.asarray(x, dtype=float)
        f = self._fields(x, p)
        phi = float(f.nu[-1])
        return {
            "phi": phi,
            "delta": phi - float(p["nu"]),
            "shear_stress": float(f.a[-1] * f.up[-1]),
            "pressure": float(f.c.f1[0] * f.T[0]),
            "nu_bottom": float(f.nu[0]),
            "nu_top": phi,
            "T_bottom": float(f.T[0]),
            "T_mid": float(self._mid_interpolation() @ f.T),
            "T_top": float(f.T[-1]),
        }

    def _mid_interpolation(self) -> Array:
        """Weights w with w . f = grid.interpolate(f, 0) (the interpolant is linear in f)."""
        if self._mid_weights is None:
            self._mid_weights = self.grid.interpolation_weights(0.0)
        return self._mid_weights

    def energy_balance(self, x: Array, p: Mapping[str, Any]) -> tuple[float, float]:
        """(integral of a u'^2 - D dy, Q(1/2) - Q(-1/2)).

        Integrating the energy equation, Q' = a u'^2 - f5 T^{3/2}, the two numbers agree for
        every steady state up to the discretization error: heat produced in the bulk leaves
        through the walls (zero for adiabatic no-slip walls).
        """
        f = self._fields(np.asarray(x, dtype=float), p)
        source = float(self.grid.integrate(f.a * f.up**2 - f.D))
        q = self.heat_flux(x, p)
        return source, float(q[-1] - q[0])

    def momentum_balance(self, x: Array, p: Mapping[str, Any]) -> dict[str, float]:
        """Deviations from the integrated momentum balances (zero up to discretization error).

        shear_stress : max |S(y) - S(1/2)| / |S(1/2)|, S = a u' (x-momentum: S constant)
        normal_stress : max |f1 T + H^3 G M - mean| / mean (y-momentum, integrated)
        normal_stress_gradient : max |D1(f1 T) + H^3 G nu| / max(f1 T) (differential form)
        """
        x = np.asarray(x, dtype=float)
        f = self._fields(x, p)
        s = f.a * f.up
        pyy = f.c.f1 * f.T
        hg = p["H"] ** 3 * p["G"]
        total = pyy + (hg * f.M if self.gravity else 0.0)
        scale = float(np.max(np.abs(pyy)))
        return {
            "shear_stress": float(np.max(np.abs(s - s[-1])) / abs(s[-1])),
            "normal_stress": float(np.max(np.abs(total - np.mean(total))) / abs(np.mean(total))),
            "normal_stress_gradient": float(np.max(np.abs(self._d1 @ pyy + hg * f.nu)) / scale),
        }

    # ------------------------------------------------------------------ symmetry
    def symmetric(self, p: Mapping[str, Any]) -> bool:
        """True when the reflection of :meth:`symmetry` is a symmetry of F(., p), i.e. G = 0."""
        return p["G"] == 0

    def symmetry(self, x: Array) -> Array:
        """The reflection y -> -y: (nu, T)(y) -> (nu, T)(-y), u(y) -> -u(-y), P -> P, M(y) -> -M(-y).

        A signed permutation and an involution with F(Sx, p') = S F(x, p), p' = p with
        G -> -G; hence a symmetry of F(., p) exactly when :meth:`symmetric` (G = 0).
        """
        return reflected(self, x)

    def symmetry_matrix(self) -> sp.csr_matrix:
        """Sparse matrix of :meth:`symmetry` (built once per instance; a copy is returned)."""
        if self._symmetry_matrix is None:  # shared by the instances on this grid (_grid_setup)
            self._symmetry_matrix = self._shared_layouts.get("symmetry")
            if self._symmetry_matrix is None:
                self._symmetry_matrix = self._shared_layouts["symmetry"] = self._build_symmetry_matrix()
        return self._symmetry_matrix.copy()

    def _build_symmetry_matrix(self) -> sp.csr_matrix:
        n = self.n
        rf = sp.csr_matrix((np.ones(n), (np.arange(n), self.grid.reflection())), shape=(n, n))
        blocks = [rf, -rf, rf, sp.eye(1)] + ([-rf] if self.gravity else [])
        return sp.csr_matrix(sp.block_diag(blocks))

    # ------------------------------------------------------------------ stability
    def eigenproblem(self, x: Array, p: Mapping[str, Any], kx: float = 0.0, kz: float = 0.0):
        """Generalized eigenproblem A X = omega B X of physics.md section 5 at the steady state x.

        Delegates to :func:`problems.couette.linear.linear_operator` (imported lazily) with
        this instance's wall model, chi, Dufour and gravity switches.  Unknowns of the
        eigenproblem are (nu, u, v, w, T) perturbations, not the steady state vector, on the
        grid of :meth:`eigen_grid`: this instance's grid for Chebyshev, otherwise the base
        profiles resampled onto a Chebyshev grid (:func:`problems.couette.linear.to_chebyshev`),
        because collocated FD grids carry spurious, slowly decaying density modes.
        """
        from problems.couette.linear import linear_operator

        grid, nu, u, T = self._eigen_base(x)
        return linear_operator(
            grid, nu, u, T, p, walls=self.walls, kx=kx, kz=kz, chi=self.chi,
            dufour=self.dufour, gravity=self.gravity,
        )

    def _eigen_base(self, x: Array):
        from problems.couette.linear import to_chebyshev

        nu, u, T, _, _ = self.unpack(np.asarray(x, dtype=float))
        return to_chebyshev(self.grid, nu, u, T)

    def eigen_grid(self):
        """The grid of the eigenproblem unknowns (Chebyshev; see :meth:`eigenproblem`)."""
        if self.method == "cheb":
            return self.grid
        return self._eigen_base(np.ones(self.size))[0]

    def eigenvector_profiles(self, x: Array, vec) -> tuple[Array, dict[str, Any]]:
        """(y, {'nu', 'u', 'v', 'w', 'T'}) of an eigenvector of :meth:`eigenproblem` at x."""
        from problems.couette.linear import FIELDS

        grid = self.eigen_grid()
        vec = np.asarray(vec)
        if vec.shape != (5 * grid.size,):
            raise ValueError(f"eigenvector has shape {vec.shape}, expected ({5 * grid.size},)")
        return grid.y.copy(), dict(zip(FIELDS, vec.reshape(5, grid.size)))

    # ------------------------------------------------------------------ grid hooks (contin.adapt)
    # under_resolved, grid_size, transfer and the estimates: problems.gridhooks.ResolutionHooks
    def with_grid(self, N: int) -> CouetteProblem:
        """The same model (method, walls, chi, gravity, Dufour term) on N intervals; the same engine
        where it can run that grid (the compiled engine stops at its dense-Jacobian size limit,
        ``compiled.supports``: beyond it the numpy engine serves)."""
        engine = "auto" if self.engine == "numba" else self.engine
        return CouetteProblem(self.method, int(N), walls=self.walls, chi=self.chi, gravity=self.gravity,
                              dufour=self.dufour, engine=engine)


class _Layout:
    """Structure of J = sum_k diag(row_k) Op_k diag(col_k) placed at block offsets (r0_k, c0_k).

    Built once per term list (operators are fixed per problem instance); each Jacobian is then
    one gather-multiply of all operator entries by their row and column factors and one
    ``np.bincount`` scatter (overlapping terms are summed) into the CSR data or into a dense
    array: no sparse products, sums or per-block matrices in the Newton loop.  A factor given
    as None is 1.  An operator's row factor has one entry per operator row, or one per wall
    (length 2: bottom, top) for the wall-row operators (:data:`_WALL_OPS`).

    The dense J of a grid with dense operators (Chebyshev, :data:`BLOCKWISE_MIN` entries or
    more in them) is assembled term by term instead (:meth:`assemble_dense`): the int64 index
    arrays and gathered factors of the one-scatter form are ~10 arrays of the size of J,
    streamed through memory per Jacobian (4.3 ms at cheb 200, 2.2x that inside a Newton
    iteration whose LU has just evicted them), where one operator block scaled by its factors
    stays in cache.  Same products (op * row) * col, added in the same term order from 0: the
    same J bit for bit (tested).
    """

    def __init__(self, size: int, ops: Mapping[str, sp.coo_matrix], key: tuple) -> None:
        self.size = size
        self._ops, self._key = ops, key
        self._steps: list[tuple] | None = None
        rows, cols, vals, rsrc, csrc = [], [], [], [], []
        r_off = c_off = 1  # slot 0 of the stacked factors holds the constant 1
        for r0, c0, name, row_none, col_none in key:
            op = ops[name]
            wall = getattr(op, "wall", False)
            local = (op.row > 0).astype(np.int64) if wall else op.row
            rows.append(op.row + r0)
            cols.append(op.col + c0)
            vals.append(op.data)
            rsrc.append(np.zeros(op.nnz, dtype=np.int64) if row_none else local + r_off)
            csrc.append(np.zeros(op.nnz, dtype=np.int64) if col_none else op.col + c_off)
            r_off += 0 if row_none else (2 if wall else op.shape[0])
            c_off += 0 if col_none else op.shape[1]
        r_all, c_all = np.concatenate(rows).astype(np.int64), np.concatenate(cols).astype(np.int64)
        flat = r_all * size + c_all
        uniq, pos = np.unique(flat, return_inverse=True)
        urows, ucols = np.divmod(uniq, size)
        idx_t = np.int32 if uniq.size < 2**31 else np.int64
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(urows, minlength=size))]).astype(idx_t)
        self.indices = ucols.astype(idx_t)
        self.pos = pos.ravel()
        self.flat_f = c_all * size + r_all  # position in a Fortran-ordered dense (size, size) array
        self.vals = np.concatenate(vals).astype(float)
        self.rsrc = np.concatenate(rsrc)
        self.csrc = np.concatenate(csrc)
        self.nnz = uniq.size

    def _weights(self, rows: list[Array], cols: list[Array]) -> Array:
        rstack = np.concatenate([_ONE, *rows])
        cstack = np.concatenate([_ONE, *cols])
        return self.vals * rstack[self.rsrc] * cstack[self.csrc]

    def assemble(self, rows: list[Array], cols: list[Array]) -> sp.csr_matrix:
        """CSR J from the non-None row and column factors, in term order."""
        data = np.bincount(self.pos, weights=self._weights(rows, cols), minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.size, self.size))

    def assemble_dense(self, rows: list[Array], cols: list[Array], blockwise: bool | None = None,
                       out: Array | None = None) -> Array:
        """Dense (Fortran-ordered) J from the same factors.

        ``blockwise`` (default: when the dense operators hold :data:`BLOCKWISE_MIN` entries or
        more) adds the terms one by one into J, dense operators as scaled blocks; otherwise one
        ``np.bincount`` scatter.  Both give the same J bit for bit.  The blockwise assembly
        overwrites ``out`` (a Fortran-ordered (size, size) float array) when given, instead of
        allocating J: a fresh J per Newton iteration costs ~350 page faults (~1-2 ms) at cheb 200.
        """
        size = self.size
        steps = self._steps
        if steps is None:
            steps = self._steps = self._build_steps()
        if blockwise is None:
            blockwise = self._dense_entries >= BLOCKWISE_MIN
        if not blockwise:
            return np.bincount(self.flat_f, weights=self._weights(rows, cols), minlength=size * size).reshape(
                (size, size), order="F")
        if out is not None and out.shape == (size, size) and out.flags.f_contiguous and out.dtype == np.float64:
            out.fill(0.0)
            flat = out.reshape(-1, order="F")  # a view: the steps write into either
        else:
            flat = np.zeros(size * size)
            out = flat.reshape((size, size), order="F")
        for dense, where, vals, ri, rsel, ci, csel in steps:
            # entry = (op * row) * col, as in _weights (a factor that is None is 1: skipped)
            if ri is None:
                t = vals if ci is None else vals * (cols[ci][csel] if not dense else cols[ci][None, csel])
            else:
                t = vals * (rows[ri][rsel] if not dense else rows[ri][rsel, None])
                if ci is not None:
                    t *= cols[ci][csel] if not dense else cols[ci][None, csel]
            if dense:
                out[where] += t
            elif where[1]:  # repeated positions within the operator: summed in order
                np.add.at(flat, where[0], t)
            else:
                flat[where[0]] += t
        return out

    def _build_steps(self) -> list[tuple]:
        """Per term: (dense, where, op values, row-factor index, rows, col-factor index, cols).

        A non-wall operator with at least :data:`BLOCKWISE_FILL` of its bounding box filled is a
        dense block (where: the slices of J it adds to); any other one a list of positions in
        J's Fortran-order data (where: (positions, repeated?)).  The factor indices count the
        non-None factors in term order, as :meth:`_weights` stacks them.
        """
        steps: list[tuple] = []
        blocks: dict[tuple, Array] = {}  # one dense copy per operator, shared by its terms
        n_rows = n_cols = 0
        self._dense_entries = 0
        for r0, c0, name, row_none, col_none in self._key:
            op = self._ops[name]
            wall = getattr(op, "wall", False)
            ri, ci = (None if row_none else n_rows), (None if col_none else n_cols)
            n_rows += 0 if row_none else 1
            n_cols += 0 if col_none else 1
            flat = (op.col + c0).astype(np.int64) * self.size + (op.row + r0)
            repeated = np.unique(flat).size < flat.size
            if op.nnz and not wall and not repeated:
                rlo, rhi, clo, chi = op.row.min(), op.row.max() + 1, op.col.min(), op.col.max() + 1
                if op.nnz >= BLOCKWISE_FILL * (rhi - rlo) * (chi - clo):
                    block = blocks.get(name)
                    if block is None:
                        block = blocks[name] = np.zeros((rhi - rlo, chi - clo), order="F")
                        block[op.row - rlo, op.col - clo] = op.data
                    steps.append((True, (slice(r0 + rlo, r0 + rhi), slice(c0 + clo, c0 + chi)), block,
                                  ri, slice(rlo, rhi), ci, slice(clo, chi)))
                    self._dense_entries += op.nnz
                    continue
            local = (op.row > 0).astype(np.int64) if wall else op.row
            steps.append((False, (flat, repeated), np.asarray(op.data, dtype=float), ri, local, ci, op.col))
        return steps


_ONE = np.ones(1)


class _GridSetup(NamedTuple):
    """What a :class:`CouetteProblem` builds per grid: differentiation matrices, the Jacobian
    operators in COO form, and the Jacobian layouts built from them (by term structure) and the
    reflection's matrix (key "symmetry"), filled on first use.  Read-only once built."""

    d1: sp.csr_matrix
    d2: sp.csr_matrix
    d1t: Any
    d2t: Any
    mass_M: Any
    mass_nu: Any
    ops: dict[str, sp.coo_matrix]
    layouts: dict[Any, Any]


#: (method, N, gravity) -> _GridSetup, most recently used last; at most _SETUPS_MAX entries.
_SETUPS: dict[tuple[str, int, bool], _GridSetup] = {}
_SETUPS_MAX = 32


def _grid_setup(method: str, N: int, gravity: bool) -> _GridSetup:
    """The per-grid set-up, built once per process and grid (issue 14: adaptive runs rebuild the
    problem on every grid they visit, and each trace of a diagram starts from its own instance;
    the sparse constructions cost ~3-5 ms per grid, as much as a whole cheb 10 trace of H_1^c).
    Bounded (least recently used dropped) so large grids are not kept forever."""
    key = (method, int(N), bool(gravity))
    hit = _SETUPS.pop(key, None)
    if hit is None:
        hit = _build_grid_setup(method, int(N), bool(gravity))
        while len(_SETUPS) >= _SETUPS_MAX:
            del _SETUPS[next(iter(_SETUPS))]
    _SETUPS[key] = hit
    return hit


def _build_grid_setup(method: str, N: int, gravity: bool) -> _GridSetup:
    g = make_grid(method, N)
    n = g.size
    d1 = sp.csr_matrix(g.d1)
    d2 = sp.csr_matrix(g.d2)
    # Derivatives of several fields in one product V @ D^T (V: one field per row).  Dense
    # BLAS for dense (Chebyshev) or small operators: a sparse product costs ~6 us of call
    # overhead each, more than the arithmetic at continuation sizes.
    dense = n <= DENSE_DERIVATIVES or d1.nnz > 0.25 * n * n
    d1t = np.ascontiguousarray(d1.T.toarray()) if dense else sp.csr_matrix(d1.T)
    d2t = np.ascontiguousarray(d2.T.toarray()) if dense else sp.csr_matrix(d2.T)
    # Jacobian operators.  Interior rows ("...i": wall rows dropped) and wall rows ("...w":
    # rows 0 and n-1 only, row factors of length 2, one per wall) are separate operators,
    # so that no row factor has to be masked or scattered into a length-n vector.
    eye = sp.eye(n, format="csr")
    interior = sp.diags(np.r_[0.0, np.ones(n - 2), 0.0], format="csr")
    at_walls = sp.diags(np.r_[1.0, np.zeros(n - 2), 1.0], format="csr")
    ops = {"I": eye, "Ii": interior, "d1i": interior @ d1, "d2i": interior @ d2,
           "Iw": at_walls, "d1w": at_walls @ d1, "d1w_sig": sp.diags(np.r_[-1.0, np.zeros(n - 2), 1.0]) @ d1,
           "ones_col": sp.csr_matrix(-np.ones((n, 1))), "weights": sp.csr_matrix(g.weights[None, :])}
    mass_M = mass_nu = None
    if gravity:
        mass_M, mass_nu = _mass_rows(cell_integration_matrix(g))
        ops.update(mass_M=mass_M, mass_nu=-mass_nu)
    coo = {name: _coo(op, wall=name in _WALL_OPS) for name, op in ops.items()}
    return _GridSetup(d1, d2, d1t, d2t, mass_M, mass_nu, coo, {})


#: Jacobian operators that act on the two wall rows only (row factors of length 2).
_WALL_OPS = frozenset({"Iw", "d1w", "d1w_sig"})


def _coo(op: sp.spmatrix, wall: bool) -> sp.coo_matrix:
    """``op`` as COO without stored zeros, marked ``wall`` for :class:`_Layout`."""
    coo = sp.coo_matrix(op)
    coo.eliminate_zeros()
    coo.wall = wall
    return coo


def reflected(model: Any, x: Array) -> Array:
    """The state x = (nu, u, T, P[, M]) of ``model`` (its ``unpack``, ``grid`` and ``gravity``)
    reflected y -> -y: (nu, T)(y) -> (nu, T)(-y), u(y) -> -u(-y), P -> P, M(y) -> -M(-y).
    Shared by every model with this state layout (:class:`CouetteProblem`, the disk model)."""
    r = model.grid.reflection()
    nu, u, T, P, M = model.unpack(np.asarray(x))
    parts = [nu[r], -u[r], T[r], np.atleast_1d(P)]
    if model.gravity:
        parts.append(-M[r])
    return np.concatenate(parts)


def _mass_rows(cells: sp.csr_matrix) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Matrices (A_M, A_nu) of the rows A_M M - A_nu nu = 0 of the centred cumulative mass.

    Raw rows: cell j (j = 1..N), M_j - M_j-1 - C_j nu, and the centring M_0 + M_N.  Under the
    reflection, cell j <-> cell N+1-j and the centring row changes sign, while the unknowns map
    M_i -> -M_N-i.  Slot i = 0..N gets: the cell right of node i (i < N/2, cell i+1), minus the
    cell left of node i (i > N/2, cell i), and the centring row at i = N/2 (N even); for odd N
    the slots (N-1)/2 and (N+1)/2 get centring +- middle cell.  Then the rows map exactly like
    the unknowns, slot i -> -slot N-i, so one matrix S serves both (see the module docstring).
    """
    nc, n = cells.shape
    N = nc
    diff = sp.csr_matrix(sp.eye(n, k=1) - sp.eye(n))[:N]  # row j-1: M_j - M_j-1
    center = sp.csr_matrix(([1.0, 1.0], ([0, 0], [0, N])), shape=(1, n))
    raw_M = sp.vstack([diff, center], format="csr")  # rows: cells 1..N, centring
    raw_nu = sp.vstack([cells, sp.csr_matrix((1, n))], format="csr")
    rows, cols, vals = [], [], []
    half = N // 2
    for i in range(n):  # setup only: n small permutation entries
        if 2 * i < N - 1:
            rows.append(i), cols.append(i), vals.append(1.0)  # cell i+1 is raw row i
        elif 2 * i > N + 1:
            rows.append(i), cols.append(i - 1), vals.append(-1.0)  # cell i is raw row i-1
    if N % 2 == 0:
        rows.append(half), cols.append(N), vals.append(1.0)
    else:
        mid = half  # raw index of the middle cell (N+1)/2
        rows += [half, half, half + 1, half + 1]
        cols += [mid, N, mid, N]
        vals += [1.0, 1.0, -1.0, 1.0]
    t = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
    return sp.csr_matrix(t @ raw_M), sp.csr_matrix(t @ raw_nu)


def _dufour_nu_derivative(nu: Array, p: Mapping[str, Any], chi: str, h: float = 1e-30) -> Array:
    """d f_h / d nu by the complex step (closures gives f_h but not its derivative)."""
    c = coefficients(nu + 1j * h, p["e"], chi, p["num"], dufour=True)
    return np.asarray(c.fh).imag / h
