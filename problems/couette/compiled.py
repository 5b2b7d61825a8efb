"""Compiled (numba) residual, dense Jacobian and dF/dH of gPCF: ``CouetteProblem(engine="numba")``.

The same equations as the numpy path of :mod:`problems.couette.model` (see its docstring) for
real states, no Dufour flux, and either wall model with or without gravity:

    f1(nu) T - P + H^3 G M = 0,   a u'' + a' u' = 0,   (k T'' + k' T') / H^2 + a u'^2 - D = 0

with a = f2 sqrt(T), k = f4 sqrt(T), D = f5 T^{3/2} (LSJC closures, :mod:`.closures`), the
wall rows of ``model`` and the mass rows.  Why a second implementation: at continuation sizes
(N = 12..48, 40..150 unknowns) the numpy path is 100+ array calls per Newton iteration at
0.3-0.5 us each, i.e. call overhead, not arithmetic; one compiled loop per quantity removes it
(``python -m benchmarks.run``).  Every kernel is tested against the numpy path (residual,
Jacobian, dF/dH to rounding) and through a whole trace (tests/test_compiled.py), so the two
cannot drift apart unnoticed.

Operation order differs from numpy's (loops instead of BLAS products), so results agree to
rounding (~1e-15 relative), not bitwise.  numba is optional (``pip install 'contin[fast]'``);
:func:`available` says whether it imports.
"""

from __future__ import annotations

import importlib.util
import math
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from contin.linalg import DENSE_LIMIT
from problems.couette import aot
from problems.couette.closures import _constants, wall_prefactors

#: chi models by kernel code (closures.radial_distribution)
CHI_CODES = {"jj": 0, "cs": 1, "ls": 2}
#: field rows of :func:`_fields` (index constants shared by the kernels)
(F1, F2, F4, F5, F1N, F2N, F4N, F5N, ST, A, K, D, UP, UPP, TP, TPP, AP, KP, COND, UP2, CHI, CHIN) = range(22)
N_FIELDS = 22


def supports(problem) -> str | None:
    """None if ``engine='numba'`` can run ``problem`` (a CouetteProblem), else why not."""
    if not available():
        return "engine='numba' needs numba: pip install 'contin[fast]' (or use engine='numpy')"
    if problem.dufour:
        return "engine='numba' does not cover the Dufour flux; use engine='numpy'"
    if problem.size > DENSE_LIMIT:
        return (f"engine='numba' builds dense Jacobians, for at most {DENSE_LIMIT} unknowns "
                f"(this grid has {problem.size}); use engine='numpy'")
    return None


@lru_cache(maxsize=1)
def available() -> bool:
    """True when numba (the ``fast`` extra) is installed and imports (a numba built for another
    numpy fails at import: then the numpy engine serves, as without numba), or when the
    ahead-of-time kernels (:mod:`.aot`) are built for this numba and numpy (checked without
    importing numba: that is what the ahead-of-time module saves)."""
    if importlib.util.find_spec("numba") is None:
        return False
    if aot.module_path() is not None and aot.enabled():
        return True
    try:
        import numba  # noqa: F401
    except Exception:  # noqa: BLE001 -- any import failure means "not available", never a crash
        return False
    return True


@lru_cache(maxsize=1)
def _kernels() -> tuple:
    """(fields, residual, jacobian, residual_dh): the ahead-of-time module (:mod:`.aot`) when it
    is built, else numba's JIT kernels, after building that module once for the next processes
    (numba is imported here, on first use, so that the numpy engine never pays its import)."""
    mod = aot.load()
    if mod is not None:
        return tuple(getattr(mod, name) for name in aot.KERNELS)
    kernels = _jit_kernels()
    if aot.enabled() and aot.build(kernels, kernel_argtypes()) is not None:
        mod = aot.load()
        if mod is not None:
            return tuple(getattr(mod, name) for name in aot.KERNELS)
    return kernels


@lru_cache(maxsize=1)
def _jit_kernels() -> tuple:
    """(fields, residual, jacobian, residual_dh) compiled by numba's JIT (cached on disk)."""
    import numba

    # error_model="numpy": x / 0 gives inf or nan as in the numpy engine (whose callers check
    # finiteness), not a ZeroDivisionError
    jit = numba.njit(cache=True, nogil=True, error_model="numpy")
    return jit(_fields), jit(_residual), jit(_jacobian), jit(_residual_dh)


def kernel_argtypes() -> tuple:
    """The numba argument types :class:`CompiledKernels` passes each kernel (one signature per
    kernel: C-contiguous float64/int64 arrays, the read-only constant arrays, int64, float64,
    bool), for the ahead-of-time build."""
    from numba.core import types as nt

    f1, f2 = nt.Array(nt.float64, 1, "C"), nt.Array(nt.float64, 2, "C")
    i1, ro = nt.Array(nt.int64, 1, "C"), nt.Array(nt.float64, 1, "C", readonly=True)
    i, r, b = nt.int64, nt.float64, nt.boolean
    return (
        (f1, i, f1, i1, i1, f1, f1, ro, i, r),                        # _fields
        (f2, f1, i, i, r, r, r, f1, b, ro, f2, f2, b),                # _residual
        (f2, f1, i, i, r, r, f1, i1, i1, f1, f1, b, ro, f2, f2, b),   # _jacobian
        (f2, f1, i, i, r, r, ro, b, b),                               # _residual_dh
    )


def _fields(x, n, y, ptr, cols, w1s, w2s, consts, chi_code, nu_max):
    """All per-node quantities of the residual and the Jacobian at x (rows: the constants above).

    D1 and D2 come as one CSR pattern (ptr, cols) holding both: w1s, w2s their entries there.
    consts = (b2, b4, c2, c4, d2, d4, k1, k3, k5) of closures._constants(e):
    f2, f4 = b / chi + c nu + d nu^2 chi;  f1 = nu + k1 nu^2 chi;  f3, f5 = k nu^2 chi.
    """
    b2, b4, c2, c4, dd2, dd4 = consts[0], consts[1], consts[2], consts[3], consts[4], consts[5]
    k1, k5 = consts[6], consts[8]  # (f3 = k3 nu^2 chi, the bulk viscosity, enters no equation here)
    f = np.empty((N_FIELDS, n))
    v = np.empty((4, n))  # u - y, T - T0, a - a0, k - k0 (see model._compute_fields: exact zeros of D)
    for i in range(n):
        nu = x[i]
        T = x[2 * n + i]
        if chi_code == 0:
            s = (nu / nu_max) ** (1.0 / 3.0)
            chi = 1.0 / (1.0 - s)
            chi1 = chi * chi * s / (3.0 * nu)
        elif chi_code == 1:
            chi = (1.0 - nu / 2.0) / (1.0 - nu) ** 3
            chi1 = (2.5 - nu) / (1.0 - nu) ** 4
        else:
            chi = (1.0 - nu / nu_max) ** (-2.5 * nu_max)
            chi1 = 2.5 * chi / (1.0 - nu / nu_max)
        g = nu * chi
        q = nu * g
        q_nu = 2.0 * g + nu * nu * chi1
        ic = 1.0 / chi
        ic_nu = -chi1 * ic * ic
        sT = math.sqrt(T)
        f2 = b2 * ic + c2 * nu + dd2 * q
        f4 = b4 * ic + c4 * nu + dd4 * q
        f5 = k5 * q
        f[F1, i] = nu + k1 * q
        f[F2, i] = f2
        f[F4, i] = f4
        f[F5, i] = f5
        f[F1N, i] = 1.0 + k1 * q_nu
        f[F2N, i] = b2 * ic_nu + (c2 + dd2 * q_nu)
        f[F4N, i] = b4 * ic_nu + (c4 + dd4 * q_nu)
        f[F5N, i] = k5 * q_nu
        f[CHI, i] = chi
        f[CHIN, i] = chi1
        f[ST, i] = sT
        f[A, i] = f2 * sT
        f[K, i] = f4 * sT
        f[D, i] = f5 * T * sT
    t0, a0, k0 = x[2 * n], f[A, 0], f[K, 0]
    for i in range(n):
        v[0, i] = x[n + i] - y[i]
        v[1, i] = x[2 * n + i] - t0
        v[2, i] = f[A, i] - a0
        v[3, i] = f[K, i] - k0
    for i in range(n):
        s_up = 0.0
        s_t = 0.0
        s_a = 0.0
        s_k = 0.0
        s_upp = 0.0
        s_tpp = 0.0
        for q in range(ptr[i], ptr[i + 1]):
            j, w1, w2 = cols[q], w1s[q], w2s[q]
            s_up += w1 * v[0, j]
            s_t += w1 * v[1, j]
            s_a += w1 * v[2, j]
            s_k += w1 * v[3, j]
            s_upp += w2 * v[0, j]
            s_tpp += w2 * v[1, j]
        up = s_up + 1.0
        f[UP, i] = up
        f[UPP, i] = s_upp
        f[TP, i] = s_t
        f[TPP, i] = s_tpp
        f[AP, i] = s_a
        f[KP, i] = s_k
        f[COND, i] = f[K, i] * s_tpp + s_k * s_t
        f[UP2, i] = up * up
    return f


def _residual(f, x, n, size, H, nubar, hg, weights, jj, wall, mass_m, mass_nu, gravity):
    """F(x) from the fields (model.CouetteProblem.residual).

    wall = (s_w and d_w prefactors cs, cd) for Johnson-Jackson walls (``jj``); gravity adds
    H^3 G M (hg = H^3 G) and the mass rows A_M M - A_nu nu (dense matrices, small n).
    """
    out = np.empty(size)
    inv_h2 = 1.0 / (H * H)
    for i in range(n):
        ry = f[F1, i] * x[2 * n + i] - x[3 * n]
        if gravity:
            ry += hg * x[3 * n + 1 + i]
        out[i] = ry
        out[n + i] = f[A, i] * f[UPP, i] + f[AP, i] * f[UP, i]
        out[2 * n + i] = f[COND, i] * inv_h2 + f[A, i] * f[UP2, i] - f[D, i]
    for side in range(2):
        i = 0 if side == 0 else n - 1
        sig = -1.0 if side == 0 else 1.0
        slip = x[n + i] - 0.5 * sig
        if not jj:
            out[n + i] = slip
            out[2 * n + i] = sig * f[TP, i]
        else:
            T = x[2 * n + i]
            g = x[i] * f[CHI, i]
            sw = wall[0] * g * f[ST, i]
            dw = wall[1] * g * T * f[ST, i]
            out[n + i] = -sig * f[A, i] * f[UP, i] - H * sw * slip
            out[2 * n + i] = sig * f[K, i] * f[TP, i] * inv_h2 - H * sw * slip * slip + dw / H
    total = 0.0
    for i in range(n):
        total += weights[i] * x[i]
    out[3 * n] = total - nubar
    if gravity:
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += mass_m[i, j] * x[3 * n + 1 + j] - mass_nu[i, j] * x[j]
            out[3 * n + 1 + i] = s
    return out


def _jacobian(f, x, n, size, H, hg, weights, ptr, cols, w1s, w2s, jj, wall, mass_m, mass_nu, gravity):
    """Dense, Fortran-ordered dF/dx from the fields (model.CouetteProblem._jacobian_terms).

    Interior rows: x-momentum da (u'' + u' D1) + (a D2 + a' D1) du; energy
    (dk (T'' + T' D1) + k D2 dT + k' D1 dT) / H^2 + da u'^2 + 2 a u' D1 du - dD, with
    da = a_nu dnu + a_T dT (a_T = f2 / (2 sqrt T)), dk likewise, dD = D_nu dnu + (3/2) f5 sqrt(T) dT.
    """
    jac = np.zeros((size, size)).T  # Fortran order: getrf takes it without a copy
    h2 = 1.0 / (H * H)
    iu, it, ip = n, 2 * n, 3 * n
    a_nu = np.empty(n)
    a_t = np.empty(n)
    k_nu = np.empty(n)
    k_t = np.empty(n)
    for j in range(n):
        st = f[ST, j]
        a_nu[j] = f[F2N, j] * st
        a_t[j] = f[F2, j] / (2.0 * st)
        k_nu[j] = f[F4N, j] * st
        k_t[j] = f[F4, j] / (2.0 * st)
    for i in range(n):
        T = x[2 * n + i]
        jac[i, i] = f[F1N, i] * T
        jac[i, it + i] = f[F1, i]
        jac[i, ip] = -1.0
        jac[ip, i] = weights[i]
        if gravity and hg != 0.0:
            jac[i, ip + 1 + i] = hg
    for i in range(1, n - 1):
        a, ap, up, upp = f[A, i], f[AP, i], f[UP, i], f[UPP, i]
        tp_h2, k_h2, kp_h2 = f[TP, i] * h2, f[K, i] * h2, f[KP, i] * h2
        two_a_up = 2.0 * a * up
        for q in range(ptr[i], ptr[i + 1]):
            j, w1, w2 = cols[q], w1s[q], w2s[q]
            jac[iu + i, iu + j] = a * w2 + ap * w1
            jac[iu + i, j] = up * w1 * a_nu[j]
            jac[iu + i, it + j] = up * w1 * a_t[j]
            jac[it + i, it + j] = tp_h2 * w1 * k_t[j] + k_h2 * w2 + kp_h2 * w1
            jac[it + i, j] = tp_h2 * w1 * k_nu[j]
            jac[it + i, iu + j] = two_a_up * w1
        up2 = f[UP2, i]
        d_nu = f[F5N, i] * x[2 * n + i] * f[ST, i]
        d_t = 1.5 * f[F5, i] * f[ST, i]
        jac[iu + i, i] += upp * a_nu[i]
        jac[iu + i, it + i] += upp * a_t[i]
        jac[it + i, it + i] += f[TPP, i] * k_t[i] * h2 + up2 * a_t[i] - d_t
        jac[it + i, i] += f[TPP, i] * k_nu[i] * h2 + up2 * a_nu[i] - d_nu
    for side in range(2):
        i = 0 if side == 0 else n - 1
        sig = -1.0 if side == 0 else 1.0
        if not jj:
            jac[iu + i, iu + i] = 1.0
            for q in range(ptr[i], ptr[i + 1]):
                jac[it + i, it + cols[q]] = sig * w1s[q]
        else:
            T = x[2 * n + i]
            st = f[ST, i]
            chi, chi_nu = f[CHI, i], f[CHIN, i]
            g = x[i] * chi
            g_nu = chi + x[i] * chi_nu
            sw = wall[0] * g * st
            sw_nu = wall[0] * g_nu * st
            sw_t = sw / (2.0 * T)
            dw_nu = wall[1] * g_nu * T * st
            dw_t = 1.5 * wall[1] * g * st
            slip = x[n + i] - 0.5 * sig
            upw, tpw = f[UP, i], f[TP, i]
            for q in range(ptr[i], ptr[i + 1]):
                j, w1 = cols[q], w1s[q]
                jac[iu + i, iu + j] = -sig * f[A, i] * w1
                jac[it + i, it + j] = sig * f[K, i] * h2 * w1
            jac[iu + i, iu + i] += -H * sw
            jac[iu + i, i] += -sig * a_nu[i] * upw - H * sw_nu * slip
            jac[iu + i, it + i] += -sig * a_t[i] * upw - H * sw_t * slip
            jac[it + i, it + i] += sig * k_t[i] * tpw * h2 - H * sw_t * slip * slip + dw_t / H
            jac[it + i, i] += sig * k_nu[i] * tpw * h2 - H * sw_nu * slip * slip + dw_nu / H
            jac[it + i, iu + i] += -2.0 * H * sw * slip
    if gravity:
        for i in range(n):
            for j in range(n):
                jac[ip + 1 + i, j] = -mass_nu[i, j]
                jac[ip + 1 + i, ip + 1 + j] = mass_m[i, j]
    return jac


def _residual_dh(f, x, n, size, H, G, wall, jj, gravity):
    """dF/dH (model.CouetteProblem._residual_dH)."""
    out = np.zeros(size)
    c = -2.0 / (H * H * H)
    for i in range(1, n - 1):
        out[2 * n + i] = c * f[COND, i]
    if jj:
        for side in range(2):
            i = 0 if side == 0 else n - 1
            sig = -1.0 if side == 0 else 1.0
            T = x[2 * n + i]
            g = x[i] * f[CHI, i]
            sw = wall[0] * g * f[ST, i]
            dw = wall[1] * g * T * f[ST, i]
            slip = x[n + i] - 0.5 * sig
            out[n + i] = -sw * slip
            out[2 * n + i] = -2.0 * sig * f[K, i] * f[TP, i] / (H * H * H) - sw * slip * slip - dw / (H * H)
    if gravity:
        for i in range(n):
            out[i] = 3.0 * H * H * G * x[3 * n + 1 + i]
    return out


def _stencil(g, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(ptr, cols, w1s, w2s): D1 and D2 of grid g on the union of their sparsity patterns (all
    columns for Chebyshev, a band for finite differences), CSR-like, so that the kernels' cost
    follows the stencils, not n^2.  Read-only once built (shared by the problems on g)."""
    d1, d2 = sp.csr_matrix(g.d1), sp.csr_matrix(g.d2)
    pattern = sp.csr_matrix((np.ones(d1.nnz + d2.nnz), (np.r_[d1.tocoo().row, d2.tocoo().row],
                                                        np.r_[d1.tocoo().col, d2.tocoo().col])), shape=d1.shape)
    pattern.sum_duplicates()
    pattern.sort_indices()
    rows = np.repeat(np.arange(n), np.diff(pattern.indptr))
    ptr, cols = pattern.indptr.astype(np.int64), pattern.indices.astype(np.int64)
    w1s = np.asarray(d1[rows, cols], dtype=float).ravel()
    w2s = np.asarray(d2[rows, cols], dtype=float).ravel()
    return ptr, cols, w1s, w2s


class CompiledKernels:
    """The kernels bound to one ``CouetteProblem``'s grid and switches (its ``engine="numba"``).

    The model calls these for real double states and parameters only; complex steps (dF/dp
    for p != H) keep the numpy path.  The fields of the last state are cached, as in the numpy
    path: the residual at an iterate is followed by the Jacobian and dF/dH at the same iterate.
    """

    def __init__(self, problem) -> None:
        why = supports(problem)
        if why is not None:
            raise ValueError(why)
        g = problem.grid
        self.n, self.size = problem.n, problem.size
        self.y = np.ascontiguousarray(g.y, dtype=float)
        # The stencil depends on the grid only: built once per grid and shared by the problems
        # on it through the model's per-grid set-up (an adaptive run rebuilds its problem on
        # every grid it visits; the sparse constructions cost ~4 ms per instance).
        shared = getattr(problem, "_shared_layouts", None)
        stencil = shared.get("compiled_stencil") if shared is not None else None
        if stencil is None:
            stencil = _stencil(g, self.n)
            if shared is not None:
                shared["compiled_stencil"] = stencil
        self.ptr, self.cols, self.w1s, self.w2s = stencil
        self.weights = np.ascontiguousarray(g.weights, dtype=float)
        self.chi_code = CHI_CODES[problem.chi]
        self.jj = problem.walls == "jj"
        self.gravity = problem.gravity
        if self.gravity:
            self.mass_m = np.ascontiguousarray(problem._mass_M.toarray())
            self.mass_nu = np.ascontiguousarray(problem._mass_nu.toarray())
        else:
            self.mass_m = self.mass_nu = np.zeros((1, 1))
        self._cache: tuple | None = None
        self._fields, self._residual, self._jacobian, self._residual_dh = _kernels()

    def fields(self, x, p):
        e, num = float(p["e"]), float(p["num"])
        raw = x.tobytes()
        cached = self._cache
        if cached is not None and cached[0] == raw and cached[1] == e and cached[2] == num:
            return cached[3]
        f = self._fields(x, self.n, self.y, self.ptr, self.cols, self.w1s, self.w2s, _closure_constants(e),
                         self.chi_code, num)
        self._cache = (raw, e, num, f)
        return f

    def wall(self, p):
        if not self.jj:
            return _NO_WALL
        return _wall_array(float(p["phi_w"]), float(p["ew"]), float(p["num"]))

    def residual(self, x, p):
        f = self.fields(x, p)
        H = float(p["H"])
        return self._residual(f, x, self.n, self.size, H, float(p["nu"]), H**3 * float(p["G"]), self.weights,
                              self.jj, self.wall(p), self.mass_m, self.mass_nu, self.gravity)

    def jacobian(self, x, p):
        f = self.fields(x, p)
        H = float(p["H"])
        return self._jacobian(f, x, self.n, self.size, H, H**3 * float(p["G"]), self.weights, self.ptr, self.cols,
                              self.w1s, self.w2s, self.jj, self.wall(p), self.mass_m, self.mass_nu, self.gravity)

    def residual_dh(self, x, p):
        f = self.fields(x, p)
        return self._residual_dh(f, x, self.n, self.size, float(p["H"]), float(p["G"]), self.wall(p), self.jj, self.gravity)


_NO_WALL = np.zeros(2)
_NO_WALL.flags.writeable = False  # read-only like _wall_array: one numba specialization for both


@lru_cache(maxsize=64)
def _wall_array(phi_w: float, ew: float, num: float) -> np.ndarray:
    """closures.wall_prefactors as a kernel argument (cached: called three times per Newton
    iteration with the same values).  Read-only."""
    out = np.array(wall_prefactors(phi_w, ew, num))
    out.flags.writeable = False
    return out


@lru_cache(maxsize=64)
def _closure_constants(e: float) -> np.ndarray:
    """(b2, b4, c2, c4, d2, d4, k1, k3, k5) of closures._constants(e) (cached per e).  Read-only."""
    (b2, b4), (c2, c4), (d2, d4), (k1, k3, k5) = _constants(e)
    out = np.array([b2, b4, c2, c4, d2, d4, k1, k3, k5], dtype=float)
    out.flags.writeable = False
    return out
