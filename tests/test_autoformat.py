"""contin export --auto: AUTO-07p's b.NAME / s.NAME (contin.autoformat).

The reference is AUTO-07p's own output for the same problem: tests/data/auto_ab holds the b.ab and
s.ab that AUTO-07p 0.9 (the Debian package's Fortran core) wrote for its demo ab (equation file
ab.f90, constants c.ab: u = 0 at D = 0 continued in D with B = 14, beta = 3, to D = 0.5).  The
export of contin's `ab` scene must have AUTO's fixed-width layout line for line and the same HB
labels (within AUTO's accuracy, ~5e-7), read back by an AUTO-layout reader.  (AUTO's Fortran core
restarting from the exported s.NAME is checked by ``python -m benchmarks.auto_peer.export_check``,
which needs AUTO-07p.)
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.autoformat import e19, write_auto
from contin.cli import main

DATA = Path(__file__).resolve().parent / "data" / "auto_ab"
NUMBER = r" [ -]\d\.\d{10}E[+-]\d{3}"  # 19 characters


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def read_b(path: Path) -> tuple[list[str], list[tuple[int, int, int, int, list[float]]]]:
    """(column names, rows (BR, PT, TY, LAB, values)) of the first section of a b-file, by AUTO's
    rule (parseB.parseHeader): 19 characters for BR PT TY LAB, then 19 per column, the names at
    the same positions in the last header line."""
    lines = Path(path).read_text().splitlines()
    header = [ln for ln in lines if ln.split()[0] == "0"]
    data = [ln for ln in lines if ln.split()[0] != "0"]
    ncol = len(data[0].split()) - 4
    assert len(data[0]) == 19 + 19 * ncol
    names = [header[-1][19 + 19 * i:38 + 19 * i].strip() for i in range(ncol)]
    rows = []
    for ln in data:
        assert re.fullmatch(r"[ \d-]{4}[ \d-]{6}[ \d-]{4}[ \d-]{5}" + f"(?:{NUMBER}){{{ncol}}}", ln), ln
        rows.append((int(ln[:4]), int(ln[4:10]), int(ln[10:14]), int(ln[14:19]),
                     [float(ln[19 + 19 * i:38 + 19 * i]) for i in range(ncol)]))
    return names, rows


def read_s(path: Path) -> list[dict]:
    """Blocks of an s-file: header integers, then NROWPR lines (AUTO's algebraic layout)."""
    lines = Path(path).read_text().splitlines()
    out, i = [], 0
    while i < len(lines):
        head = [int(x) for x in lines[i].split()]
        assert len(head) == 16
        nrowpr, ndim, npar, nfpr = head[8], head[13], head[11], head[4]
        body = lines[i + 1:i + 1 + nrowpr]
        assert len(body) == nrowpr
        k = ndim // 7 + 1
        u = [float(x) for ln in body[:k] for x in ln.split()]
        icp = [int(x) for x in body[k].split()]
        par = [float(x) for ln in body[-((npar + 6) // 7):] for x in ln.split()]
        out.append({"head": head, "t_u": u, "icp": icp, "par": par, "nfpr": nfpr})
        i += 1 + nrowpr
    return out


@pytest.fixture(scope="module")
def ab_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("ab")
    res = run("trace", "ab", "-o", d / "ab.h5")
    assert res.exit_code == 0, res.output
    res = run("export", d / "ab.h5", "--auto", "ab", "-d", d)
    assert res.exit_code == 0, res.output
    return d


def test_b_file_has_autos_layout_and_hb_rows(ab_run):
    names, rows = read_b(ab_run / "b.ab")
    auto_names, auto_rows = read_b(DATA / "b.ab")
    assert names[:4] == auto_names == ["PAR(1)", "L2-NORM", "U(1)", "U(2)"] and names[4] == "phi"
    ours_hb = [r for r in rows if r[2] == 3]
    auto_hb = [r for r in auto_rows if r[2] == 3]
    assert len(ours_hb) == len(auto_hb) == 2
    for mine, theirs in zip(ours_hb, auto_hb, strict=True):
        assert (mine[1] < 0) == (theirs[1] < 0)  # the same stability at the HB
        assert np.allclose(mine[4][:4], theirs[4], rtol=2e-6, atol=0)  # AUTO's HB2 is 5e-7 off
    # labels as contin's (HB1, HB2, EP3), EP on the bound D = 0.5
    assert [(r[2], r[3]) for r in rows if r[2] != 0] == [(3, 1), (3, 2), (9, 3)]
    assert rows[-1][4][0] == 0.5
    # headers AUTO's parser reads: the active parameter and the names of PAR(i)
    text = (ab_run / "b.ab").read_text()
    assert "   0   Active continuation parameter:      1" in text and "parnames = {1: 'D', 2: 'B', 3: 'beta'}" in text


def test_s_file_blocks_as_autos_with_the_period_at_hb(ab_run):
    ours = {b["head"][3]: b for b in read_s(ab_run / "s.ab")}
    auto = [b for b in read_s(DATA / "s.ab") if b["head"][2] == 3]
    assert sorted(ours) == [1, 2, 3] and len(auto) == 2
    for lab, theirs in zip((1, 2), auto, strict=True):
        mine = ours[lab]
        # header: BR, PT, TY, LAB, NFPR, ISW, NTPL, NAR, NROWPR, NTST, NCOL, NPAR, NPARI, NDIM, IPS, IPRIV
        assert [mine["head"][i] for i in (2, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)] == \
               [theirs["head"][i] for i in (2, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)]
        assert mine["icp"] == theirs["icp"] == [1]
        assert np.allclose(mine["t_u"], theirs["t_u"], rtol=2e-6, atol=1e-12)
        assert np.allclose(mine["par"][:3], theirs["par"][:3], rtol=2e-6)
        assert mine["par"][10] == pytest.approx(theirs["par"][10], rel=1e-5)  # 2 pi / omega
    # an independent reader of AUTO's files (written against AUTO's own output)
    from benchmarks.auto_peer.fort import read_solutions

    sols = read_solutions(ab_run / "s.ab")
    auto_hb = [s for s in read_solutions(DATA / "s.ab") if s.type == "HB"]
    assert [s.type for s in sols] == ["HB", "HB", "EP"]
    assert [s.par[0] for s in sols[:2]] == pytest.approx([s.par[0] for s in auto_hb], rel=2e-6)


def test_curves_codim2_codes_and_bad_input(tmp_path, ab_run):
    res = run("continue", ab_run / "ab.h5", "--from", "HB1", "--free", "B", "--bounds", "B=0:40", "-o", tmp_path / "h.h5")
    assert res.exit_code == 0, res.output
    res = run("export", tmp_path / "h.h5", "--auto", "hopf", "-d", tmp_path)
    assert res.exit_code == 0, res.output
    names, rows = read_b(tmp_path / "b.hopf")
    assert names == ["PAR(1)", "L2-NORM", "U(1)", "U(2)", "PAR(2)", "phi"]
    codes = {r[2]: r for r in rows if r[2] != 0}
    assert set(codes) == {9, -1, -32, 2}  # EP, BT, GH, LP (extremum of D)
    assert codes[-1][4][4] == pytest.approx(64 / 3, rel=1e-9)  # BT at B = 64/3
    blocks = read_s(tmp_path / "s.hopf")
    assert all(b["icp"] == [1, 2] and b["nfpr"] == 2 and b["head"][13] == 2 for b in blocks)  # base state u only
    # bad input: one Error line each
    for args, expect in ((("--auto", "a b"), "bad AUTO run name"), (("--auto", "x", "--par", "D=1"), "no PAR index"),
                         (("--auto", "x", "--par", "D=0,B=2,beta=3"), "INDEX >= 1"),
                         (("--auto", "x", "-d", tmp_path / "none"), "no such directory")):
        res = run("export", tmp_path / "h.h5", *args)
        assert res.exit_code != 0 and expect in res.output and "Traceback" not in res.output
    (branch,), _ = io.load(tmp_path / "h.h5")
    branch.states[3, 0] = math.nan
    with pytest.raises(ValueError, match="not finite"):
        write_auto([branch], "bad", tmp_path)
    assert not (tmp_path / "b.bad").exists()


def test_special_points_between_stored_points_are_rows_of_their_own(ab_run):
    (branch,), _ = io.load(ab_run / "ab.h5")
    _, rows = read_b(ab_run / "b.ab")
    assert len(rows) == len(branch) + 2  # the two HBs inserted, the EP labels the last stored point
    hb = branch.points("HB")
    mine = [r for r in rows if r[2] == 3]
    for sp, row in zip(hb, mine, strict=True):
        assert row[4][0] == float(e19(sp.params["D"]))
        assert row[4][2] == float(e19(sp.state[0])) and row[4][3] == float(e19(sp.state[1]))
    assert json.dumps(e19(1e-5)) == json.dumps("  1.0000000000E-005")  # AUTO's 3-digit exponent


def test_s_file_point_numbers_are_unsigned_as_autos(ab_run):
    """AUTO writes PT signed in the b-file (negative = stable) and unsigned in the s-file header
    (ae.f90 WRTSP8; its own s.ab: PT 1 for the b-file's -1 at LAB 1).  contin wrote the b-file's
    sign into the s-file too (results/s.ab had PT -25)."""
    _, b_rows = read_b(ab_run / "b.ab")
    pt_of = {lab: pt for (_, pt, _, lab, _) in b_rows if lab > 0}
    blocks = read_s(ab_run / "s.ab")
    assert blocks and all(b["head"][1] == abs(pt_of[b["head"][3]]) > 0 for b in blocks)
    assert any(pt_of[b["head"][3]] < 0 for b in blocks)  # a stable labelled point is among them
    _, auto_b = read_b(DATA / "b.ab")
    auto_pt = {lab: pt for (_, pt, _, lab, _) in auto_b if lab > 0}
    assert all(b["head"][1] == abs(auto_pt[b["head"][3]]) for b in read_s(DATA / "s.ab"))
