"""Scenes: named, reproducible continuation jobs that the CLI can run.

contin knows no physics; problem packages register scenes through the entry-point group
``contin.scenes`` (see ``pyproject.toml``).  Each entry point names a ``dict[str, Scene]``.
A scene turns a :class:`SceneRequest` (user parameters, discretization, options) into a
:class:`SceneResult` (branches plus notes and provenance).

Stability.  ``request.stability`` (default True; ``contin trace --no-stability`` clears it)
asks for the linear-stability pass at k_x = k_z = 0 on every branch, ``request.kx`` for extra
wavenumbers.  A scene either calls :meth:`SceneRequest.run_stability` (problem, branch) on each
branch before ``request.finished(branch)``, or leaves it to the CLI, which does it after the
run when the scene has a ``problem_factory`` (:func:`stability_after_run`: ``contin trace`` and
every ``contin sweep`` task alike).  A scene with ``Scene.stability = False`` has no
linear-stability operator (its residual has algebraic rows -- boundary conditions, constraints --
and no mass matrix or ``eigenproblem`` to say which rows are dynamics): the CLI runs no pass on
it and ``contin stability`` refuses its files, rather than count those rows as unstable modes
(``contin trace`` and ``contin sweep`` hand such a scene a request with ``stability=False``, so
its own :meth:`SceneRequest.run_stability` calls do nothing either).

Rebuilding the problem from a file.  ``Scene.problem_factory(parameters, discretization) ->
problem`` (optional) rebuilds the problem instance from the ``parameters`` and
``discretization`` dicts of the scene's :class:`SceneResult` (stored as the root attributes of
the HDF5 file).  It must return the problem whose states the scene's branches hold (same
size and layout); ``contin stability FILE.h5`` and the CLI's post-run stability pass use it
together with the parameters stored along each branch.  Without it those features report that
the file's problem cannot be rebuilt.
"""

from __future__ import annotations

import dataclasses
import importlib
import logging
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any

import numpy as np

from contin.branch import Branch
from contin.options import AdaptOptions, ContinuationOptions


#: Values of SceneRequest.engine (the CLI's --engine), see :mod:`contin.engines`.
from contin.engines import ENGINES  # noqa: E402


class SceneError(ValueError):
    """Bad input for a scene (unknown parameter, value out of range...): one clear sentence."""


@dataclass(frozen=True)
class SceneRequest:
    """What the user asked for.

    params : user overrides (name -> value as typed, e.g. {'nu': 0.3, 'Fr': inf, 'chi': 'jj'})
    method, grid : discretization (None = the scene's default)
    options : continuation options (None = the scene's defaults)
    stability : run the linear-stability pass on every branch
    kx : extra streamwise wavenumbers for the stability pass
    completed : branches already finished in an earlier run (``--resume``), by branch id;
        a scene reuses them instead of recomputing.
    on_branch : called with each finished branch (the CLI appends it to the HDF5 file at once,
        so an interrupted run loses at most the branch in progress).
    progress : called with a short human-readable status line (never prints itself).
    engine : implementation of the problem's residual and Jacobian where a problem has several
        (ENGINES: 'auto', 'numpy', 'numba'); None = the problem's default.  Scenes whose
        problems have one implementation ignore it.
    overrides : user changes to the scene's continuation options (``--ds``, ``--ds-max``, ``--uz``, ``--stop-at``,
        ``--max-steps``, ``--resolution-tol`` -> keys 'ds', 'ds_max', 'max_steps',
        'resolution_tol' (None: guard off)); scenes apply them with :meth:`options_for` so that
        their own defaults (bounds...) survive.  (The command line also sets resolution_tol for
        every trace of the run, ``contin.options.resolution_override``: scenes build options of
        their own too.)  Adaptive resolution (``--tol``, ``--max-grid``; only for scenes with
        ``Scene.adaptive``): keys 'tol', 'max_grid' and 'solve_check' (False: ``--no-solve-check``)
        become ``ContinuationOptions.adapt``; ``contin trace`` and ``contin sweep`` set them by
        :meth:`Scene.accuracy_overrides`.
    """

    params: Mapping[str, Any] = field(default_factory=dict)
    method: str | None = None
    grid: int | None = None
    options: ContinuationOptions | None = None
    stability: bool = True
    kx: tuple[float, ...] = ()
    completed: Mapping[str, Branch] = field(default_factory=dict)
    on_branch: Callable[[Branch], None] | None = None
    progress: Callable[[str], None] | None = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    engine: str | None = None
    # Options resolved by options_for (the CLI stores them and warns if overrides were ignored).
    _resolved: list[ContinuationOptions] = field(default_factory=list, repr=False, compare=False)
    # Branch ids whose extra --kx columns run_stability skipped: the problem has no eigenproblem.
    _no_wavenumber: list[str] = field(default_factory=list, repr=False, compare=False)

    def options_for(self, default: ContinuationOptions) -> ContinuationOptions:
        """The options to use for one trace: ``self.options`` if given, else ``default``
        with the user's :attr:`overrides` applied (step.ds keeps the default's sign)."""
        base = self.options if self.options is not None else default
        ov = dict(self.overrides)
        step = base.step
        if "ds" in ov or "ds_max" in ov:
            # --ds-max alone below the scene's first step caps that step too: `contin trace bratu
            # --ds-max 0.01` ended "Error: need ds_max >= |ds| >= ds_min > 0, got ds_max=0.01, ds=0.05"
            first = abs(float(ov["ds"])) if "ds" in ov else min(abs(step.ds), float(ov["ds_max"]))
            if "ds" in ov and "ds_max" in ov and first > float(ov["ds_max"]):
                raise SceneError(f"--ds ({first:g}) must not exceed --ds-max ({float(ov['ds_max']):g})")
            ds = first * (1.0 if step.ds >= 0 else -1.0)
            ds_max = float(ov.get("ds_max", max(step.ds_max, abs(ds))))
            step = dataclasses.replace(step, ds=ds, ds_max=ds_max,
                                       ds_min=min(step.ds_min, abs(ds)))
        kw: dict[str, Any] = {"step": step}
        if "max_steps" in ov:
            kw["max_steps"] = int(ov["max_steps"])
        if "resolution_tol" in ov:
            kw["resolution_tol"] = ov["resolution_tol"]
        if ov.get("tol") is not None:
            adapt = AdaptOptions(tol=float(ov["tol"]))
            if ov.get("solve_check") is False:  # --no-solve-check
                adapt = dataclasses.replace(adapt, solve_check=False)
            if ov.get("special_tol") is not None:  # --special-tol
                adapt = dataclasses.replace(adapt, special_tol=float(ov["special_tol"]))
            kw["adapt"] = dataclasses.replace(adapt, max_grid=int(ov["max_grid"])) if ov.get("max_grid") else adapt
        if "user_zeros" in ov:  # --uz NAME=V1,V2 (AUTO's UZR), added to the scene's own
            kw["user_zeros"] = {**base.user_zeros, **ov["user_zeros"]}
        if "stop_at" in ov:  # --stop-at UZ1 (AUTO's UZSTOP) replaces the scene's
            kw["stop_at"] = tuple(ov["stop_at"])
        if "bp_eigenvalues" in ov:  # --bp-eigs K: the eigenvalue-count BP detector (contin.bpdetect)
            kw["detection"] = dataclasses.replace(base.detection, bp_eigenvalues=int(ov["bp_eigenvalues"]))
        resolved = dataclasses.replace(base, **kw)
        self._resolved.append(resolved)
        return resolved

    @property
    def resolved_options(self) -> list[ContinuationOptions]:
        """Every options object handed out by :meth:`options_for` (empty if never called)."""
        return list(self._resolved)

    @property
    def kx_unavailable(self) -> list[str]:
        """Ids of the branches whose nonzero ``kx`` :meth:`run_stability` skipped because the
        problem has no ``eigenproblem(u, p, kx, kz)`` (no wavenumber: only k_x = 0 exists)."""
        return list(self._no_wavenumber)

    def run_stability(self, problem: Any, branch: Branch, params_fixed: Mapping[str, Any] | None = None, *,
                      n_eigs: int = 6) -> list[str]:
        """The stability the user asked for, on one branch; returns the audit messages.

        Nothing when :attr:`stability` is False.  Otherwise: the pass at k_x = k_z = 0
        (:func:`contin.stability.stability_pass`, skipped if the branch already has stability
        columns), :func:`contin.stability.audit`, and for every nonzero k_x in :attr:`kx` the
        columns of :func:`contin.stability.growth_columns` as observables
        (``growth_rate_kx<k>``, ``n_unstable_kx<k>``).  ``params_fixed``: the problem's
        parameters (non-numeric entries are ignored); the branch's own columns override them.
        A problem without ``eigenproblem(u, p, kx, kz)`` has no wavenumber: its nonzero k_x are
        skipped (:attr:`kx_unavailable`; the caller says so) and the k_x = 0 pass and its audit
        are kept (with ``--kx 1`` the lorenz scene's pass ended in a "stability failed" warning).
        """
        if not self.stability:
            return []
        from contin.problem import has
        from contin.stability import audit, growth_columns, stability_pass

        fixed = {k: v for k, v in dict(params_fixed or {}).items()
                 if isinstance(v, int | float | np.floating | np.integer) and not isinstance(v, bool)}
        if branch.n_unstable is None:
            stability_pass(problem, branch, fixed, n_eigs=n_eigs)
            if branch.n_unstable is None:  # a stop request ended the pass (contin.cancel)
                return []
        messages = audit(branch)
        if any("complex pair" in m for m in messages):  # Hopf points the tracer did not locate
            messages = self._hopf_points(problem, branch, fixed, 0.0, branch.n_unstable) + audit(branch)
        for kx in self.kx:
            if float(kx) != 0.0 and not has(problem, "eigenproblem"):
                if branch.id not in self._no_wavenumber:
                    self._no_wavenumber.append(branch.id)
            elif float(kx) != 0.0:
                for name, column in growth_columns(problem, branch, fixed, kx=float(kx)).items():
                    branch.observables.setdefault(name, column)
                counts = branch.observables.get(f"n_unstable_kx{float(kx):g}")
                messages += self._hopf_points(problem, branch, fixed, float(kx), counts)
        return messages

    @staticmethod
    def _hopf_points(problem: Any, branch: Branch, fixed: Mapping[str, Any], kx: float, counts: Any) -> list[str]:
        """HB points where a complex pair of the stability problem at kx crosses between stored
        points with different unstable counts (:func:`contin.hopfscan.locate_hopf`), added to
        the branch (label 0: numbered by ``contin.hopfscan.number_new_points``); returns the
        reasons for count changes it could not locate as audit lines."""
        from contin.hopfscan import locate_hopf

        if counts is None or len(branch.free) != 1:
            return []
        scan = locate_hopf(problem, branch, fixed, kx=kx, counts=counts)
        known = {(sp.type, round(sp.params.get(branch.parameter, np.nan), 9), sp.data.get("kx"))
                 for sp in branch.special_points}
        for sp in scan.points:
            if ("HB", round(sp.params[branch.parameter], 9), sp.data.get("kx")) not in known:
                branch.special_points.append(sp)
        branch.special_points.sort(key=lambda sp: sp.index)
        lines = [f"Hopf: {r}" for r in scan.reasons]
        branch.audit.extend(lines)
        return lines

    def report(self, message: str) -> None:
        if self.progress is not None:
            self.progress(message)

    def finished(self, branch: Branch) -> None:
        if self.on_branch is not None:
            self.on_branch(branch)


@dataclass
class SceneResult:
    """Branches and everything needed to store and plot them.

    parameters : the full parameter set used (defaults merged with user values)
    discretization : e.g. {'method': 'cheb', 'intervals': 48}
    y : wall-normal grid of the state profiles (None for problems without one)
    profiles : maps a state vector to named profiles on ``y`` (e.g. nu, u, T)
    notes : human-readable findings ("uniform shear has no BP at nu = 0.15")
    extra : scene-specific JSON-serialisable results (tricritical density, ...)
    not_started : ``"ID: reason"`` for each branch the scene set out to trace that could not
        start (no point, so nothing is stored); the CLI warns about each and exits 3 (incomplete),
        as for a branch that ended with MX
    """

    branches: list[Branch]
    parameters: dict[str, Any]
    discretization: dict[str, Any] = field(default_factory=dict)
    y: np.ndarray | None = None
    profiles: Callable[[np.ndarray], dict[str, np.ndarray]] | None = None
    notes: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)
    not_started: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class DiagramStart:
    """Where a scene's automatic bifurcation diagram starts (``contin trace SCENE --depth D``).

    problem, state, params, parameter, options : the arguments of
        :func:`contin.diagram.bifurcation_diagram` (``params`` all the problem's parameters)
    settings : a :class:`contin.diagram.DiagramSettings` (None = its defaults); the CLI's
        ``--depth`` and ``--max-branches`` replace its depth and max_branches
    coordinates, seeds : as in :func:`contin.diagram.bifurcation_diagram`
    parameters, discretization, y, profiles : as in :class:`SceneResult` (what the HDF5 file stores)
    notes : called with the finished :class:`contin.diagram.Diagram`; returns notes (e.g. the
        special points against their closed forms)
    """

    problem: Any
    state: np.ndarray
    params: Mapping[str, float]
    parameter: str
    options: ContinuationOptions
    settings: Any = None
    coordinates: Any = None
    seeds: tuple[Any, ...] = ()
    parameters: Mapping[str, Any] = field(default_factory=dict)
    discretization: Mapping[str, Any] = field(default_factory=dict)
    y: np.ndarray | None = None
    profiles: Callable[[np.ndarray], dict[str, np.ndarray]] | None = None
    notes: Callable[[Any], list[str]] | None = None


@dataclass(frozen=True)
class Scene:
    """A named job: ``run(request) -> SceneResult``; ``defaults`` documents its parameters.

    ``problem_factory(parameters, discretization) -> problem`` (optional) rebuilds the
    problem of the scene's branches from ``SceneResult.parameters`` and
    ``SceneResult.discretization`` (module docstring); it enables ``contin stability`` on the
    scene's files and the CLI's post-run stability pass.

    ``adaptive``: the scene takes ``--tol`` (adaptive resolution, ``contin.adapt``): its
    problems have the grid hooks, its traces get their options from
    :meth:`SceneRequest.options_for`, and whatever it does with stored points uses each point's
    grid (``Branch.grid``; ``problem_factory`` builds the start grid, ``contin.adapt.on_grid``
    the others).  Its profiles callable accepts states of any of its grids.  ``default_tol``:
    the tol of a run without --grid and --tol, chosen per scene so that it keeps the accuracy of
    the scene's former fixed default grid.  ``special_key_points``: the key points the scene
    reports for ``contin accuracy`` (``extra['key_points']``) are special points of its traces
    (BPs, LPs located by the tracer), so an accuracy can be asked of them alone
    (``--special-tol``, ``AdaptOptions.special_tol``) while the states keep ``default_tol``:
    ``contin accuracy --tols`` then runs that request too.

    ``stability`` (default True): the problem has a linear-stability operator (its own
    ``eigenproblem``, or a mass matrix that makes J x = omega M x meaningful).  False: its
    residual has algebraic rows the automatic M = I would count as dynamics, so a stability
    result would be doubtful -- ``contin trace`` runs no stability pass on the scene (the request
    it hands the scene has ``stability=False``; one ``note:`` line unless ``-q``) and ``contin
    stability`` refuses its files with one ``Error:`` line, while ``problem_factory`` still
    serves ``contin verify`` and ``contin continue``.

    ``discretized`` (default True): the problem has a discretization (``--method``, ``--grid``);
    False for systems of ODEs (ab, lorenz), whose ``contin trace --grid 10`` ran, ignored it and
    exited 0 (qa16): the CLI refuses the options with one ``Error:`` line.

    ``start(request) -> DiagramStart`` (optional): the start point of the scene's automatic
    bifurcation diagram; ``contin trace SCENE --depth D`` then runs
    :func:`contin.diagram.explore` instead of ``run``.
    """

    name: str
    summary: str
    defaults: Mapping[str, Any]
    run: Callable[[SceneRequest], SceneResult]
    x: str = ""  # default x-axis of its diagram (a parameter name)
    y: str = "phi"  # default y-axis (an observable name)
    problem_factory: Callable[[Mapping[str, Any], Mapping[str, Any]], Any] | None = None
    adaptive: bool = False
    default_tol: float = 3e-5
    special_key_points: bool = False
    stability: bool = True
    start: Callable[[SceneRequest], DiagramStart] | None = None
    discretized: bool = True

    def accuracy_overrides(self, *, grid: int | None = None, tol: float | None = None, max_grid: int | None = None,
                           special_tol: float | None = None, solve_check: bool = True,
                           names: Mapping[str, str] | None = None) -> dict[str, Any]:
        """The adaptive-resolution keys of :attr:`SceneRequest.overrides` for a run of this scene.

        The one rule ``contin trace`` and every ``contin sweep`` task resolve the accuracy with
        (a sweep task of an adaptive scene without ``grid`` ran on the scene's fixed default grid
        where ``trace`` ran adaptively at :attr:`default_tol`): an adaptive scene runs adaptively
        when ``tol`` is given or no ``grid`` is (then at ``tol``, default :attr:`default_tol`; the
        grid, if given, is the start grid), with ``solve_check``, ``special_tol`` and ``max_grid``
        as given; ``grid`` alone fixes the grid (no keys) and takes none of them (``--grid 16
        --max-grid 64`` ignored the max grid, exit 0).  A non-adaptive scene takes none of them.

        ``names``: how the caller's settings are called in messages (default the command line's
        ``--tol``, ``--max-grid``, ``--special-tol``, ``--no-solve-check``, ``--grid``).

        Raises
        ------
        SceneError
            An accuracy setting for a scene without adaptive resolution, ``special_tol``,
            ``max_grid`` or ``solve_check=False`` with a fixed grid, or ``grid`` above ``max_grid``:
            one sentence.
        """
        n = {**_ACCURACY_FLAGS, **dict(names or {})}
        if (tol is not None or max_grid is not None or special_tol is not None or not solve_check) and not self.adaptive:
            raise SceneError(f"scene {self.name!r} has no adaptive resolution ({n['tol']}, {n['max_grid']}, "
                             f"{n['special_tol']}, {n['solve_check']}); choose its grid with {n['grid']}")
        unused = [n[k] for k, v in (("special_tol", special_tol), ("max_grid", max_grid), ("solve_check", solve_check))
                  if v is not None and v is not True]
        if unused and grid is not None and tol is None:  # a fixed grid: they were ignored, exit 0 (max_grid, solve_check)
            raise SceneError(f"{', '.join(unused)} {'needs' if len(unused) == 1 else 'need'} adaptive resolution: "
                             f"drop {n['grid']} or add {n['tol']}")
        if not self.adaptive or (tol is None and grid is not None):
            return {}
        out: dict[str, Any] = {"tol": tol if tol is not None else self.default_tol}
        if not solve_check:
            out["solve_check"] = False
        if special_tol is not None:
            out["special_tol"] = special_tol
        if max_grid is not None:
            if grid is not None and grid > max_grid:
                raise SceneError(f"{n['grid']} {grid} exceeds {n['max_grid']} {max_grid}")
            out["max_grid"] = max_grid
        return out


#: The command line's names of the accuracy settings (:meth:`Scene.accuracy_overrides` messages).
_ACCURACY_FLAGS = {"tol": "--tol", "max_grid": "--max-grid", "special_tol": "--special-tol",
                   "solve_check": "--no-solve-check", "grid": "--grid"}


def stability_after_run(scene: Scene, request: SceneRequest, result: SceneResult,
                        say: Callable[[str], None] = lambda line: None, *, kx_name: str = "--kx") -> None:
    """The stability pass the scene left undone, through ``scene.problem_factory``: what
    ``contin trace`` and every ``contin sweep`` task do after the scene's run (unless the user
    switched stability off), so that a task file holds the stability columns ``trace`` writes.

    Nothing for a scene with ``stability=False`` (a ``note:`` line).  Branches the scene left
    without stability columns get :meth:`SceneRequest.run_stability` (k_x = k_z = 0, audit, and
    the extra ``kx`` columns); a scene that computed stability itself is trusted with the extra
    wavenumbers too.  Fold curves and other multi-parameter branches are skipped (their states
    are not states of the problem).  Failures become ``warning:`` lines: the traced branches are
    never lost to a stability problem.  A nonzero k_x of ``request.kx`` that no branch has a
    ``growth_rate_kx`` column for is one ``warning:`` line with the reason (never a silent
    no-op; ``kx_name``: how the caller calls the setting).  ``say`` receives the ``note:`` and
    ``warning:`` lines as they happen; ``request.report`` the progress (one line per branch).
    """
    _stability_pass_after_run(scene, request, result, say)
    missing = [f"{k:g}" for k in request.kx if k != 0
               and not any(f"growth_rate_kx{k:g}" in b.observables for b in result.branches)]
    if not missing:
        return
    name = scene.name
    if request.kx_unavailable:  # it said "computed no stability" of a scene whose k_x = 0 pass ran
        why = (f"scene {name!r} has no wavenumber: its problem has no eigenproblem(u, p, kx, kz), so only "
               f"k_x = 0 exists (that stability was computed)")
    elif not scene.stability:
        why = f"scene {name!r} has no linear-stability operator (no stability was computed)"
    elif scene.problem_factory is None and not any(b.n_unstable is not None for b in result.branches):
        why = (f"scene {name!r} computed no stability (it has no problem_factory to rebuild its problem "
               f"for a stability pass)")
    else:
        why = f"scene {name!r} computed no stability"
    say(f"warning: {kx_name} {','.join(missing)} ignored: {why}; no growth_rate_kx column was stored")


def _stability_pass_after_run(scene: Scene, request: SceneRequest, result: SceneResult,
                              say: Callable[[str], None]) -> None:
    """The k_x = 0 pass (and extra kx columns) of :func:`stability_after_run`."""
    from contin.errorline import error_line

    def missing(b: Branch) -> bool:
        return len(b.free) == 1 and len(b) > 0 and b.n_unstable is None

    if not scene.stability:  # no linear-stability operator (Scene.stability): a pass would be doubtful
        say(f"note: scene {scene.name!r} has no linear-stability operator; branches are stored without stability")
        return
    todo = [b for b in result.branches if missing(b)]
    if not todo:
        return
    if scene.problem_factory is None:
        say(f"note: scene {scene.name!r} computed no stability and has no problem_factory; "
            "branches are stored without stability")
        return
    try:
        problem = scene.problem_factory(result.parameters, result.discretization)
    except Exception as exc:  # noqa: BLE001 -- report, keep the branches
        say(f"warning: stability skipped: cannot rebuild the problem ({error_line(exc)})")
        return
    for b in todo:
        request.report(f"stability of branch {b.id} ({len(b)} points)")
        try:
            request.run_stability(problem, b, result.parameters)
        except Exception as exc:  # noqa: BLE001
            say(f"warning: stability of branch {b.id} failed: {error_line(exc)}")


def scene_params(request: SceneRequest, defaults: Mapping[str, Any], scene: str) -> dict[str, Any]:
    """``defaults`` merged with the request's values as typed; SceneError for an unknown name.

    The error lists the scene's parameters."""
    out = dict(defaults)
    for name, value in request.params.items():
        _known(name, defaults, scene)
        out[name] = value
    return out


def _known(name: str, defaults: Mapping[str, Any], scene: str) -> None:
    if name not in defaults:
        raise SceneError(f"unknown parameter {name!r} for scene {scene!r}; its parameters are {', '.join(defaults)}")


def scene_number(scene: str, name: str, value: Any) -> float:
    """``value`` as a finite float; else a one-line SceneError naming the parameter and the scene.
    A boolean is no number (a sweep file's ``lam_min = [true]`` ran bratu at lam_min = 1, 'ok')."""
    if isinstance(value, bool | np.bool_):
        raise SceneError(f"parameter {name} of scene {scene!r} must be a number, got the boolean {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SceneError(f"parameter {name} of scene {scene!r} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise SceneError(f"parameter {name} of scene {scene!r} must be finite, got {value!r}")
    return v


def scene_numbers(request: SceneRequest, defaults: Mapping[str, Any], scene: str, *,
                  words: frozenset[str] | set[str] = frozenset()) -> dict[str, Any]:
    """``defaults`` merged with the request's values, each a finite number or, in ``words``, a string.

    Checked one by one in the order given: a known name (as :func:`scene_params`), then a finite
    number (:func:`scene_number`); a name in ``words`` is kept as ``str``.  Defaults are taken as
    they are."""
    out = dict(defaults)
    for name, value in request.params.items():
        _known(name, defaults, scene)
        out[name] = str(value) if name in words else scene_number(scene, name, value)
    return out


def require_started(branch: Any, scene: str) -> Any:
    """``branch`` if it has a point; else a :class:`SceneError` saying why it could not start.

    A trace whose start point does not converge (extreme parameters, a grid far too coarse)
    returns a branch of no points with the reason in ``message``.  A scene that goes on to read
    its observables or last point would fail on the empty arrays with an unrelated message
    (``Error: asym_phi``, ``index -1 is out of bounds``); it calls this first instead."""
    if len(branch) == 0:
        raise SceneError(f"{scene}: branch {branch.id} could not start: {branch.message}")
    return branch


_log = logging.getLogger("contin.scene")

#: Entry points that failed to load at the last :func:`available_scenes` call:
#: ``[(source, "ExceptionType: message"), ...]`` (``contin scenes`` reports them).
SCENE_LOAD_ERRORS: list[tuple[str, str]] = []


def _scene_sources() -> list[tuple[str, Callable[[], Any]]]:
    """(label, loader) for every registered scene table.

    Entry points of the group ``contin.scenes``, plus ``module:ATTR`` items from the
    environment variable ``CONTIN_SCENES`` (comma separated; handy for plugins that are not
    installed as packages, and for tests).
    """
    sources: list[tuple[str, Callable[[], Any]]] = [
        (f"{ep.name} ({ep.value})", ep.load) for ep in entry_points(group="contin.scenes")
    ]
    for item in filter(None, (x.strip() for x in os.environ.get("CONTIN_SCENES", "").split(","))):
        module, _, attr = item.partition(":")

        def load(module: str = module, attr: str = attr or "SCENES") -> Any:
            return getattr(importlib.import_module(module), attr)

        sources.append((f"CONTIN_SCENES ({item})", load))
    return sources


def available_scenes() -> dict[str, Scene]:
    """All scenes registered under the ``contin.scenes`` entry-point group.

    A scene module that is missing or fails to import is skipped with a logged warning (and
    recorded in :data:`SCENE_LOAD_ERRORS`), so one broken problem package never hides the
    others.
    """
    scenes: dict[str, Scene] = {}
    SCENE_LOAD_ERRORS.clear()
    for label, load in _scene_sources():
        try:
            table = load()
            scenes.update(table)
        except Exception as exc:  # noqa: BLE001 -- any import failure must not break the CLI
            reason = f"{type(exc).__name__}: {exc}".splitlines()[0]
            SCENE_LOAD_ERRORS.append((label, reason))
            _log.warning("skipping scenes from %s: %s", label, reason)
    return dict(sorted(scenes.items()))


def get_scene(name: str) -> Scene:
    """The scene called ``name``; SceneError listing the known ones otherwise.

    Lazy: the scene tables are loaded from the last source to the first and the search stops
    at the first table holding ``name`` -- the table :func:`available_scenes` would take it
    from (later sources override earlier ones there) -- so running one scene does not import
    every problem package.
    """
    SCENE_LOAD_ERRORS.clear()
    tables: list[Mapping[str, Scene]] = []
    for label, load in reversed(_scene_sources()):
        try:
            table = dict(load())  # dict(): a malformed table fails here, as in available_scenes
        except Exception as exc:  # noqa: BLE001 -- as in available_scenes
            reason = f"{type(exc).__name__}: {exc}".splitlines()[0]
            SCENE_LOAD_ERRORS.append((label, reason))
            _log.warning("skipping scenes from %s: %s", label, reason)
            continue
        if name in table:
            return table[name]
        tables.append(table)
    SCENE_LOAD_ERRORS.reverse()  # in source order, as available_scenes lists them
    scenes = dict(sorted({k: v for table in reversed(tables) for k, v in table.items()}.items()))
    if name not in scenes:
        broken = f" ({len(SCENE_LOAD_ERRORS)} scene module(s) failed to load; see `contin scenes`)" if SCENE_LOAD_ERRORS else ""
        raise SceneError(f"unknown scene {name!r}; known scenes: {', '.join(scenes) or 'none'}{broken}")
    return scenes[name]
