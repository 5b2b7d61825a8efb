"""Byte-compile the project's packages before timing whole processes.

``pip install`` of a wheel writes the .pyc files; an editable install in an environment with
PYTHONDONTWRITEBYTECODE=1 (this machine) never does, so every process would compile contin's
and problems' ~40 modules from source again (0.2-1 s of start-up that no installed copy pays).
"""

from __future__ import annotations

import compileall
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def precompile() -> None:
    for pkg in ("contin", "problems", "benchmarks"):
        compileall.compile_dir(str(ROOT / pkg), quiet=1)
