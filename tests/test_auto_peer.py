"""The AUTO-07p peer benchmark's pieces that run without AUTO: the fort.7/fort.8 readers and the skip."""

from __future__ import annotations

from benchmarks.auto_peer import __main__ as driver
from benchmarks.auto_peer import auto
from benchmarks.auto_peer.fort import _float, count_points, read_solutions

# Two labelled solutions in AUTO-07p's fort.8 layout (header: IBR NTOT ITP LAB NFPR ISW NTPL NAR
# NROWPR NTST NCOL NPAR ...; then NTPL rows of (t, U), ICP, RLDOT, NTPL rows of U-dot, PAR).
FORT8 = """\
     1     8     6     2     2     1     2     3     7    1    1    3    0    2    4    0
      0.0000000000E+000 -5.0000000000E-001  4.8173767811E-001
      1.0000000000E+000  5.0000000000E-001  4.8173767811E-001
     1     2
      1.0000000000E+000  0.0000000000E+000
      0.0000000000E+000  0.0000000000E+000
      0.0000000000E+000  0.0000000000E+000
      1.3068529366E+001  3.2282439878E-001  2.9999674100E-001
     2    29     5     4     2    -1     2     3     7    1    1    3    0    2    4    0
      0.0000000000E+000 -5.0000000000E-001  4.8173767811E-001
      1.0000000000E+000  5.0000000000E-001  4.8173767811E-001
     1     2
      1.0000000000E+000  0.0000000000E+000
      0.0000000000E+000  0.0000000000E+000
      0.0000000000E+000  0.0000000000E+000
      4.1962532344E+001  1.2774500000E-001  1.2550000000E-001
"""

FORT7 = """\
   0  -1.7976+308  1.7976+308 -1.7976+308  1.7976+308
   0   EPSL= 1.0000E-05  EPSU = 1.0000E-05  EPSS = 1.0000E-05
   0    PT  TY  LAB       H               L2-NORM
   1     1   9    1  2.0000000000E+000  6.5985189553E-001
   1    -2   0    0  2.5000000000E+000  6.5985189553E-001
   1     3   6    2  1.3068529366E+001  6.5985189553E-001
"""


def test_fort8_labels_types_and_full_precision_parameters(tmp_path):
    (tmp_path / "fort.8").write_text(FORT8)
    sols = read_solutions(tmp_path / "fort.8")
    assert [(s.branch, s.point, s.type, s.label) for s in sols] == [(1, 8, "BP", 2), (2, 29, "LP", 4)]
    assert sols[0].par == (13.068529366, 0.32282439878, 0.299996741)
    assert sols[1].par[0] == 41.962532344


def test_fort7_counts_points_not_headers(tmp_path):
    (tmp_path / "fort.7").write_text(FORT7)
    assert count_points(tmp_path / "fort.7") == 3


def test_auto_number_formats():
    assert _float("1.0000E-005") == 1e-5
    assert _float("-1.7976+308") == -1.7976e308
    assert _float("4.1962532344E+001") == 41.962532344


def test_constants_file_keywords():
    text = auto.constants(IRS=2, ICP="['H', 'S']", UZSTOP="{'H': 43.1}")
    assert "ICP = ['H', 'S']" in text and "UZSTOP = {'H': 43.1}" in text and "NTST = 40" in text
    assert text.startswith("parnames = {1: 'H'")


def test_without_auto_the_benchmark_says_so_and_exits_0(monkeypatch, capsys):
    monkeypatch.setattr(auto, "find_auto", lambda: (None, "AUTO-07p is not installed (test)"))
    assert driver.main(["--repeats", "1"]) == 0
    assert "skipped: AUTO-07p is not installed (test)" in capsys.readouterr().out
