"""Helpers shared by the robustness sweeps' CLI tests (tests/test_cli_qa15.py, _qa16, _qa17).

``real_scenes`` (autouse where imported): the real scene registry, not a fixture's
CONTIN_SCENES; ``run``: the CLI in-process, exceptions not caught (a traceback fails the test);
``one_error``: the project's rule for bad input -- exactly one ``Error:`` line, a non-zero exit,
no traceback -- asserted, the line returned.
"""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from contin.cli import main


@pytest.fixture(autouse=True)
def real_scenes(monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)


def run(args: list[str]):
    return CliRunner().invoke(main, args, catch_exceptions=False)


def one_error(res) -> str:
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code != 0 and len(errors) == 1 and "Traceback" not in res.stderr, res.stderr
    return errors[0]
