"""Start-up structure (not timed): the CLI entry point and scene lookup import only what they use."""

from __future__ import annotations

import os
import subprocess
import sys

HEAVY = ("numpy", "scipy", "h5py", "matplotlib", "numba")


def _loaded(code: str, **env: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True, env={**os.environ, **env})
    return set(out.stdout.split())


def test_import_cli_loads_no_heavy_library():
    """``contin --help`` / ``--version`` import contin.cli only: no numpy, scipy, h5py, matplotlib, numba."""
    loaded = _loaded("import contin.cli")
    assert "contin.cli.trace" in loaded  # the commands are registered
    assert not {m for m in loaded if m.split(".")[0] in HEAVY}


def test_lazy_package_attributes():
    """``import contin`` is light; ``contin.Branch`` etc. resolve on first access."""
    loaded = _loaded("import contin")
    assert not {m for m in loaded if m.split(".")[0] in HEAVY}
    import contin
    from contin.branch import Branch
    from contin.problem import check_jacobian

    assert contin.Branch is Branch and contin.check_jacobian is check_jacobian
    assert set(contin.__all__) <= set(dir(contin))


def test_get_scene_imports_only_what_it_needs():
    """Finding one scene stops at the table holding it (no scipy.optimize at import time)."""
    loaded = _loaded("import contin.scene as s; s.get_scene('pitchfork')", CONTIN_SCENES="")
    assert "problems.couette.scenes" in loaded
    assert "scipy.optimize" not in loaded and "h5py" not in loaded and "matplotlib" not in loaded


def test_get_scene_later_source_wins(monkeypatch):
    """get_scene takes a name from the same table as available_scenes (later sources override)."""
    import contin.scene as sc

    first = {"x": sc.Scene("x", "first", {}, lambda r: None)}
    second = {"x": sc.Scene("x", "second", {}, lambda r: None), "y": sc.Scene("y", "y", {}, lambda r: None)}

    def broken():
        raise ImportError("no such module")

    monkeypatch.setattr(sc, "_scene_sources", lambda: [("a", lambda: first), ("b", lambda: second), ("c", broken)])
    assert sc.available_scenes()["x"].summary == "second"
    assert sc.get_scene("x").summary == "second"
    assert sc.get_scene("y").summary == "y"
    try:
        sc.get_scene("z")
    except sc.SceneError as exc:
        assert "known scenes: x, y" in str(exc) and "1 scene module(s) failed" in str(exc)
    else:  # pragma: no cover
        raise AssertionError("unknown scene accepted")
    assert sc.SCENE_LOAD_ERRORS == [("c", "ImportError: no such module")]


def test_version_matches_the_package_metadata():
    """``contin --version`` prints contin.__version__ without a metadata scan: it must stay the
    installed package's version."""
    from importlib.metadata import version

    import contin

    assert contin.__version__ == version("contin")
