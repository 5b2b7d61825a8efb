"""The shear-banding pitchfork hierarchy of gravity-free granular Couette flow (physics.md sections 3-4).

Reusable pieces of the ``pitchfork`` and ``jj-walls`` scenes (``problems.couette.scenes``):

- :func:`analytic_critical_gaps` -- H_n^c = n pi psi(nu, e) of uniform shear (no-slip walls);
- :func:`threshold_density` -- the density below which psi is not finite (uniform shear has no BP,
  "bifurcation from infinity"), root of the bracket of psi^2;
- :func:`trace_base` -- uniform shear (no-slip) or the symmetric JJ base branch, traced in H,
  re-traced with smaller steps when a step jumped between branches (:func:`retrace_on_jumps`);
- :func:`isolated_symmetric_branch` -- a symmetric branch not connected to the JJ base branch;
- :func:`departure`, :func:`first_point_on` -- |Phi - Phi_base(H)| along a branch, and whether a
  branch comes back onto the base branch;
- :func:`banded_branches` -- switching at a BP onto both signs of the banded branch (the second
  sign as the mirror image S x of the first when the first is not S-invariant);
  the ``pitchfork`` and ``jj-walls`` scenes build the same with ``contin.diagram`` (their
  choices: :class:`WallCoordinates`, :func:`first_point_on` as the jump test; so does
  gravity.gravity_free_branches through :func:`banded_diagram`);
- :func:`mirror_branch` -- the image of a branch under the reflection symmetry;
- :func:`density_continuation` -- a banded state at a density where uniform shear has no BP,
  reached by continuation in nu at fixed H from a density where the BP exists;
- :func:`newton_at` -- a branch evaluated at given parameter values by Newton from the nearest point;
- :func:`criticality` -- the fit H - H_c = a delta^2 + b delta^3 + c delta^4 (delta = Phi - nu_bar)
  near the BP: a > 0 supercritical, a < 0 subcritical;
- :func:`confirm_branch_points` -- a BP found on a banded branch is re-located on a 1.5x finer grid;
  one that moves by more than a few per cent is a discretization artefact and becomes a UZ point;
- :class:`StabilityOperator`, :func:`stability` -- the k_x = k_z = 0 stability pass (plus extra
  k_x), always on a Chebyshev grid.

Stability on finite-difference grids.  Collocated FD stencils give the density/pressure coupling
spurious, slowly decaying modes (decay ~ (pi/2N)^2, see ``problems.couette.linear.to_chebyshev``),
so for ``fd2/fd4/fd6`` states the eigenproblem is set up on a Chebyshev grid with the same number
of intervals (at most 80) after interpolating the base profiles; Chebyshev states are used as they
are.  At k_x = k_z = 0 the spanwise velocity w decouples (its equation is nu0 sigma w =
(1/H^2) (mu0 w')', Dirichlet, negative definite), so its block is dropped: same unstable count,
about half the QZ cost.

Johnson-Jackson walls (nu = 0.3, e = 0.8, phi_w = 0.5, ew = 0.9, H <= 43.13; cheb 48/64/96 agree).
Uniform shear is not a solution; the symmetric base branch starts near-uniform (Phi = 0.3007 at
H = 2.16) and has one BP, symmetry-breaking, at H = 18.15134523 (the JJ counterpart of H_1^c =
13.07; supercritical, k_x = 0: one unstable mode after it).  There is no symmetric BP: with no-slip,
zero-flux walls the mode-2 pitchfork is kept by the hidden symmetry of the mode-n scaling property
(physics.md section 3), which JJ walls break, so it unfolds.  The base branch turns smoothly, but
steeply near H ~ 29.5 (dPhi/dH ~ 0.019), into the dense-wall state (Phi = 0.5078 at H = 43.13), and
the other halves form an isolated symmetric branch: a near-uniform sheet (Phi ~ 0.30, two unstable
modes) and a dense-centre sheet (Phi -> 0.21, one unstable mode) joined at a fold at H = 33.14946,
Phi = 0.27561.  The earlier 'symmetric BP near H = 33.48' was a base-branch step that jumped onto
that isolated branch (the orientation of the tangent flips, so the BP test function changed sign
and the location could not converge); n2.1 then "fell back" onto the base branch because there
was no second branch there.  The n = 1 branch drives a dense plug against one wall (Phi -> 0.6395
or 0.1868 at H = 43.13, max nu = 0.644); at cheb 32 it is under-resolved above H ~ 35 and a
log N-moving wall-wiggle BP appears (H = 34.6, 38.8, 41.5 for N = 32, 48, 64; demoted to UZ).

The secondary BP on banded branches.  Close to random close packing (Phi -> nu_m) the discrete
banded branch crosses a spurious discrete branch whose profiles carry a grid-scale wiggle at the
dense wall.  Its location grows like log N (nu = 0.3, e = 0.8, Chebyshev: H = 29.88, 33.15, 35.35,
38.34, 40.39 for N = 32, 48, 64, 96, 128), the Jacobian has no small eigenvalue next to it and the
k_x = 0 spectrum does not cross zero: it is not physics.  :func:`confirm_branch_points` demotes it.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.adapt import on_grid, point_problem
from contin.blas import limited
from contin.branch import Branch, SpecialPoint
from contin.continuation import newton, switch, trace, trace_both
from contin.jumps import retrace_on_jumps as _retrace_on_jumps
from contin.options import ContinuationOptions, NewtonOptions
from contin.overlap import is_invariant
from contin.overlap import mirror_branch as _mirror_branch
from contin.stability import audit, eigenvalues, stability_columns
from problems.couette.closures import coefficients, critical_gap_factor, packing_limit
from problems.couette.model import CouetteProblem, rebuilt_engine

log = logging.getLogger("contin")

Array = np.ndarray

#: Unstable-count tolerance of the stability pass: an exactly neutral eigenvalue (at a BP) comes out
#: at ~1e-15 (Chebyshev N <= 96), while banded states next to a subcritical BP grow at
#: ~1e-11 .. 1e-8; contin's default 1e-8 would count those as stable and the audit would see the
#: change of n_unstable several points after the BP.
STABILITY_TOL = 1e-12

#: Relative change of a banded-branch BP under 1.5x grid refinement above which it is an artefact.
BP_REFINEMENT_TOL = 0.02

#: Halvings of ds_max when a base-branch trace jumped between branches (:func:`trace_base`).
BASE_RETRACES = 4


# ----------------------------------------------------------------------------- analytic facts
def analytic_critical_gaps(nu: float, e: float, modes: int = 3, *, chi: str = "jj", num: float = 0.65,
                           dufour: bool = False) -> list[float]:
    """H_n^c = n pi psi(nu, e), n = 1..modes (physics.md section 4; ``dufour``: with the kappa_h flux); nan where psi is not finite."""
    psi = float(critical_gap_factor(nu, e, chi, num, dufour=dufour))
    return [n * math.pi * psi for n in range(1, modes + 1)]


#: A BP of uniform shear is mode n when |H/(pi psi) - n| <= min(MODE_TOL n, 1/4) (nearest mode,
#: never ambiguous between neighbours).
MODE_TOL = 0.02


def bp_mode(H: float, hc1: float) -> int | None:
    """The mode n of a BP of uniform shear at gap H, from H_n^c = n pi psi (hc1 = pi psi); None if none fits."""
    if not (math.isfinite(H) and math.isfinite(hc1) and hc1 > 0):
        return None
    n = round(H / hc1)
    return n if n >= 1 and abs(H / hc1 - n) <= min(MODE_TOL * n, 0.25) else None


def name_modes(base: Branch, hc1: float) -> None:
    """Append "mode n (n pi psi = ...)" to the note of every BP of uniform shear that matches one.

    Why: BP labels count the BPs found; a BP skipped (or not resolved by the grid) would shift
    every later number, so the mode is read off the location, H_n^c = n pi psi (physics.md sec. 4).
    Idempotent (a resumed branch already carries the names).
    """
    named = []
    for s in base.special_points:
        n = bp_mode(s.params.get("H", math.nan), hc1) if s.type == "BP" else None
        if n is not None and "mode " not in s.note:
            s = replace(s, note=f"{s.note}; mode {n} (n pi psi = {n * hc1:.10g})".lstrip("; "))
        named.append(s)
    base.special_points = named


def mode_notes(base: Branch, hc1: float, H_lo: float, H_max: float) -> list[str]:
    """Notes on the BPs of uniform shear that match no mode, and on the modes in [H_lo, H_max] not found."""
    notes = []
    found = set()
    for s in base.branch_points:
        n = bp_mode(s.params["H"], hc1)
        if n is None:
            notes.append(f"BP at H = {s.params['H']:.10g} on uniform shear matches no mode n pi psi "
                         f"(pi psi = {hc1:.10g}): not a pitchfork of uniform shear; check the grid")
        else:
            found.add(n)
    expected = [n for n in range(1, int(H_max / hc1) + 1) if H_lo < n * hc1 < H_max]
    if not expected and not found:  # H_max below H_1^c: the run had no BP to find and said nothing (session 14)
        notes.append(f"no pitchfork below H_max = {H_max:.6g}: the first, H_1^c = pi psi = {hc1:.10g}, lies above it; "
                     "uniform shear only")
    missing = [n for n in expected if n not in found]
    if missing:
        shown = ", ".join(f"{n} (H = {n * hc1:.6g})" for n in missing[:12]) + (", ..." if len(missing) > 12 else "")
        notes.append(f"{len(missing)} of the {len(expected)} modes with H_n^c = n pi psi below H_max = {H_max:.6g} "
                     f"were not found on uniform shear: modes {shown}; a finer grid resolves higher modes")
    return notes


def _psi_bracket(nu: float, e: float, chi: str, num: float) -> float:
    """(f1/f1')(f2'/f2 + f5'/f5) - 2: psi^2 = (f4/f5) / bracket (closures.critical_gap_factor)."""
    c = coefficients(np.float64(nu), e, chi, num)
    return float((c.f1 / c.f1_nu) * (c.f2_nu / c.f2 + c.f5_nu / c.f5) - 2.0)


def threshold_density(e: float, *, chi: str = "jj", num: float = 0.65, below: float | None = None) -> float:
    """Largest density (below ``below``, default the packing limit) where psi stops being finite.

    Root of the bracket of psi^2 (:func:`_psi_bracket`), bracketed on a grid of nu and refined by
    Brent's method; e = 0.8, chi_JJ: 0.156139.  nan if psi is finite on the whole range.
    """
    top = packing_limit(chi, num) * (1 - 1e-6) if below is None else below
    grid = np.linspace(1e-3, top, 400)
    values = np.array([_psi_bracket(v, e, chi, num) for v in grid])
    change = np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))
    if change.size == 0:
        return math.nan
    i = int(change[-1])
    from scipy.optimize import brentq  # lazily: scipy.optimize costs ~0.1-0.25 s to import

    return float(brentq(_psi_bracket, grid[i], grid[i + 1], args=(e, chi, num), xtol=1e-14, rtol=1e-14))


# ----------------------------------------------------------------------------- helpers
def interpolate_state(source: CouetteProblem, target: CouetteProblem, x: Array) -> Array:
    """A state of ``source`` resampled onto ``target``'s grid (profiles by the grid interpolant)."""
    nu, u, T, P, _ = source.unpack(np.asarray(x, dtype=float))
    y = target.grid.y
    return target.pack(*(source.grid.interpolate(f, y) for f in (nu, u, T)), P)


def state_on(problem: CouetteProblem, x: Array) -> Array:
    """A state of any grid of ``problem``'s model (its size tells the grid: adaptive runs store
    points of several grids) carried onto ``problem``'s grid."""
    x = np.asarray(x, dtype=float)
    if x.size == problem.size:
        return x
    fields = 4 if problem.gravity else 3
    source = on_grid(problem, (x.size - 1) // fields - 1)
    return source.transfer(x, problem)


def newton_at(problem: Any, branch: Branch, values: Mapping[str, float], params: Mapping[str, float],
              options: NewtonOptions = NewtonOptions()) -> Array:
    """The state of ``branch`` at ``values`` (e.g. {'H': 12.5}) by Newton at fixed parameters.

    Starts from the stored point nearest in the branch's continuation parameter (no
    interpolation of states), solved on that point's grid (adaptive runs) and returned on
    ``problem``'s grid.  Raises ValueError if Newton does not converge.
    """
    par = branch.parameter
    i = int(np.argmin(np.abs(branch.parameter_values - values[par])))
    p = {**params, **{k: float(v[i]) for k, v in branch.params.items()}, **values}
    source = point_problem(problem, branch, i)
    res = newton(source, branch.state(i), p, options)
    if not res.converged:
        raise ValueError(f"Newton failed on branch {branch.id} at {values}: {res.message}")
    return res.u if source is problem else source.transfer(res.u, problem)


def mirror_branch(problem: CouetteProblem, branch: Branch, params: Mapping[str, float], branch_id: str) -> Branch:
    """The image of ``branch`` under the reflection S (:func:`contin.overlap.mirror_branch`, which
    reflects points of adaptive runs on their own grids), with recomputed observables and the
    original's message.

    Stability columns are copied: S maps the k_x = 0 eigenproblem at x onto that at S x.
    """
    out = _mirror_branch(problem, branch, params, branch_id)
    out.message = branch.message
    return out


def _is_invariant(problem: CouetteProblem, branch: Branch, tol: float = 1e-6) -> bool:
    """True when the middle state of the branch is S-invariant (:func:`contin.overlap.is_invariant`)."""
    return is_invariant(problem, branch, tol)


# ----------------------------------------------------------------------------- diagram coordinates
@dataclasses.dataclass(frozen=True)
class WallCoordinates:
    """(H / H_scale, nu at the top wall, nu at the bottom wall): the coordinates in which the
    diagram builder (``contin.diagram``) compares gPCF states.  The reflection S (y -> -y) swaps
    the two wall densities, so a banded state and its image differ; both are nodes of every grid,
    so points of adaptive runs need no interpolation."""

    problem: CouetteProblem
    H_scale: float

    def point(self, problem: Any, u: Array, p: Mapping[str, float]) -> Array:
        x = np.asarray(u, dtype=float)
        fields = 4 if self.problem.gravity else 3
        pb = self.problem if x.size == self.problem.size else on_grid(self.problem, (x.size - 1) // fields - 1)
        nu = pb.unpack(x)[0]
        return np.array([p["H"] / self.H_scale, float(nu[-1]), float(nu[0])])

    def branch(self, b: Branch) -> Array:
        H = b.params["H"]
        return np.array([self.point(None, b.state(i), {"H": float(H[i])}) for i in range(len(b))])


# ----------------------------------------------------------------------------- branches
def trace_base(problem: CouetteProblem, params: Mapping[str, float], H_start: float, options: ContinuationOptions,
               *, branch_id: str = "0", progress: Callable[[str], None] | None = None) -> Branch:
    """Uniform shear (no-slip walls; exact at every H) or the symmetric JJ base state, traced in H.

    The start is ``problem.initial_guess`` at H = H_start, corrected by Newton inside ``trace``;
    traces that jumped between branches are repeated with smaller steps (:func:`retrace_on_jumps`).
    """
    p = {**params, "H": H_start}
    kind = "uniform shear" if problem.walls == "noslip" else "base"
    return retrace_on_jumps(
        lambda o: trace(problem, problem.initial_guess(p), p, "H", o, branch_id=branch_id, kind=kind,
                        progress=progress), options, what="base branch")


def retrace_on_jumps(run: Callable[[ContinuationOptions], Branch], options: ContinuationOptions, *, what: str,
                     jumped: Callable[[Branch], str | None] | None = None, unconverged_bp: bool = True) -> Branch:
    """``run(options)``, repeated with ds_max halved (at most :data:`BASE_RETRACES` times) while it
    jumped (:func:`contin.jumps.retrace_on_jumps`).

    Why in gPCF.  With JJ walls the base branch steepens where JJ walls unfold the no-slip mode-2
    pitchfork (module docstring), next to a fold-bounded isolated symmetric branch.  The
    step-length norm is dominated by H (the state enters with weight 1/n), so a step long in H
    can land on the other branch: the tangent orientation there is the opposite one, the BP test
    function changes sign and a spurious 'symmetric' BP appears whose location does not converge
    (nu = 0.3, e = 0.8, cheb 32, ds_max = 8.6: "BP" at H = 33.48).  Likewise a banded branch
    bending away from the base branch (H - H_c ~ a delta^2) can fall back onto it after a long
    step (JJ, cheb 64, ds_max = 4.3: the n = 1 branch back on the base branch at H = 22.3).
    A jump is a BP whose location did not converge (if ``unconverged_bp``), or whatever
    ``jumped(branch)`` reports (a reason, or None).  The retrace is recorded in ``branch.audit``
    ("<what> re-traced with ds_max = ...").
    """
    return _retrace_on_jumps(run, options, what=what, jumped=jumped, unconverged_bp=unconverged_bp,
                             retraces=BASE_RETRACES)


def first_point_on(problem: CouetteProblem, base: Branch, branch: Branch, params: Mapping[str, float], *,
                   start: int = 0, tol: float = 1e-6) -> str | None:
    """Where ``branch`` (from point ``start`` on) lies on ``base``, or None.

    Point i lies on the base branch when Newton on the base problem at its H, started from the
    nearest stored base point, lands within tol max(1, |x|) (max norm) of it.
    """
    for i in range(start, len(branch)):
        h = float(branch.parameter_values[i])
        x = state_on(problem, branch.state(i))
        try:
            xb = newton_at(problem, base, {"H": h}, params)
        except ValueError:
            continue
        if float(np.max(np.abs(xb - x))) <= tol * max(1.0, float(np.max(np.abs(x)))):
            return f"point {i} (H = {h:.6g}) lies on the base branch {base.id}"
    return None


def base_phi(problem: CouetteProblem, base: Branch, H: Array, params: Mapping[str, float]) -> Array:
    """Phi of the base branch at the gaps ``H`` (Newton from the nearest stored base point; nan on failure)."""
    out = np.full(len(H), np.nan)
    for i, h in enumerate(np.asarray(H, dtype=float)):
        try:
            out[i] = problem.order_parameter(newton_at(problem, base, {"H": float(h)}, params))
        except ValueError:
            continue
    return out


def departure(problem: CouetteProblem, branch: Branch, base: Branch, params: Mapping[str, float]) -> Array:
    """|Phi - Phi_base(H)| at every point of ``branch``: a branch that really leaves the base branch
    has it growing from 0 at the BP (like sqrt(H - H_c) at a pitchfork)."""
    return np.abs(branch.observables["phi"] - base_phi(problem, base, branch.parameter_values, params))


def isolated_symmetric_branch(problem: CouetteProblem, base: Branch, params: Mapping[str, float],
                              options: ContinuationOptions, *, branch_id: str = "s1",
                              progress: Callable[[str], None] | None = None) -> tuple[Branch | None, str]:
    """A symmetric branch not connected to the base branch within the H bounds, or None; and a note.

    Newton from ``problem.initial_guess`` (the near-uniform slip state) at the upper H bound.
    With JJ walls at nu = 0.3, e = 0.8 (phi_w = 0.5, ew = 0.9) the base branch has turned into the
    dense-wall state there, and the slip guess converges instead onto the near-uniform sheet of
    an isolated branch whose other sheet is the dense-centre state (the two halves of the
    no-slip mode-2 pitchfork that JJ walls disconnect); it is traced both ways in H.  None if
    Newton fails, the state is not S-invariant, or it lies on the base branch (the note says which).
    """
    _, hi = options.bounds["H"]
    p = {**params, "H": hi}
    res = newton(problem, problem.initial_guess(p), p, options.newton)
    if not res.converged:
        return None, f"no second symmetric state: Newton from the slip guess at H = {hi:.6g} did not converge"
    x = res.u
    scale = max(1.0, float(np.max(np.abs(x))))
    if float(np.max(np.abs(problem.symmetry(x) - x))) > 1e-8 * scale:
        return None, f"no second symmetric state: the slip guess at H = {hi:.6g} converged to a non-symmetric state"
    try:
        x_base: Array | None = newton_at(problem, base, {"H": hi}, params)
    except ValueError:
        x_base = None
    if x_base is not None and float(np.max(np.abs(x_base - x))) <= 1e-6 * scale:
        return None, f"no second symmetric state: the slip guess at H = {hi:.6g} converges onto the base branch"

    def on_base(branch: Branch) -> str | None:
        return first_point_on(problem, base, branch, params)

    branch = retrace_on_jumps(
        lambda o: trace_both(problem, x, p, "H", o, branch_id=branch_id, kind="isolated symmetric",
                             parent=f"slip guess at H={hi:.6g}", progress=progress),
        options, what=f"isolated branch {branch_id}", jumped=on_base)
    if on_base(branch) is not None:
        return None, f"the symmetric state from the slip guess at H = {hi:.6g} is connected to the base branch"
    return branch, (f"isolated symmetric branch {branch_id}: the slip guess at H = {hi:.6g} converges to Phi = "
                    f"{problem.order_parameter(x):.6g}, off the base branch (Phi = "
                    f"{problem.order_parameter(x_base) if x_base is not None else math.nan:.6g}); traced both ways")


def banded_branches(problem: CouetteProblem, base: Branch, bp: SpecialPoint, params: Mapping[str, float],
                    options: ContinuationOptions, prefix: str, *, first: Branch | None = None) -> list[Branch]:
    """Both signs of the branch bifurcating at ``bp``: ids f"{prefix}.1" and f"{prefix}.2".

    The first is traced by :func:`contin.continuation.switch` (or is ``first``, a finished branch
    of an interrupted run: ``--resume`` must not retrace it); the second is its mirror image
    when the first is not S-invariant (symmetry-breaking BPs), otherwise it is traced too
    (S-invariant branches, e.g. mode 2, whose two signs are different states).
    """
    def switched(direction: int) -> Branch:
        def run(o: ContinuationOptions) -> Branch:
            new = switch(problem, base, bp, o, directions=(direction,), branch_id_prefix=prefix)
            if not new:
                side = "" if direction == 1 else " in the second direction"
                raise ValueError(f"switching at {bp.name} (H = {bp.params['H']:.6g}){side} found no new branch")
            return new[0]

        # A new branch must not come back onto its parent (from point 2 on: points 0 and 1 are
        # within one short step of the BP).
        return retrace_on_jumps(run, options, what=f"branch from {bp.name}", unconverged_bp=False,
                                jumped=lambda b: first_point_on(problem, base, b, params, start=2))

    b1 = first if first is not None else switched(+1)
    b1.id = f"{prefix}.1"
    if _is_invariant(problem, b1):
        b2 = switched(-1)
        b2.id = f"{prefix}.2"
    else:
        b2 = mirror_branch(problem, b1, params, f"{prefix}.2")
        b2.message = f"mirror image of branch {b1.id} (reflection y -> -y)"
    return [b1, b2]


def banded_diagram(problem: CouetteProblem, params: Mapping[str, float], base_options: ContinuationOptions,
                   band_options: ContinuationOptions, select: Callable[[Branch], Sequence[tuple[int, SpecialPoint]]], *,
                   H_scale: float, base_id: str = "0", finish: Callable[[Branch, SpecialPoint | None, int], None] | None = None,
                   on_branch: Callable[[Branch, Branch | None], None] | None = None,
                   completed: Mapping[str, Branch] | None = None,
                   progress: Callable[[str], None] | None = None) -> Any:
    """The base branch (``problem.initial_guess`` at params['H'], traced upwards in H) and both signs
    of the banded branch at each BP that ``select(base)`` returns as (k, BP), ids
    f"{base_id}" / "n<k>.1" / "n<k>.2" (base_id "0") or f"{base_id}.<k>.1/2", built by
    :func:`contin.diagram.bifurcation_diagram` to depth 2.

    What is gPCF here: the coordinates (:class:`WallCoordinates`), the jump test of a switched
    branch (it comes back onto the base branch, by Newton: :func:`first_point_on`; re-traced with
    ds_max halved, at most :data:`BASE_RETRACES` times, as the base branch when a BP location does
    not converge), the second sign of a symmetry-breaking mode as the mirror image (reflection
    y -> -y) of the first, of an S-invariant mode (mode 2) traced.  ``finish(branch, bp, k)`` is
    called on every traced branch before it is stored and mirrored (bp None for the base branch),
    ``on_branch(branch, source)`` on every stored branch (source: the branch it mirrors).
    """
    from contin.diagram import DiagramHooks, DiagramSettings, bifurcation_diagram

    picked: dict[str, tuple[int, SpecialPoint]] = {}  # prefix -> (k, BP of the base branch)

    def prefix_of(k: int) -> str:
        return f"n{k}" if base_id == "0" else f"{base_id}.{k}"

    def finishing(b: Branch) -> None:
        if finish is not None:
            k, bp = picked.get(b.id.rsplit(".", 1)[0], (0, None)) if b.id != base_id else (0, None)
            finish(b, bp, k)

    def stored(b: Branch, source: Branch | None) -> None:
        if source is not None:
            b.message = f"mirror image of branch {source.id} (reflection y -> -y)"
        if on_branch is not None:
            on_branch(b, source)

    def switch_at(parent: Branch, bp: SpecialPoint) -> str | None:
        if parent.id != base_id:
            return None
        k = next((k for k, c in select(parent) if c.index == bp.index), None)
        if k is None:
            return None
        if progress is not None:
            progress(f"switching at {bp.name} (H = {bp.params['H']:.6g})")
        picked[prefix_of(k)] = (k, bp)
        return prefix_of(k)

    hooks = DiagramHooks(
        switch_at=switch_at, mirror_id=lambda i: i[:-2] + ".2" if i.endswith(".1") else i + "'",
        # a new branch must not come back onto its parent (from point 2 on: points 0 and 1 are
        # within one short step of the BP)
        jumped=lambda parent, b: first_point_on(problem, parent, b, params, start=2),
        finish=finishing, on_branch=stored, completed=dict(completed or {}), start_id=base_id,
        options=lambda parent: base_options if parent is None else band_options)
    settings = DiagramSettings(depth=2, probe_steps=0, start_direction=1, retraces=BASE_RETRACES)
    return bifurcation_diagram(problem, problem.initial_guess(params), params, "H", base_options, settings,
                               coordinates=WallCoordinates(problem, H_scale), progress=progress, hooks=hooks)


def density_continuation(problem: CouetteProblem, params: Mapping[str, float], nu_from: float, nu_to: float,
                         H_fixed: float, options: ContinuationOptions, *,
                         progress: Callable[[str], None] | None = None) -> tuple[Array, list[Branch]]:
    """A banded mode-1 state at (nu_to, H_fixed) from the BP of uniform shear at nu_from.

    Uniform shear at nu_from is traced in H up to its first BP, the banded branch is followed
    to H_fixed (bound), then that state is continued in nu at fixed H down to nu_to (bound).
    Returns the state and the auxiliary branches (uniform, banded, density path).

    Raises ValueError if a stage does not reach its target.
    """
    hc = analytic_critical_gaps(nu_from, params["e"], 1, chi=problem.chi, num=params["num"])[0]
    p0 = {**params, "nu": nu_from}
    H_lo = 0.5 * hc
    H_hi = max(H_fixed, 1.2 * hc)
    opts_H = dataclasses.replace(options, bounds={"H": (H_lo, H_hi)})
    uni = trace(problem, problem.uniform_state({**p0, "H": 0.8 * hc}), {**p0, "H": 0.8 * hc}, "H",
                dataclasses.replace(opts_H, bounds={"H": (H_lo, 1.1 * hc)}), branch_id="aux.uniform",
                progress=progress)
    bps = [b for b in uni.branch_points if "symmetry-breaking" in b.note]
    if not bps:
        raise ValueError(f"uniform shear at nu = {nu_from:g} has no symmetry-breaking BP near H = {hc:.6g}")
    opts_b = dataclasses.replace(opts_H, bounds={"H": (H_lo, H_fixed)})
    band = switch(problem, uni, bps[0], opts_b, directions=(+1,), branch_id_prefix="aux.banded")
    if not band or abs(band[0].parameter_values[-1] - H_fixed) > 1e-9 * H_fixed:
        why = f" ({band[0].message})" if band else ""
        raise ValueError(f"the banded branch at nu = {nu_from:g} did not reach H = {H_fixed:g}{why}")
    x = band[0].state(len(band[0]) - 1)
    lo, hi = sorted((nu_to, nu_from))
    opts_nu = dataclasses.replace(options, bounds={"nu": (lo, hi + 1e-9)})
    path = trace(point_problem(problem, band[0], len(band[0]) - 1), x, {**p0, "H": H_fixed}, "nu", opts_nu, direction=1 if nu_to > nu_from else -1,
                 branch_id="aux.density", kind="density path", progress=progress)
    if abs(path.parameter_values[-1] - nu_to) > 1e-12:
        raise ValueError(f"continuation in nu at H = {H_fixed:g} stopped at nu = {path.parameter_values[-1]:.6g} "
                         f"before reaching nu = {nu_to:g} ({path.message})")
    return state_on(problem, path.state(len(path) - 1)), [uni, band[0], path]


# ----------------------------------------------------------------------------- analysis
def criticality(branch: Branch, H_c: float, phi_c: float, *, delta_max: float = 0.06) -> dict[str, Any]:
    """Least-squares fit of H - H_c = a delta^2 + b delta^3 + c delta^4 near the BP, delta = Phi - Phi_c.

    Phi_c is Phi at the BP (nu_bar on uniform shear; the base state's Phi with JJ walls).
    Uses the points with 0 < |delta| <= delta_max before the first fold (at least 3; with fewer
    than 4 points only a and b are fitted).  kind = 'supercritical' for a > 0, 'subcritical' for
    a < 0 (physics.md section 4).
    """
    if len(branch) == 0 or "phi" not in branch.observables:  # a switched branch that could not start (MX, no points)
        return {"branch": branch.id, "a": math.nan, "kind": "unknown", "points": 0}
    d = branch.observables["phi"] - phi_c
    h = branch.parameter_values - H_c
    stop = len(branch)
    lps = branch.fold_points
    if lps:
        stop = min(stop, lps[0].index + 1)
    sel = np.flatnonzero((np.abs(d[:stop]) > 1e-12) & (np.abs(d[:stop]) <= delta_max))
    if sel.size < 3:
        sel = np.flatnonzero(np.abs(d[:stop]) > 1e-12)[:4]
    if sel.size < 2:
        return {"branch": branch.id, "a": math.nan, "kind": "unknown", "points": int(sel.size)}
    powers = (2, 3, 4) if sel.size >= 4 else (2, 3)
    A = np.column_stack([d[sel] ** k for k in powers])
    coef, *_ = np.linalg.lstsq(A, h[sel], rcond=None)
    a = float(coef[0])
    return {"branch": branch.id, "a": a, "b": float(coef[1]), "kind": "supercritical" if a > 0 else "subcritical",
            "points": int(sel.size), "delta_max": float(np.max(np.abs(d[sel])))}


def confirm_branch_points(problem: CouetteProblem, branch: Branch, params: Mapping[str, float],
                          options: ContinuationOptions, *, factor: float = 1.5,
                          tol: float = BP_REFINEMENT_TOL) -> list[str]:
    """Re-locate every BP of a non-uniform branch on a grid ``factor`` times finer.

    From the BP state (interpolated) at H_bp (1 - 2 tol), the refined branch is traced up to
    H_bp (1 + 2 tol).  A BP whose refined twin is missing, or lies more than ``tol`` (relative)
    away, is replaced by a UZ point with a note; returns one message per demoted point.  Genuine
    BPs converge with the grid (exponentially for Chebyshev), the wall-wiggle crossing of the
    module docstring moves like log N.
    """
    bps = branch.branch_points
    if not bps:
        return []
    messages = []
    new_points = []
    for sp_ in branch.special_points:
        if sp_.type != "BP":
            new_points.append(sp_)
            continue
        hb = sp_.params["H"]
        lo, hi = hb * (1 - 2 * tol), hb * (1 + 2 * tol)
        i0 = int(np.argmin(np.abs(branch.parameter_values - lo)))
        p = {**params, **{k: float(v[i0]) for k, v in branch.params.items()}}
        source = on_grid(problem, sp_.grid)  # the grid the BP was located on (adaptive runs)
        fine = CouetteProblem(problem.method, int(round(factor * source.N)), walls=problem.walls, chi=problem.chi,
                              dufour=problem.dufour, engine=rebuilt_engine(problem.engine))
        x0 = interpolate_state(source, fine, state_on(source, branch.state(i0)))
        p["H"] = float(np.clip(p["H"], lo, hi))
        step = dataclasses.replace(options.step, ds=min(abs(options.step.ds), 0.05 * hb * tol),
                                   ds_max=min(options.step.ds_max, hb * tol))
        opts = dataclasses.replace(options, step=step, bounds={"H": (lo, hi)}, max_steps=60, adapt=None)
        direction = 1 if branch.parameter_values[min(i0 + 1, len(branch) - 1)] >= branch.parameter_values[i0] else -1
        ref = trace(fine, x0, p, "H", opts, direction=direction, branch_id="refine")
        twins = [b for b in ref.branch_points if abs(b.params["H"] - hb) <= tol * hb]
        if twins:
            new_points.append(sp_)
            continue
        moved = ", ".join(f"{b.params['H']:.6g}" for b in ref.branch_points) or "none"
        note = (f"unconfirmed BP at H = {hb:.6g} (N = {source.N}): no BP within {100 * tol:g}% at N = {fine.N} "
                f"(BPs there: {moved}); discretization artefact")
        messages.append(f"branch {branch.id}: {note}")
        new_points.append(replace(sp_, type="UZ", note=note))
    branch.special_points = new_points
    return messages


class StabilityOperator:
    """Eigenproblem of physics.md section 5 for states of a CouetteProblem, on a Chebyshev grid.

    ``eigenproblem(x, p, kx, kz)`` interpolates FD base profiles onto a Chebyshev grid with the
    same number of intervals (at most 80; ``linear.to_chebyshev``) and drops the decoupled,
    always-stable w block at k_x = k_z = 0 (module docstring).
    """

    def __init__(self, problem: CouetteProblem) -> None:
        self.problem = problem

    def eigenproblem(self, x: Array, p: Mapping[str, float], kx: float = 0.0, kz: float = 0.0) -> tuple[Any, Any]:
        from problems.couette.linear import linear_operator, to_chebyshev

        pb = self.problem
        nu, u, T, _, _ = pb.unpack(np.asarray(x, dtype=float))
        grid, nu, u, T = to_chebyshev(pb.grid, nu, u, T)
        A, B = linear_operator(grid, nu, u, T, p, walls=pb.walls, kx=kx, kz=kz, chi=pb.chi, dufour=pb.dufour,
                               gravity=False, dense=True)
        if kx == 0.0 and kz == 0.0:
            n = grid.size
            keep = np.r_[0:3 * n, 4 * n:5 * n]
            A = A[np.ix_(keep, keep)]
            B = B[np.ix_(keep, keep)]
        return A, B

    def spectrum(self, x: Array, p: Mapping[str, float], kx: float = 0.0) -> np.ndarray:
        """All finite eigenvalues at wavenumber k_x (k_z = 0), real part descending.

        k_x = 0: ``linear.k0_spectrum`` (the constrained Schur form, split into S-even and S-odd
        halves on symmetric states); otherwise, or if its boundary block is singular,
        :func:`finite_eigenvalues` of :meth:`eigenproblem`.
        """
        if kx == 0.0:
            from problems.couette.linear import k0_spectrum, to_chebyshev

            pb = self.problem
            nu, u, T, _, _ = pb.unpack(np.asarray(x, dtype=float))
            grid, nu, u, T = to_chebyshev(pb.grid, nu, u, T)
            w = k0_spectrum(grid, nu, u, T, p, walls=pb.walls, chi=pb.chi, dufour=pb.dufour, gravity=False)
            if w is not None:
                return w
        return finite_eigenvalues(*self.eigenproblem(x, p, kx=kx))


def finite_eigenvalues(A: Any, B: Any) -> np.ndarray:
    """All finite eigenvalues of A X = omega B X, real part descending.

    When B is diagonal (the Couette operator: B = diag(1, nu0, nu0, (3/2) nu0) with zero rows at
    the boundary conditions) the zero-B rows Z are eliminated with the unknowns of the same
    index: A_ZZ x_Z = -A_ZK x_K, leaving the standard problem
    B_KK^-1 (A_KK - A_KZ A_ZZ^-1 A_ZK) x_K = omega x_K, whose eigenvalues are exactly the finite
    ones (about 2.5x cheaper than QZ).  Otherwise, or if A_ZZ is singular, dense QZ
    (``contin.stability.eigenvalues``).
    """
    a = A.toarray() if sp.issparse(A) else np.asarray(A)
    b = B.toarray() if sp.issparse(B) else np.asarray(B)
    d = np.diag(b)
    if np.count_nonzero(b - np.diag(d)) == 0:
        z = np.flatnonzero(d == 0)
        k = np.flatnonzero(d != 0)
        azz = a[np.ix_(z, z)]
        if z.size == 0 or np.linalg.cond(azz) < 1e12:
            schur = a[np.ix_(k, k)]
            if z.size:
                schur = schur - a[np.ix_(k, z)] @ np.linalg.solve(azz, a[np.ix_(z, k)])
            import scipy.linalg as la  # lazy: the package is off the path to the first step (contin.lapack)

            w = la.eigvals(schur / d[k][:, None])
            return w[np.lexsort((-w.imag, -w.real))]
    return eigenvalues(A, B)


def _stability_columns(problem: CouetteProblem, branch: Branch, params: Mapping[str, float], kx: float,
                       n_eigs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(stable, n_unstable, eigenvalues) of every stored point by the generic per-point loop
    (``contin.stability.stability_columns``: stop requests, unknown points, the columns) with
    gPCF's eigenproblem: :meth:`StabilityOperator.spectrum` at k_x, each point on its own grid
    (adaptive runs); None when a stop request ended the loop."""

    def spectrum(i: int, x: Array, p: dict[str, float]) -> np.ndarray:
        return StabilityOperator(point_problem(problem, branch, i)).spectrum(x, p, kx=kx)

    return stability_columns(branch, params, spectrum, n_eigs=n_eigs, tol=STABILITY_TOL,
                             errors=(np.linalg.LinAlgError, ValueError))


@limited()  # small dense eigenproblems: one BLAS thread (contin.blas)
def stability(problem: CouetteProblem, branch: Branch, params: Mapping[str, float], *, n_eigs: int = 6) -> list[str]:
    """k_x = k_z = 0 stability of every stored point, then ``contin.stability.audit``.

    Fills ``branch.stable``, ``n_unstable`` and ``eigenvalues`` with the semantics of
    ``contin.stability.stability_pass`` (unstable: Re omega > STABILITY_TOL max(1, |omega|); the
    n_eigs leading eigenvalues) but solves each eigenproblem by :func:`finite_eigenvalues` on
    the :class:`StabilityOperator`.  Audit messages are returned and appended to
    ``branch.audit`` after the continuation's own entries.
    """
    before = list(branch.audit)
    columns = _stability_columns(problem, branch, params, 0.0, n_eigs)
    if columns is None:  # stopped: the branch stays without stability (a --resume computes it)
        return []
    branch.stable, branch.n_unstable, branch.eigenvalues = columns
    msgs = audit_branch(branch)
    branch.audit = before + [f"stability audit: {m}" for m in msgs]
    return msgs


def audit_branch(branch: Branch) -> list[str]:
    """``contin.stability.audit`` of the branch (which counts point 0 of a switched branch, the
    parent's BP with its exactly-zero eigenvalue, with the unstable count of point 1)."""
    return audit(branch)


@limited()
def growth_rates(problem: CouetteProblem, branch: Branch, params: Mapping[str, float], kx: float) -> dict[str, list] | None:
    """max Re omega and the unstable count at wavenumber k_x (k_z = 0) at every stored point
    (None when a stop request ended the loop)."""
    columns = _stability_columns(problem, branch, params, kx, 1)
    if columns is None:
        return None
    _, counts, eigs = columns
    return {"growth_rate": [float(v) for v in eigs[:, 0].real], "n_unstable": [int(c) for c in counts]}


def fold_table(branches: Sequence[Branch]) -> list[dict[str, Any]]:
    """Every LP as {branch, label, H, phi}."""
    return [{"branch": b.id, "label": lp.name, "H": float(lp.params["H"]), "phi": float(lp.order_parameter)}
            for b in branches for lp in b.fold_points]
