"""Scenes: named, reproducible continuation jobs that the CLI can run.

contin knows no physics; problem packages register scenes through the entry-point group
``contin.scenes`` (see ``pyproject.toml``).  Each entry point names a ``dict[str, Scene]``.
A scene turns a :class:`SceneRequest` (user parameters, discretization, options) into a
:class:`SceneResult` (branches plus notes and provenance).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any

import numpy as np

from contin.branch import Branch
from contin.options import ContinuationOptions


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
    """

    branches: list[Branch]
    parameters: dict[str, Any]
    discretization: dict[str, Any] = field(default_factory=dict)
    y: np.ndarray | None = None
    profiles: Callable[[np.ndarray], dict[str, np.ndarray]] | None = None
    notes: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Scene:
    """A named job: ``run(request) -> SceneResult``; ``defaults`` documents its parameters."""

    name: str
    summary: str
    defaults: Mapping[str, Any]
    run: Callable[[SceneRequest], SceneResult]
    x: str = ""  # default x-axis of its diagram (a parameter name)
    y: str = "phi"  # default y-axis (an observable name)


def available_scenes() -> dict[str, Scene]:
    """All scenes registered under the ``contin.scenes`` entry-point group."""
    scenes: dict[str, Scene] = {}
    for ep in entry_points(group="contin.scenes"):
        scenes.update(ep.load())
    return dict(sorted(scenes.items()))


def get_scene(name: str) -> Scene:
    """The scene called ``name``; SceneError listing the known ones otherwise."""
    scenes = available_scenes()
    if name not in scenes:
        raise SceneError(f"unknown scene {name!r}; known scenes: {', '.join(scenes) or 'none'}")
    return scenes[name]
