"""README.md: the "Your own problem" example runs as printed (F(u, p) to a diagram in under 15
lines) and the API reference lists exactly the public API (contin.apiref)."""

from __future__ import annotations

import contextlib
import io as _io
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def _section(title: str) -> str:
    text = README.read_text()
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


def test_own_problem_example_runs(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", _section("Your own problem"), re.S)
    assert len(blocks) == 2
    lines = [ln for ln in blocks[0].splitlines() if ln.strip()]
    assert len(lines) < 15, "the example must take a reader from F(u, p) to a diagram in under 15 lines"
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    out = _io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(blocks[0], "README-own-problem", "exec"), ns)
    lam = float(re.search(r"LP1: lam = ([0-9.]+)", out.getvalue()).group(1))
    # fold of the n = 100 difference problem: within O(h^2) ~ 1e-4 of the continuous 3.513830719
    assert lam == pytest.approx(3.513830719, abs=3e-4)
    assert (tmp_path / "bratu.png").stat().st_size > 1000
    exec(compile(blocks[1], "README-restart", "exec"), ns)
    assert ns["p"] == {"lam": pytest.approx(lam, abs=1e-6)} and ns["tangent"].size == 101
    assert ns["more"].status == "EP" and len(ns["more"]) == 21


def test_api_reference_matches_the_code():
    from contin.apiref import END, START, markdown

    text = README.read_text()
    current = text[text.index(START): text.index(END) + len(END)]
    assert current == markdown(), "README API reference is stale: run `python -m contin.apiref --write`"


def test_api_reference_lists_every_public_name():
    from contin.apiref import MODULES, markdown, public_names

    doc = markdown()
    for module in MODULES:
        for name in public_names(module):
            assert f"| `{name}` (" in doc
    assert "| `from_functions` (def)" in doc and "| `restart` (def)" in doc and "| `continue_point` (def)" in doc
